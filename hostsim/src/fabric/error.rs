//! Why a run fails, on any fabric, and the last events a simulated failure carries.
//!
//! Invariant: every failure says what was broken and where; a simulated one also names the
//! seed and scheduler that replay it event for event.

use super::config::Scheduler;
use super::shift::ShiftFailure;
use std::fmt;
use voxcube_kernel::node::msg::DecodeError;
use voxcube_kernel::node::partition::PartitionError;
use voxcube_kernel::node::worker::WorkerError;
use voxcube_kernel::volume::slab::SlabError;

/// The last events of a run, oldest first.
#[derive(Clone, Debug, Default)]
pub struct Trace(pub Vec<String>);

impl fmt::Display for Trace {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for line in &self.0 {
            writeln!(f, "  {line}")?;
        }
        Ok(())
    }
}

/// Why a run failed, on any fabric. A simulated run's failure names its seed and scheduler:
/// replay with them.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    /// The partition does not fit the grid.
    #[error("partition: {0}")]
    Partition(#[from] PartitionError),
    /// The plane shift to balanced cuts failed.
    #[error("{0}")]
    Shift(#[from] ShiftFailure),
    /// A slab could not be built.
    #[error("slab: {0}")]
    Slab(#[from] SlabError),
    /// A worker could not be set up (e.g. a buffer too small for any ray to start).
    #[error("worker: {0}")]
    Worker(#[from] WorkerError),
    /// The receive buffer leaves no ray room to start.
    #[error("a receive buffer of {bytes} bytes allows i_max {i_max} in clusters of {size}; this view needs i_max {needed}: give each node at least {min_bytes} bytes")]
    Buffer {
        /// Bytes given.
        bytes: usize,
        /// Nodes per cluster.
        size: usize,
        /// `i_max` those bytes allow.
        i_max: usize,
        /// `i_max` needed (`r_imax + 1`).
        needed: usize,
        /// The smallest buffer that works.
        min_bytes: usize,
    },
    /// A message did not decode.
    #[error("message from node {from}: {error}")]
    Decode {
        /// Sender.
        from: u16,
        /// Why.
        error: DecodeError,
    },
    /// The host of a fabric that cannot replay its schedule (threads, MPI) saw a rule broken
    /// (a pixel twice, a message it cannot take) or heard nothing for too long.
    #[error("{0}")]
    Host(String),
    /// An invariant failed in the simulator.
    #[error("invariant broken after {events} events (seed {seed}, {scheduler}): {what}\nlast events:\n{trace}")]
    Invariant {
        /// What.
        what: String,
        /// Events run.
        events: u64,
        /// The seed.
        seed: u64,
        /// The scheduler.
        scheduler: Scheduler,
        /// The last events.
        trace: Trace,
    },
    /// No event is possible and the host has not ended: a deadlock.
    #[error("deadlock after {events} events (seed {seed}, {scheduler}): {missing} pixels missing, {tokens} tokens, {reports} of {nodes} reports; unfinished nodes {unfinished:?}\nlast events:\n{trace}")]
    Deadlock {
        /// Events run.
        events: u64,
        /// Pixels the host lacks.
        missing: u64,
        /// Tokens the host holds.
        tokens: u32,
        /// Statistics received.
        reports: usize,
        /// Nodes.
        nodes: usize,
        /// Nodes whose pixels are not final.
        unfinished: Vec<u16>,
        /// The seed.
        seed: u64,
        /// The scheduler.
        scheduler: Scheduler,
        /// The last events.
        trace: Trace,
    },
    /// A node stopped answering: the run cannot complete.
    #[error("node {node} stopped answering ({waiting} messages wait unread for it); {missing} pixels are lost, in rows {rows}")]
    Lost {
        /// The node that stopped.
        node: u16,
        /// Messages waiting for it.
        waiting: usize,
        /// Pixels the host lacks.
        missing: u64,
        /// The rows they are in, summarised.
        rows: String,
    },
    /// Far more events than the work can need: a livelock.
    #[error("no end after {events} events (seed {seed}, {scheduler})\nlast events:\n{trace}")]
    Watchdog {
        /// Events run.
        events: u64,
        /// The seed.
        seed: u64,
        /// The scheduler.
        scheduler: Scheduler,
        /// The last events.
        trace: Trace,
    },
}

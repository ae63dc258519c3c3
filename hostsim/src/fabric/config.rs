//! How to run a view on the machine, whatever carries the messages: the layout, who generates
//! primary rays, the slab cuts and how the nodes reach them, the receive buffers and flow
//! control, virtual time, skipping, and the simulator's schedule.
//!
//! Invariant: nothing here changes a pixel. The image depends on the view alone; a
//! configuration decides only where the work runs, in what order and at what cost.

use crate::memory::storage::SkipMode;
use crate::profile::MachineProfile;
use std::fmt;
use voxcube_kernel::node::flow;
use voxcube_kernel::node::partition::{Partition, PartitionError};
use voxcube_kernel::node::topology::{Layout, LayoutError};
use voxcube_kernel::node::worker::Generation;

/// How long a node may go unheard before the host declares it lost: long against a poll
/// (microseconds) and against the OS taking a core from a thread on a busy machine.
pub const DEFAULT_LOST_AFTER: std::time::Duration = std::time::Duration::from_secs(2);

/// `i_max` the default receive buffer is sized for.
pub const DEFAULT_I_MAX: usize = 8;

/// Which in-flight message or node the scheduler favours.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Scheduler {
    /// Every enabled event equally likely.
    Uniform,
    /// Deliver the newest message first (a stack, not a queue), stepping nodes at random.
    NewestFirst,
    /// Never deliver on the link `from → to` while anything else can happen.
    Starve {
        /// Sending node.
        from: u16,
        /// Receiving node.
        to: u16,
    },
    /// Deliver acknowledgements only when nothing else can happen.
    DelayAcks,
}

impl fmt::Display for Scheduler {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Scheduler::Uniform => f.write_str("uniform"),
            Scheduler::NewestFirst => f.write_str("newest-first"),
            Scheduler::Starve { from, to } => write!(f, "starve {from}->{to}"),
            Scheduler::DelayAcks => f.write_str("delay-acks"),
        }
    }
}

/// How the simulator orders events (read by the sim fabric only; threads and MPI are
/// scheduled by the OS and the network).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Schedule {
    /// Scheduler seed: the same seed gives the same run, event for event.
    pub seed: u64,
    /// Scheduler policy.
    pub scheduler: Scheduler,
    /// A fault to inject: this node stops answering after this many of its own steps (the
    /// simulator) or polls (threads, MPI).
    pub stop: Option<(u16, u64)>,
    /// With `stop`, on MPI: the stopped node's process exits (a crash) instead of hanging.
    /// The other fabrics cannot tell the two apart.
    pub crash: bool,
    /// A second fault, in the re-trace the first one causes: this node of the machine (of a
    /// surviving cluster) stops after this many of its own steps there.
    pub retrace_stop: Option<(u16, u64)>,
}

/// How to run a view, on any fabric.
#[derive(Clone, Debug)]
pub struct RunConfig {
    /// Clusters and their size.
    pub layout: Layout,
    /// Primary-ray generation.
    pub generation: Generation,
    /// Slab cuts (`cd + 1` of them); `None` for a uniform partition.
    pub cuts: Option<Vec<u32>>,
    /// With `cuts`: every node starts on its uniform slab and shifts planes to its neighbours
    /// by slab-plane messages until it holds its slab of `cuts`, before rendering (timed runs
    /// add the shift's time). Without it the nodes load their slabs of `cuts` directly.
    pub shift: bool,
    /// Receive-buffer bytes per node; `None` for room for [`DEFAULT_I_MAX`].
    pub buffer_bytes: Option<usize>,
    /// Ack-counter flow control (off only to show what it prevents).
    pub flow_control: bool,
    /// Virtual time on this machine profile (simulator): events run in time order (the
    /// scheduler and seed then only break ties) and every node's time is kept by category.
    pub time: Option<MachineProfile>,
    /// With `time`: keep every node's timeline of compute, send, receive, test and idle
    /// spans ([`crate::fabric::VirtualTime::timeline`]).
    pub timeline: bool,
    /// How the nodes skip provably empty samples (changes no pixel; off to compare).
    pub skipping: SkipMode,
    /// The simulator's event order.
    pub schedule: Schedule,
    /// How long the threads and MPI hosts wait without hearing from a node before they
    /// declare it lost (the simulator declares it once nothing else can happen).
    pub lost_after: std::time::Duration,
    /// Test-only faults, applied to every worker.
    #[cfg(feature = "mutants")]
    pub mutants: voxcube_kernel::node::worker::Mutants,
}

impl RunConfig {
    /// One cluster of `size` nodes, uniform slabs, distributed generation, uniform schedule
    /// from `seed`.
    pub fn cluster(size: u32, seed: u64) -> Result<RunConfig, LayoutError> {
        RunConfig::machine(1, size, seed)
    }

    /// `clusters` clusters of `size` nodes, otherwise as [`RunConfig::cluster`].
    pub fn machine(clusters: u32, size: u32, seed: u64) -> Result<RunConfig, LayoutError> {
        Ok(RunConfig {
            layout: Layout::new(clusters, size)?,
            generation: Generation::Distributed,
            cuts: None,
            shift: false,
            buffer_bytes: None,
            flow_control: true,
            time: None,
            timeline: false,
            skipping: SkipMode::ALL,
            schedule: Schedule {
                seed,
                scheduler: Scheduler::Uniform,
                stop: None,
                crash: false,
                retrace_stop: None,
            },
            lost_after: DEFAULT_LOST_AFTER,
            #[cfg(feature = "mutants")]
            mutants: Default::default(),
        })
    }

    /// The slabs of a grid `nx` planes long: the configured cuts, else uniform.
    pub fn partition(&self, nx: u32) -> Result<Partition, PartitionError> {
        match &self.cuts {
            Some(cuts) => Partition::new(cuts, nx),
            None => Partition::uniform(nx, usize::from(self.layout.size())),
        }
    }

    /// The receive-buffer bytes this configuration gives each node.
    pub fn buffer(&self) -> usize {
        self.buffer_bytes
            .unwrap_or_else(|| flow::buffer_bytes(usize::from(self.layout.size()), DEFAULT_I_MAX))
    }
}

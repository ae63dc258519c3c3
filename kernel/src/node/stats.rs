//! What a worker reports about itself: its work counters and its traffic.
//!
//! Invariant: traffic counts messages this worker handed to its port (local deliveries to its
//! own pixel records are not messages and are not counted).

use crate::counters::Counters;
use crate::node::kind::KINDS;

/// Message kinds, in the order of [`NodeStats::sent`].
pub const KIND_NAMES: [&str; 8] = [
    "ray", "hit", "resolved", "ack", "token", "pixels", "stats", "planes",
];

/// A worker's statistics.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct NodeStats {
    /// The node.
    pub node: u16,
    /// Work done.
    pub counters: Counters,
    /// Rays forwarded to the next ring position (toward higher X).
    pub forwarded_next: u64,
    /// Rays forwarded to the previous ring position (toward lower X).
    pub forwarded_prev: u64,
    /// Rays forwarded past a neighbour (a step longer than the next slab).
    pub forwarded_far: u64,
    /// Hit records and resolved descriptors sent home to another node.
    pub returned: u64,
    /// Messages sent, by kind (see [`KIND_NAMES`]).
    pub sent: [u64; KINDS],
    /// Messages that made no sense here (unknown pixel record, duplicate part): must be 0.
    pub protocol_errors: u64,
    /// Most rays waiting in the local continuation queues at once.
    pub peak_pending: u64,
    /// Most pixel records in use at once.
    pub peak_records: u64,
    /// Most messages waiting in the outbox at once.
    pub peak_outbox: u64,
    /// Largest unacknowledged count toward one destination in one class (never above `i_max`).
    pub peak_unacked: u64,
    /// Pixels this worker sent to the host: the host ends only once it holds them all.
    pub pixels_sent: u64,
}

//! One node of the machine: the worker's sans-IO state machine, the port it talks through,
//! its messages and their encoding, flow control, pixel records, the slice partition, the
//! hypercube topology, plane shifting for load balancing, and the statistics it reports.
//!
//! Invariant: a worker never blocks, sleeps, reads a clock or allocates; a full container
//! hands its item back, and a message is sent only within its destination's credit.

pub mod flow;
pub mod kind;
pub mod msg;
pub mod partition;
pub mod port;
pub mod record;
pub mod shift;
pub mod stats;
pub mod topology;
pub mod worker;

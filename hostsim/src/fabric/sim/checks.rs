//! The simulator's checks: the last events of a run, for the failure that names them, and the
//! invariants checked after every event and when the host ends.
//!
//! After every event: no buffer holds more than its capacity; every `n_i` stays within
//! `[0, i_max)` (with flow control on: the start rule, [`after_step`]); a token passes only from a node whose `n_i` are all 0;
//! messages are conserved (sent = delivered + in flight).
//! The host itself refuses a pixel twice. When the host ends: no message is in flight, every
//! `n_i` is 0 and no node counted a protocol error.

use super::network::Network;
use crate::fabric::harness::NodeWorker;
use crate::fabric::Trace;
use std::collections::VecDeque;
use std::fmt;
use voxcube_kernel::node::msg::MsgKind;
use voxcube_kernel::node::port::Dest;
use voxcube_kernel::volume::sample::Sample;

/// Events a failure shows.
const KEPT: usize = 64;

/// One scheduler event, for traces.
#[derive(Clone, Copy, Debug)]
pub(super) enum Event {
    Deliver {
        from: Option<u16>,
        to: Dest,
        kind: MsgKind,
    },
    Step {
        node: u16,
        busy: bool,
    },
    Refused {
        from: u16,
        to: u16,
        kind: MsgKind,
    },
}

impl fmt::Display for Event {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let who = |n: Option<u16>| n.map_or("host".to_string(), |n| format!("node {n}"));
        match *self {
            Event::Deliver { from, to, kind } => {
                let to = match to {
                    Dest::Node(n) => format!("node {n}"),
                    Dest::Host => "host".into(),
                };
                write!(f, "deliver {kind:?} {} -> {to}", who(from))
            }
            Event::Step { node, busy } => write!(
                f,
                "step node {node}: {}",
                if busy { "busy" } else { "idle" }
            ),
            Event::Refused { from, to, kind } => {
                write!(f, "refused {kind:?} node {from} -> node {to}: buffer full")
            }
        }
    }
}

/// The last [`KEPT`] events of a run, oldest first.
#[derive(Clone, Default)]
pub(super) struct EventLog(VecDeque<Event>);

impl EventLog {
    /// Keep `e`, forgetting the oldest past [`KEPT`].
    pub(super) fn record(&mut self, e: Event) {
        if self.0.len() == KEPT {
            self.0.pop_front();
        }
        self.0.push_back(e);
    }

    /// The events kept, as a failure shows them.
    pub(super) fn trace(&self) -> Trace {
        Trace(self.0.iter().map(ToString::to_string).collect())
    }
}

/// After every event: no buffer past its capacity, and every message sent is delivered or in
/// flight.
pub(super) fn after_event(net: &Network) -> Result<(), String> {
    if let Some((n, held)) = net.overflow {
        return Err(format!(
            "node {n}'s receive buffer holds {held} bytes, capacity {}",
            net.capacity
        ));
    }
    if net.sent != net.delivered + net.inflight.len() as u64 {
        return Err(format!(
            "{} sent, {} delivered, {} in flight",
            net.sent,
            net.delivered,
            net.inflight.len()
        ));
    }
    Ok(())
}

/// After node `n`'s step, with flow control on: its `n_i` below `i_max`. This is the paper's
/// start rule where it shows: a ray starts only with `n_i + r_imax < i_max` toward every node
/// it may send to, and tracing it sends at most `r_imax` messages of a class to one node, so
/// no `n_i` reaches `i_max`; a node that started a ray without that headroom can. A ring of
/// one node sends no credited message and has no `i_max` (0).
pub(super) fn after_step<T: Sample>(worker: &NodeWorker<'_, T>, i_max: u16) -> Result<(), String> {
    match i_max > 0 && worker.max_unacked() >= i_max {
        true => Err(format!(
            "start rule broken: node {} has {} unacknowledged messages to one node in one class, i_max is {i_max} (a ray starts only with n_i + r_imax < i_max)",
            worker.node(),
            worker.max_unacked()
        )),
        false => Ok(()),
    }
}

/// After node `n`'s step, with flow control on: if it passed its cluster's token in `sent`
/// (what the step sent), every message it had sent was acknowledged (the token rule's
/// "every `n_i = 0`"; its "pixels final" shows at the host's end).
pub(super) fn token_rule<T: Sample>(
    worker: &NodeWorker<'_, T>,
    sent: &[super::network::Envelope],
) -> Result<(), String> {
    let token = sent
        .iter()
        .any(|e| e.from == Some(worker.node()) && e.bytes[0] == MsgKind::Token as u8);
    match token && worker.max_unacked() != 0 {
        true => Err(format!(
            "node {} passed its cluster's token with messages unacknowledged",
            worker.node()
        )),
        false => Ok(()),
    }
}

/// When the host has ended: nothing may be left anywhere, but in a cluster declared lost
/// (`lost(node)`), whose nodes keep what they held when it stopped.
pub(super) fn at_end<T: Sample>(
    net: &Network,
    workers: &[Box<NodeWorker<'_, T>>],
    lost: &dyn Fn(u16) -> bool,
) -> Result<(), String> {
    if !net.inflight.is_empty() {
        return Err(format!(
            "the host ended with {} messages in flight",
            net.inflight.len()
        ));
    }
    for w in workers.iter().filter(|w| !lost(w.node())) {
        if w.max_unacked() != 0 {
            return Err(format!(
                "node {} ended with unacknowledged messages",
                w.node()
            ));
        }
        if w.stats().protocol_errors > 0 {
            return Err(format!(
                "node {} counted {} protocol errors",
                w.node(),
                w.stats().protocol_errors
            ));
        }
    }
    Ok(())
}

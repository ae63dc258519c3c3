//! The simulator's scheduler: which in-flight message to deliver or which node to step next,
//! by a seeded policy.
//!
//! Invariant: a pick depends only on the policy, the generator's state and the events on
//! offer, so the same seed gives the same run, event for event.

use super::network::Envelope;
use crate::fabric::Scheduler;
use crate::rng::SplitMix;
use voxcube_kernel::node::msg::MsgKind;
use voxcube_kernel::node::port::Dest;

/// The next event: deliver in-flight message `i`, or step active node `i`.
pub(super) enum Choice {
    Deliver(usize),
    Step(usize),
}

/// The untimed scheduler's pick among the in-flight messages and `nodes` active nodes.
pub(super) fn choose(
    scheduler: Scheduler,
    rng: &mut SplitMix,
    inflight: &[Envelope],
    nodes: usize,
) -> Choice {
    let uniform = |rng: &mut SplitMix| {
        let pick = rng.below(inflight.len() + nodes);
        if pick < inflight.len() {
            Choice::Deliver(pick)
        } else {
            Choice::Step(pick - inflight.len())
        }
    };
    // Pick among the messages `keep` allows, falling back to all when it allows none.
    let among = |rng: &mut SplitMix, keep: &dyn Fn(&Envelope) -> bool| {
        let allowed: Vec<usize> = (0..inflight.len())
            .filter(|&i| keep(&inflight[i]))
            .collect();
        if allowed.is_empty() && nodes == 0 {
            return uniform(rng);
        }
        let pick = rng.below(allowed.len() + nodes);
        if pick < allowed.len() {
            Choice::Deliver(allowed[pick])
        } else {
            Choice::Step(pick - allowed.len())
        }
    };
    match scheduler {
        Scheduler::Uniform => uniform(rng),
        Scheduler::NewestFirst => {
            if !inflight.is_empty() && (nodes == 0 || rng.below(2) == 0) {
                let newest = (0..inflight.len())
                    .max_by_key(|&i| inflight[i].seq)
                    .unwrap_or(0);
                Choice::Deliver(newest)
            } else {
                Choice::Step(rng.below(nodes.max(1)))
            }
        }
        Scheduler::Starve { from, to } => among(rng, &|e: &Envelope| {
            !(e.from == Some(from) && e.to == Dest::Node(to))
        }),
        Scheduler::DelayAcks => {
            let is_ack = |e: &Envelope| e.bytes[0] == MsgKind::Ack as u8;
            among(rng, &|e: &Envelope| !is_ack(e))
        }
    }
}

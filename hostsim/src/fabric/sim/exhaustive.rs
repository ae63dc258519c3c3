//! Every schedule of a small machine: a depth-first walk over every interleaving of message
//! deliveries (in any order, as the random schedulers allow) and node steps, from the first
//! state to every end, pruning states already seen.
//!
//! Invariants: a state's digest covers everything that steers what follows — each worker's
//! [`voxcube_kernel::node::worker::Worker::digest`], each mailbox, the multiset of messages
//! in flight, each receive buffer's use, the host's [`crate::fabric::host::Host::digest`],
//! and which nodes may step (and, with a node set to stop, each node's steps so far) — and
//! nothing that is only history (event counts, peaks, sequence numbers), so two schedules
//! that reach the same state are explored once. The simulator's
//! checks run after every event, the end's at every end; a state with no event
//! possible and the host not done is a deadlock.

use super::{checks, Sim};
use crate::fabric::harness::Plan;
use crate::fabric::{RunConfig, RunError};
use crate::input::dataset::{Volume, VolumeData};
use std::collections::{BTreeSet, HashSet};
use std::hash::{DefaultHasher, Hasher};
use voxcube_kernel::trace::view::View;
use voxcube_kernel::volume::sample::Sample;

/// What walking every schedule found.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Exhaustive {
    /// Distinct states reached (the first included).
    pub states: u64,
    /// Events tried from them (deliveries and steps), revisits included.
    pub transitions: u64,
    /// Distinct end states: the host done.
    pub ends: u64,
    /// States with no event possible and the host not done.
    pub deadlocks: u64,
    /// Events that broke an invariant, and ends that failed the end's checks.
    pub violations: u64,
    /// The distinct images the ends hold (one, for a correct protocol).
    pub images: BTreeSet<Vec<[u8; 4]>>,
    /// The first failure, described.
    pub first_failure: Option<String>,
    /// The walk stopped at its state limit before it was complete.
    pub truncated: bool,
}

impl std::fmt::Display for Exhaustive {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        writeln!(f, "distinct states       {}", self.states)?;
        writeln!(f, "events tried          {}", self.transitions)?;
        writeln!(f, "end states            {}", self.ends)?;
        writeln!(f, "deadlocks             {}", self.deadlocks)?;
        writeln!(f, "invariant violations  {}", self.violations)?;
        writeln!(f, "distinct images       {}", self.images.len())?;
        write!(
            f,
            "complete              {}",
            if self.truncated {
                "no (state limit)"
            } else {
                "yes"
            }
        )?;
        if let Some(e) = &self.first_failure {
            write!(f, "\nfirst failure: {e}")?;
        }
        Ok(())
    }
}

/// Walk every schedule of `view` of `volume` on `cfg`'s machine, up to `max_states` distinct
/// states. Meant for machines of a few nodes and images of a handful of pixels: the states
/// grow with every message that can be in flight at once.
pub fn explore(
    volume: &Volume,
    view: &View,
    cfg: &RunConfig,
    max_states: u64,
) -> Result<Exhaustive, RunError> {
    match &volume.data {
        VolumeData::U8(d) => explore_typed(volume, d, view, cfg, max_states),
        VolumeData::U16(d) => explore_typed(volume, d, view, cfg, max_states),
        VolumeData::I16(d) => explore_typed(volume, d, view, cfg, max_states),
        VolumeData::F32(d) => explore_typed(volume, d, view, cfg, max_states),
    }
}

fn explore_typed<T: Sample + Sync>(
    volume: &Volume,
    data: &[T],
    view: &View,
    cfg: &RunConfig,
    max_states: u64,
) -> Result<Exhaustive, RunError> {
    let grid = volume.grid;
    let plan = Plan::new(&grid, view, cfg)?;
    let (storage, _) = plan.load(volume, data, cfg, 1, |job| {
        Ok(super::super::shift::run(job, data, None)?)
    })?;
    let root = Sim::new(&plan, plan.workers(&storage, cfg)?, cfg);
    let mut found = Exhaustive::default();
    let mut seen: HashSet<u64> = HashSet::new();
    seen.insert(digest(&root));
    found.states = 1;
    // The path from the first state, each with the index of its next event to try.
    let mut path: Vec<(Sim<'_, '_, T>, usize)> = vec![(root, 0)];
    while let Some(top) = path.len().checked_sub(1) {
        let (sim, next) = &mut path[top];
        let (flying, active) = (sim.net.inflight.len(), sim.active.len());
        if *next == flying + active {
            path.pop();
            continue;
        }
        let event = *next;
        *next += 1;
        let mut child = sim.clone();
        // Its depth along the path, which a failure names.
        child.events += 1;
        found.transitions += 1;
        let done = if event < flying {
            child.deliver(event, &|_| {})
        } else {
            child.step(event - flying)
        }
        .and_then(|()| checks::after_event(&child.net).map_err(|what| child.fail(what)));
        if let Err(e) = done {
            found.violations += 1;
            found.first_failure.get_or_insert_with(|| e.to_string());
            continue;
        }
        if !seen.insert(digest(&child)) {
            continue;
        }
        found.states += 1;
        if child.host.done() {
            found.ends += 1;
            let end = checks::at_end(&child.net, &child.workers, &|_| false)
                .map_err(|what| child.fail(what))
                .and_then(|()| child.host.clone().finish().map_err(|what| child.fail(what)));
            match end {
                Ok((image, _)) => {
                    found.images.insert(image);
                }
                Err(e) => {
                    found.violations += 1;
                    found.first_failure.get_or_insert_with(|| e.to_string());
                }
            }
            continue;
        }
        if child.net.inflight.is_empty() && child.active.is_empty() {
            found.deadlocks += 1;
            found
                .first_failure
                .get_or_insert_with(|| child.stuck().to_string());
            continue;
        }
        if found.states >= max_states {
            found.truncated = true;
            break;
        }
        path.push((child, 0));
    }
    Ok(found)
}

/// A state's digest: 64 bits of SipHash over what steers it. Two distinct states of a walk
/// of `n` states share one with odds about `n² / 2⁶⁵` (1 in 10⁹ at 10⁵ states), which would
/// prune a state unexplored; the walks here stay far below that.
fn digest<T: Sample>(sim: &Sim<'_, '_, T>) -> u64 {
    let mut h = DefaultHasher::new();
    feed(&mut h, sim);
    h.finish()
}

fn feed<T: Sample, H: Hasher>(h: &mut H, sim: &Sim<'_, '_, T>) {
    for w in &sim.workers {
        w.digest(h);
    }
    for m in &sim.mailboxes {
        h.write(format!("{:?}", m.by_class).as_bytes());
    }
    // In flight is a multiset: any message may be delivered next.
    let mut flying: Vec<String> = sim
        .net
        .inflight
        .iter()
        .map(|e| format!("{:?}>{:?}:{:?}", e.from, e.to, &e.bytes[..e.len]))
        .collect();
    flying.sort_unstable();
    h.write(flying.join("|").as_bytes());
    h.write(format!("{:?}", sim.net.used).as_bytes());
    sim.host.digest(h);
    let mut active = sim.active.clone();
    active.sort_unstable();
    h.write(format!("{active:?}{:?}", sim.stopped).as_bytes());
    // With a node set to stop after some steps, its steps so far steer what follows.
    if sim.cfg.schedule.stop.is_some() {
        h.write(format!("{:?}", sim.steps).as_bytes());
    }
}

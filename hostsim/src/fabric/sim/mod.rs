//! The simulator fabric: every node of the machine in one thread, a seeded scheduler choosing
//! at each event either an in-flight message to deliver or a node to step. The same seed gives
//! the same run, event for event, so any failure replays from its seed.
//!
//! Each node has a receive buffer of a fixed byte capacity. A message takes its room there
//! when it is sent, and gives it back when the node reads it. A send that does not fit is
//! refused: the worker keeps the message and, once its outbox is full, stops. Flow control
//! exists to make this never happen.
//!
//! The parts: `network` (messages in flight, buffers, mailboxes), `schedule` (the seeded
//! pick of the next event), `clock` (virtual time on a machine profile) and `checks` (the
//! invariants after every event and at the end, and the last events a failure shows).
//!
//! The run ends when the host holds every cluster's token and every worker's statistics.
//! Then no message may be in flight, every `n_i` must be 0, every pixel present and no
//! protocol error counted. "Stuck" means no event is possible while the host has not ended (a
//! deadlock); a run far longer than its work can need is stopped by a watchdog (a livelock).
//! Either way the error carries the seed and the last events.

mod checks;
mod clock;
pub mod exhaustive;
mod network;
mod schedule;

use super::config::RunConfig;
use super::error::RunError;
use super::harness::{NodeWorker, Plan};
use super::host::Host;
use super::recovery::{self, LostNode, Retraced};
use super::{Category, Distributed};
use crate::input::dataset::{Volume, VolumeData};
use crate::profile::MachineProfile;
use crate::rng::SplitMix;
use checks::{Event, EventLog};
use clock::Clock;
use network::{Delivered, Mailbox, Network, SimPort};
use schedule::Choice;
use std::collections::VecDeque;
use voxcube_kernel::node::msg::Msg;
use voxcube_kernel::node::port::Dest;
use voxcube_kernel::node::worker::Progress;
use voxcube_kernel::trace::view::View;
use voxcube_kernel::volume::sample::Sample;

/// Render `view` of `volume` on the simulated machine.
pub fn run(volume: &Volume, view: &View, cfg: &RunConfig) -> Result<Distributed, RunError> {
    run_with_progress(volume, view, cfg, &|_| {})
}

/// [`run`], telling `progress` how many pixels the host holds as they arrive.
pub fn run_with_progress(
    volume: &Volume,
    view: &View,
    cfg: &RunConfig,
    progress: &dyn Fn(u64),
) -> Result<Distributed, RunError> {
    match &volume.data {
        VolumeData::U8(d) => run_typed(volume, d, view, cfg, progress),
        VolumeData::U16(d) => run_typed(volume, d, view, cfg, progress),
        VolumeData::I16(d) => run_typed(volume, d, view, cfg, progress),
        VolumeData::F32(d) => run_typed(volume, d, view, cfg, progress),
    }
}

fn run_typed<T: Sample + Sync>(
    volume: &Volume,
    data: &[T],
    view: &View,
    cfg: &RunConfig,
    progress: &dyn Fn(u64),
) -> Result<Distributed, RunError> {
    let grid = volume.grid;
    let plan = Plan::new(&grid, view, cfg)?;
    let (storage, shift) = plan.load(volume, data, cfg, 1, |job| {
        Ok(super::shift::run(job, data, cfg.time.as_ref())?)
    })?;
    let mut sim = Sim::new(&plan, plan.workers(&storage, cfg)?, cfg);
    sim.run(progress)?;
    let Sim {
        host,
        net,
        clock,
        mut messages,
        mut bytes,
        mut events,
        log,
        lost,
        ..
    } = sim;
    let mut peaks = net.peak;
    let mut time = clock.map(Clock::finish);
    let (image, stats, recovered) = match lost {
        None => {
            let (image, stats) = host
                .finish()
                .map_err(|what| fail(cfg, what, events, &log))?;
            (image, stats, None)
        }
        Some(lost) => {
            let already = host.received();
            let retrace = |survivors: &RunConfig, _: &[u16]| {
                simulate(volume, data, view, survivors, &|n| progress(already + n))
            };
            let done = recovery::complete(view, cfg, lost, host, &retrace)?;
            for (kind, more) in messages.iter_mut().zip(done.messages) {
                *kind += more;
            }
            bytes += done.bytes;
            events += done.events;
            done.raise_peaks(&mut peaks);
            if let Some(time) = &mut time {
                done.append_time(time);
            }
            (done.image, done.stats, Some(done.recovery))
        }
    };
    let mut run = plan.finish(
        cfg,
        &grid,
        T::KIND,
        image,
        stats,
        &|n| peaks[n],
        &|_| std::time::Duration::ZERO,
        shift,
    );
    // The simulator counts what it delivered itself, host's messages included.
    run.messages = messages;
    run.bytes = bytes;
    run.events = events;
    run.recovery = recovered;
    run.time = time;
    if let (Some(t), Some(report)) = (&mut run.time, &run.shift) {
        // The render starts once every node has shifted: each node's own sends and
        // receives, then idle until the busiest is done.
        let whole = report.seconds.unwrap_or(0.0);
        for (parts, &(send, receive)) in t.parts.iter_mut().zip(&report.per_node) {
            parts[Category::Write as usize] += send;
            parts[Category::Read as usize] += receive;
            parts[Category::Idle as usize] += (whole - send - receive).max(0.0);
        }
        t.frame += whole;
        t.end += whole;
    }
    Ok(run)
}

/// One unshifted simulation of `cfg` to its end: a re-trace on surviving clusters.
fn simulate<T: Sample + Sync>(
    volume: &Volume,
    data: &[T],
    view: &View,
    cfg: &RunConfig,
    progress: &dyn Fn(u64),
) -> Result<Retraced, RunError> {
    let grid = volume.grid;
    let plan = Plan::new(&grid, view, cfg)?;
    let (storage, _) = plan.load(volume, data, cfg, 1, |_| {
        Err(RunError::Host(
            "a re-trace loads its slabs, it does not shift them".into(),
        ))
    })?;
    let mut sim = Sim::new(&plan, plan.workers(&storage, cfg)?, cfg);
    sim.run(progress)?;
    if let Some(lost) = sim.lost {
        return Err(recovery::lost_in_retrace(lost.node));
    }
    Ok(Retraced {
        host: sim.host,
        peaks: sim.net.peak,
        messages: sim.messages,
        bytes: sim.bytes,
        events: sim.events,
        time: sim.clock.map(Clock::finish),
    })
}

/// An invariant broken after `events` events, with the seed, scheduler and last events.
fn fail(cfg: &RunConfig, what: String, events: u64, log: &EventLog) -> RunError {
    RunError::Invariant {
        what,
        events,
        seed: cfg.schedule.seed,
        scheduler: cfg.schedule.scheduler,
        trace: log.trace(),
    }
}

/// The whole simulated machine during a run.
#[derive(Clone)]
struct Sim<'a, 'c, T: Sample> {
    cfg: &'c RunConfig,
    workers: Vec<Box<NodeWorker<'a, T>>>,
    mailboxes: Vec<Mailbox>,
    net: Network,
    /// Nodes that may step: those not idle, and not stopped.
    active: Vec<usize>,
    is_active: Vec<bool>,
    /// Steps each node has taken, and whether it has stopped (an injected fault).
    steps: Vec<u64>,
    stopped: Vec<bool>,
    /// Virtual seconds at which the stopped node stopped (a timed run).
    stopped_at: f64,
    host: Host,
    rng: SplitMix,
    clock: Option<Clock>,
    log: EventLog,
    /// Messages delivered by kind, and their bytes; events run.
    messages: [u64; 9],
    bytes: u64,
    events: u64,
    i_max: u16,
    layout: voxcube_kernel::node::topology::Layout,
    /// Events past which a run is a livelock: far more than its work can need.
    limit: u64,
    /// The node declared lost, its cluster, and the events run by then.
    lost: Option<LostNode>,
}

impl<'a, 'c, T: Sample> Sim<'a, 'c, T> {
    fn new(plan: &Plan<'_>, workers: Vec<Box<NodeWorker<'a, T>>>, cfg: &'c RunConfig) -> Self {
        let nodes = plan.nodes();
        Sim {
            cfg,
            workers,
            mailboxes: (0..nodes).map(|_| Mailbox::default()).collect(),
            net: Network::new(nodes, plan.capacity),
            active: (0..nodes).collect(),
            is_active: vec![true; nodes],
            steps: vec![0; nodes],
            stopped: vec![false; nodes],
            stopped_at: 0.0,
            host: plan.host(),
            rng: SplitMix(cfg.schedule.seed),
            clock: cfg.time.as_ref().map(|p| {
                let surfaces = MachineProfile::searched_surfaces(&plan.view);
                Clock::new(p, surfaces, nodes, cfg.timeline)
            }),
            log: EventLog::default(),
            messages: [0; 9],
            bytes: 0,
            events: 0,
            i_max: plan.flow.i_max,
            layout: plan.layout,
            limit: 10_000_000 + 4_000 * plan.view.pixel_count() * nodes as u64,
            lost: None,
        }
    }

    fn fail(&self, what: String) -> RunError {
        fail(self.cfg, what, self.events, &self.log)
    }

    /// Events until the host ends, checking the invariants after each; then the end's.
    fn run(&mut self, progress: &dyn Fn(u64)) -> Result<(), RunError> {
        // The host ends once it has every report and every pixel the reports say were sent.
        while !self.host.done() {
            if self.net.inflight.is_empty() && self.active.is_empty() {
                self.declare_lost()?;
                continue;
            }
            self.events += 1;
            if self.events > self.limit {
                return Err(RunError::Watchdog {
                    events: self.events,
                    seed: self.cfg.schedule.seed,
                    scheduler: self.cfg.schedule.scheduler,
                    trace: self.log.trace(),
                });
            }
            let choice = match &self.clock {
                Some(clock) => clock.choose(&self.net.inflight, &self.active),
                None => schedule::choose(
                    self.cfg.schedule.scheduler,
                    &mut self.rng,
                    &self.net.inflight,
                    self.active.len(),
                ),
            };
            match choice {
                Choice::Deliver(i) => self.deliver(i, progress)?,
                Choice::Step(i) => self.step(i)?,
            }
            checks::after_event(&self.net).map_err(|what| self.fail(what))?;
        }
        let layout = self.layout;
        let lost = self.lost.map(|l| l.cluster);
        let in_lost = |node: u16| lost == Some(layout.place(node).0);
        checks::at_end(&self.net, &self.workers, &in_lost).map_err(|what| self.fail(what))
    }

    /// Nothing can happen and the host has not ended. When a node has stopped and other
    /// clusters may finish the frame, the host declares its cluster lost, stops waiting for it
    /// and collects the others' statistics; their re-trace of its rows follows
    /// ([`run_typed`]). Otherwise the run fails: a lost node, or a deadlock.
    ///
    /// In virtual time the host declares the node lost once it has been silent for
    /// `RunConfig::lost_after` since it stopped, or when the other nodes are done if that is
    /// later (the re-trace then starts on clusters that are all free).
    fn declare_lost(&mut self) -> Result<(), RunError> {
        let stopped = self.stopped.iter().position(|&s| s);
        let recoverable = self.layout.clusters() > 1;
        let (Some(n), true, None) = (stopped, recoverable, self.lost) else {
            return Err(self.stuck());
        };
        if let Some(clock) = &mut self.clock {
            let declared = self.stopped_at + self.cfg.lost_after.as_secs_f64();
            clock.host_time = clock.host_time.max(declared);
        }
        let cluster = self.layout.place(n as u16).0;
        self.lost = Some(LostNode {
            node: n as u16,
            cluster,
            events: Some(self.events),
            after: None,
        });
        match self.host.declare_lost(cluster) {
            Ok(true) => self.collect(),
            Ok(false) => {}
            Err(what) => return Err(self.fail(what)),
        }
        Ok(())
    }

    /// Ask every node the host waits for for its statistics.
    fn collect(&mut self) {
        for n in 0..self.workers.len() as u16 {
            if !self.host.expects_report(usize::from(n)) {
                continue;
            }
            self.net.push(None, Dest::Node(n), &Msg::Collect);
            if let (Some(clock), Some(env)) = (&self.clock, self.net.inflight.last_mut()) {
                env.arrival = clock.host_time + clock.transfer(env.len, 1);
            }
        }
    }

    /// No event is possible and the host has not ended: a node lost, or a deadlock.
    fn stuck(&self) -> RunError {
        if let Some(n) = self.stopped.iter().position(|&s| s) {
            let waiting = self.mailboxes[n]
                .by_class
                .iter()
                .map(VecDeque::len)
                .sum::<usize>()
                + self
                    .net
                    .inflight
                    .iter()
                    .filter(|e| e.to == Dest::Node(n as u16))
                    .count();
            return RunError::Lost {
                node: n as u16,
                waiting,
                missing: self.host.missing(),
                rows: self.host.missing_rows(),
            };
        }
        RunError::Deadlock {
            events: self.events,
            missing: self.host.missing(),
            tokens: self.host.tokens(),
            reports: self.host.reports(),
            nodes: self.workers.len(),
            unfinished: self
                .workers
                .iter()
                .filter(|w| !w.pixels_final())
                .map(|w| w.node())
                .collect(),
            seed: self.cfg.schedule.seed,
            scheduler: self.cfg.schedule.scheduler,
            trace: self.log.trace(),
        }
    }

    /// Deliver in-flight message `i`: to the host, or into its node's mailbox (waking it).
    fn deliver(&mut self, i: usize, progress: &dyn Fn(u64)) -> Result<(), RunError> {
        // Decoded where it waited, then dropped: moving the envelope out first cost a copy.
        let Some(waiting) = self.net.inflight.get(i) else {
            return Err(self.fail(format!("no message {i} in flight")));
        };
        let decoded = Msg::decode(&waiting.bytes[..waiting.len]);
        let env = Delivered {
            from: waiting.from,
            to: waiting.to,
            len: waiting.len,
            arrival: waiting.arrival,
        };
        self.net.inflight.swap_remove(i);
        let msg = decoded.map_err(|error| RunError::Decode {
            from: env.from.unwrap_or(u16::MAX),
            error,
        })?;
        self.net.delivered += 1;
        self.messages[msg.kind() as usize] += 1;
        self.bytes += env.len as u64;
        self.log.record(Event::Deliver {
            from: env.from,
            to: env.to,
            kind: msg.kind(),
        });
        match env.to {
            Dest::Host => {
                if let Some(clock) = &mut self.clock {
                    clock.host_receives(env.arrival, &msg);
                }
                let collect = match self.host.receive(msg) {
                    Ok(collect) => collect,
                    Err(what) => return Err(self.fail(what)),
                };
                progress(self.host.received());
                if collect {
                    // Every cluster's token: every pixel is final (some may still be on their
                    // way here); ask every worker for its statistics.
                    self.collect();
                }
            }
            Dest::Node(n) => {
                let n = usize::from(n);
                let from = env.from.map_or(Dest::Host, Dest::Node);
                if let Some(mailbox) = self.mailboxes.get_mut(n) {
                    mailbox.by_class[msg.class().index()].push_back((from, msg));
                    if let Some(clock) = &mut self.clock {
                        clock.wake(n, env.arrival);
                    }
                    if !self.is_active[n] && !self.stopped[n] {
                        self.is_active[n] = true;
                        self.active.push(n);
                    }
                }
            }
        }
        Ok(())
    }

    /// Step active node `active[i]` once: it reads, traces and sends through its port.
    fn step(&mut self, i: usize) -> Result<(), RunError> {
        let n = self.active[i];
        self.steps[n] += 1;
        if self
            .cfg
            .schedule
            .stop
            .is_some_and(|(node, after)| usize::from(node) == n && self.steps[n] > after)
        {
            // The faulty node: it takes no more steps and reads nothing.
            self.active.swap_remove(i);
            self.is_active[n] = false;
            self.stopped[n] = true;
            self.stopped_at = self.clock.as_ref().map_or(0.0, |c| c.now[n]);
            return Ok(());
        }
        // What a timed run's clock needs from before the step. An untimed run skips it:
        // reading a node's mailboxes and counters before its step was a cache miss per step
        // on a machine of many nodes.
        let before = self.clock.is_some().then(|| {
            let pending = self.mailboxes[n]
                .by_class
                .iter()
                .map(VecDeque::len)
                .sum::<usize>();
            (pending, self.workers[n].counters(), self.net.inflight.len())
        });
        let capacity = self.net.capacity;
        let sent_before = self.net.inflight.len();
        let mut port = SimPort {
            from: n as u16,
            net: &mut self.net,
            mailbox: &mut self.mailboxes[n],
            capacity,
            received: 0,
        };
        let progress = self.workers[n].poll(&mut port);
        let received = port.received;
        if let (Some(clock), Some((pending, counters, sent))) = (&mut self.clock, &before) {
            clock.step(
                n,
                &self.workers[n].counters(),
                counters,
                *pending,
                received,
                &mut self.net.inflight[*sent..],
            );
        }
        if let Some((from, to, kind)) = self.net.refused.take() {
            self.log.record(Event::Refused { from, to, kind });
        }
        self.log.record(Event::Step {
            node: n as u16,
            busy: progress == Progress::Busy,
        });
        if progress == Progress::Idle {
            self.active.swap_remove(i);
            self.is_active[n] = false;
        }
        if self.cfg.flow_control {
            checks::after_step(&self.workers[n], self.i_max).map_err(|what| self.fail(what))?;
            checks::token_rule(&self.workers[n], &self.net.inflight[sent_before..])
                .map_err(|what| self.fail(what))?;
        }
        Ok(())
    }
}

//! The simulator fabric: every node of the machine in one thread, a seeded scheduler choosing
//! at each event either an in-flight message to deliver or a node to step. The same seed gives
//! the same run, event for event, so any failure replays from its seed.
//!
//! Each node has a receive buffer of a fixed byte capacity. A message takes its room there
//! when it is sent, and gives it back when the node reads it. A send that does not fit is
//! refused: the worker keeps the message and, once its outbox is full, stops. Flow control
//! exists to make this never happen.
//!
//! After every event the invariants are checked:
//! - no buffer holds more than its capacity;
//! - every `n_i` stays within `[0, i_max]` (with flow control on);
//! - messages are conserved: sent = delivered + in flight;
//! - no pixel reaches the host twice;
//! - the host never ends with a pixel missing.
//!
//! The run ends when the host holds every cluster's token and every worker's statistics.
//! Then no message may be in flight, every `n_i` must be 0, every pixel present and no
//! protocol error counted. "Stuck" means no event is possible while the host has not ended (a
//! deadlock); a run far longer than its work can need is stopped by a watchdog (a livelock).
//! Either way the error carries the seed and the last events.

use super::host::Host;
use super::Distributed;
use super::{Category, VirtualTime};
use crate::dataset::{Volume, VolumeData};
use crate::profile::MachineProfile;
use crate::rng::SplitMix;
use std::collections::VecDeque;
use std::fmt;
use std::time::{Duration, Instant};
use voxcube_kernel::counters::Counters;
use voxcube_kernel::node::flow::{self, Class};
use voxcube_kernel::node::msg::{DecodeError, Msg, MsgKind, MAX_MSG_LEN, PIXELS_PER_SET};
use voxcube_kernel::node::partition::{Partition, PartitionError};
use voxcube_kernel::node::port::{Dest, Port};
use voxcube_kernel::node::topology::hops;
use voxcube_kernel::node::topology::Layout;
use voxcube_kernel::node::worker::{
    Generation, Place, Progress, Setup, Worker, WorkerError, RAYS_PER_POLL,
};
use voxcube_kernel::trace::view::View;
use voxcube_kernel::volume::sample::Sample;
use voxcube_kernel::volume::slab::{Slab, SlabError};

/// Worker capacities in the simulator: continuations per direction, pixel records, outbox.
pub type SimWorker<'a, T> = Worker<'a, T, 32, 64, 16>;

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

/// How to run.
#[derive(Clone, Debug)]
pub struct SimConfig {
    /// Clusters and their size.
    pub layout: Layout,
    /// Scheduler seed.
    pub seed: u64,
    /// Scheduler policy.
    pub scheduler: Scheduler,
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
    /// Virtual time on this machine profile: events run in time order (the scheduler and seed
    /// then only break ties) and every node's time is kept by category.
    pub time: Option<MachineProfile>,
    /// A fault to inject: this node stops answering after this many of its own steps.
    pub stop: Option<(u16, u64)>,
    /// How the nodes skip provably empty samples (changes no pixel; off to compare).
    pub skipping: crate::storage::SkipMode,
    /// Test-only faults, applied to every worker.
    #[cfg(feature = "mutants")]
    pub mutants: voxcube_kernel::node::worker::Mutants,
}

impl SimConfig {
    /// One cluster of `size` nodes, uniform slabs, distributed generation, uniform schedule.
    pub fn cluster(
        size: u32,
        seed: u64,
    ) -> Result<SimConfig, voxcube_kernel::node::topology::LayoutError> {
        SimConfig::machine(1, size, seed)
    }

    /// `clusters` clusters of `size` nodes, otherwise as [`SimConfig::cluster`].
    pub fn machine(
        clusters: u32,
        size: u32,
        seed: u64,
    ) -> Result<SimConfig, voxcube_kernel::node::topology::LayoutError> {
        Ok(SimConfig {
            layout: Layout::new(clusters, size)?,
            seed,
            scheduler: Scheduler::Uniform,
            generation: Generation::Distributed,
            cuts: None,
            shift: false,
            buffer_bytes: None,
            flow_control: true,
            time: None,
            stop: None,
            skipping: crate::storage::SkipMode::ALL,
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

/// One scheduler event, for traces.
#[derive(Clone, Copy, Debug)]
enum Event {
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

/// Why a simulated run failed. Every failure of a run names its seed; replay with it.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// The partition does not fit the grid.
    #[error("partition: {0}")]
    Partition(#[from] PartitionError),
    /// The plane shift to balanced cuts failed.
    #[error("{0}")]
    Shift(#[from] super::shift::ShiftFailure),
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
    /// An invariant failed.
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

struct Envelope {
    from: Option<u16>,
    to: Dest,
    len: usize,
    bytes: [u8; MAX_MSG_LEN],
    seq: u64,
    /// Virtual arrival time (timed runs).
    arrival: f64,
}

/// What delivering an envelope needs of it once its message is decoded.
struct Delivered {
    from: Option<u16>,
    to: Dest,
    len: usize,
    arrival: f64,
}

#[derive(Default)]
struct Mailbox {
    by_class: [VecDeque<(Dest, Msg)>; 7],
}

struct SimPort<'n> {
    from: u16,
    net: &'n mut Network,
    mailbox: &'n mut Mailbox,
    capacity: usize,
    received: u64,
}

/// Messages in flight and what each node's buffer holds.
struct Network {
    inflight: Vec<Envelope>,
    /// Bytes each node's receive buffer holds or has promised (in flight to it, or unread).
    used: Vec<usize>,
    peak: Vec<usize>,
    /// Bytes a receive buffer may hold.
    capacity: usize,
    /// The first node whose buffer was pushed past `capacity`, and the bytes it then held.
    /// Buffers only grow in [`Network::push`], so watching there sees every overflow, at the
    /// cost of one comparison a message instead of a scan of every node each event.
    overflow: Option<(u16, usize)>,
    sent: u64,
    delivered: u64,
    seq: u64,
    refused: Option<(u16, u16, MsgKind)>,
}

impl Network {
    /// An empty network of `nodes` receive buffers of `capacity` bytes each.
    fn new(nodes: usize, capacity: usize) -> Network {
        Network {
            inflight: Vec::new(),
            used: vec![0; nodes],
            peak: vec![0; nodes],
            capacity,
            overflow: None,
            sent: 0,
            delivered: 0,
            seq: 0,
            refused: None,
        }
    }

    fn push(&mut self, from: Option<u16>, to: Dest, msg: &Msg) {
        self.seq += 1;
        self.sent += 1;
        // Encoded where it waits: encoding on the stack cost a copy of the envelope.
        self.inflight.push(Envelope {
            from,
            to,
            len: 0,
            bytes: [0u8; MAX_MSG_LEN],
            seq: self.seq,
            arrival: f64::NAN,
        });
        let Some(env) = self.inflight.last_mut() else {
            return;
        };
        env.len = msg.encode(&mut env.bytes);
        let len = env.len;
        if let Dest::Node(n) = to {
            if let Some(u) = self.used.get_mut(usize::from(n)) {
                *u += len;
                self.peak[usize::from(n)] = self.peak[usize::from(n)].max(*u);
                if *u > self.capacity && self.overflow.is_none() {
                    self.overflow = Some((n, *u));
                }
            }
        }
    }
}

impl Port for SimPort<'_> {
    fn try_send(&mut self, to: Dest, msg: Msg) -> Result<(), Msg> {
        if let Dest::Node(n) = to {
            let len = msg.kind().encoded_len();
            if self
                .net
                .used
                .get(usize::from(n))
                .is_none_or(|&u| u + len > self.capacity)
            {
                self.net.refused = Some((self.from, n, msg.kind()));
                return Err(msg);
            }
        }
        self.net.push(Some(self.from), to, &msg);
        Ok(())
    }

    fn peek(&mut self, class: Class) -> Option<&Msg> {
        self.mailbox.by_class[class.index()].front().map(|(_, m)| m)
    }

    fn try_recv(&mut self, class: Class) -> Option<(Dest, Msg)> {
        // Handed on as it left the mailbox: taking it apart and putting it back together
        // cost a copy of the whole message.
        let read = self.mailbox.by_class[class.index()].pop_front();
        if let Some((_, msg)) = &read {
            self.received += 1;
            if let Some(u) = self.net.used.get_mut(usize::from(self.from)) {
                *u = u.saturating_sub(msg.kind().encoded_len());
            }
        }
        read
    }

    fn pending(&self) -> usize {
        self.mailbox.by_class.iter().map(VecDeque::len).sum()
    }
}

/// Render `view` of `volume` on the simulated machine.
pub fn run(volume: &Volume, view: &View, cfg: &SimConfig) -> Result<Distributed, SimError> {
    run_with_progress(volume, view, cfg, &|_| {})
}

/// [`run`], telling `progress` how many pixels the host holds as they arrive.
pub fn run_with_progress(
    volume: &Volume,
    view: &View,
    cfg: &SimConfig,
    progress: &dyn Fn(u64),
) -> Result<Distributed, SimError> {
    match &volume.data {
        VolumeData::U8(d) => run_typed(volume, d, view, cfg, progress),
        VolumeData::U16(d) => run_typed(volume, d, view, cfg, progress),
        VolumeData::F32(d) => run_typed(volume, d, view, cfg, progress),
    }
}

/// A ring of one's rays a poll: a pixel set's, which a `u8` must hold (checked here, not
/// truncated by a cast should the set grow).
const RING_OF_ONE_RAYS: u8 = {
    assert!(PIXELS_PER_SET <= u8::MAX as usize);
    PIXELS_PER_SET as u8
};

/// Node `node`'s worker in `cfg`'s machine: `slab` is its slab of `partition`, at the ring
/// position `node` holds. Every fabric builds its workers here.
pub fn node_worker<'a, T: Sample>(
    view: &'a View,
    slab: Slab<'a, T>,
    partition: &'a Partition,
    cfg: &SimConfig,
    node: u16,
    flow: flow::FlowControl,
) -> Result<Box<SimWorker<'a, T>>, WorkerError> {
    let layout = cfg.layout;
    let (cluster, position) = layout.place(node);
    let place = Place {
        layout,
        cluster,
        position,
    };
    let checked = SimWorker::check(Setup {
        view,
        slab,
        partition,
        place,
        generation: cfg.generation,
        flow,
        // A timed run charges time per poll: its nodes read their links between rays. A
        // ring of one has no links to read and hears only from the host: a pixel set's rays
        // a poll (3.6 M of 264.5 M instructions fewer on SOD's paper view, two clusters).
        rays_per_poll: match (&cfg.time, layout.size()) {
            (Some(_), _) => 1,
            (None, 1) => RING_OF_ONE_RAYS,
            (None, _) => RAYS_PER_POLL,
        },
    })?;
    // Built where it stays: a worker built on the stack was copied into its box whole.
    Ok(Box::write(Box::new_uninit(), SimWorker::new(checked)))
}

fn run_typed<T: Sample + Sync>(
    volume: &Volume,
    data: &[T],
    view: &View,
    cfg: &SimConfig,
    progress: &dyn Fn(u64),
) -> Result<Distributed, SimError> {
    let view = &*cfg.skipping.view(view);
    let start = Instant::now();
    let grid = volume.grid;
    let layout = cfg.layout;
    let size = usize::from(layout.size());
    let nx = grid.dims()[0];
    let partition = cfg.partition(nx)?;
    let (flow, capacity) = super::flow_for(cfg, view)?;
    let ghost = view.ghost_planes();
    let nodes = layout.nodes() as usize;
    // Balanced cuts are reached by message from uniform slabs; then each node holds its own.
    let shifted = match (&cfg.cuts, cfg.shift) {
        (Some(_), true) => {
            let uniform = Partition::uniform(nx, size)?;
            let (storages, report) = super::shift::run(
                &grid,
                data,
                layout,
                &uniform,
                &partition,
                ghost,
                capacity,
                cfg.time.as_ref(),
            )?;
            Some((storages, report))
        }
        _ => None,
    };
    let nodes_storage = crate::storage::NodeStorage::new(
        &grid,
        layout,
        &partition,
        ghost,
        data,
        shifted.as_ref().map(|(s, _)| s.as_slice()),
    )
    .with_skipping(view, cfg.skipping, 1);
    let mut workers: Vec<Box<SimWorker<'_, T>>> = Vec::with_capacity(nodes);
    for node in 0..nodes as u16 {
        let slab = nodes_storage.slab(node)?;
        #[allow(unused_mut, reason = "mutable only to switch on test faults")]
        let mut worker = node_worker(view, slab, &partition, cfg, node, flow)?;
        #[cfg(feature = "mutants")]
        {
            worker.mutants = cfg.mutants;
        }
        workers.push(worker);
    }
    let mut mailboxes: Vec<Mailbox> = (0..nodes).map(|_| Mailbox::default()).collect();
    let mut net = Network::new(nodes, capacity);
    let mut active: Vec<usize> = (0..nodes).collect();
    let mut is_active = vec![true; nodes];
    let pixels = view.pixel_count() as usize;
    let mut host = Host::new(
        pixels,
        view.spec().width,
        usize::from(layout.clusters()),
        nodes,
    );
    let (mut messages, mut bytes, mut events) = ([0u64; 9], 0u64, 0u64);
    let mut rng = SplitMix(cfg.seed);
    let mut steps = vec![0u64; nodes];
    let mut stopped = vec![false; nodes];
    let mut clock = cfg.time.as_ref().map(|p| Clock::new(p, nodes));
    let mut trace: VecDeque<Event> = VecDeque::with_capacity(64);
    let limit = 10_000_000 + 4_000 * pixels as u64 * nodes as u64;
    let fail = |what: String, events: u64, trace: &VecDeque<Event>| SimError::Invariant {
        what,
        events,
        seed: cfg.seed,
        scheduler: cfg.scheduler,
        trace: Trace(trace.iter().map(ToString::to_string).collect()),
    };
    let record = |trace: &mut VecDeque<Event>, e: Event| {
        if trace.len() == 64 {
            trace.pop_front();
        }
        trace.push_back(e);
    };
    loop {
        // The host ends once it has every report and every pixel the reports say were sent.
        if host.done() {
            break;
        }
        let choices = net.inflight.len() + active.len();
        if choices == 0 {
            if let Some(n) = stopped.iter().position(|&s| s) {
                let waiting = mailboxes[n]
                    .by_class
                    .iter()
                    .map(VecDeque::len)
                    .sum::<usize>()
                    + net
                        .inflight
                        .iter()
                        .filter(|e| e.to == Dest::Node(n as u16))
                        .count();
                return Err(SimError::Lost {
                    node: n as u16,
                    waiting,
                    missing: host.missing(),
                    rows: host.missing_rows(),
                });
            }
            let unfinished: Vec<u16> = workers
                .iter()
                .filter(|w| !w.pixels_final())
                .map(|w| w.node())
                .collect();
            return Err(SimError::Deadlock {
                events,
                missing: host.missing(),
                tokens: host.tokens(),
                reports: host.reports(),
                nodes,
                unfinished,
                seed: cfg.seed,
                scheduler: cfg.scheduler,
                trace: Trace(trace.iter().map(ToString::to_string).collect()),
            });
        }
        events += 1;
        if events > limit {
            return Err(SimError::Watchdog {
                events,
                seed: cfg.seed,
                scheduler: cfg.scheduler,
                trace: Trace(trace.iter().map(ToString::to_string).collect()),
            });
        }
        let choice = match &clock {
            Some(clock) => clock.choose(&net.inflight, &active),
            None => choose(cfg.scheduler, &mut rng, &net.inflight, active.len()),
        };
        match choice {
            Choice::Deliver(i) => {
                // Decoded where it waited, then dropped: moving the envelope out first
                // cost a copy of it.
                let Some(waiting) = net.inflight.get(i) else {
                    return Err(fail(format!("no message {i} in flight"), events, &trace));
                };
                let decoded = Msg::decode(&waiting.bytes[..waiting.len]);
                let env = Delivered {
                    from: waiting.from,
                    to: waiting.to,
                    len: waiting.len,
                    arrival: waiting.arrival,
                };
                net.inflight.swap_remove(i);
                let msg = decoded.map_err(|error| SimError::Decode {
                    from: env.from.unwrap_or(u16::MAX),
                    error,
                })?;
                net.delivered += 1;
                messages[msg.kind() as usize] += 1;
                bytes += env.len as u64;
                record(
                    &mut trace,
                    Event::Deliver {
                        from: env.from,
                        to: env.to,
                        kind: msg.kind(),
                    },
                );
                match env.to {
                    Dest::Host => {
                        if let Some(clock) = &mut clock {
                            clock.host_receives(env.arrival, &msg);
                        }
                        let collect = host
                            .receive(msg)
                            .map_err(|what| fail(what, events, &trace))?;
                        progress(host.received());
                        if collect {
                            // Every cluster's token: every pixel is final (some may still be
                            // on their way here); ask every worker for its statistics.
                            for n in 0..nodes as u16 {
                                net.push(None, Dest::Node(n), &Msg::Collect);
                                if let (Some(clock), Some(env)) = (&clock, net.inflight.last_mut())
                                {
                                    env.arrival = clock.host_time + clock.transfer(env.len, 1);
                                }
                            }
                        }
                    }
                    Dest::Node(n) => {
                        let n = usize::from(n);
                        let from = env.from.map_or(Dest::Host, Dest::Node);
                        if let Some(mailbox) = mailboxes.get_mut(n) {
                            mailbox.by_class[msg.class().index()].push_back((from, msg));
                            if let Some(clock) = &mut clock {
                                clock.wake(n, env.arrival);
                            }
                            if !is_active[n] && !stopped[n] {
                                is_active[n] = true;
                                active.push(n);
                            }
                        }
                    }
                }
            }
            Choice::Step(i) => {
                let n = active[i];
                steps[n] += 1;
                if cfg
                    .stop
                    .is_some_and(|(node, after)| usize::from(node) == n && steps[n] > after)
                {
                    // The faulty node: it takes no more steps and reads nothing.
                    active.swap_remove(i);
                    is_active[n] = false;
                    stopped[n] = true;
                    continue;
                }
                // What a timed run's clock needs from before the step. An untimed run skips
                // it: reading a node's mailboxes and counters before its step was a cache
                // miss per step on a machine of many nodes.
                let before = clock.is_some().then(|| {
                    let pending = mailboxes[n]
                        .by_class
                        .iter()
                        .map(VecDeque::len)
                        .sum::<usize>();
                    (pending, workers[n].counters(), net.inflight.len())
                });
                let mut port = SimPort {
                    from: n as u16,
                    net: &mut net,
                    mailbox: &mut mailboxes[n],
                    capacity,
                    received: 0,
                };
                let progress = workers[n].poll(&mut port);
                let received = port.received;
                if let (Some(clock), Some((pending, counters, sent))) = (&mut clock, &before) {
                    clock.step(
                        n,
                        &workers[n].counters(),
                        counters,
                        *pending,
                        received,
                        &mut net.inflight[*sent..],
                    );
                }
                if let Some((from, to, kind)) = net.refused.take() {
                    record(&mut trace, Event::Refused { from, to, kind });
                }
                record(
                    &mut trace,
                    Event::Step {
                        node: n as u16,
                        busy: progress == Progress::Busy,
                    },
                );
                if progress == Progress::Idle {
                    active.swap_remove(i);
                    is_active[n] = false;
                }
                if cfg.flow_control && workers[n].max_unacked() > flow.i_max {
                    return Err(fail(
                        format!("node {n} has {} unacknowledged messages to one node in one class, i_max is {}", workers[n].max_unacked(), flow.i_max),
                        events,
                        &trace,
                    ));
                }
            }
        }
        if let Some((n, held)) = net.overflow {
            return Err(fail(
                format!("node {n}'s receive buffer holds {held} bytes, capacity {capacity}"),
                events,
                &trace,
            ));
        }
        if net.sent != net.delivered + net.inflight.len() as u64 {
            return Err(fail(
                format!(
                    "{} sent, {} delivered, {} in flight",
                    net.sent,
                    net.delivered,
                    net.inflight.len()
                ),
                events,
                &trace,
            ));
        }
    }
    // The host has ended: nothing may be left anywhere.
    let end_fail = |what: String| fail(what, events, &trace);
    if !net.inflight.is_empty() {
        return Err(end_fail(format!(
            "the host ended with {} messages in flight",
            net.inflight.len()
        )));
    }
    for w in &workers {
        if w.max_unacked() != 0 {
            return Err(end_fail(format!(
                "node {} ended with unacknowledged messages",
                w.node()
            )));
        }
        if w.stats().protocol_errors > 0 {
            return Err(end_fail(format!(
                "node {} counted {} protocol errors",
                w.node(),
                w.stats().protocol_errors
            )));
        }
    }
    let (image, stats) = host.finish().map_err(end_fail)?;
    let shape = super::RunShape::new(cfg, &partition, &grid, view, size_of::<T>());
    // The host keeps the nodes' statistics by node id.
    let nodes = stats
        .into_iter()
        .zip(&net.peak)
        .enumerate()
        .map(|(node, (stats, &peak))| shape.report(node as u16, stats, peak, Duration::ZERO))
        .collect();
    let mut time = clock.map(Clock::finish);
    let shift = shifted.map(|(_, report)| report);
    if let (Some(t), Some(report)) = (&mut time, &shift) {
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
    Ok(Distributed {
        time,
        shift,
        pixels: image,
        nodes,
        messages,
        bytes,
        events,
        buffer_capacity: capacity,
        i_max: flow.i_max,
        wall: start.elapsed(),
    })
}

enum Choice {
    Deliver(usize),
    Step(usize),
}

fn choose(scheduler: Scheduler, rng: &mut SplitMix, inflight: &[Envelope], nodes: usize) -> Choice {
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

/// Virtual time of a timed run: every node's clock and its time by category.
struct Clock {
    profile: MachineProfile,
    now: Vec<f64>,
    parts: Vec<[f64; Category::COUNT]>,
    host_time: f64,
    last_pixel: f64,
}

impl Clock {
    fn new(profile: &MachineProfile, nodes: usize) -> Clock {
        Clock {
            profile: profile.clone(),
            now: vec![0.0; nodes],
            parts: vec![[0.0; Category::COUNT]; nodes],
            host_time: 0.0,
            last_pixel: 0.0,
        }
    }

    /// Seconds for a message of `len` bytes over `hops` hops.
    fn transfer(&self, len: usize, hops: u32) -> f64 {
        let m = &self.profile.messages;
        // Message costs are the machine's own: `scale` calibrates only the tracer's compute.
        m.latency + len as f64 * m.per_byte + f64::from(hops.saturating_sub(1)) * m.per_hop
    }

    /// The earliest event: a delivery, or a step of the node whose clock is earliest.
    fn choose(&self, inflight: &[Envelope], active: &[usize]) -> Choice {
        let deliver = inflight
            .iter()
            .enumerate()
            .min_by(|(_, a), (_, b)| a.arrival.total_cmp(&b.arrival).then(a.seq.cmp(&b.seq)));
        let step = active
            .iter()
            .enumerate()
            .min_by(|(_, &a), (_, &b)| self.now[a].total_cmp(&self.now[b]).then(a.cmp(&b)));
        match (deliver, step) {
            (Some((i, e)), Some((_, &n))) if e.arrival <= self.now[n] => Choice::Deliver(i),
            (_, Some((j, _))) => Choice::Step(j),
            (Some((i, _)), None) => Choice::Deliver(i),
            (None, None) => Choice::Step(0),
        }
    }

    /// Charge node `n`'s step (counters `before` → `after`, `pending` messages waiting when it
    /// began, `received` read) and stamp the arrival of the messages it sent.
    fn step(
        &mut self,
        n: usize,
        after: &Counters,
        before: &Counters,
        pending: usize,
        received: u64,
        sent: &mut [Envelope],
    ) {
        let (m, scale) = (self.profile.messages, self.profile.scale);
        let [interpolate, trace, shade] = self.profile.compute(&after.since(before));
        let mut parts = [0.0; Category::COUNT];
        parts[Category::Test as usize] = m.test + m.test_per_pending * pending as f64;
        parts[Category::Interpolate as usize] = interpolate;
        parts[Category::Trace as usize] = trace;
        parts[Category::SampleShade as usize] = shade;
        parts[Category::Read as usize] = received as f64 * m.read;
        parts[Category::Write as usize] = sent.len() as f64 * m.write;
        let mut spent = 0.0;
        for (category, (total, part)) in Category::ALL
            .iter()
            .zip(self.parts[n].iter_mut().zip(parts))
        {
            // `scale` calibrates the tracer's compute; message handling is the machine's own.
            let part = if category.is_compute() {
                part * scale
            } else {
                part
            };
            *total += part;
            spent += part;
        }
        self.now[n] += spent;
        let me = n as u16;
        for e in sent.iter_mut() {
            let h = match e.to {
                Dest::Node(to) => hops(me, to).max(1),
                Dest::Host => 1,
            };
            e.arrival = self.now[n] + self.transfer(e.len, h);
        }
    }

    /// Node `n` is woken by a message arriving at `at`: the wait is idle time.
    fn wake(&mut self, n: usize, at: f64) {
        if at > self.now[n] {
            self.parts[n][Category::Idle as usize] += at - self.now[n];
            self.now[n] = at;
        }
    }

    fn host_receives(&mut self, at: f64, msg: &Msg) {
        self.host_time = self.host_time.max(at);
        if let Msg::Pixels(_) = msg {
            self.last_pixel = self.last_pixel.max(at);
        }
    }

    fn finish(self) -> VirtualTime {
        let end = self.last_pixel;
        // From a node's last work to the end of the frame it is idle too.
        let parts = self
            .parts
            .into_iter()
            .zip(&self.now)
            .map(|(mut p, &now)| {
                if end > now {
                    p[Category::Idle as usize] += end - now;
                }
                p
            })
            .collect();
        VirtualTime {
            frame: end,
            end: self.host_time,
            parts,
        }
    }
}

/// The image rows with missing pixels, summarised as ranges.
pub fn missing_rows(image: &[Option<[u8; 4]>], width: u32) -> String {
    let width = width.max(1) as usize;
    let rows: Vec<usize> = image
        .chunks(width)
        .enumerate()
        .filter(|(_, r)| r.iter().any(Option::is_none))
        .map(|(i, _)| i)
        .collect();
    let mut out: Vec<String> = Vec::new();
    let mut i = 0;
    while i < rows.len() {
        let start = rows[i];
        while i + 1 < rows.len() && rows[i + 1] == rows[i] + 1 {
            i += 1;
        }
        out.push(if rows[i] == start {
            start.to_string()
        } else {
            format!("{start}-{}", rows[i])
        });
        i += 1;
    }
    if out.len() > 12 {
        let n = out.len();
        out.truncate(12);
        out.push(format!("... ({n} runs in all)"));
    }
    out.join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_worker_that_may_generate_no_ray_a_poll_is_refused_and_one_is_enough() {
        let jobs = crate::scene::Scene::default_scene()
            .and_then(crate::scene::Scene::load)
            .unwrap();
        let (volume, view) = (&jobs[0].volume, &jobs[0].views[0].view);
        let VolumeData::U8(data) = &volume.data else {
            panic!("the default scene is u8");
        };
        let partition = Partition::uniform(volume.grid.dims()[0], 1).unwrap();
        let cfg = SimConfig::cluster(1, 0).unwrap();
        let (flow, _) = super::super::flow_for(&cfg, view).unwrap();
        let setup = |rays_per_poll| Setup {
            view,
            slab: Slab::new(volume.grid, partition.planes(0), view.ghost_planes(), data).unwrap(),
            partition: &partition,
            place: Place {
                layout: cfg.layout,
                cluster: 0,
                position: 0,
            },
            generation: Generation::Distributed,
            flow,
            rays_per_poll,
        };
        assert_eq!(
            SimWorker::check(setup(0)).map(|_| ()),
            Err(WorkerError::Capacity)
        );
        assert!(SimWorker::check(setup(1)).is_ok());
    }

    #[test]
    fn a_push_past_capacity_is_an_overflow_even_when_the_buffer_drains_later() {
        let len = Msg::Collect.kind().encoded_len();
        let mut net = Network::new(2, 2 * len);
        for _ in 0..2 {
            net.push(None, Dest::Node(1), &Msg::Collect);
        }
        net.push(None, Dest::Host, &Msg::Collect);
        assert_eq!(net.overflow, None, "full is not over");
        net.push(None, Dest::Node(1), &Msg::Collect);
        net.used[1] = 0;
        net.push(None, Dest::Node(1), &Msg::Collect);
        assert_eq!(
            net.overflow,
            Some((1, 3 * len)),
            "the first overflow is kept"
        );
    }
}

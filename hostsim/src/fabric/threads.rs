//! The threads fabric: the same workers on OS threads, for wall-clock speed. Nodes are dealt
//! out to a pool of threads (one per core by default), and each thread polls its nodes in
//! turn. Each node's receive buffer has the simulator's byte capacity: a send reserves its
//! bytes with a compare-and-swap and is refused when they do not fit, so flow control bounds
//! it exactly as in the simulator; its messages wait in lock-free queues, one per class. The
//! host has no thread of its own, so that a run takes no more threads than cores: each
//! thread polls it between the rounds of its own nodes (the calling thread waits its turn,
//! the others pass when it is taken). It collects pixels and tokens, asks for statistics
//! once every token is in, and ends when it has them and every pixel. A run whose host hears
//! nothing for [`STALL`] is reported as stalled, not left hanging.
//!
//! With balanced cuts the nodes first shift planes from their uniform slabs to their new ones
//! by slab-plane messages over the same buffers ([`shift`]), in rounds that every thread
//! finishes before any starts the next.
//!
//! Scheduling is up to the OS, so runs are not repeatable event for event. Images still are,
//! bit for bit: nothing the image depends on depends on order.

use super::harness::{NodeWorker, Plan};
use super::host::Host;
use super::recovery::{self, LostNode, Retraced};
use super::shift::{self as planes, Counted, ShiftFailure, ShiftJob, ShiftReport};
use super::{Distributed, RunConfig, RunError};
use crate::input::dataset::{Volume, VolumeData};
use crossbeam_queue::SegQueue;
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::mpsc;
use std::sync::{Mutex, PoisonError};
use std::time::{Duration, Instant};
use voxcube_kernel::node::flow::Class;
use voxcube_kernel::node::msg::Msg;
use voxcube_kernel::node::partition::Partition;
use voxcube_kernel::node::port::{Dest, Port};
use voxcube_kernel::node::topology::Layout;
use voxcube_kernel::node::worker::Progress;
use voxcube_kernel::trace::view::View;
use voxcube_kernel::volume::grid::Grid;
use voxcube_kernel::volume::sample::Sample;

/// How long the host waits without hearing from any node before it reports a stall.
pub const STALL: Duration = Duration::from_secs(20);

/// Polls of one node in a row while it is busy, before the thread turns to its next node.
const BURST: u32 = 16;

/// How long a thread whose nodes have nothing to do yields before it sleeps ([`Crew::rest`]).
const SPIN: Duration = Duration::from_millis(1);

/// A node's received messages by class, first in first out within a class. Lock-free, so
/// that no sender or receiver waits for another on a ring's message path: behind a lock, a
/// thread whose core is taken while it holds the lock holds up every thread that needs it,
/// which a shared machine does often. A queue allocates a block per 31 messages, not one a
/// message.
#[derive(Default)]
struct Inbox {
    by_class: [SegQueue<(Dest, Msg)>; 7],
}

/// A node's receive buffer, shared by every sender.
struct Buffer {
    inbox: Inbox,
    /// Bytes held or promised (sent, not yet read).
    used: AtomicUsize,
    peak: AtomicUsize,
    /// Messages in `inbox`, or about to be: counted before they are queued, so that a
    /// receiver never takes more than it counted.
    queued: AtomicUsize,
}

impl Buffer {
    fn new() -> Buffer {
        Buffer {
            inbox: Inbox::default(),
            used: AtomicUsize::new(0),
            peak: AtomicUsize::new(0),
            queued: AtomicUsize::new(0),
        }
    }

    /// Reserve `len` bytes unless that would pass `capacity`.
    fn reserve(&self, len: usize, capacity: usize) -> bool {
        let mut used = self.used.load(Ordering::Acquire);
        loop {
            if used + len > capacity {
                return false;
            }
            match self.used.compare_exchange_weak(
                used,
                used + len,
                Ordering::AcqRel,
                Ordering::Acquire,
            ) {
                Ok(_) => {
                    self.peak.fetch_max(used + len, Ordering::Relaxed);
                    return true;
                }
                Err(now) => used = now,
            }
        }
    }

    fn push(&self, from: Dest, msg: Msg) {
        self.queued.fetch_add(1, Ordering::Release);
        self.inbox.by_class[msg.class().index()].push((from, msg));
    }
}

struct ThreadPort<'s> {
    node: u16,
    buffers: &'s [Buffer],
    capacity: usize,
    host: mpsc::Sender<(u16, Msg)>,
    local: [VecDeque<(Dest, Msg)>; 7],
}

impl ThreadPort<'_> {
    /// Move every message of `class` from the shared inbox into the local queue.
    #[inline]
    fn fetch(&mut self, class: Class) {
        let i = class.index();
        if !self.local[i].is_empty() {
            return;
        }
        let buffers = self.buffers;
        let me = &buffers[usize::from(self.node)];
        if me.queued.load(Ordering::Acquire) == 0 {
            return;
        }
        self.take(i, me);
    }

    /// The part of [`ThreadPort::fetch`] that moves messages, out of line, so that the two
    /// checks before it inline: most polls find nothing queued, and `fetch` is called about
    /// seven times a poll.
    #[inline(never)]
    fn take(&mut self, i: usize, me: &Buffer) {
        let mut moved = 0;
        while let Some(message) = me.inbox.by_class[i].pop() {
            self.local[i].push_back(message);
            moved += 1;
        }
        me.queued.fetch_sub(moved, Ordering::Release);
    }
}

impl Port for ThreadPort<'_> {
    fn try_send(&mut self, to: Dest, msg: Msg) -> Result<(), Msg> {
        match to {
            Dest::Host => {
                // The host is always there to take pixels, tokens and statistics.
                self.host.send((self.node, msg)).map_err(|e| e.0 .1)
            }
            Dest::Node(n) => {
                let Some(buffer) = self.buffers.get(usize::from(n)) else {
                    return Err(msg);
                };
                if !buffer.reserve(msg.kind().encoded_len(), self.capacity) {
                    return Err(msg);
                }
                buffer.push(Dest::Node(self.node), msg);
                Ok(())
            }
        }
    }

    fn peek(&mut self, class: Class) -> Option<&Msg> {
        self.fetch(class);
        self.local[class.index()].front().map(|(_, m)| m)
    }

    fn try_recv(&mut self, class: Class) -> Option<(Dest, Msg)> {
        self.fetch(class);
        let (from, msg) = self.local[class.index()].pop_front()?;
        self.buffers[usize::from(self.node)]
            .used
            .fetch_sub(msg.kind().encoded_len(), Ordering::AcqRel);
        Some((from, msg))
    }

    fn pending(&self) -> usize {
        self.local.iter().map(VecDeque::len).sum::<usize>()
            + self.buffers[usize::from(self.node)]
                .queued
                .load(Ordering::Acquire)
    }
}

/// Render `view` of `volume` on `threads` OS threads (0: one per core), with the machine,
/// buffers and generation of `cfg` (its seed and scheduler do not apply).
pub fn run(
    volume: &Volume,
    view: &View,
    cfg: &RunConfig,
    threads: usize,
) -> Result<Distributed, RunError> {
    run_with_progress(volume, view, cfg, threads, &|_| {})
}

/// [`run`], telling `progress` how many pixels the host holds as they arrive.
pub fn run_with_progress(
    volume: &Volume,
    view: &View,
    cfg: &RunConfig,
    threads: usize,
    progress: &dyn Fn(u64),
) -> Result<Distributed, RunError> {
    match &volume.data {
        VolumeData::U8(d) => run_typed(volume, d, view, cfg, threads, progress),
        VolumeData::U16(d) => run_typed(volume, d, view, cfg, threads, progress),
        VolumeData::I16(d) => run_typed(volume, d, view, cfg, threads, progress),
        VolumeData::F32(d) => run_typed(volume, d, view, cfg, threads, progress),
    }
}

fn run_typed<T: Sample + Send + Sync>(
    volume: &Volume,
    data: &[T],
    view: &View,
    cfg: &RunConfig,
    threads: usize,
    progress: &dyn Fn(u64),
) -> Result<Distributed, RunError> {
    let grid = volume.grid;
    let plan = Plan::new(&grid, view, cfg)?;
    let ran = run_hosted(&plan, volume, data, cfg, threads, progress)?;
    let Ran {
        host,
        lost,
        late,
        mut peaks,
        busy,
        shifted,
    } = ran;
    let (image, reports, recovered) = match lost {
        None => {
            let (image, reports) = host.finish().map_err(host_failure)?;
            (image, reports, None)
        }
        Some(lost) => {
            let already = host.received();
            let retrace = |survivors: &RunConfig, _: &[u16]| {
                let plan = Plan::new(&grid, view, survivors)?;
                let again = run_hosted(&plan, volume, data, survivors, threads, &|n| {
                    progress(already + n)
                })?;
                if let Some(lost) = again.lost {
                    return Err(recovery::lost_in_retrace(lost.node));
                }
                Ok(Retraced {
                    host: again.host,
                    peaks: again.peaks,
                    messages: [0; 9],
                    bytes: 0,
                    events: 0,
                    time: None,
                })
            };
            let mut done = recovery::complete(view, cfg, lost, host, &retrace)?;
            done.raise_peaks(&mut peaks);
            done.recovery.late = late;
            (done.image, done.stats, Some(done.recovery))
        }
    };
    let mut run = plan.finish(
        cfg,
        &grid,
        T::KIND,
        image,
        reports,
        &|n| peaks[n],
        &|n| busy[n],
        shifted,
    );
    run.recovery = recovered;
    Ok(run)
}

/// What one run on the threads left: its host, the node it declared lost, each node's peak
/// buffer and busy time, and the plane shift's report.
struct Ran {
    host: Host,
    lost: Option<LostNode>,
    /// Messages of the lost cluster that came after it was declared lost, dropped.
    late: u64,
    peaks: Vec<usize>,
    busy: Vec<Duration>,
    shifted: Option<ShiftReport>,
}

/// Run `plan` on the threads until the host ends: with every pixel, or with a cluster lost.
fn run_hosted<T: Sample + Send + Sync>(
    plan: &Plan<'_>,
    volume: &Volume,
    data: &[T],
    cfg: &RunConfig,
    threads: usize,
    progress: &dyn Fn(u64),
) -> Result<Ran, RunError> {
    let (nodes, capacity) = (plan.nodes(), plan.capacity);
    let threads = match threads {
        0 => std::thread::available_parallelism().map_or(1, usize::from),
        t => t,
    }
    .clamp(1, nodes);
    let (storage, shifted) = plan.load(volume, data, cfg, threads, |job| {
        Ok(shift(job, data, threads)?)
    })?;
    let workers = plan.workers(&storage, cfg)?;
    let buffers: Vec<Buffer> = (0..nodes).map(|_| Buffer::new()).collect();
    let last: Vec<AtomicU64> = (0..nodes).map(|_| AtomicU64::new(0)).collect();
    let beats = Beats {
        last: &last,
        epoch: Instant::now(),
        stop: cfg.schedule.stop,
    };
    let done = AtomicBool::new(false);
    let (host_tx, host_rx) = mpsc::channel::<(u16, Msg)>();
    // Deal the nodes out to the threads; the calling thread takes the first share.
    let mut shares: Vec<Vec<Box<NodeWorker<'_, T>>>> = (0..threads).map(|_| Vec::new()).collect();
    for (i, w) in workers.into_iter().enumerate() {
        shares[i % threads].push(w);
    }
    let mut shares = shares
        .into_iter()
        .map(|share| Crew::new(share, &buffers, capacity, &host_tx, beats));
    let mut own = shares.next().unwrap_or_else(|| Crew::empty(beats));
    let others: Vec<_> = shares.collect();
    // The ports hold the only senders: should every port go with its failed thread, the host
    // hears so at once rather than after STALL.
    drop(host_tx);
    let mut busy = vec![Duration::ZERO; nodes];
    let host = Mutex::new(HostLoop::new(
        host_rx,
        plan.host(),
        beats,
        cfg.lost_after,
        plan.layout,
    ));
    let outcome = std::thread::scope(|scope| {
        let (done, host, buffers) = (&done, &host, &buffers);
        let handles: Vec<_> = others
            .into_iter()
            .map(|mut crew| {
                // The nodes' rounds are what a profile of a frame after its set-up samples
                // (`bench`, `bench --scale`); their storage was loaded before.
                scope.spawn(move || {
                    voxcube_sampler::sampled(|| {
                        while !done.load(Ordering::Acquire) {
                            let progressed = crew.round();
                            let heard = host
                                .try_lock()
                                .is_ok_and(|mut host| host.poll(buffers, capacity));
                            crew.rest(progressed || heard);
                        }
                    });
                    crew.times()
                })
            })
            .collect();
        // The host runs between the rounds of the threads' own nodes, not on a thread of its
        // own: a host thread that sleeps and wakes takes a core from a worker at each wake-up,
        // and the workers then end unevenly.
        let result = voxcube_sampler::sampled(|| loop {
            let progressed = own.round();
            let mut at = host.lock().unwrap_or_else(PoisonError::into_inner);
            let heard = at.poll(buffers, capacity);
            let (failure, done, received) = (at.failure.take(), at.done(), at.host.received());
            // Told with the host free, so that another thread may take it meanwhile.
            drop(at);
            progress(received);
            match failure {
                Some(e) => break Err(e),
                None if done => break Ok(()),
                None => own.rest(progressed || heard),
            }
        });
        done.store(true, Ordering::Release);
        let own_times = own.times();
        // A worker thread that panicked has no times to give; the host's result stands.
        let times = handles
            .into_iter()
            .flat_map(|h| h.join().unwrap_or_default())
            .chain(own_times);
        for (node, spent) in times {
            if let Some(b) = busy.get_mut(usize::from(node)) {
                *b = spent;
            }
        }
        result
    });
    outcome?;
    let host = host.into_inner().unwrap_or_else(PoisonError::into_inner);
    Ok(Ran {
        host: host.host,
        lost: host.lost,
        late: host.late,
        peaks: buffers
            .iter()
            .map(|b| b.peak.load(Ordering::Relaxed))
            .collect(),
        busy,
        shifted,
    })
}

/// A thread's nodes during the shift: id and storage.
type Share<T> = Vec<(u16, Vec<T>)>;

/// Carry out `job` by slab-plane messages between `threads` OS threads, in rounds between
/// neighbours. Each node loads its slab of the old cuts from `data` and from then on has only
/// its own storage. A round ends when every thread's nodes are done, so no chunk of the next
/// round reaches a node still taking this one. Returns each node's storage (its new stored
/// planes) in node-id order and the report, which has no simulated time: this fabric is
/// timed by the clock. Nothing hangs: a thread that sees no progress for [`STALL`] fails.
pub fn shift<T: Sample + Send + Sync>(
    job: &ShiftJob<'_>,
    data: &[T],
    threads: usize,
) -> Result<(Vec<Vec<T>>, ShiftReport), ShiftFailure> {
    let (grid, layout, ghost, capacity) = (job.grid, job.layout, job.ghost, job.capacity);
    let steps = planes::rounds(&job.old, job.new)?;
    let nodes = layout.nodes() as usize;
    let threads = threads.clamp(1, nodes);
    let buffers: Vec<Buffer> = (0..nodes).map(|_| Buffer::new()).collect();
    // The shift sends nothing to the host; the ports still need somewhere to send it.
    let (host, _unused) = mpsc::channel::<(u16, Msg)>();
    let mut shares: Vec<Share<T>> = (0..threads).map(|_| Vec::new()).collect();
    for node in 0..nodes as u16 {
        let storage = planes::load(grid, data, layout, &job.old, ghost, node);
        shares[usize::from(node) % threads].push((node, storage));
    }
    let arrived = AtomicUsize::new(0);
    // The first failure is kept; the flag lets the polling loops see it without a lock.
    let failure: Mutex<Option<ShiftFailure>> = Mutex::new(None);
    let stop = AtomicBool::new(false);
    let fail = |e: ShiftFailure| {
        let mut f = failure.lock().unwrap_or_else(PoisonError::into_inner);
        f.get_or_insert(e);
        stop.store(true, Ordering::Release);
    };
    let failed = || stop.load(Ordering::Acquire);
    let mut report = ShiftReport {
        messages: 0,
        bytes: 0,
        seconds: None,
        per_node: Vec::new(),
        peak_samples: 0,
        rounds: steps.len() as u32,
    };
    let mut storages: Vec<Vec<T>> = vec![Vec::new(); nodes];
    std::thread::scope(|scope| {
        let handles: Vec<_> = shares
            .into_iter()
            .map(|mut share| {
                let (buffers, arrived, steps, host) = (&buffers, &arrived, &steps, host.clone());
                let (fail, failed) = (&fail, &failed);
                scope.spawn(move || {
                    let mut counts = [0u64; 2];
                    let mut peak = 0usize;
                    for (r, cuts) in steps.iter().enumerate() {
                        let ports = share
                            .iter()
                            .map(|(node, _)| {
                                Counted::new(ThreadPort {
                                    node: *node,
                                    buffers,
                                    capacity,
                                    host: host.clone(),
                                    local: Default::default(),
                                })
                            })
                            .collect();
                        let outcome = shift_round(
                            grid,
                            layout,
                            (&cuts.0, &cuts.1),
                            ghost,
                            &mut share,
                            ports,
                            failed,
                        );
                        match outcome {
                            Ok((sent, bytes, held)) => {
                                counts[0] += sent;
                                counts[1] += bytes;
                                peak = peak.max(held);
                            }
                            Err(e) => {
                                fail(e);
                                return (share, counts, peak);
                            }
                        }
                        arrived.fetch_add(1, Ordering::AcqRel);
                        let waited = Instant::now();
                        while arrived.load(Ordering::Acquire) < (r + 1) * threads {
                            if failed() {
                                return (share, counts, peak);
                            }
                            if waited.elapsed() > STALL {
                                fail(ShiftFailure::Stalled { unfinished: 0 });
                                return (share, counts, peak);
                            }
                            std::thread::yield_now();
                        }
                    }
                    (share, counts, peak)
                })
            })
            .collect();
        for h in handles {
            match h.join() {
                Ok((share, counts, peak)) => {
                    report.messages += counts[0];
                    report.bytes += counts[1];
                    report.peak_samples = report.peak_samples.max(peak);
                    for (node, storage) in share {
                        storages[usize::from(node)] = storage;
                    }
                }
                Err(_) => fail(ShiftFailure::Stalled { unfinished: 0 }),
            }
        }
    });
    if let Some(e) = failure.into_inner().unwrap_or_else(PoisonError::into_inner) {
        return Err(e);
    }
    Ok((storages, report))
}

/// One thread's nodes through one round of the shift: messages sent, their bytes, and the
/// largest storage held.
fn shift_round<T: Sample>(
    grid: &Grid,
    layout: Layout,
    cuts: (&Partition, &Partition),
    ghost: u32,
    share: &mut Share<T>,
    mut ports: Vec<Counted<ThreadPort<'_>>>,
    failed: &dyn Fn() -> bool,
) -> Result<(u64, u64, usize), ShiftFailure> {
    let mut held = 0;
    let mut shifts = Vec::with_capacity(share.len());
    for (node, storage) in share.iter_mut() {
        let (shift, samples) = planes::start(grid, layout, *node, cuts, ghost, storage)?;
        held = held.max(samples);
        shifts.push((*node, shift));
    }
    let mut heard = Instant::now();
    loop {
        let unfinished = shifts.iter().filter(|(_, s)| !s.done()).count();
        if unfinished == 0 || failed() {
            break;
        }
        let mut moved = false;
        for ((_, shift), port) in shifts.iter_mut().zip(&mut ports) {
            moved |= shift.poll(port) == Progress::Busy;
        }
        if moved {
            heard = Instant::now();
        } else if heard.elapsed() > STALL {
            return Err(ShiftFailure::Stalled { unfinished });
        } else {
            std::thread::yield_now();
        }
    }
    if let Some((node, _)) = shifts.iter().find(|(_, s)| s.strays() > 0) {
        return Err(ShiftFailure::Strays { node: *node });
    }
    let stored: Vec<_> = shifts.iter().map(|(_, s)| s.stored()).collect();
    drop(shifts);
    for ((_, storage), s) in share.iter_mut().zip(&stored) {
        planes::keep(grid, storage, s);
    }
    let sent = ports.iter().map(|p| p.sent).sum();
    let bytes = ports.iter().map(|p| p.sent_bytes).sum();
    Ok((sent, bytes, held))
}

/// A thread's nodes and their ports, polled in turn, and each node's busy time.
struct Crew<'s, 'v, T: Sample> {
    workers: Vec<Box<NodeWorker<'v, T>>>,
    ports: Vec<ThreadPort<'s>>,
    busy: Vec<Duration>,
    /// When the rounds without progress began; `None` after one with progress.
    idle_since: Option<Instant>,
    /// Each node's polls that did something so far (what the injected fault counts).
    polls: Vec<u64>,
    beats: Beats<'s>,
}

/// Every node's heartbeat: microseconds from `epoch` to its last poll, and the injected
/// fault, a node that stops being polled after so many polls.
#[derive(Clone, Copy)]
struct Beats<'s> {
    last: &'s [AtomicU64],
    epoch: Instant,
    stop: Option<(u16, u64)>,
}

impl Beats<'_> {
    /// Whether `node`, after `polls` polls that did something, has stopped (the injected
    /// fault).
    fn stopped(&self, node: u16, polls: u64) -> bool {
        self.stop
            .is_some_and(|(n, after)| n == node && polls >= after)
    }

    /// Record a poll of `node` at `now`.
    fn beat(&self, node: u16, now: Instant) {
        if let Some(b) = self.last.get(usize::from(node)) {
            let at = now.saturating_duration_since(self.epoch).as_micros() as u64;
            b.store(at, Ordering::Relaxed);
        }
    }

    /// The node heard from least recently, and how long ago, if it is longer than `limit`.
    fn silent(&self, limit: Duration) -> Option<(u16, Duration)> {
        let now = self.epoch.elapsed().as_micros() as u64;
        let (node, last) = self
            .last
            .iter()
            .map(|b| b.load(Ordering::Relaxed))
            .enumerate()
            .min_by_key(|&(_, at)| at)?;
        let silent = Duration::from_micros(now.saturating_sub(last));
        (silent > limit).then_some((node as u16, silent))
    }
}

impl<'s, 'v, T: Sample> Crew<'s, 'v, T> {
    fn new(
        workers: Vec<Box<NodeWorker<'v, T>>>,
        buffers: &'s [Buffer],
        capacity: usize,
        host: &mpsc::Sender<(u16, Msg)>,
        beats: Beats<'s>,
    ) -> Crew<'s, 'v, T> {
        let ports = workers
            .iter()
            .map(|w| ThreadPort {
                node: w.node(),
                buffers,
                capacity,
                host: host.clone(),
                local: Default::default(),
            })
            .collect();
        let busy = vec![Duration::ZERO; workers.len()];
        let polls = vec![0; workers.len()];
        Crew {
            workers,
            ports,
            busy,
            idle_since: None,
            polls,
            beats,
        }
    }

    /// A crew of no nodes, for a calling thread dealt none.
    fn empty(beats: Beats<'s>) -> Crew<'s, 'v, T> {
        Crew {
            workers: Vec::new(),
            ports: Vec::new(),
            busy: Vec::new(),
            idle_since: None,
            polls: Vec::new(),
            beats,
        }
    }

    /// Each node polled while it has work, up to [`BURST`] times; whether any had work.
    fn round(&mut self) -> bool {
        let mut progressed = false;
        // The clock is read once per burst: a poll is one to four rays, too little work to
        // read the clock around. Each burst's time runs from the previous read.
        let mut t = Instant::now();
        let beats = self.beats;
        let nodes = self.workers.iter_mut().zip(&mut self.ports);
        for (((w, port), spent), total) in nodes.zip(&mut self.busy).zip(&mut self.polls) {
            let node = w.node();
            if beats.stopped(node, *total) {
                // The injected fault: no longer polled, no heartbeat.
                continue;
            }
            let mut polls = 0;
            while polls < BURST && !beats.stopped(node, *total) {
                if w.poll(port) != Progress::Busy {
                    break;
                }
                // Only a poll that did something counts toward the injected fault, as the
                // simulator counts only a node's steps while it is not idle: a node waiting on
                // a loaded machine polls idly without end, and would stop wherever that was.
                *total += 1;
                polls += 1;
            }
            let now = Instant::now();
            beats.beat(node, now);
            if polls > 0 {
                progressed = true;
                *spent += now - t;
            }
            t = now;
        }
        progressed
    }

    /// After a round: nothing if something happened, else a yield, and once nothing has
    /// happened for [`SPIN`] a short sleep, so that a thread idle for long leaves its core to
    /// the others. A frame's last messages (the tokens, the request for statistics and the
    /// answers) cross threads within microseconds of each other, and a thread that slept
    /// sooner would sleep through them and end the frame late.
    fn rest(&mut self, progressed: bool) {
        if progressed {
            self.idle_since = None;
            return;
        }
        let since = *self.idle_since.get_or_insert_with(Instant::now);
        if since.elapsed() < SPIN {
            std::thread::yield_now();
        } else {
            std::thread::sleep(Duration::from_micros(50));
        }
    }

    /// Each node's busy time.
    fn times(self) -> Vec<(u16, Duration)> {
        let nodes = self.workers.iter().map(|w| w.node());
        nodes.zip(self.busy).collect()
    }
}

/// The host's side of a run: pixels and tokens in, then statistics. Shared by the threads:
/// each polls it after its own round when no other thread is at it (the calling thread waits
/// its turn), so the host's work falls on every core rather than delaying one thread's
/// nodes while the others wait idle at the end.
struct HostLoop<'s> {
    rx: mpsc::Receiver<(u16, Msg)>,
    host: Host,
    heard: Instant,
    /// The first break of the host's protocol, or a stall, for the calling thread to end the
    /// run with.
    failure: Option<RunError>,
    /// Lost nodes: the heartbeats, how long a node may be silent, the machine, the node
    /// declared lost and the messages of its cluster dropped since.
    beats: Beats<'s>,
    lost_after: Duration,
    layout: Layout,
    lost: Option<LostNode>,
    late: u64,
}

impl<'s> HostLoop<'s> {
    fn new(
        rx: mpsc::Receiver<(u16, Msg)>,
        host: Host,
        beats: Beats<'s>,
        lost_after: Duration,
        layout: Layout,
    ) -> HostLoop<'s> {
        HostLoop {
            rx,
            host,
            heard: Instant::now(),
            failure: None,
            beats,
            lost_after,
            layout,
            lost: None,
            late: 0,
        }
    }

    /// Take every message waiting, and ask every node for its statistics once every token
    /// is in; whether any came. Polled, never waited on: a receiver blocked in `recv` is
    /// woken by every send, a futex call and a context switch per pixel message. The clock
    /// is read once a poll, not once a
    /// message. A failure is kept in `failure`, and nothing more is taken after it.
    fn poll(&mut self, buffers: &[Buffer], capacity: usize) -> bool {
        if self.failure.is_some() {
            return false;
        }
        match self.take(buffers, capacity) {
            Ok(heard) => heard,
            Err(e) => {
                self.failure = Some(e);
                false
            }
        }
    }

    fn take(&mut self, buffers: &[Buffer], capacity: usize) -> Result<bool, RunError> {
        let mut heard = false;
        loop {
            let (from, msg) = match self.rx.try_recv() {
                Ok(message) => message,
                Err(mpsc::TryRecvError::Empty) if heard => {
                    self.heard = Instant::now();
                    break;
                }
                Err(mpsc::TryRecvError::Empty) if self.heard.elapsed() < STALL => {
                    self.watch(buffers, capacity)?;
                    break;
                }
                Err(_) => {
                    return Err(host_failure(format!(
                        "threads stalled: no message for {STALL:?}; {} of {} pixels",
                        self.host.received(),
                        self.host.received() + self.host.missing()
                    )))
                }
            };
            heard = true;
            if self
                .lost
                .is_some_and(|l| self.layout.place(from).0 == l.cluster)
            {
                // A late message of a cluster declared lost: its rows are re-traced.
                self.late += 1;
                continue;
            }
            if self.host.receive(msg).map_err(host_failure)? {
                self.collect(buffers, capacity)?;
            }
        }
        Ok(heard)
    }

    /// Ask every node the host waits for for its statistics.
    fn collect(&self, buffers: &[Buffer], capacity: usize) -> Result<(), RunError> {
        for (n, b) in buffers.iter().enumerate() {
            if !self.host.expects_report(n) {
                continue;
            }
            // The control reserve of every buffer has room for this request.
            if !b.reserve(Msg::Collect.kind().encoded_len(), capacity) {
                return Err(host_failure("no room for the host's request".into()));
            }
            b.push(Dest::Host, Msg::Collect);
        }
        Ok(())
    }

    /// With nothing to take: declare a node not polled for `lost_after` lost, once. With
    /// another cluster to re-trace its rows, the host waits for its cluster no more;
    /// without, the run fails naming it.
    fn watch(&mut self, buffers: &[Buffer], capacity: usize) -> Result<(), RunError> {
        if self.lost.is_some() || self.host.done() {
            return Ok(());
        }
        let Some((node, _)) = self.beats.silent(self.lost_after) else {
            return Ok(());
        };
        let cluster = self.layout.place(node).0;
        if self.layout.clusters() < 2 {
            return Err(RunError::Lost {
                node,
                waiting: 0,
                missing: self.host.missing(),
                rows: self.host.missing_rows(),
            });
        }
        self.lost = Some(LostNode {
            node,
            cluster,
            events: None,
            after: Some(self.beats.epoch.elapsed()),
        });
        if self.host.declare_lost(cluster).map_err(host_failure)? {
            self.collect(buffers, capacity)?;
        }
        Ok(())
    }

    /// Whether every pixel and every node's statistics are in.
    fn done(&self) -> bool {
        self.host.done()
    }
}

/// The host's failure as the run's error: a message that breaks its protocol, or a stall.
fn host_failure(what: String) -> RunError {
    RunError::Host(what)
}

#[cfg(test)]
mod tests {
    use super::*;
    use voxcube_kernel::node::msg::PixelSet;

    /// A message that breaks the host's protocol is kept as the run's failure for the calling
    /// thread, whichever thread polled, and nothing more is taken after it; the pixels before
    /// it stay counted.
    #[test]
    fn the_host_keeps_its_first_failure_and_takes_nothing_after_it() {
        let (tx, rx) = mpsc::channel();
        let last = [AtomicU64::new(0)];
        let beats = Beats {
            last: &last,
            epoch: Instant::now(),
            stop: None,
        };
        let layout = Layout::new(1, 1).expect("one node");
        let mut host = HostLoop::new(rx, Host::new(4, 2, 1, 1), beats, STALL, layout);
        let buffers = [Buffer::new()];
        let set = |pixel: u32| {
            let mut set = PixelSet::default();
            set.push(pixel, [1, 2, 3, 4]).expect("room for one pixel");
            Msg::Pixels(set)
        };
        tx.send((0, set(1))).expect("the host listens");
        assert!(host.poll(&buffers, 1024), "a pixel was heard");
        assert!(host.failure.is_none());
        // Pixel 1 again, then a new one.
        tx.send((0, set(1))).expect("the host listens");
        tx.send((0, set(2))).expect("the host listens");
        assert!(!host.poll(&buffers, 1024));
        let kept = host.failure.as_ref().map(ToString::to_string);
        assert!(
            kept.as_ref().is_some_and(|f| f.contains("twice")),
            "{kept:?}"
        );
        assert!(
            !host.poll(&buffers, 1024),
            "nothing taken after the failure"
        );
        assert_eq!(host.host.received(), 1);
        assert!(host.rx.try_recv().is_ok(), "pixel 2 still waits");
    }

    /// A node unheard for longer than the limit is declared lost once, its cluster's later
    /// messages are dropped and counted, and the host then waits for the others alone.
    #[test]
    fn a_silent_node_is_declared_lost_and_its_cluster_s_late_messages_dropped() {
        let (tx, rx) = mpsc::channel();
        let last = [AtomicU64::new(0), AtomicU64::new(0)];
        let epoch = Instant::now()
            .checked_sub(Duration::from_secs(5))
            .expect("a clock five seconds old");
        // Node 0 polled just now, node 1 not since the start.
        last[0].store(5_000_000, Ordering::Relaxed);
        let beats = Beats {
            last: &last,
            epoch,
            stop: None,
        };
        let layout = Layout::new(2, 1).expect("two clusters of one");
        let mut host = HostLoop::new(
            rx,
            Host::new(2, 1, 2, 2),
            beats,
            Duration::from_secs(1),
            layout,
        );
        let buffers = [Buffer::new(), Buffer::new()];
        assert!(!host.poll(&buffers, 1024));
        assert!(host.failure.is_none(), "{:?}", host.failure);
        let lost = host.lost.expect("node 1 declared lost");
        assert_eq!((lost.node, lost.cluster), (1, 1));
        let mut set = PixelSet::default();
        set.push(1, [1, 2, 3, 4]).expect("room for one pixel");
        tx.send((1, Msg::Pixels(set))).expect("the host listens");
        tx.send((0, Msg::Token { cluster: 0 }))
            .expect("the host listens");
        assert!(host.poll(&buffers, 1024));
        assert_eq!(
            (host.late, host.host.received()),
            (1, 0),
            "the late pixel dropped"
        );
        // Node 0 alone is asked for its statistics; node 1's buffer gets no request.
        assert_eq!(buffers[0].queued.load(Ordering::Acquire), 1);
        assert_eq!(buffers[1].queued.load(Ordering::Acquire), 0);
        assert!(host.host.expects_report(0) && !host.host.expects_report(1));
    }
}

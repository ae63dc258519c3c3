//! The threads fabric: the same workers on OS threads, for wall-clock speed. Nodes are dealt
//! out to a pool of threads (one per core by default), and each thread polls its nodes in
//! turn. Each node's receive buffer has the simulator's byte capacity: a send reserves its
//! bytes with a compare-and-swap and is refused when they do not fit, so flow control bounds
//! it exactly as in the simulator. The host runs on the calling thread. It collects pixels and
//! tokens, asks for statistics once every token is in, and ends when it has them and every
//! pixel. A run whose host hears nothing for [`STALL`] is reported as stalled, not left
//! hanging.
//!
//! Scheduling is up to the OS, so runs are not repeatable event for event. Images still are,
//! bit for bit: nothing the image depends on depends on order.

use super::host::Host;
use super::{Distributed, NodeReport};
use crate::dataset::{Volume, VolumeData};
use crate::fabric::sim::{SimConfig, SimError, SimWorker};
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc;
use std::sync::Mutex;
use std::time::{Duration, Instant};
use voxcube_kernel::flow::Class;
use voxcube_kernel::msg::Msg;
use voxcube_kernel::partition::Partition;
use voxcube_kernel::port::{Dest, Port};
use voxcube_kernel::sample::Sample;
use voxcube_kernel::slab::{stored_planes, Slab};
use voxcube_kernel::stats::NodeStats;
use voxcube_kernel::view::View;
use voxcube_kernel::worker::{Place, Progress};

/// How long the host waits without hearing from any node before it reports a stall.
pub const STALL: Duration = Duration::from_secs(20);

/// Polls of one node in a row while it is busy, before the thread turns to its next node.
const BURST: u32 = 16;

/// How often the host looks for messages when it has none.
const HOST_POLL: Duration = Duration::from_micros(100);

#[derive(Default)]
struct Inbox {
    by_class: [VecDeque<(Dest, Msg)>; 7],
}

/// A node's receive buffer, shared by every sender.
struct Buffer {
    inbox: Mutex<Inbox>,
    /// Bytes held or promised (sent, not yet read).
    used: AtomicUsize,
    peak: AtomicUsize,
    /// Messages in `inbox`.
    queued: AtomicUsize,
}

impl Buffer {
    fn new() -> Buffer {
        Buffer {
            inbox: Mutex::new(Inbox::default()),
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
        let mut inbox = self
            .inbox
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        inbox.by_class[msg.class().index()].push_back((from, msg));
        self.queued.fetch_add(1, Ordering::Release);
    }
}

struct ThreadPort<'s> {
    node: u16,
    buffers: &'s [Buffer],
    capacity: usize,
    host: mpsc::Sender<Msg>,
    local: [VecDeque<(Dest, Msg)>; 7],
}

impl ThreadPort<'_> {
    /// Move every message of `class` from the shared inbox into the local queue.
    fn fetch(&mut self, class: Class) {
        let i = class.index();
        if !self.local[i].is_empty() {
            return;
        }
        let me = &self.buffers[usize::from(self.node)];
        if me.queued.load(Ordering::Acquire) == 0 {
            return;
        }
        let mut inbox = me
            .inbox
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        let moved = inbox.by_class[i].len();
        self.local[i].extend(inbox.by_class[i].drain(..));
        me.queued.fetch_sub(moved, Ordering::Release);
    }
}

impl Port for ThreadPort<'_> {
    fn try_send(&mut self, to: Dest, msg: Msg) -> Result<(), Msg> {
        match to {
            Dest::Host => {
                // The host is always there to take pixels, tokens and statistics.
                self.host.send(msg).map_err(|e| e.0)
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
    cfg: &SimConfig,
    threads: usize,
) -> Result<Distributed, SimError> {
    run_with_progress(volume, view, cfg, threads, &|_| {})
}

/// [`run`], telling `progress` how many pixels the host holds as they arrive.
pub fn run_with_progress(
    volume: &Volume,
    view: &View,
    cfg: &SimConfig,
    threads: usize,
    progress: &dyn Fn(u64),
) -> Result<Distributed, SimError> {
    match &volume.data {
        VolumeData::U8(d) => run_typed(volume, d, view, cfg, threads, progress),
        VolumeData::U16(d) => run_typed(volume, d, view, cfg, threads, progress),
        VolumeData::F32(d) => run_typed(volume, d, view, cfg, threads, progress),
    }
}

fn run_typed<T: Sample + Sync>(
    volume: &Volume,
    data: &[T],
    view: &View,
    cfg: &SimConfig,
    threads: usize,
    progress: &dyn Fn(u64),
) -> Result<Distributed, SimError> {
    let start = Instant::now();
    let grid = volume.grid;
    let layout = cfg.layout;
    let size = usize::from(layout.size());
    let partition = match &cfg.cuts {
        Some(cuts) => Partition::new(cuts, grid.dims()[0])?,
        None => Partition::uniform(grid.dims()[0], size)?,
    };
    let (flow, capacity) = super::flow_for(cfg, view)?;
    let ghost = view.ghost_planes();
    let plane = grid.plane_len();
    let stored: Vec<_> = (0..size)
        .map(|j| stored_planes(&grid, partition.planes(j), ghost))
        .collect();
    let block_stores: Vec<Vec<voxcube_kernel::blocks::Range>> = (0..size)
        .map(|j| {
            let data = &data[stored[j].start as usize * plane..stored[j].end as usize * plane];
            Slab::new(grid, partition.planes(j), ghost, data)
                .map(|s| super::block_storage(&s, cfg.skip))
                .unwrap_or_default()
        })
        .collect();
    let nodes = layout.nodes() as usize;
    let mut workers = Vec::with_capacity(nodes);
    for node in 0..nodes as u16 {
        let (cluster, position) = layout.place(node);
        let j = usize::from(position);
        let slab = super::with_blocks(
            Slab::new(
                grid,
                partition.planes(j),
                ghost,
                &data[stored[j].start as usize * plane..stored[j].end as usize * plane],
            )?,
            &block_stores[j],
        );
        let place = Place {
            layout,
            cluster,
            position,
        };
        workers.push(Box::new(SimWorker::new(
            view,
            slab,
            &partition,
            place,
            cfg.generation,
            flow,
        )?));
    }
    let buffers: Vec<Buffer> = (0..nodes).map(|_| Buffer::new()).collect();
    let threads = match threads {
        0 => std::thread::available_parallelism().map_or(1, usize::from),
        t => t,
    }
    .clamp(1, nodes);
    let pixels = view.pixel_count() as usize;
    let done = AtomicBool::new(false);
    let (host_tx, host_rx) = mpsc::channel::<Msg>();
    // Deal the nodes out to the threads.
    let mut shares: Vec<Vec<Box<SimWorker<'_, T>>>> = (0..threads).map(|_| Vec::new()).collect();
    for (i, w) in workers.into_iter().enumerate() {
        shares[i % threads].push(w);
    }
    let mut busy = vec![Duration::ZERO; nodes];
    let outcome = std::thread::scope(|scope| {
        let mut handles = Vec::new();
        for share in shares {
            let (buffers, done, host) = (&buffers, &done, host_tx.clone());
            handles.push(scope.spawn(move || {
                let mut ports: Vec<ThreadPort<'_>> = share
                    .iter()
                    .map(|w| ThreadPort {
                        node: w.node(),
                        buffers,
                        capacity,
                        host: host.clone(),
                        local: Default::default(),
                    })
                    .collect();
                let mut share = share;
                let mut busy_time = vec![Duration::ZERO; share.len()];
                let mut idle_rounds = 0u32;
                while !done.load(Ordering::Acquire) {
                    let mut busy = false;
                    // A node is polled while it has work, up to BURST times, and the clock is
                    // read once per burst: a poll is about one ray, and reading the clock around
                    // each took 4% of a frame. Each burst's time runs from the previous read.
                    let mut t = Instant::now();
                    for ((w, port), spent) in share.iter_mut().zip(&mut ports).zip(&mut busy_time) {
                        let mut polls = 0;
                        while polls < BURST && w.poll(port) == Progress::Busy {
                            polls += 1;
                        }
                        let now = Instant::now();
                        if polls > 0 {
                            busy = true;
                            *spent += now - t;
                        }
                        t = now;
                    }
                    if busy {
                        idle_rounds = 0;
                    } else {
                        idle_rounds += 1;
                        if idle_rounds < 64 {
                            std::thread::yield_now();
                        } else {
                            std::thread::sleep(Duration::from_micros(50));
                        }
                    }
                }
                share
                    .iter()
                    .map(|w| w.node())
                    .zip(busy_time)
                    .collect::<Vec<_>>()
            }));
        }
        drop(host_tx);
        let result = host(
            &host_rx,
            &buffers,
            capacity,
            pixels,
            view.spec().width,
            nodes,
            usize::from(layout.clusters()),
            progress,
        );
        done.store(true, Ordering::Release);
        for h in handles {
            // A worker thread that panicked has no times to give; the host's result stands.
            for (node, spent) in h.join().unwrap_or_default() {
                if let Some(b) = busy.get_mut(usize::from(node)) {
                    *b = spent;
                }
            }
        }
        result
    });
    let (image, reports) = outcome?;
    let nodes: Vec<NodeReport> = reports
        .into_iter()
        .enumerate()
        .map(|(n, stats)| {
            let peak = buffers[n].peak.load(Ordering::Relaxed);
            NodeReport::new(
                layout,
                &partition,
                &grid,
                ghost,
                size_of::<T>(),
                n as u16,
                stats,
                peak,
                busy[n],
            )
        })
        .collect();
    let messages = super::sent_by_kind(&nodes);
    Ok(Distributed {
        pixels: image,
        nodes,
        messages,
        bytes: 0,
        events: 0,
        buffer_capacity: capacity,
        i_max: flow.i_max,
        wall: start.elapsed(),
        time: None,
        shift: None,
    })
}

type HostResult = Result<(Vec<[u8; 4]>, Vec<NodeStats>), SimError>;

/// The host: pixels and tokens in, then statistics; returns the image and the reports.
#[allow(clippy::too_many_arguments, reason = "one call site: the run's shape")]
fn host(
    rx: &mpsc::Receiver<Msg>,
    buffers: &[Buffer],
    capacity: usize,
    pixels: usize,
    width: u32,
    nodes: usize,
    clusters: usize,
    progress: &dyn Fn(u64),
) -> HostResult {
    let failed = |what: String| SimError::Invariant {
        what,
        events: 0,
        seed: 0,
        scheduler: crate::fabric::sim::Scheduler::Uniform,
        trace: Default::default(),
    };
    let mut host = Host::new(pixels, width, clusters, nodes);
    let mut heard = Instant::now();
    while !host.done() {
        // Polled, not waited on: a receiver blocked in `recv` is woken by every send, and
        // those wake-ups (a futex call and a context switch per pixel message, on a machine
        // whose cores the workers need) cost a measured fifth of a one-node frame. Polling
        // every HOST_POLL costs one wake-up per interval and at most one interval of latency.
        let msg = match rx.try_recv() {
            Ok(msg) => {
                heard = Instant::now();
                msg
            }
            Err(mpsc::TryRecvError::Empty) if heard.elapsed() < STALL => {
                std::thread::sleep(HOST_POLL);
                continue;
            }
            Err(_) => {
                return Err(failed(format!(
                    "threads stalled: no message for {STALL:?}; {} of {pixels} pixels",
                    host.received()
                )))
            }
        };
        if host.receive(msg).map_err(failed)? {
            for b in buffers {
                // The control reserve of every buffer has room for this request.
                if !b.reserve(Msg::Collect.kind().encoded_len(), capacity) {
                    return Err(failed("no room for the host's request".into()));
                }
                b.push(Dest::Host, Msg::Collect);
            }
        }
        progress(host.received());
    }
    host.finish().map_err(failed)
}

//! The simulator fabric: every node of the machine in one thread, a seeded scheduler choosing
//! at each event either an in-flight message to deliver or a node to step. The same seed gives
//! the same run, event for event.
//!
//! Invariants checked as it runs: every message is encoded and decoded on the way (the codec
//! is on the path); a pixel reaches the host once; the run ends only when no message is in
//! flight and no node can step, and then the host must hold every pixel and every worker must
//! be finished with no protocol error — anything else is a reported failure, never a partial
//! image. Links are unbounded here; bounded buffers and flow control come with the next fabric
//! features.

use super::{Distributed, NodeReport};
use crate::dataset::{Volume, VolumeData};
use crate::rng::SplitMix;
use std::collections::VecDeque;
use std::time::Instant;
use voxcube_kernel::msg::{DecodeError, Msg, MAX_MSG_LEN};
use voxcube_kernel::partition::{Partition, PartitionError};
use voxcube_kernel::port::{Class, Dest, Port};
use voxcube_kernel::sample::Sample;
use voxcube_kernel::slab::{stored_planes, Slab, SlabError};
use voxcube_kernel::topology::Layout;
use voxcube_kernel::view::View;
use voxcube_kernel::worker::{Generation, Place, Progress, Worker, WorkerError};

/// Worker capacities in the simulator: rays, shadow rays, pixel records, outbox.
pub type SimWorker<'a, T> = Worker<'a, T, 64, 64, 64, 16>;

/// How to run.
#[derive(Clone, Debug)]
pub struct SimConfig {
    /// Clusters and their size.
    pub layout: Layout,
    /// Scheduler seed.
    pub seed: u64,
    /// Primary-ray generation.
    pub generation: Generation,
    /// Slab cuts (`cd + 1` of them); `None` for a uniform partition.
    pub cuts: Option<Vec<u32>>,
    /// Test-only faults, applied to every worker.
    #[cfg(feature = "mutants")]
    pub mutants: voxcube_kernel::worker::Mutants,
}

impl SimConfig {
    /// One cluster of `size` nodes, uniform slabs, distributed generation.
    pub fn cluster(
        size: u32,
        seed: u64,
    ) -> Result<SimConfig, voxcube_kernel::topology::LayoutError> {
        Ok(SimConfig {
            layout: Layout::new(1, size)?,
            seed,
            generation: Generation::Distributed,
            cuts: None,
            #[cfg(feature = "mutants")]
            mutants: Default::default(),
        })
    }
}

/// Why a simulated run failed.
#[derive(Debug, thiserror::Error)]
pub enum SimError {
    /// The partition does not fit the grid.
    #[error("partition: {0}")]
    Partition(#[from] PartitionError),
    /// A slab could not be built.
    #[error("slab: {0}")]
    Slab(#[from] SlabError),
    /// A worker could not be set up.
    #[error("worker: {0}")]
    Worker(#[from] WorkerError),
    /// A message did not decode.
    #[error("message from node {from}: {error}")]
    Decode {
        /// Sender.
        from: u16,
        /// Why.
        error: DecodeError,
    },
    /// The host received a pixel twice or out of range.
    #[error("pixel {pixel} reached the host twice or is out of range (seed {seed})")]
    Pixel {
        /// The pixel.
        pixel: u32,
        /// The seed, to replay.
        seed: u64,
    },
    /// No event is possible and work remains.
    #[error("stuck after {events} events with {missing} pixels missing; unfinished nodes {unfinished:?} (seed {seed})")]
    Stuck {
        /// Events run.
        events: u64,
        /// Pixels the host lacks.
        missing: u64,
        /// Nodes not finished.
        unfinished: Vec<u16>,
        /// The seed, to replay.
        seed: u64,
    },
    /// A worker reported messages that made no sense.
    #[error("node {node} counted {count} protocol errors (seed {seed})")]
    Protocol {
        /// The node.
        node: u16,
        /// How many.
        count: u64,
        /// The seed.
        seed: u64,
    },
    /// Far more events than the work can need.
    #[error("no end after {events} events (seed {seed})")]
    Watchdog {
        /// Events run.
        events: u64,
        /// The seed.
        seed: u64,
    },
}

struct Envelope {
    from: u16,
    to: Dest,
    len: usize,
    bytes: [u8; MAX_MSG_LEN],
}

#[derive(Default)]
struct Mailbox {
    by_class: [VecDeque<Msg>; 4],
}

fn class_index(c: Class) -> usize {
    match c {
        Class::Ack => 0,
        Class::Resolved => 1,
        Class::Ray => 2,
        Class::Control => 3,
    }
}

struct SimPort<'n> {
    from: u16,
    inflight: &'n mut Vec<Envelope>,
    mailbox: &'n mut Mailbox,
}

impl Port for SimPort<'_> {
    fn try_send(&mut self, to: Dest, msg: Msg) -> Result<(), Msg> {
        let mut bytes = [0u8; MAX_MSG_LEN];
        let len = msg.encode(&mut bytes);
        self.inflight.push(Envelope {
            from: self.from,
            to,
            len,
            bytes,
        });
        Ok(())
    }

    fn try_recv(&mut self, class: Class) -> Option<Msg> {
        self.mailbox.by_class[class_index(class)].pop_front()
    }

    fn pending(&self) -> usize {
        self.mailbox.by_class.iter().map(VecDeque::len).sum()
    }
}

/// Render `view` of `volume` on the simulated machine.
pub fn run(volume: &Volume, view: &View, cfg: &SimConfig) -> Result<Distributed, SimError> {
    match &volume.data {
        VolumeData::U8(d) => run_typed(volume, d, view, cfg),
        VolumeData::U16(d) => run_typed(volume, d, view, cfg),
        VolumeData::F32(d) => run_typed(volume, d, view, cfg),
    }
}

fn run_typed<T: Sample>(
    volume: &Volume,
    data: &[T],
    view: &View,
    cfg: &SimConfig,
) -> Result<Distributed, SimError> {
    let start = Instant::now();
    let grid = volume.grid;
    let layout = cfg.layout;
    let size = usize::from(layout.size());
    let nx = grid.dims()[0];
    let partition = match &cfg.cuts {
        Some(cuts) => Partition::new(cuts, nx)?,
        None => Partition::uniform(nx, size)?,
    };
    let ghost = view.ghost_planes();
    let plane = grid.plane_len();
    // Each ring position loads only its slab (the same for every cluster, so shared here).
    let stored: Vec<_> = (0..size)
        .map(|j| stored_planes(&grid, partition.planes(j), ghost))
        .collect();
    let storage: Vec<&[T]> = stored
        .iter()
        .map(|r| &data[r.start as usize * plane..r.end as usize * plane])
        .collect();
    let mut workers: Vec<Box<SimWorker<'_, T>>> = Vec::new();
    let mut reports = Vec::new();
    for node in 0..layout.nodes() as u16 {
        let (cluster, position) = layout.place(node);
        let j = usize::from(position);
        let slab = Slab::new(grid, partition.planes(j), ghost, storage[j])?;
        let place = Place {
            layout,
            cluster,
            position,
        };
        #[allow(unused_mut, reason = "mutable only to switch on test faults")]
        let mut worker = Box::new(SimWorker::new(
            view,
            slab,
            &partition,
            place,
            cfg.generation,
        )?);
        #[cfg(feature = "mutants")]
        {
            worker.mutants = cfg.mutants;
        }
        workers.push(worker);
        reports.push((cluster, position, partition.planes(j), stored[j].clone()));
    }
    let nodes = workers.len();
    let mut mailboxes: Vec<Mailbox> = (0..nodes).map(|_| Mailbox::default()).collect();
    let mut inflight: Vec<Envelope> = Vec::new();
    let mut active: Vec<usize> = (0..nodes).collect();
    let mut is_active = vec![true; nodes];
    let pixels = view.pixel_count() as usize;
    let mut image: Vec<Option<[u8; 4]>> = vec![None; pixels];
    let mut received = 0u64;
    let (mut messages, mut bytes, mut events) = ([0u64; 8], 0u64, 0u64);
    let mut rng = SplitMix(cfg.seed);
    let limit = 1_000_000 + 2_000 * pixels as u64 * nodes as u64;
    loop {
        let choices = inflight.len() + active.len();
        if choices == 0 {
            break;
        }
        events += 1;
        if events > limit {
            return Err(SimError::Watchdog {
                events,
                seed: cfg.seed,
            });
        }
        let pick = rng.below(choices);
        if pick < inflight.len() {
            let env = inflight.swap_remove(pick);
            let msg = Msg::decode(&env.bytes[..env.len]).map_err(|error| SimError::Decode {
                from: env.from,
                error,
            })?;
            messages[msg.kind() as usize] += 1;
            bytes += env.len as u64;
            match env.to {
                Dest::Host => {
                    if let Msg::Pixels(set) = msg {
                        for &(pixel, rgba) in set.entries() {
                            match image.get_mut(pixel as usize) {
                                Some(slot @ None) => *slot = Some(rgba),
                                _ => {
                                    return Err(SimError::Pixel {
                                        pixel,
                                        seed: cfg.seed,
                                    })
                                }
                            }
                            received += 1;
                        }
                    }
                }
                Dest::Node(n) => {
                    let n = usize::from(n);
                    if let Some(mailbox) = mailboxes.get_mut(n) {
                        mailbox.by_class[class_index(msg.kind().class())].push_back(msg);
                        if !is_active[n] {
                            is_active[n] = true;
                            active.push(n);
                        }
                    }
                }
            }
        } else {
            let i = pick - inflight.len();
            let n = active[i];
            let mut port = SimPort {
                from: n as u16,
                inflight: &mut inflight,
                mailbox: &mut mailboxes[n],
            };
            if workers[n].poll(&mut port) == Progress::Idle {
                active.swap_remove(i);
                is_active[n] = false;
            }
        }
    }
    let unfinished: Vec<u16> = workers
        .iter()
        .filter(|w| !w.is_finished())
        .map(|w| w.node())
        .collect();
    if received < pixels as u64 || !unfinished.is_empty() {
        return Err(SimError::Stuck {
            events,
            missing: pixels as u64 - received,
            unfinished,
            seed: cfg.seed,
        });
    }
    if let Some(w) = workers.iter().find(|w| w.stats().protocol_errors > 0) {
        return Err(SimError::Protocol {
            node: w.node(),
            count: w.stats().protocol_errors,
            seed: cfg.seed,
        });
    }
    let nodes = workers
        .iter()
        .zip(reports)
        .map(|(w, (cluster, position, planes, stored))| NodeReport {
            cluster,
            position,
            planes,
            stored,
            stats: w.stats(),
        })
        .collect();
    Ok(Distributed {
        pixels: image.into_iter().map(|p| p.unwrap_or_default()).collect(),
        nodes,
        messages,
        bytes,
        events,
        wall: start.elapsed(),
    })
}

//! One run's set-up and teardown, the same on every fabric: the view with its skipping, the
//! partition, flow control and receive buffers, the uniform slabs a balanced run shifts from,
//! each node's storage and worker, the host, and the run's report.
//!
//! Invariant: every fabric builds its nodes and its result here, so fabrics differ only in
//! how they carry messages and keep time, and a worker is the same state machine, set up the
//! same way, whichever fabric runs it.

use super::config::RunConfig;
use super::error::RunError;
use super::host::Host;
use super::shift::{ShiftJob, ShiftReport};
use super::{Distributed, NodeReport, RunShape};
use crate::input::dataset::Volume;
use crate::memory::storage::NodeStorage;
use std::borrow::Cow;
use std::time::{Duration, Instant};
use voxcube_kernel::node::flow::{self, FlowControl};
use voxcube_kernel::node::msg::PIXELS_PER_SET;
use voxcube_kernel::node::partition::Partition;
use voxcube_kernel::node::stats::NodeStats;
use voxcube_kernel::node::topology::Layout;
use voxcube_kernel::node::worker::{Place, Setup, WorkerError, RAYS_PER_POLL};
use voxcube_kernel::trace::view::View;
use voxcube_kernel::volume::grid::Grid;
use voxcube_kernel::volume::sample::{Sample, SampleKind};
use voxcube_kernel::volume::slab::Slab;

pub use crate::memory::budget::NodeWorker;

/// A ring of one's rays a poll: a pixel set's, which a `u8` must hold (checked here, not
/// truncated by a cast should the set grow).
const RING_OF_ONE_RAYS: u8 = {
    assert!(PIXELS_PER_SET <= u8::MAX as usize);
    PIXELS_PER_SET as u8
};

/// Flow control for `cfg`'s receive buffers, and their capacity; refused when the buffer
/// leaves no ray room to start, naming the smallest that works.
pub fn flow_for(cfg: &RunConfig, view: &View) -> Result<(FlowControl, usize), RunError> {
    let size = usize::from(cfg.layout.size());
    let capacity = cfg.buffer();
    let mut control = FlowControl::for_buffer(capacity, size);
    control.enabled = cfg.flow_control;
    let needed = flow::min_i_max(view.effects().shadow_lights);
    if cfg.flow_control && size > 1 && usize::from(control.i_max) < needed {
        return Err(RunError::Buffer {
            bytes: capacity,
            size,
            i_max: usize::from(control.i_max),
            needed,
            min_bytes: flow::buffer_bytes(size, needed),
        });
    }
    Ok((control, capacity))
}

/// Node `node`'s worker in `cfg`'s machine: `slab` is its slab of `partition`, at the ring
/// position `node` holds.
pub fn node_worker<'a, T: Sample>(
    view: &'a View,
    slab: Slab<'a, T>,
    partition: &'a Partition,
    cfg: &RunConfig,
    node: u16,
    flow: FlowControl,
) -> Result<Box<NodeWorker<'a, T>>, WorkerError> {
    let layout = cfg.layout;
    let (cluster, position) = layout.place(node);
    let place = Place {
        layout,
        cluster,
        position,
    };
    let checked = NodeWorker::check(Setup {
        view,
        slab,
        partition,
        place,
        generation: cfg.generation,
        flow,
        // A timed run charges time per poll: its nodes read their links between rays. A
        // ring of one has no links to read and hears only from the host: a pixel set's rays
        // a poll.
        rays_per_poll: match (&cfg.time, layout.size()) {
            (Some(_), _) => 1,
            (None, 1) => RING_OF_ONE_RAYS,
            (None, _) => RAYS_PER_POLL,
        },
    })?;
    // Built where it stays: a worker built on the stack was copied into its box whole.
    #[allow(unused_mut, reason = "mutable only to switch on test faults")]
    let mut worker = Box::write(Box::new_uninit(), NodeWorker::new(checked));
    #[cfg(feature = "mutants")]
    {
        worker.mutants = cfg.mutants;
    }
    Ok(worker)
}

/// What a run of one view derives before any node exists, the same on every fabric.
#[derive(Debug)]
pub struct Plan<'v> {
    /// The view, with the skipping the configuration asks for.
    pub view: Cow<'v, View>,
    /// The slabs the nodes render on (the configured cuts, else uniform).
    pub partition: Partition,
    /// Flow control for the receive buffers.
    pub flow: FlowControl,
    /// Receive-buffer bytes per node.
    pub capacity: usize,
    /// Ghost planes each slab stores on either side.
    pub ghost: u32,
    /// The machine.
    pub layout: Layout,
    /// When the run began (for its wall time).
    pub start: Instant,
    /// How long [`Plan::load`] took, once it has run here: the nodes' storage and the view's
    /// skipping structures (and the volume's value ranges and node field where no run before
    /// built them). MPI's host plans but never loads: its ranks build their own.
    loaded_in: std::cell::Cell<Option<Duration>>,
}

impl<'v> Plan<'v> {
    /// The plan of `view` over `grid` run as `cfg` says; refused when the partition does not
    /// fit the grid or the buffers leave no ray room to start.
    pub fn new(grid: &Grid, view: &'v View, cfg: &RunConfig) -> Result<Plan<'v>, RunError> {
        let start = Instant::now();
        let view = cfg.skipping.view(view);
        let partition = cfg.partition(grid.dims()[0])?;
        let (flow, capacity) = flow_for(cfg, &view)?;
        let ghost = view.ghost_planes();
        Ok(Plan {
            view,
            partition,
            flow,
            capacity,
            ghost,
            layout: cfg.layout,
            start,
            loaded_in: std::cell::Cell::new(None),
        })
    }

    /// Nodes in the machine.
    pub fn nodes(&self) -> usize {
        self.layout.nodes() as usize
    }

    /// Every node's storage, with the view's skipping structures built on up to `threads` OS
    /// threads: its slab of the plan's partition in `data`, or, when the configuration asks
    /// the nodes to reach balanced cuts by message, what the fabric's `shift` left it after
    /// moving planes from uniform slabs (and the shift's report).
    pub fn load<'d, T: Sample + Sync>(
        &self,
        volume: &'d Volume,
        data: &'d [T],
        cfg: &RunConfig,
        threads: usize,
        shift: impl FnOnce(&ShiftJob<'_>) -> Result<(Vec<Vec<T>>, ShiftReport), RunError>,
    ) -> Result<(NodeStorage<'d, T>, Option<ShiftReport>), RunError> {
        let began = Instant::now();
        let grid = &volume.grid;
        let (shifted, report) = match (&cfg.cuts, cfg.shift) {
            (Some(_), true) => {
                let job = ShiftJob {
                    grid,
                    layout: self.layout,
                    old: Partition::uniform(grid.dims()[0], usize::from(self.layout.size()))?,
                    new: &self.partition,
                    ghost: self.ghost,
                    capacity: self.capacity,
                };
                let (storages, report) = shift(&job)?;
                (Some(storages), Some(report))
            }
            _ => (None, None),
        };
        let storage = NodeStorage::new(
            grid,
            self.layout,
            &self.partition,
            self.ghost,
            data,
            shifted,
        )
        .with_skipping(&self.view, cfg.skipping, threads, &volume.built);
        self.loaded_in.set(Some(began.elapsed()));
        Ok((storage, report))
    }

    /// Every node's worker, in node-id order, over `storage`.
    pub fn workers<'a, T: Sample + Sync>(
        &'a self,
        storage: &'a NodeStorage<'_, T>,
        cfg: &RunConfig,
    ) -> Result<Vec<Box<NodeWorker<'a, T>>>, RunError> {
        (0..self.nodes() as u16)
            .map(|node| {
                let slab = storage.slab(node)?;
                Ok(node_worker(
                    &self.view,
                    slab,
                    &self.partition,
                    cfg,
                    node,
                    self.flow,
                )?)
            })
            .collect()
    }

    /// The host of this run: every pixel of the view, a token per cluster, a report per node.
    pub fn host(&self) -> Host {
        Host::new(
            self.view.pixel_count() as usize,
            self.view.spec().width,
            usize::from(self.layout.clusters()),
            self.nodes(),
        )
    }

    /// The run's result from what the host collected: the image and each node's statistics
    /// (by node id), with each node's buffer `peak` and `busy` time. Fabrics that count
    /// messages, bytes, events or virtual time themselves set those after.
    #[allow(
        clippy::too_many_arguments,
        reason = "the parts of a result, named at the one call of each fabric"
    )]
    pub fn finish(
        &self,
        cfg: &RunConfig,
        grid: &Grid,
        kind: SampleKind,
        image: Vec<[u8; 4]>,
        stats: Vec<NodeStats>,
        peak: &dyn Fn(usize) -> usize,
        busy: &dyn Fn(usize) -> Duration,
        shift: Option<ShiftReport>,
    ) -> Distributed {
        let shape = RunShape::new(cfg, &self.partition, grid, &self.view, kind);
        let nodes: Vec<NodeReport> = stats
            .into_iter()
            .enumerate()
            .map(|(n, stats)| shape.report(n as u16, stats, peak(n), busy(n)))
            .collect();
        let messages = super::sent_by_kind(&nodes);
        Distributed {
            pixels: image,
            nodes,
            messages,
            bytes: 0,
            events: 0,
            buffer_capacity: self.capacity,
            i_max: self.flow.i_max,
            wall: self.start.elapsed(),
            setup: self.loaded_in.get(),
            time: None,
            shift,
            recovery: None,
            data_range: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::dataset::VolumeData;
    use glam::Vec3;
    use voxcube_kernel::node::flow::Class;
    use voxcube_kernel::node::msg::{Msg, Outcome, Reply, Resolved, Travel, NO_LIGHT};
    use voxcube_kernel::node::port::{Dest, Port};
    use voxcube_kernel::node::worker::{Generation, Progress};
    use voxcube_kernel::trace::lattice::Lattice;
    use voxcube_kernel::trace::ray::{Entry, Ray};
    use voxcube_kernel::trace::state::{RayKind, RayState};

    /// Ring position 0's set-up in a ring of `size` over the default scene, handed to `check`.
    fn at_position_0(size: u32, rays_per_poll: u8, check: impl FnOnce(Setup<'_, u8>)) {
        let jobs = crate::input::scene::Scene::default_scene()
            .and_then(crate::input::scene::Scene::load)
            .unwrap();
        let (volume, view) = (&jobs[0].volume, &jobs[0].views[0].view);
        let VolumeData::U8(data) = &volume.data else {
            panic!("the default scene is u8");
        };
        let grid = volume.grid;
        let partition = Partition::uniform(grid.dims()[0], size as usize).unwrap();
        let cfg = RunConfig::cluster(size, 0).unwrap();
        let (flow, _) = flow_for(&cfg, view).unwrap();
        let planes = partition.planes(0);
        let stored =
            voxcube_kernel::volume::slab::stored_planes(&grid, planes.clone(), view.ghost_planes());
        let plane = grid.plane_len();
        let part = &data[stored.start as usize * plane..stored.end as usize * plane];
        check(Setup {
            view,
            slab: Slab::new(grid, planes, view.ghost_planes(), part).unwrap(),
            partition: &partition,
            place: Place {
                layout: cfg.layout,
                cluster: 0,
                position: 0,
            },
            generation: Generation::Distributed,
            flow,
            rays_per_poll,
        });
    }

    /// A port that hands the worker what a test queued, by class, and records what it took.
    #[derive(Default)]
    struct Recording {
        queues: [std::collections::VecDeque<(Dest, Msg)>; 7],
        taken: Vec<Class>,
        /// Messages counted as received but in no queue the worker reads.
        unread: usize,
    }

    impl Recording {
        fn queue(&mut self, from: u16, msg: Msg) {
            self.queues[msg.class().index()].push_back((Dest::Node(from), msg));
        }
    }

    impl Port for Recording {
        fn try_send(&mut self, _: Dest, _: Msg) -> Result<(), Msg> {
            Ok(())
        }
        fn peek(&mut self, class: Class) -> Option<&Msg> {
            self.queues[class.index()].front().map(|(_, m)| m)
        }
        fn try_recv(&mut self, class: Class) -> Option<(Dest, Msg)> {
            let m = self.queues[class.index()].pop_front()?;
            self.taken.push(class);
            Some(m)
        }
        fn pending(&self) -> usize {
            self.queues.iter().map(|q| q.len()).sum::<usize>() + self.unread
        }
    }

    #[test]
    fn a_worker_reads_acks_then_results_then_rays_and_generates_only_when_nothing_waits() {
        at_position_0(2, 1, |setup| {
            let (me, next) = (setup.place.layout.node(0, 0), setup.place.layout.node(0, 1));
            let end = setup.partition.planes(0).end as f32;
            let checked = NodeWorker::check(setup).unwrap();
            let mut worker = Box::write(Box::new_uninit(), NodeWorker::new(checked));
            // A ray coming down from the next slab, queued first; then a result for this
            // node, then an ack: the worker must read them in the paper's order all the same.
            let dir = Vec3::new(-1.0, 0.0, 0.0);
            let ray = RayState::new(
                RayKind::Primary,
                0,
                Ray {
                    origin: Vec3::new(end, 20.0, 20.0),
                    dir,
                    dir_world: dir,
                },
                Lattice::new(0.0, end, 0.5).unwrap(),
                Entry::Inside,
                0,
            );
            let mut port = Recording::default();
            port.queue(
                next,
                Msg::Ray(Travel {
                    ray,
                    reply: Reply {
                        home: next,
                        slot: 0,
                        hit: 0,
                        light: NO_LIGHT,
                    },
                }),
            );
            port.queue(
                next,
                Msg::Resolved(Resolved {
                    reply: Reply {
                        home: me,
                        slot: 0,
                        hit: 0,
                        light: NO_LIGHT,
                    },
                    pixel: 0,
                    outcome: Outcome::Color(Vec3::ONE),
                }),
            );
            port.queue(
                next,
                Msg::Ack {
                    from: next,
                    class: 0,
                    count: 0,
                },
            );
            assert_eq!(worker.poll(&mut port), Progress::Busy);
            assert_eq!(port.taken, [Class::Ack, Class::Result, Class::RayDown]);
        });
        // Generation: none while anything at all is received and unread, then some.
        at_position_0(2, 1, |setup| {
            let checked = NodeWorker::check(setup).unwrap();
            let mut worker = Box::write(Box::new_uninit(), NodeWorker::new(checked));
            let mut port = Recording {
                unread: 1,
                ..Recording::default()
            };
            assert_eq!(worker.poll(&mut port), Progress::Idle);
            assert_eq!(worker.counters().primary_rays, 0);
            port.unread = 0;
            assert_eq!(worker.poll(&mut port), Progress::Busy);
        });
    }

    #[test]
    fn a_worker_that_may_generate_no_ray_a_poll_is_refused_and_one_is_enough() {
        at_position_0(1, 0, |setup| {
            assert_eq!(
                NodeWorker::check(setup).map(|_| ()),
                Err(WorkerError::Capacity)
            );
        });
        at_position_0(1, 1, |setup| assert!(NodeWorker::check(setup).is_ok()));
    }

    #[test]
    fn a_ring_larger_than_the_workers_counters_is_refused() {
        at_position_0(2, 1, |setup| {
            assert_eq!(
                voxcube_kernel::node::worker::Worker::<'_, u8, 32, 64, 16, 1>::check(setup)
                    .map(|_| ()),
                Err(WorkerError::Ring {
                    size: 2,
                    capacity: 1
                })
            );
        });
        at_position_0(2, 1, |setup| {
            assert!(
                voxcube_kernel::node::worker::Worker::<'_, u8, 32, 64, 16, 2>::check(setup).is_ok()
            );
        });
    }
}

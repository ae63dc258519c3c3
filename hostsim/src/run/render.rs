//! Rendering one view: directly on one node that holds the whole volume (the reference), or on
//! a simulated machine of clusters of nodes.
//!
//! Invariant: both paths trace with the same kernel and combine ray trees with the same
//! formula, so their images are bit-identical; a non-finite colour is counted in the counters
//! (`non_finite_pixels`, which tests require to be zero) before it becomes a defined pixel.

use crate::fabric::sim;
use crate::fabric::threads;
use crate::fabric::Distributed;
use crate::fabric::{RunConfig, RunError};
use crate::input::dataset::{Volume, VolumeData};
use crate::memory::budget::{self, BudgetError, Profile};
use crate::memory::storage::{SkipMode, Skipping};
use std::time::{Duration, Instant};
use voxcube_kernel::counters::Counters;
use voxcube_kernel::node::flow;
use voxcube_kernel::node::topology::LayoutError;
use voxcube_kernel::node::worker::Generation;
use voxcube_kernel::trace::pixel::rgba8;
use voxcube_kernel::trace::tracer::Pixels;
use voxcube_kernel::trace::view::View;
use voxcube_kernel::volume::sample::Sample;
use voxcube_kernel::volume::slab::{Slab, SlabError};

/// What carries the work.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fabric {
    /// One node, in process, no messages: the reference.
    Direct,
    /// The deterministic simulator.
    Sim,
    /// OS threads, for wall-clock speed.
    Threads,
    /// MPI ranks: rank 0 the host, rank r node r - 1 (cargo feature `mpi`).
    Mpi,
}

impl Fabric {
    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Fabric::Direct => "direct",
            Fabric::Sim => "sim",
            Fabric::Threads => "threads",
            Fabric::Mpi => "mpi",
        }
    }
}

/// The machine a view renders on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Machine {
    /// The fabric.
    pub fabric: Fabric,
    /// All nodes.
    pub nodes: u32,
    /// Clusters (image partition); `nodes / clusters` per cluster (ray dataflow).
    pub clusters: u32,
    /// Scheduler seed (sim).
    pub seed: u64,
    /// Primary-ray generation.
    pub generation: Generation,
    /// Receive-buffer bytes per node (`None`: the simulator's default).
    pub buffer_bytes: Option<usize>,
    /// Ack-counter flow control (off only as a debug option).
    pub flow_control: bool,
    /// The machine profile whose node memory every node must fit.
    pub profile: Profile,
    /// OS threads for the threads fabric (0: one per core).
    pub threads: usize,
    /// How provably empty samples are skipped (changes no pixel; off to compare or debug).
    pub skipping: SkipMode,
    /// Keep the simulator's timeline in virtual time on the machine profile of this name
    /// (`render --trace`).
    pub timeline: Option<&'static str>,
    /// An injected fault: this node stops answering after this many of its
    /// polls, and the surviving clusters re-trace its cluster's rows.
    pub stop: Option<(u16, u64)>,
    /// With `stop`, on MPI: the node's process exits instead of hanging.
    pub crash: bool,
    /// A second injected fault: this node stops after this many of its polls in the
    /// re-trace that the first causes.
    pub retrace_stop: Option<(u16, u64)>,
    /// How long the threads and MPI hosts wait without hearing from a node before they
    /// declare it lost.
    pub lost_after: Duration,
}

impl Machine {
    /// `nodes` in `clusters` on `fabric`: default buffers, flow control on, distributed
    /// generation, the nCUBE 2's 4 MiB nodes.
    pub fn new(fabric: Fabric, nodes: u32, clusters: u32, seed: u64) -> Machine {
        Machine {
            fabric,
            nodes,
            clusters,
            seed,
            generation: Generation::Distributed,
            buffer_bytes: None,
            flow_control: true,
            profile: Profile::ncube2(),
            threads: 0,
            skipping: SkipMode::ALL,
            timeline: None,
            stop: None,
            crash: false,
            retrace_stop: None,
            lost_after: crate::fabric::config::DEFAULT_LOST_AFTER,
        }
    }

    /// Nodes per cluster.
    pub fn cluster_size(&self) -> u32 {
        self.nodes / self.clusters.max(1)
    }

    /// The simulator configuration for this machine (also the shape the other fabrics use).
    pub fn sim_config(&self) -> Result<RunConfig, LayoutError> {
        let base = RunConfig::machine(self.clusters, self.cluster_size(), self.seed)?;
        Ok(RunConfig {
            generation: self.generation,
            buffer_bytes: self.buffer_bytes,
            flow_control: self.flow_control,
            skipping: self.skipping,
            schedule: crate::fabric::Schedule {
                stop: self.stop,
                crash: self.crash,
                retrace_stop: self.retrace_stop,
                ..base.schedule
            },
            lost_after: self.lost_after,
            ..base
        })
    }
}

/// Why a view could not be rendered.
#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    /// The volume does not fit a slab (a bug: loaders check sizes).
    #[error("slab: {0}")]
    Slab(#[from] SlabError),
    /// Nodes and clusters do not make a machine.
    #[error("{0}")]
    Layout(#[from] LayoutError),
    /// The machine does not fit the fabric or the volume.
    #[error("{0}")]
    Machine(String),
    /// A run on a fabric failed; the message names the fabric.
    #[error("{fabric} fabric: {source}")]
    Run {
        /// The fabric's name (`--fabric`).
        fabric: &'static str,
        /// What went wrong.
        source: RunError,
    },
    /// The configuration cannot run on any fabric (found before the run).
    #[error("{0}")]
    Config(RunError),
    /// A node would not fit the machine's node memory.
    #[error("{0}")]
    Budget(#[from] BudgetError),
    /// A node's measured high-water mark exceeded the machine's node memory.
    #[error("node {node} reached {used} bytes; the {profile} has {available} bytes per node")]
    Exceeded {
        /// The node.
        node: u16,
        /// Its high-water mark.
        used: usize,
        /// The profile.
        profile: &'static str,
        /// Bytes per node.
        available: usize,
    },
}

/// A rendered image and what it cost.
#[derive(Clone, Debug)]
pub struct Rendered {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// RGBA8, row-major, row 0 at the top.
    pub pixels: Vec<[u8; 4]>,
    /// Work done, summed over nodes.
    pub counters: Counters,
    /// Wall-clock time.
    pub wall: Duration,
    /// Of the wall time, the set-up before any ray was traced: the slab's skipping
    /// structures for the view, and the volume's value ranges and node field the first time
    /// (`None` where the fabric's ranks each build their own: MPI).
    pub setup: Option<Duration>,
    /// The distributed run, when there was one.
    pub distributed: Option<Distributed>,
}

impl Rendered {
    /// The result of a distributed run of `view`.
    pub fn from_run(view: &View, run: Distributed) -> Rendered {
        let spec = view.spec();
        Rendered {
            width: spec.width,
            height: spec.height,
            pixels: run.pixels.clone(),
            counters: run.counters(),
            wall: run.wall,
            setup: run.setup,
            distributed: Some(run),
        }
    }

    /// The pixels as one RGBA8 byte buffer.
    pub fn bytes(&self) -> Vec<u8> {
        self.pixels.iter().flatten().copied().collect()
    }
}

/// Told how many pixels are done, as a render goes.
pub type OnProgress<'a> = &'a dyn Fn(u64);

/// Render `view` of `volume` directly, on one node, skipping empty space.
pub fn render(volume: &Volume, view: &View) -> Result<Rendered, SlabError> {
    render_direct(volume, view, SkipMode::ALL, &|_| {})
}

/// [`render`], skipping empty space as `mode` says.
pub fn render_skipping(
    volume: &Volume,
    view: &View,
    mode: SkipMode,
) -> Result<Rendered, SlabError> {
    render_direct(volume, view, mode, &|_| {})
}

fn render_direct(
    volume: &Volume,
    view: &View,
    mode: SkipMode,
    progress: OnProgress<'_>,
) -> Result<Rendered, SlabError> {
    match &volume.data {
        VolumeData::U8(d) => render_typed(volume, d, view, mode, progress),
        VolumeData::U16(d) => render_typed(volume, d, view, mode, progress),
        VolumeData::I16(d) => render_typed(volume, d, view, mode, progress),
        VolumeData::F32(d) => render_typed(volume, d, view, mode, progress),
    }
}

/// Check that `view` of `volume` can render on `machine`, before anything renders: the
/// machine's shape, enough X planes for the slabs, a receive buffer that lets a ray start,
/// and every node within the profile's memory, the direct fabric's one node too (only the
/// library's reference render, [`render`], is not budgeted).
pub fn preflight(volume: &Volume, view: &View, machine: &Machine) -> Result<(), RenderError> {
    let default_buffer = |s: u32| flow::buffer_bytes(s as usize, crate::fabric::DEFAULT_I_MAX);
    let fits = |size: u32, buffer_for: &dyn Fn(u32) -> usize| {
        budget::check(
            machine.profile,
            &volume.grid,
            volume.data.kind().bytes(),
            size,
            budget::ViewNeeds::of(view),
            buffer_for,
        )
    };
    if machine.fabric == Fabric::Direct {
        if machine.nodes != 1 {
            return Err(RenderError::Machine(format!(
                "the direct fabric renders on one node, not {}; use --fabric sim",
                machine.nodes
            )));
        }
        fits(1, &default_buffer)?;
        return Ok(());
    }
    if machine.clusters == 0
        || machine.nodes == 0
        || !machine.nodes.is_multiple_of(machine.clusters)
    {
        return Err(RenderError::Machine(format!(
            "{} nodes do not split into {} clusters",
            machine.nodes, machine.clusters
        )));
    }
    let size = machine.cluster_size();
    let nx = volume.grid.dims()[0];
    if size > nx {
        return Err(RenderError::Machine(format!(
            "clusters of {size} nodes need at least {size} X planes to slice; the volume has {nx}"
        )));
    }
    let cfg = machine.sim_config()?;
    let needed = flow::min_i_max(view.effects().shadow_lights);
    let i_max = flow::i_max_for(cfg.buffer(), size as usize);
    if machine.flow_control && size > 1 && i_max < needed {
        return Err(RenderError::Config(RunError::Buffer {
            bytes: cfg.buffer(),
            size: size as usize,
            i_max,
            needed,
            min_bytes: flow::buffer_bytes(size as usize, needed),
        }));
    }
    fits(size, &|s| {
        machine.buffer_bytes.unwrap_or_else(|| default_buffer(s))
    })?;
    Ok(())
}

/// How `machine`'s nodes skip empty space in `view`: `machine.skipping`, without depth
/// bounds where the view has none ([`crate::memory::storage::depth_bytes`]) or a node could
/// not hold them beside everything [`preflight`] counts, without cell leap maps where the view
/// takes none given its bounds ([`crate::memory::storage::cell_leap_octants`]) or a node could
/// not hold them beside all that, and then without the node field and the cells' value
/// ranges where a node could not hold them beside all that. They are accelerations, not
/// needs: a machine that fits without them renders without them, the same pixels. Slabs
/// `balanced` by the host may grow up to the cap balancing keeps them under
/// ([`budget::max_owned_planes`]), so then that slab must fit. Every node and the host
/// decide alike from the same inputs.
pub fn node_skipping(volume: &Volume, view: &View, machine: &Machine, balanced: bool) -> SkipMode {
    let mode = machine.skipping;
    if machine.fabric == Fabric::Direct {
        return mode;
    }
    let fits = |needs: budget::ViewNeeds, buffer: usize| {
        let (grid, bytes) = (&volume.grid, volume.data.kind().bytes());
        let least = budget::ViewNeeds::of(view);
        match balanced {
            true => {
                let cap = budget::max_owned_planes(machine.profile, grid, bytes, least, buffer);
                budget::max_owned_planes(machine.profile, grid, bytes, needs, buffer) >= cap
            }
            false => budget::largest_node(grid, bytes, machine.cluster_size(), needs, buffer)
                .is_some_and(|m| m.total() <= machine.profile.node_memory),
        }
    };
    // A machine without a layout renders nothing (`preflight` says why): it holds neither.
    let Ok(cfg) = machine.sim_config() else {
        return SkipMode {
            cell_leaps: false,
            depths: false,
            nodes: false,
            ranges: false,
            ..mode
        };
    };
    // Depth bounds first: whether a view takes cell leap maps depends on whether it has them.
    let least = budget::ViewNeeds::of(view);
    let bounds = crate::memory::storage::depth_bytes(view, mode, cfg.layout.clusters());
    let depths = bounds > 0 && fits(least.with_depths(bounds), cfg.buffer());
    let with_depths = least.with_depths(if depths { bounds } else { 0 });
    let kept = crate::memory::storage::maps_kept(volume.data.kind(), mode);
    let maps = crate::memory::storage::cell_leap_octants(view, SkipMode { depths, ..mode }, kept);
    let maps = maps.count_ones() as usize;
    let held = maps > 0 && fits(with_depths.with_cell_maps(maps), cfg.buffer());
    let with_maps = with_depths.with_cell_maps(if held { maps } else { 0 });
    // Then the node field, which only the fast tier's shading reads.
    let lanes = crate::memory::storage::node_field_bytes(view, mode, volume.data.kind());
    let nodes = lanes > 0 && fits(with_maps.with_node_bytes(lanes), cfg.buffer());
    let with_nodes = with_maps.with_node_bytes(if nodes { lanes } else { 0 });
    // Last the cells' value ranges, which only save each view's pass over the nodes.
    let cells = crate::memory::storage::cell_range_bytes(view, mode, volume.data.kind());
    let ranges = cells > 0 && fits(with_nodes.with_cell_ranges(cells), cfg.buffer());
    SkipMode {
        cell_leaps: held,
        depths,
        nodes,
        ranges,
        ..mode
    }
}

/// Render `view` of `volume` on `machine`.
pub fn render_on(volume: &Volume, view: &View, machine: &Machine) -> Result<Rendered, RenderError> {
    render_on_with_progress(volume, view, machine, &|_| {})
}

/// [`render_on`], telling `progress` how many pixels are done as they arrive.
pub fn render_on_with_progress(
    volume: &Volume,
    view: &View,
    machine: &Machine,
    progress: OnProgress<'_>,
) -> Result<Rendered, RenderError> {
    render_cut(volume, view, machine, None, progress)
}

/// [`render_on_with_progress`] with every cluster's slabs cut at `cuts` (`None`: uniform),
/// as static load balancing chooses them. The image does not depend on the cuts.
pub fn render_cut(
    volume: &Volume,
    view: &View,
    machine: &Machine,
    cuts: Option<&[u32]>,
    progress: OnProgress<'_>,
) -> Result<Rendered, RenderError> {
    preflight(volume, view, machine)?;
    match machine.fabric {
        Fabric::Direct => Ok(render_direct(volume, view, machine.skipping, progress)?),
        Fabric::Mpi => Err(RenderError::Machine(
            "the MPI fabric renders through `voxcube render --fabric mpi` under mpirun".into(),
        )),
        Fabric::Sim | Fabric::Threads => {
            // The nodes start on uniform slabs and shift planes to the cuts by message.
            let cfg = RunConfig {
                cuts: cuts.map(<[u32]>::to_vec),
                shift: cuts.is_some(),
                skipping: node_skipping(volume, view, machine, cuts.is_some()),
                time: machine
                    .timeline
                    .map(crate::profile::MachineProfile::load)
                    .transpose()
                    .map_err(|e| RenderError::Machine(e.to_string()))?,
                timeline: machine.timeline.is_some(),
                ..machine.sim_config()?
            };
            let run = match machine.fabric {
                Fabric::Threads => {
                    threads::run_with_progress(volume, view, &cfg, machine.threads, progress)
                }
                _ => sim::run_with_progress(volume, view, &cfg, progress),
            }
            .map_err(|source| RenderError::Run {
                fabric: machine.fabric.name(),
                source,
            })?;
            if let Some(n) = run
                .nodes
                .iter()
                .find(|n| n.memory.total() > machine.profile.node_memory)
            {
                return Err(RenderError::Exceeded {
                    node: n.stats.node,
                    used: n.memory.total(),
                    profile: machine.profile.name,
                    available: machine.profile.node_memory,
                });
            }
            Ok(Rendered::from_run(view, run))
        }
    }
}

fn render_typed<T: Sample + Sync>(
    volume: &Volume,
    data: &[T],
    view: &View,
    mode: SkipMode,
    progress: OnProgress<'_>,
) -> Result<Rendered, SlabError> {
    let view = &*mode.view(view);
    let slab = Slab::whole(volume.grid, data)?;
    // The clock covers the leap map and cell masks too: they belong to the view, so they are
    // part of its frame, as on every other fabric; and the volume's value ranges and node
    // field, the first time they are built.
    let start = Instant::now();
    let cells = crate::memory::storage::cell_range_bytes(view, mode, T::KIND) > 0;
    let ranges = volume.built.ranges(&slab, cells, 1);
    let skipping = Skipping::build(&slab, &ranges, view, mode);
    let field = volume.built.field(
        &slab,
        crate::memory::storage::holds_node_field(view, mode),
        1,
    );
    let segments = crate::memory::segments::SegmentTable::of(view);
    let slab = segments.apply(field.apply(skipping.apply(slab)));
    let setup = start.elapsed();
    let mut counters = Counters::default();
    let n = view.pixel_count();
    let mut pixels = Vec::with_capacity(n as usize);
    let mut non_finite = 0;
    // The rays are what a profile of the frame after its set-up samples (`bench`,
    // `bench --scale`).
    voxcube_sampler::sampled(|| {
        for (pixel, c) in (1..).zip(Pixels::new(view, &slab, &mut counters)) {
            non_finite += u64::from(!c.is_finite());
            pixels.push(rgba8(c));
            if pixel % u64::from(view.spec().width) == 0 {
                progress(pixel);
            }
        }
    });
    counters.non_finite_pixels += non_finite;
    let spec = view.spec();
    Ok(Rendered {
        width: spec.width,
        height: spec.height,
        pixels,
        counters,
        wall: start.elapsed(),
        setup: Some(setup),
        distributed: None,
    })
}

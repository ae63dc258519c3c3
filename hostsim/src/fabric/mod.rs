//! Fabrics: what carries kernel messages between nodes and to the host. `sim` is the
//! deterministic single-threaded reference; `threads` runs the same workers on OS threads;
//! `mpi` (feature) runs them as MPI ranks. What a run is ([`config`]), how it fails
//! ([`error`]), how its nodes are set up and its result made ([`harness`]), the host
//! ([`host`]), plane shifting ([`shift`]) and the re-tracing of a lost cluster's rows
//! ([`recovery`]) are shared by all three.
//!
//! Invariant: the image of a run depends on its view alone, never on its fabric.

pub mod config;
pub mod error;
pub mod harness;
pub mod host;
#[cfg(feature = "mpi")]
pub mod mpi;
pub mod recovery;
pub mod shift;
pub mod sim;
pub mod threads;

pub use config::{RunConfig, Schedule, Scheduler, DEFAULT_I_MAX};
pub use error::{RunError, Trace};

use crate::memory::budget::{structure_bytes, worker_bytes, NodeMemory, ViewNeeds, CODE_AND_STACK};
use std::ops::Range;
use std::time::Duration;
use voxcube_kernel::counters::Counters;
use voxcube_kernel::node::partition::Partition;
use voxcube_kernel::node::stats::NodeStats;
use voxcube_kernel::node::topology::Layout;
use voxcube_kernel::trace::view::View;
use voxcube_kernel::volume::grid::Grid;
use voxcube_kernel::volume::slab::stored_planes;

/// One node of a distributed run.
#[derive(Clone, Debug, PartialEq)]
pub struct NodeReport {
    /// Its cluster.
    pub cluster: u16,
    /// Its ring position.
    pub position: u16,
    /// The X planes it owned.
    pub planes: Range<u32>,
    /// The X planes it stored (with ghosts).
    pub stored: Range<u32>,
    /// What it did and sent, as it reported to the host.
    pub stats: NodeStats,
    /// Most bytes its receive buffer held at once.
    pub peak_buffer: usize,
    /// Its measured memory high-water mark: slab, receive buffer at its peak, worker state,
    /// code and stack.
    pub memory: NodeMemory,
    /// Wall time it spent in busy polls (threads fabric; zero in the simulator, whose time is
    /// not wall time).
    pub busy: Duration,
    /// The peak resident memory of the process it ran in alone, bytes, as the operating
    /// system measured it when the node could trace (MPI: its rank's); `None` where nodes
    /// share a process.
    pub resident_peak: Option<u64>,
    /// The X planes of the volume its process held (MPI: its rank's, which loads only its
    /// slab's where it can); `None` where nodes share the host's volume.
    pub held: Option<Range<u32>>,
}

/// What every node report of one run shares: the machine's layout, the slabs of
/// `partition` over `grid` with the ghost planes and leap maps the view needs, and the
/// sample size.
#[derive(Clone, Copy, Debug)]
pub struct RunShape<'a> {
    layout: Layout,
    partition: &'a Partition,
    grid: &'a Grid,
    needs: ViewNeeds,
    sample_bytes: usize,
}

impl<'a> RunShape<'a> {
    /// The shape of a run of `view` configured by `cfg` (its layout, and how its nodes skip:
    /// which cell leap maps they hold), slabs `partition` of `grid`, samples of
    /// `kind`.
    pub fn new(
        cfg: &RunConfig,
        partition: &'a Partition,
        grid: &'a Grid,
        view: &View,
        kind: voxcube_kernel::volume::sample::SampleKind,
    ) -> RunShape<'a> {
        let kept = crate::memory::storage::maps_kept(kind, cfg.skipping);
        let cell_maps = crate::memory::storage::cell_leap_octants(view, cfg.skipping, kept)
            .count_ones() as usize;
        RunShape {
            layout: cfg.layout,
            partition,
            grid,
            needs: ViewNeeds::of(view)
                .with_cell_maps(cell_maps)
                .with_depths(crate::memory::storage::depth_bytes(
                    view,
                    cfg.skipping,
                    cfg.layout.clusters(),
                ))
                .with_node_bytes(crate::memory::storage::node_field_bytes(
                    view,
                    cfg.skipping,
                    kind,
                ))
                .with_cell_ranges(crate::memory::storage::cell_range_bytes(
                    view,
                    cfg.skipping,
                    kind,
                )),
            sample_bytes: kind.bytes(),
        }
    }

    /// The report of `node`: its place, planes, memory (the receive buffer at its `peak`),
    /// statistics and busy time.
    pub fn report(&self, node: u16, stats: NodeStats, peak: usize, busy: Duration) -> NodeReport {
        let (grid, needs) = (self.grid, self.needs);
        let (cluster, position) = self.layout.place(node);
        let planes = self.partition.planes(usize::from(position));
        let stored = stored_planes(grid, planes.clone(), needs.ghost);
        let memory = NodeMemory {
            slab: (stored.end - stored.start) as usize * grid.plane_len() * self.sample_bytes
                + structure_bytes(grid, planes.clone(), needs),
            buffer: peak,
            worker: worker_bytes(),
            allowance: CODE_AND_STACK,
        };
        NodeReport {
            cluster,
            position,
            planes,
            stored,
            stats,
            peak_buffer: peak,
            memory,
            busy,
            resident_peak: None,
            held: None,
        }
    }
}

/// Messages sent, by kind, summed over `nodes`' reports.
pub fn sent_by_kind(nodes: &[NodeReport]) -> [u64; 9] {
    let mut messages = [0u64; 9];
    for n in nodes {
        for (total, sent) in messages.iter_mut().zip(n.stats.sent) {
            *total += sent;
        }
    }
    messages
}

/// Where a node's virtual time went (the paper's Table 4 categories, plus idle).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Category {
    /// Testing the communication buffer for messages (the nCUBE's `ntest`).
    Test,
    /// Interpolating the field (`Interpolate`).
    Interpolate,
    /// Stepping along rays (`Trace`).
    Trace,
    /// Finding and refining crossings, gradients and shading (`Voxel_Sample`).
    SampleShade,
    /// Setting up primary rays to find where they start: under the paper's distributed
    /// generation every node of a ring does it for every pixel (not among its Table 4's
    /// routines).
    Generate,
    /// Reading messages (`nread`).
    Read,
    /// Writing messages (`nwrite`).
    Write,
    /// Waiting with nothing to do.
    Idle,
}

impl Category {
    /// Number of categories.
    pub const COUNT: usize = 8;
    /// All, in order.
    pub const ALL: [Category; 8] = [
        Category::Test,
        Category::Interpolate,
        Category::Trace,
        Category::SampleShade,
        Category::Generate,
        Category::Read,
        Category::Write,
        Category::Idle,
    ];

    /// Whether this is the tracer's compute (times the profile's fitted `scale`), as opposed
    /// to message handling and waiting.
    pub fn is_compute(self) -> bool {
        matches!(
            self,
            Category::Interpolate | Category::Trace | Category::SampleShade | Category::Generate
        )
    }

    /// The paper's name for it.
    pub fn name(self) -> &'static str {
        match self {
            Category::Test => "ntest",
            Category::Interpolate => "Interpolate",
            Category::Trace => "Trace",
            Category::SampleShade => "Voxel_Sample",
            Category::Generate => "generate",
            Category::Read => "nread",
            Category::Write => "nwrite",
            Category::Idle => "idle",
        }
    }
}

/// Virtual time of a timed simulated run.
#[derive(Clone, Debug, PartialEq)]
pub struct VirtualTime {
    /// Seconds until the host held the last pixel: the frame time.
    pub frame: f64,
    /// Seconds until the host's run ended (statistics collected).
    pub end: f64,
    /// Per node, in node-id order (not ring order: ids are Gray-coded), seconds by
    /// [`Category`].
    pub parts: Vec<[f64; Category::COUNT]>,
    /// Per node, in node-id order, its spans in time order (empty unless asked for with
    /// [`RunConfig::timeline`]); neighbouring spans of one kind are merged.
    pub timeline: Vec<Vec<Span>>,
}

impl VirtualTime {
    /// The seconds by [`Category`] of each ring position of a run on one cluster of `size`
    /// (node ids are Gray-coded; slabs go by ring position).
    pub fn by_position(&self, size: u32) -> Result<Vec<[f64; Category::COUNT]>, String> {
        let layout = Layout::new(1, size).map_err(|e| e.to_string())?;
        (0..size as u16)
            .map(|j| {
                self.parts
                    .get(usize::from(layout.node(0, j)))
                    .copied()
                    .ok_or_else(|| format!("no time for ring position {j}"))
            })
            .collect()
    }
}

/// A stretch of a node's virtual time spent one way.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Span {
    /// What the node did: `compute`, `test`, `receive`, `send` or `idle`.
    pub kind: &'static str,
    /// Start, seconds.
    pub start: f64,
    /// End, seconds.
    pub end: f64,
}

/// The result of a distributed render.
#[derive(Clone, Debug)]
pub struct Distributed {
    /// RGBA8 pixels, row-major.
    pub pixels: Vec<[u8; 4]>,
    /// Per node, in node-id order.
    pub nodes: Vec<NodeReport>,
    /// Messages delivered, by kind (see `voxcube_kernel::node::stats::KIND_NAMES`).
    pub messages: [u64; 9],
    /// Bytes delivered.
    pub bytes: u64,
    /// Scheduler events (deliveries and node steps).
    pub events: u64,
    /// Receive-buffer capacity of each node, bytes.
    pub buffer_capacity: usize,
    /// The `i_max` that capacity allows.
    pub i_max: u16,
    /// Wall-clock time.
    pub wall: Duration,
    /// Of the wall time, what the host spent building every node's storage and the view's
    /// skipping structures before any node traced (its plane shift included); on MPI, where
    /// each rank builds its own side by side, the slowest rank's (`None` when a node was lost).
    pub setup: Option<Duration>,
    /// Virtual time, for timed simulated runs.
    pub time: Option<VirtualTime>,
    /// The plane shift before rendering, when the nodes moved to balanced cuts by message.
    pub shift: Option<shift::ShiftReport>,
    /// A node lost during the run and how the frame was completed without it.
    pub recovery: Option<Recovery>,
    /// The least and greatest sample value over the planes the nodes' processes held, where
    /// the host does not hold the samples itself (MPI); `None` elsewhere.
    pub data_range: Option<(f64, f64)>,
}

/// How a run lost a node and completed its frame: the surviving clusters re-traced the lost
/// cluster's unfinished rows. Every pixel reached the image once: a re-traced pixel the host
/// already held is dropped and counted.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Recovery {
    /// The node that stopped answering.
    pub node: u16,
    /// Its cluster, waited for no more.
    pub cluster: u16,
    /// When the host declared it lost: events run (simulator).
    pub declared_after_events: Option<u64>,
    /// When the host declared it lost: milliseconds from the start of the run (threads and
    /// MPI, after not hearing from it for the configured time).
    pub declared_after_ms: Option<f64>,
    /// The rows still missing pixels then, summarised.
    pub rows: String,
    /// The clusters that re-traced them.
    pub by: Vec<u16>,
    /// Pixels the re-trace filled.
    pub retraced: u64,
    /// Pixels re-traced that the host already held, dropped.
    pub dropped: u64,
    /// Messages from the lost cluster that reached the host after it was declared lost,
    /// dropped (none in the simulator, which declares a node lost only once nothing else
    /// can happen).
    pub late: u64,
    /// Nodes lost during the re-trace, in order: each took its cluster out of it, and the
    /// clusters left re-traced again.
    pub also_lost: Vec<u16>,
}

impl std::fmt::Display for Recovery {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let by: Vec<String> = self.by.iter().map(u16::to_string).collect();
        let when = match (self.declared_after_events, self.declared_after_ms) {
            (Some(events), _) => format!("{events} events"),
            (None, Some(ms)) => format!("{ms:.0} ms"),
            (None, None) => "an unknown time".into(),
        };
        write!(
            f,
            "node {} (cluster {}) stopped answering and was declared lost after {}; clusters {} re-traced rows {}: {} pixels filled, {} already held dropped, {} late messages of its cluster dropped",
            self.node,
            self.cluster,
            when,
            by.join(", "),
            self.rows,
            self.retraced,
            self.dropped,
            self.late
        )?;
        for node in &self.also_lost {
            write!(f, "; node {node} was lost during the re-trace, and the clusters left re-traced without its cluster")?;
        }
        Ok(())
    }
}

impl Distributed {
    /// Work counters summed over nodes.
    pub fn counters(&self) -> Counters {
        let mut c = Counters::default();
        for n in &self.nodes {
            c.add(&n.stats.counters);
        }
        c
    }

    /// Rays that crossed each slab boundary of each cluster: `[cluster][boundary j]` counts
    /// rays between ring positions `j` and `j + 1`, either way.
    pub fn boundary_crossings(&self) -> Vec<Vec<u64>> {
        let clusters = self
            .nodes
            .iter()
            .map(|n| usize::from(n.cluster) + 1)
            .max()
            .unwrap_or(0);
        let size = self
            .nodes
            .iter()
            .map(|n| usize::from(n.position) + 1)
            .max()
            .unwrap_or(0);
        let mut out = vec![vec![0u64; size.saturating_sub(1)]; clusters];
        for n in &self.nodes {
            let (c, j) = (usize::from(n.cluster), usize::from(n.position));
            if let Some(b) = out[c].get_mut(j) {
                *b += n.stats.forwarded_next;
            }
            if j > 0 {
                out[c][j - 1] += n.stats.forwarded_prev;
            }
        }
        out
    }
}

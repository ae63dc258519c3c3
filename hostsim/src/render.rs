//! Rendering one view: directly on one node that holds the whole volume (the reference), or on
//! a simulated machine of clusters of nodes.
//!
//! Invariant: both paths trace with the same kernel and combine ray trees with the same
//! formula, so their images are bit-identical; a non-finite colour is counted in the counters
//! (`non_finite_pixels`, which tests require to be zero) before it becomes a defined pixel.

use crate::dataset::{Volume, VolumeData};
use crate::fabric::sim::{self, SimConfig, SimError};
use crate::fabric::Distributed;
use std::time::{Duration, Instant};
use voxcube_kernel::counters::Counters;
use voxcube_kernel::pixel::rgba8;
use voxcube_kernel::sample::Sample;
use voxcube_kernel::slab::{Slab, SlabError};
use voxcube_kernel::topology::LayoutError;
use voxcube_kernel::trace::trace_pixel;
use voxcube_kernel::view::View;
use voxcube_kernel::worker::Generation;

/// What carries the work.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fabric {
    /// One node, in process, no messages: the reference.
    Direct,
    /// The deterministic simulator.
    Sim,
}

impl Fabric {
    /// The name used on the command line and in reports.
    pub fn name(self) -> &'static str {
        match self {
            Fabric::Direct => "direct",
            Fabric::Sim => "sim",
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
}

impl Machine {
    /// `nodes` in `clusters` on `fabric`, with default buffers, flow control on, distributed
    /// generation.
    pub fn new(fabric: Fabric, nodes: u32, clusters: u32, seed: u64) -> Machine {
        Machine {
            fabric,
            nodes,
            clusters,
            seed,
            generation: Generation::Distributed,
            buffer_bytes: None,
            flow_control: true,
        }
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
    /// The simulated run failed.
    #[error("simulation: {0}")]
    Sim(#[from] SimError),
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
    /// The distributed run, when there was one.
    pub distributed: Option<Distributed>,
}

impl Rendered {
    /// The pixels as one RGBA8 byte buffer.
    pub fn bytes(&self) -> Vec<u8> {
        self.pixels.iter().flatten().copied().collect()
    }
}

/// Render `view` of `volume` directly, on one node.
pub fn render(volume: &Volume, view: &View) -> Result<Rendered, SlabError> {
    match &volume.data {
        VolumeData::U8(d) => render_typed(volume, d, view),
        VolumeData::U16(d) => render_typed(volume, d, view),
        VolumeData::F32(d) => render_typed(volume, d, view),
    }
}

/// Render `view` of `volume` on `machine`.
pub fn render_on(volume: &Volume, view: &View, machine: &Machine) -> Result<Rendered, RenderError> {
    match machine.fabric {
        Fabric::Direct => {
            if machine.nodes != 1 {
                return Err(RenderError::Machine(format!(
                    "the direct fabric renders on one node, not {}; use --fabric sim",
                    machine.nodes
                )));
            }
            Ok(render(volume, view)?)
        }
        Fabric::Sim => {
            if machine.clusters == 0 || machine.nodes % machine.clusters != 0 {
                return Err(RenderError::Machine(format!(
                    "{} nodes do not split into {} clusters",
                    machine.nodes, machine.clusters
                )));
            }
            let size = machine.nodes / machine.clusters;
            let nx = volume.grid.dims()[0];
            if size > nx {
                return Err(RenderError::Machine(format!(
                    "clusters of {size} nodes need at least {size} X planes to slice; the volume has {nx}"
                )));
            }
            let cfg = SimConfig {
                generation: machine.generation,
                buffer_bytes: machine.buffer_bytes,
                flow_control: machine.flow_control,
                ..SimConfig::machine(machine.clusters, size, machine.seed)?
            };
            let run = sim::run(volume, view, &cfg)?;
            let spec = view.spec();
            Ok(Rendered {
                width: spec.width,
                height: spec.height,
                pixels: run.pixels.clone(),
                counters: run.counters(),
                wall: run.wall,
                distributed: Some(run),
            })
        }
    }
}

fn render_typed<T: Sample>(
    volume: &Volume,
    data: &[T],
    view: &View,
) -> Result<Rendered, SlabError> {
    let slab = Slab::whole(volume.grid, data)?;
    let start = Instant::now();
    let mut counters = Counters::default();
    let n = view.pixel_count();
    let mut pixels = Vec::with_capacity(n as usize);
    for pixel in 0..n {
        let c = trace_pixel(view, &slab, pixel as u32, &mut counters);
        counters.non_finite_pixels += u64::from(!c.is_finite());
        pixels.push(rgba8(c));
    }
    let spec = view.spec();
    Ok(Rendered {
        width: spec.width,
        height: spec.height,
        pixels,
        counters,
        wall: start.elapsed(),
        distributed: None,
    })
}

//! The paper's runs in simulated nCUBE 2 time: one timed run of a machine shape (its slabs
//! reached by shifting planes when cut), the paper's sequential tracer, and a traced run; what
//! the paper's tables ([`crate::experiments::paper`]) and the fit of the profile's constants
//! ([`crate::experiments::fit`]) both take, so neither reads the other for them.
//!
//! Invariant: every run models the paper's tracer, without empty-space skipping.

use crate::fabric::sim;
use crate::fabric::VirtualTime;
use crate::fabric::{RunConfig, RunError};
use crate::input::scene::{DatasetJob, SceneError};
use crate::profile::MachineProfile;
use voxcube_kernel::trace::view::View;

/// Why the experiments could not run.
#[derive(Debug, thiserror::Error)]
pub enum PaperError {
    /// The scene did not load.
    #[error("{0}")]
    Scene(#[from] SceneError),
    /// A simulated run failed.
    #[error("{0}")]
    Sim(#[from] RunError),
    /// An output could not be written.
    #[error("{0}")]
    Write(String),
    /// SOD is not where the command was told to read it.
    #[error("{}: SOD not found: expected {SOD_FILE}, or a folder holding it (--substitute renders the built-in molecule instead)", .0.display())]
    NoSod(std::path::PathBuf),
}

/// SOD's file name in the shared data folder.
pub const SOD_FILE: &str = "sod-97x97x116.u8.binary";

/// One timed run: the view on `clusters` clusters of `size`, optionally with slab `cuts`,
/// which the nodes reach from uniform slabs by shifting planes (the shift's time included).
pub fn timed(
    job: &DatasetJob,
    view: &View,
    profile: &MachineProfile,
    clusters: u32,
    size: u32,
    cuts: Option<Vec<u32>>,
) -> Result<VirtualTime, PaperError> {
    timed_with(job, view, profile, (clusters, size), cuts, false)
}

/// The paper's one-node time: its sequential tracer on the whole image, priced from the
/// direct render's counted work (no empty-space skipping, as the paper had none) by
/// [`MachineProfile::sequential`]: no slab test on each sample, no messages.
pub fn sequential(
    job: &DatasetJob,
    view: &View,
    profile: &MachineProfile,
) -> Result<f64, PaperError> {
    let run = crate::run::render::render_skipping(
        &job.volume,
        view,
        crate::memory::storage::SkipMode::OFF,
    )
    .map_err(|e| PaperError::Write(e.to_string()))?;
    Ok(crate::experiments::accuracy::one_node_seconds(
        &run.counters,
        view,
        profile,
    ))
}

/// The paper's run of `nodes` nodes in clusters of `size` (a row of Tables 1 and 2), with
/// every node's timeline kept: what `paper --trace` writes.
pub fn traced(
    job: &DatasetJob,
    profile: &MachineProfile,
    nodes: u32,
    size: u32,
) -> Result<VirtualTime, PaperError> {
    if size == 0
        || !nodes.is_multiple_of(size)
        || !nodes.is_power_of_two()
        || !size.is_power_of_two()
    {
        return Err(PaperError::Write(format!(
            "--trace {nodes}/{size}: nodes and cluster size are powers of two, the size dividing the nodes"
        )));
    }
    timed_with(
        job,
        &job.views[0].view,
        profile,
        (nodes / size, size),
        None,
        true,
    )
}

fn timed_with(
    job: &DatasetJob,
    view: &View,
    profile: &MachineProfile,
    (clusters, size): (u32, u32),
    cuts: Option<Vec<u32>>,
    timeline: bool,
) -> Result<VirtualTime, PaperError> {
    let Ok(base) = RunConfig::machine(clusters, size, 1) else {
        return Err(PaperError::Write(format!(
            "no layout of {clusters} clusters of {size}"
        )));
    };
    // The paper's tracer had no acceleration: model it without empty-space skipping.
    let cfg = RunConfig {
        time: Some(profile.clone()),
        timeline,
        shift: cuts.is_some(),
        cuts,
        skipping: crate::memory::storage::SkipMode::OFF,
        ..base
    };
    let run = sim::run(&job.volume, view, &cfg)?;
    run.time
        .ok_or_else(|| PaperError::Write("a timed run returned no time".into()))
}

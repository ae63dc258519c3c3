//! The paper's runs in simulated nCUBE 2 time: one timed run of a machine shape (its slabs
//! reached by shifting planes when cut), the paper's sequential tracer, and a traced run; what
//! the paper's tables ([`crate::experiments::paper`]) and the fit of the profile's constants
//! ([`crate::experiments::fit`]) both take, so neither reads the other for them.
//!
//! Invariant: every run models the paper's tracer, without empty-space skipping.

use super::error::ExperimentError;
use crate::fabric::sim;
use crate::fabric::RunConfig;
use crate::fabric::VirtualTime;
use crate::input::scene::DatasetJob;
use crate::profile::MachineProfile;
use crate::run::render::RenderError;
use voxcube_kernel::trace::view::View;

/// One timed run: the view on `clusters` clusters of `size`, optionally with slab `cuts`,
/// which the nodes reach from uniform slabs by shifting planes (the shift's time included).
pub fn timed(
    job: &DatasetJob,
    view: &View,
    profile: &MachineProfile,
    clusters: u32,
    size: u32,
    cuts: Option<Vec<u32>>,
) -> Result<VirtualTime, ExperimentError> {
    timed_with(job, view, profile, (clusters, size), cuts, false)
}

/// The paper's one-node time: its sequential tracer on the whole image, priced from the
/// direct render's counted work (no empty-space skipping, as the paper had none) by
/// [`MachineProfile::sequential`]: no slab test on each sample, no messages.
pub fn sequential(
    job: &DatasetJob,
    view: &View,
    profile: &MachineProfile,
) -> Result<f64, ExperimentError> {
    let run = crate::run::render::render_skipping(
        &job.volume,
        view,
        crate::memory::storage::SkipMode::OFF,
    )
    .map_err(RenderError::from)?;
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
) -> Result<VirtualTime, ExperimentError> {
    if size == 0
        || !nodes.is_multiple_of(size)
        || !nodes.is_power_of_two()
        || !size.is_power_of_two()
    {
        return Err(ExperimentError::Asked(format!(
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
) -> Result<VirtualTime, ExperimentError> {
    let Ok(base) = RunConfig::machine(clusters, size, 1) else {
        return Err(ExperimentError::Asked(format!(
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
        .ok_or_else(|| ExperimentError::Missing("a timed run returned no time".into()))
}

//! Schedule exploration: many configurations (scenes, cube shapes, buffer sizes) × schedulers
//! × seeds on the simulator. For each run it checks that the run completes, that the image is
//! bit-identical to the direct render, and that every invariant held. It reports how many runs
//! deadlocked, broke an invariant or differed, and the worst buffer occupancy seen against its
//! capacity.

use crate::fabric::sim;
use crate::fabric::{RunConfig, RunError, Scheduler};
use crate::input::scene::{DatasetJob, Scene, SceneError};
use crate::run::render::render;
use std::fmt;
use voxcube_kernel::node::flow;

/// The scenes explored (`explore.toml`): shadow rays flowing against primary rays, nested
/// transparency, point lights inside the volume (rays in both directions), compositing.
pub const SCENES: &str = include_str!("explore.toml");

/// Cube shapes explored: (clusters, nodes per cluster).
pub const SHAPES: [(u32, u32); 9] = [
    (1, 2),
    (1, 3),
    (1, 4),
    (2, 2),
    (1, 8),
    (2, 4),
    (4, 2),
    (1, 16),
    (2, 8),
];

/// Receive buffers explored, as `i_max` above the smallest that admits a ray.
pub const HEADROOMS: [usize; 3] = [0, 1, 6];

/// One configuration.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Config {
    /// Index of the view in [`SCENES`].
    pub view: usize,
    /// Clusters.
    pub clusters: u32,
    /// Nodes per cluster.
    pub size: u32,
    /// Receive-buffer bytes per node.
    pub buffer: usize,
}

/// What exploring found.
#[derive(Clone, Debug, Default)]
pub struct Findings {
    /// Configurations explored.
    pub configs: usize,
    /// Runs (configurations × schedulers × seeds).
    pub runs: u64,
    /// Runs that deadlocked.
    pub deadlocks: u64,
    /// Runs that broke an invariant (or a watchdog fired).
    pub violations: u64,
    /// Runs that completed with an image that differs from the direct render.
    pub differing: u64,
    /// Highest peak receive-buffer occupancy over capacity, with the bytes.
    pub worst_occupancy: (usize, usize),
    /// Runs with a node stopped (`--faults`), runs whose frame was completed by re-tracing
    /// its cluster's rows, and the pixels re-traced (runs that failed are violations: a
    /// lost pixel fails the run).
    pub faults: u64,
    /// See `faults`.
    pub recovered: u64,
    /// See `faults`.
    pub retraced: u64,
    /// The first failure, with everything needed to replay it.
    pub first_failure: Option<String>,
}

impl Findings {
    /// Runs that failed in any way.
    pub fn failures(&self) -> u64 {
        self.deadlocks + self.violations + self.differing
    }
}

impl fmt::Display for Findings {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let (peak, cap) = self.worst_occupancy;
        writeln!(f, "configurations        {}", self.configs)?;
        writeln!(f, "schedules run         {}", self.runs)?;
        writeln!(f, "deadlocks             {}", self.deadlocks)?;
        writeln!(f, "invariant violations  {}", self.violations)?;
        writeln!(f, "images differing      {}", self.differing)?;
        let pct = if cap > 0 {
            100.0 * peak as f64 / cap as f64
        } else {
            0.0
        };
        writeln!(f, "worst buffer use      {peak} of {cap} bytes ({pct:.0}%)")?;
        if self.faults > 0 {
            writeln!(f, "nodes stopped         {}", self.faults)?;
            writeln!(f, "frames re-traced      {}", self.recovered)?;
            writeln!(f, "pixels re-traced      {}", self.retraced)?;
            writeln!(f, "pixels lost           {}", self.violations)?;
        }
        if let Some(first) = &self.first_failure {
            writeln!(f, "first failure:\n{first}")?;
        }
        Ok(())
    }
}

/// The explored scenes, loaded.
pub fn scenes() -> Result<DatasetJob, SceneError> {
    let mut jobs =
        Scene::parse(SCENES, "<exploration scenes>", std::path::Path::new("."))?.load()?;
    Ok(jobs.remove(0))
}

/// Every configuration: views × shapes × buffers.
pub fn configs(job: &DatasetJob) -> Vec<Config> {
    let mut out = Vec::new();
    for (view, v) in job.views.iter().enumerate() {
        let needed = flow::min_i_max(v.view.effects().shadow_lights);
        for &(clusters, size) in &SHAPES {
            for headroom in HEADROOMS {
                let buffer = flow::buffer_bytes(size as usize, needed + headroom);
                out.push(Config {
                    view,
                    clusters,
                    size,
                    buffer,
                });
            }
        }
    }
    out
}

/// The schedulers tried on a cluster of `size`.
pub fn schedulers(size: u32) -> Vec<Scheduler> {
    let mut s = vec![
        Scheduler::Uniform,
        Scheduler::NewestFirst,
        Scheduler::DelayAcks,
    ];
    if size > 1 {
        s.push(Scheduler::Starve { from: 0, to: 1 });
    }
    s
}

/// Run `seeds` seeds of every scheduler on every configuration. `adjust` may change each
/// simulator configuration (flow control off, a mutant) before it runs.
pub fn explore(
    job: &DatasetJob,
    configs: &[Config],
    seeds: u64,
    adjust: &dyn Fn(&mut RunConfig),
) -> Findings {
    let mut findings = Findings {
        configs: configs.len(),
        ..Findings::default()
    };
    let references: Vec<Vec<[u8; 4]>> = job
        .views
        .iter()
        .map(|v| {
            render(&job.volume, &v.view)
                .map(|r| r.pixels)
                .unwrap_or_default()
        })
        .collect();
    for c in configs {
        let view = &job.views[c.view];
        for scheduler in schedulers(c.size) {
            for seed in 0..seeds {
                let Ok(base) = RunConfig::machine(c.clusters, c.size, seed) else {
                    continue;
                };
                let mut cfg = RunConfig {
                    buffer_bytes: Some(c.buffer),
                    ..base
                };
                cfg.schedule.scheduler = scheduler;
                adjust(&mut cfg);
                findings.runs += 1;
                findings.faults += u64::from(cfg.schedule.stop.is_some());
                let failure = match sim::run(&job.volume, &view.view, &cfg) {
                    Ok(run) => {
                        if let Some(r) = &run.recovery {
                            findings.recovered += 1;
                            findings.retraced += r.retraced;
                        }
                        for n in &run.nodes {
                            let (peak, cap) = findings.worst_occupancy;
                            if cap == 0 || n.peak_buffer * cap > peak * run.buffer_capacity {
                                findings.worst_occupancy = (n.peak_buffer, run.buffer_capacity);
                            }
                        }
                        if run.pixels == references[c.view] {
                            None
                        } else {
                            findings.differing += 1;
                            Some("the image differs from the direct render".to_string())
                        }
                    }
                    Err(e @ RunError::Deadlock { .. }) => {
                        findings.deadlocks += 1;
                        Some(e.to_string())
                    }
                    Err(e) => {
                        findings.violations += 1;
                        Some(e.to_string())
                    }
                };
                if let (Some(what), None) = (failure, &findings.first_failure) {
                    findings.first_failure = Some(format!(
                        "view {} on {} clusters of {}, buffer {} bytes, {scheduler}, seed {seed}, flow control {}:\n{what}",
                        view.name,
                        c.clusters,
                        c.size,
                        c.buffer,
                        if cfg.flow_control { "on" } else { "off" }
                    ));
                }
            }
        }
    }
    findings
}

/// A node stop for `cfg`'s run, drawn from its seed and shape: a node of any cluster, after
/// 1 to 600 of its steps (some nodes finish sooner: those stops cost nothing).
pub fn inject_stop(cfg: &mut RunConfig) {
    let nodes = cfg.layout.nodes() as usize;
    let mut rng = crate::rng::SplitMix(cfg.schedule.seed ^ (nodes as u64) << 32 ^ 0x5709);
    let node = rng.below(nodes) as u16;
    let after = 1 + rng.below(600) as u64;
    cfg.schedule.stop = Some((node, after));
}

/// The configurations a stopped node can be recovered in: two clusters or more.
pub fn recoverable(configs: &[Config]) -> Vec<Config> {
    configs
        .iter()
        .filter(|c| c.clusters >= 2)
        .cloned()
        .collect()
}

/// The small machines walked exhaustively: a handful of rays with shadows and transparency
/// (the built-in molecule, `width` × `height` pixels, a semi-transparent outer surface and an
/// opaque inner one, one shadow-casting light).
pub fn few_rays(width: u32, height: u32) -> Result<DatasetJob, SceneError> {
    let text = format!(
        r#"
[[datasets]]
name = "m"
builtin = "molecule"
[[datasets.views]]
name = "few-rays"
width = {width}
height = {height}
[[datasets.views.surfaces]]
iso = 30.0
transparency = 0.3
[[datasets.views.surfaces]]
iso = 60.0
[[datasets.views.lights]]
type = "directional"
direction = [1.0, -0.3, -0.2]
shadows = true
"#
    );
    let mut jobs = Scene::parse(&text, "<few rays>", std::path::Path::new("."))?.load()?;
    Ok(jobs.remove(0))
}

/// One ring of `size` on the smallest buffer that lets a ray with one shadow light start.
pub fn tight_ring(size: u32) -> Result<RunConfig, RunError> {
    Ok(RunConfig {
        buffer_bytes: Some(flow::buffer_bytes(size as usize, flow::min_i_max(1))),
        ..RunConfig::cluster(size, 0).map_err(|e| RunError::Host(e.to_string()))?
    })
}

/// The small machines whose every schedule [`exhaustive_walks`] walks: (pixels wide, high,
/// ring size).
pub const SMALL_MACHINES: [(u32, u32, u32); 3] = [(2, 1, 2), (3, 2, 2), (2, 1, 3)];

/// One small machine's walk: its label, what every schedule gave, and the direct render.
pub type Walk = (String, sim::exhaustive::Exhaustive, Vec<[u8; 4]>);

/// Every schedule of each of [`SMALL_MACHINES`], with the direct render of its view.
pub fn exhaustive_walks() -> Result<Vec<Walk>, Box<dyn std::error::Error>> {
    let mut out = Vec::new();
    for (width, height, size) in SMALL_MACHINES {
        let job = few_rays(width, height)?;
        let view = &job.views[0].view;
        let reference = render(&job.volume, view)?.pixels;
        let found = sim::exhaustive::explore(&job.volume, view, &tight_ring(size)?, 2_000_000)?;
        out.push((
            format!("{width}x{height} pixels on a ring of {size}"),
            found,
            reference,
        ));
    }
    Ok(out)
}

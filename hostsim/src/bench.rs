//! `voxcube bench`: milliseconds per frame and samples per second, medians of several runs,
//! for the default scene and SOD at the paper's 350×250 and Δt = 1/2, surfaces and
//! compositing, on one node and on the machine shapes worth comparing here.

use crate::render::{render_on, Fabric, Machine, RenderError};
use crate::scene::{Scene, SceneError};
use std::fmt::Write;
use std::path::Path;
use std::time::Duration;

/// The views benchmarked: the paper's view as a shaded surface and composited.
const VIEWS: &str = r#"
[[datasets.views]]
name = "surfaces"
dt = 0.5
[datasets.views.camera]
azimuth = 45.0
[[datasets.views.surfaces]]
iso = ISO
color = [0.95, 0.78, 0.45]
[[datasets.views.lights]]
type = "directional"
direction = [0.4, -0.5, 1.0]
frame = "camera"

[[datasets.views]]
name = "composite"
dt = 0.5
mode = "composite"
[datasets.views.camera]
azimuth = 45.0
[[datasets.views.transfer]]
value = 10.0
color = [0.2, 0.3, 0.8]
opacity = 0.0
[[datasets.views.transfer]]
value = 60.0
color = [0.9, 0.7, 0.3]
opacity = 0.15
[[datasets.views.transfer]]
value = 200.0
color = [1.0, 0.2, 0.1]
opacity = 0.8
"#;

/// Why the benchmark could not run.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    /// A benchmark scene did not load.
    #[error("{0}")]
    Scene(#[from] SceneError),
    /// A render failed.
    #[error("{0}")]
    Render(#[from] RenderError),
}

/// One measured configuration.
#[derive(Clone, Debug)]
pub struct Row {
    /// Dataset.
    pub dataset: String,
    /// View.
    pub view: String,
    /// Fabric and shape.
    pub config: String,
    /// Median wall time per frame.
    pub median: Duration,
    /// Samples per frame.
    pub samples: u64,
}

fn median(mut v: Vec<Duration>) -> Duration {
    v.sort();
    v.get(v.len() / 2).copied().unwrap_or_default()
}

/// The machine shapes compared: one node, pure image partition over the cores, and a
/// ray-dataflow cluster of 16.
pub fn machines(cores: u32) -> Vec<(String, Machine)> {
    let cores = cores.max(1).next_power_of_two();
    vec![
        (
            "direct, 1 node".into(),
            Machine::new(Fabric::Direct, 1, 1, 1),
        ),
        (
            format!("threads, {cores} clusters of 1"),
            Machine::new(Fabric::Threads, cores, cores, 1),
        ),
        (
            "threads, 1 cluster of 16".into(),
            Machine::new(Fabric::Threads, 16, 1, 1),
        ),
    ]
}

/// Run the benchmark: `runs` renders of each view on each machine. SOD is read from `sod`
/// when it exists, and left out (with a line saying so) when it does not.
pub fn run(runs: usize, sod: &Path, out: &mut String) -> Result<Vec<Row>, BenchError> {
    let mut scenes = vec![format!(
        "[[datasets]]\nname = \"molecule\"\nbuiltin = \"molecule\"\n{}",
        VIEWS.replace("ISO", "40.0")
    )];
    if sod.is_file() {
        let path = sod.display().to_string().replace('\\', "/");
        scenes.push(format!(
            "[[datasets]]\nname = \"sod\"\npath = \"{path}\"\nformat = \"raw\"\ndims = [97, 97, 116]\ntype = \"u8\"\nheader_bytes = 12\n{}",
            VIEWS.replace("ISO", "50.0")
        ));
    } else {
        let _ = writeln!(
            out,
            "SOD not found at {}: benchmarking the default scene only",
            sod.display()
        );
    }
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get() as u32);
    let mut rows = Vec::new();
    for text in scenes {
        let jobs = Scene::parse(&text, "<bench>", Path::new("."))?.load()?;
        for job in &jobs {
            for v in &job.views {
                for (name, machine) in machines(cores) {
                    let mut times = Vec::with_capacity(runs);
                    let mut samples = 0;
                    for _ in 0..runs.max(1) {
                        let r = render_on(&job.volume, &v.view, &machine)?;
                        times.push(r.wall);
                        samples = r.counters.samples;
                    }
                    rows.push(Row {
                        dataset: job.name.clone(),
                        view: v.name.clone(),
                        config: name,
                        median: median(times),
                        samples,
                    });
                }
            }
        }
    }
    Ok(rows)
}

/// The table.
pub fn table(rows: &[Row], runs: usize) -> String {
    let mut out = format!(
        "{:<10} {:<10} {:<28} {:>10} {:>12} {:>9}\n",
        "dataset", "view", "machine", "ms/frame", "samples/s", "speedup"
    );
    let mut base = Duration::ZERO;
    for r in rows {
        if r.config.starts_with("direct") {
            base = r.median;
        }
        let ms = r.median.as_secs_f64() * 1e3;
        let rate = r.samples as f64 / r.median.as_secs_f64().max(1e-9);
        let speedup = base.as_secs_f64() / r.median.as_secs_f64().max(1e-9);
        let _ = writeln!(
            out,
            "{:<10} {:<10} {:<28} {:>10.1} {:>10.1} M {:>8.2}x",
            r.dataset,
            r.view,
            r.config,
            ms,
            rate / 1e6,
            speedup
        );
    }
    let _ = writeln!(out, "medians of {runs} runs, 350x250, dt = 1/2");
    out
}

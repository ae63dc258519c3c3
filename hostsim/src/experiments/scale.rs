//! `voxcube bench --scale`: how the cost of a composited frame grows with the work, in both
//! accuracy tiers. The built-in molecule resampled to 128³, 256³ and 512³ at 350×250, and
//! the 128³ volume at images from 350×250 to 2048×1536, each on one node and on a cluster
//! of one node per core (threads), each node a modern one (1 GiB); time per evaluated
//! sample and per pixel show where the cost goes as the volume or the image grows. Each
//! view's first frame is timed apart from the median of those after it: it builds what the
//! volume keeps for later frames (the exact view, first of a volume, its value ranges,
//! masks and cell leap map; the fast view after it, its node field), so it shows what a
//! single frame of a new volume costs, and the median what a further one does.

use super::error::ExperimentError;
use super::sod::COMPOSITE_TRANSFER;
use crate::input::builtin;
use crate::input::dataset::Volume;
use crate::input::scene::Scene;
use crate::run::render::{render_on, Fabric, Machine};
use std::fmt::Write;
use std::path::Path;
use std::time::Duration;

/// Volume edges measured at the paper's image size.
pub const VOLUMES: [u32; 3] = [128, 256, 512];
/// Images measured on the 128³ volume.
pub const IMAGES: [(u32, u32); 4] = [(350, 250), (700, 500), (1400, 1000), (2048, 1536)];

/// One measured frame.
#[derive(Clone, Debug)]
pub struct ScaleRow {
    /// Volume edge, samples.
    pub volume: u32,
    /// Image size.
    pub image: (u32, u32),
    /// Accuracy tier.
    pub tier: &'static str,
    /// Fabric and shape.
    pub config: String,
    /// Median wall time of the frames after the first.
    pub median: Duration,
    /// Wall time of the first frame of the view, which builds what the volume keeps for
    /// every later one (its value ranges, the fast tier's node field, the view's masks and
    /// cell leap map) where no view before it did.
    pub first: Duration,
    /// Lattice samples evaluated.
    pub samples: u64,
}

impl ScaleRow {
    fn ns_per_sample(&self) -> f64 {
        self.median.as_secs_f64() * 1e9 / self.samples.max(1) as f64
    }

    fn us_per_pixel(&self) -> f64 {
        self.median.as_secs_f64() * 1e6 / f64::from(self.image.0 * self.image.1)
    }
}

/// The composited view of an `n`³ volume in `tier`: the paper's direction (azimuth 45°), the
/// camera placed outright (the scene's placeholder volume has another size) so the cube
/// fills about 86% of the image's width.
fn view(tier: &str, (width, height): (u32, u32), n: u32) -> String {
    let c = (n - 1) as f32 / 2.0;
    let far = 2.0 * n as f32;
    let side = far * core::f32::consts::FRAC_1_SQRT_2;
    let eye = [c + side, c, c + side];
    let span = 1.65 * n as f32;
    format!(
        r#"[[datasets.views]]
name = "{tier}"
width = {width}
height = {height}
dt = 0.5
mode = "composite"
accuracy = "{tier}"
[datasets.views.camera]
eye = {eye:?}
look_at = [{c:?}, {c:?}, {c:?}]
width = {span:?}
{COMPOSITE_TRANSFER}"#
    )
}

/// Measure every volume size and every image size, both tiers, on one node and on every
/// core; `runs` renders of each (the median kept), interleaved across machines.
pub fn run(runs: usize, out: &mut String) -> Result<Vec<ScaleRow>, ExperimentError> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get() as u32);
    let cores = cores.next_power_of_two();
    // Today's nodes, not the nCUBE 2's 4 MiB: a 512³ volume is 128 MiB on one node.
    let modern = crate::memory::budget::Profile::builtin("modern")
        .ok_or_else(|| ExperimentError::Missing("the shipped modern profile is missing".into()))?;
    let on = |m: Machine| Machine {
        profile: modern,
        ..m
    };
    let machines = [
        (
            "direct, 1 node".to_string(),
            on(Machine::new(Fabric::Direct, 1, 1, 1)),
        ),
        (
            format!("threads, {cores} clusters of 1"),
            on(Machine::new(Fabric::Threads, cores, cores, 1)),
        ),
    ];
    let mut work: Vec<(u32, (u32, u32))> = VOLUMES.iter().map(|&n| (n, IMAGES[0])).collect();
    work.extend(IMAGES[1..].iter().map(|&i| (VOLUMES[0], i)));
    let mut rows = Vec::new();
    let mut volume: Option<Volume> = None;
    for (n, image) in work {
        if volume.as_ref().is_none_or(|v| v.grid.dims()[0] != n) {
            volume = Some(builtin::molecule_at(n));
        }
        let Some(volume) = volume.as_ref() else {
            continue;
        };
        // A placeholder dataset carries the views through the scene checks; they are then
        // built on the resampled grid.
        let text = format!(
            "[[datasets]]\nname = \"m\"\nbuiltin = \"sphere\"\n{}{}",
            view("exact", image, n),
            view("fast", image, n)
        );
        let jobs = Scene::parse(&text, "<bench --scale>", Path::new("."))?.load()?;
        for v in jobs.iter().flat_map(|j| &j.views) {
            let spec = v.view.spec().clone();
            let built = voxcube_kernel::trace::view::View::new(spec, &volume.grid)
                .map_err(|e| ExperimentError::Asked(format!("scale sweep: {e}")))?;
            let mut times = vec![Vec::new(); machines.len()];
            let mut samples = vec![0; machines.len()];
            let mut first = Vec::new();
            for (_, machine) in &machines {
                first.push(render_on(volume, &built, machine)?.wall);
            }
            for _ in 0..runs.max(1) {
                for (m, (_, machine)) in machines.iter().enumerate() {
                    let r = render_on(volume, &built, machine)?;
                    times[m].push(r.wall);
                    samples[m] = r.counters.samples;
                }
            }
            let measured = machines.iter().zip(times).zip(samples).zip(first);
            for ((((config, _), mut t), samples), first) in measured {
                t.sort();
                let row = ScaleRow {
                    volume: n,
                    image,
                    tier: if v.name == "fast" { "fast" } else { "exact" },
                    config: config.clone(),
                    median: t[t.len() / 2],
                    first,
                    samples,
                };
                let _ = writeln!(
                    out,
                    "measured {}³ {}x{} {} on {}: {:.1} ms",
                    n,
                    image.0,
                    image.1,
                    row.tier,
                    row.config,
                    row.median.as_secs_f64() * 1e3
                );
                rows.push(row);
            }
        }
    }
    Ok(rows)
}

/// The table: each row's time, samples, time per sample and per pixel, and its growth over
/// the first row of the same tier, machine and sweep.
pub fn table(rows: &[ScaleRow], runs: usize) -> String {
    let mut out = format!(
        "How the cost grows (composited molecule resampled to n³, dt 1/2, the cube across 86% of the width; medians of {runs} frames after the first, which builds what the volume keeps):\n{:<7} {:<10} {:<6} {:<24} {:>10} {:>10} {:>10} {:>10} {:>10} {:>9} {:>9}\n",
        "volume", "image", "tier", "machine", "first ms", "ms", "samples", "ns/sample", "us/pixel", "time x", "samples x"
    );
    for sweep in ["volume", "image"] {
        let _ = writeln!(out, "-- growing the {sweep}");
        let in_sweep = |r: &&ScaleRow| match sweep {
            "volume" => r.image == IMAGES[0],
            _ => r.volume == VOLUMES[0],
        };
        for r in rows.iter().filter(in_sweep) {
            let first = rows
                .iter()
                .filter(in_sweep)
                .find(|f| f.tier == r.tier && f.config == r.config);
            let (tx, sx) = first.map_or((1.0, 1.0), |f| {
                (
                    r.median.as_secs_f64() / f.median.as_secs_f64().max(1e-9),
                    r.samples as f64 / f.samples.max(1) as f64,
                )
            });
            let _ = writeln!(
                out,
                "{:<7} {:<10} {:<6} {:<24} {:>10.1} {:>10.1} {:>10} {:>10.2} {:>10.3} {:>9.2} {:>9.2}",
                format!("{}³", r.volume),
                format!("{}x{}", r.image.0, r.image.1),
                r.tier,
                r.config,
                r.first.as_secs_f64() * 1e3,
                r.median.as_secs_f64() * 1e3,
                r.samples,
                r.ns_per_sample(),
                r.us_per_pixel(),
                tx,
                sx
            );
        }
    }
    out
}

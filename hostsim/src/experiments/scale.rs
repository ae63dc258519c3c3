//! `voxcube bench --scale`: how the cost of a composited frame grows with the work, in both
//! accuracy tiers. The built-in molecule resampled to 128³, 256³ and 512³ at 350×250, and
//! the 128³ volume at images from 350×250 to 2048×1536, each on one node and on a cluster
//! of one node per core (threads) sharing this machine's memory (`--machine host`); time
//! per evaluated sample and per pixel show where the cost goes as the volume or the image
//! grows. Each view's first frame is timed apart from the median of those after it: it
//! builds what the volume keeps for later frames (the exact view, first of a volume, its
//! value ranges, masks and cell leap map; the fast view after it, its node field), so it
//! shows what a single frame of a new volume costs, and the median what a further one
//! does. Beside them,
//! in the same run, VTK's CPU ray caster on each volume of the sweep, framed the same
//! ([`super::peer`]), where it is installed. Then the same beside VTK for a CT-like volume,
//! the built-in head in Hounsfield units (`i16`, CT's sample kind) at 256³ and 512³, with a
//! transfer function of skin and bone.

use super::bench::{median, median_frame, run_paired, seconds, sorted_ratios, spread, PAIR_FRAMES};
use super::chart::{self, Line};
use super::error::ExperimentError;
use super::peer::{Frame, Peer, PeerMode, Request};
use super::phases::{self, Phases};
use super::sod::COMPOSITE_TRANSFER;
use crate::input::builtin;
use crate::input::dataset::{to_file_order, Volume, VolumeData};
use crate::input::scene::Scene;
use crate::run::render::{render_on, Fabric, Machine};
use plotters::prelude::*;
use std::fmt::Write;
use std::path::Path;
use std::time::Duration;

/// Volume edges measured at the paper's image size.
pub const VOLUMES: [u32; 3] = [128, 256, 512];
/// Images measured on the 128³ volume.
pub const IMAGES: [(u32, u32); 4] = [(350, 250), (700, 500), (1400, 1000), (2048, 1536)];
/// Edges of the CT-like head measured at the paper's image size.
pub const HEADS: [u32; 2] = [256, 512];

/// The head's transfer function (value in HU, colour, opacity per unit length): air and
/// fat clear, soft tissue faint, bone opaque, so a ray crosses skin, brain and skull.
pub const HEAD_TRANSFER: [(f32, [f32; 3], f32); 5] = [
    (-400.0, [0.8, 0.5, 0.4], 0.0),
    (0.0, [0.9, 0.6, 0.5], 0.01),
    (80.0, [0.9, 0.6, 0.5], 0.02),
    (300.0, [1.0, 0.95, 0.85], 0.15),
    (1100.0, [1.0, 1.0, 0.95], 0.8),
];

/// Which volume a row measured.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Dataset {
    /// The molecule resampled to n³ (u8).
    Molecule,
    /// The CT-like head on n³ (i16).
    Head,
}

impl Dataset {
    /// The volume on `n`³ samples.
    fn volume(self, n: u32) -> Volume {
        match self {
            Dataset::Molecule => builtin::molecule_at(n),
            Dataset::Head => builtin::head(n),
        }
    }

    /// Its composited views' transfer function, as a scene's tables.
    fn transfer(self) -> String {
        match self {
            Dataset::Molecule => COMPOSITE_TRANSFER.to_string(),
            Dataset::Head => HEAD_TRANSFER
                .iter()
                .map(|(v, c, o)| {
                    format!(
                        "[[datasets.views.transfer]]\nvalue = {v:?}\ncolor = {c:?}\nopacity = {o:?}\n"
                    )
                })
                .collect(),
        }
    }

    /// A row's volume, as the tables name it.
    fn label(self, n: u32) -> String {
        match self {
            Dataset::Molecule => format!("{n}³"),
            Dataset::Head => format!("head {n}³"),
        }
    }
}

/// One measured frame.
#[derive(Clone, Debug)]
pub struct ScaleRow {
    /// The volume measured.
    pub dataset: Dataset,
    /// Volume edge, samples.
    pub volume: u32,
    /// Image size.
    pub image: (u32, u32),
    /// Accuracy tier.
    pub tier: &'static str,
    /// Fabric and shape.
    pub config: String,
    /// Whether it ran on a cluster of one node per core (threads) rather than one node.
    pub every_core: bool,
    /// Median wall time of the frames after the first.
    pub median: Duration,
    /// Wall time of the first frame of the view, which builds what the volume keeps for
    /// every later one (its value ranges, the fast tier's node field, the view's masks and
    /// cell leap map) where no view before it did.
    pub first: Duration,
    /// Of the median frame, the set-up before any ray was traced: the view's skipping
    /// structures (what a further frame of the same view builds again: its depth bounds, the
    /// leap maps it copies or builds).
    pub setup: Duration,
    /// Lattice samples evaluated.
    pub samples: u64,
    /// Where its frames' time after the set-up went, by a sampling profile of frames after
    /// the timed ones (`None` where the profiler could not run: the notes say why).
    pub phases: Option<Phases>,
}

/// VTK's composited frame of one volume of the sweep, in the same run.
#[derive(Clone, Debug)]
pub struct VtkRow {
    /// The volume measured.
    pub dataset: Dataset,
    /// Volume edge, samples.
    pub volume: u32,
    /// Median wall time of its renders after a first one (which builds its gradients).
    pub median: Duration,
    /// PSNR (dB) of VTK's image against voxcube's fast tier's: the same framing, two
    /// renderers' lighting and sampling.
    pub psnr: f64,
    /// The fast tier on every core over VTK in paired rounds, each round's ratio, ascending
    /// ([`super::bench::paired`]'s method: the two back to back, each first in turn).
    pub paired: Vec<f64>,
    /// The rounds' medians of each side's frame, voxcube's then VTK's: which one moved.
    pub paired_medians: Option<(Duration, Duration)>,
}

/// What the sweep measured: voxcube's rows, VTK's where it ran, and why it did not.
#[derive(Clone, Debug)]
pub struct Scale {
    /// voxcube's frames.
    pub rows: Vec<ScaleRow>,
    /// VTK's, one per volume at the paper's image size.
    pub vtk: Vec<VtkRow>,
    /// Set when VTK was not run.
    pub vtk_missing: Option<String>,
}

impl ScaleRow {
    fn ns_per_sample(&self) -> f64 {
        self.median.as_secs_f64() * 1e9 / self.samples.max(1) as f64
    }

    /// The columns that name the row in every table: volume, image, tier and machine.
    fn head(&self) -> String {
        format!(
            "{:<9} {:<10} {:<6} {:<24}",
            self.dataset.label(self.volume),
            format!("{}x{}", self.image.0, self.image.1),
            self.tier,
            self.config
        )
    }

    fn us_per_pixel(&self) -> f64 {
        self.median.as_secs_f64() * 1e6 / f64::from(self.image.0 * self.image.1)
    }
}

/// The composited view of an `n`³ volume in `tier`: the paper's direction (azimuth 45°), the
/// camera placed outright (the scene's placeholder volume has another size) so the cube
/// fills about 86% of the image's width.
fn view(tier: &str, (width, height): (u32, u32), n: u32, dataset: Dataset) -> String {
    let c = (n - 1) as f32 / 2.0;
    let far = 2.0 * n as f32;
    let side = far * core::f32::consts::FRAC_1_SQRT_2;
    let eye = [c + side, c, c + side];
    let span = span(n);
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
{}"#,
        dataset.transfer()
    )
}

/// World units across the image for an `n`³ volume: its diagonal seen from 45° (`n·√2`) fills
/// about 86% of it.
fn span(n: u32) -> f32 {
    1.65 * n as f32
}

/// VTK's median frame of `volume` (the molecule or the head on `n`³) framed as [`view`]
/// frames it at the paper's image size, `runs` renders after a first, and its image's PSNR
/// against `ours`; then `runs` paired rounds ([`run_paired`]) of VTK's median of
/// [`PAIR_FRAMES`] frames against the median of as many of voxcube's `frame_ours`.
fn vtk_on(
    (dataset, volume): (Dataset, &Volume),
    n: u32,
    runs: usize,
    ours: &[[u8; 4]],
    mut frame_ours: impl FnMut() -> Result<Duration, String>,
) -> Result<Option<VtkRow>, String> {
    let dims = volume.grid.dims();
    let peer = match (&volume.data, dataset) {
        (VolumeData::U8(samples), Dataset::Molecule) => {
            Peer::of_samples(&to_file_order(samples, dims), dims)?
        }
        (VolumeData::I16(samples), Dataset::Head) => {
            Peer::of_i16(&to_file_order(samples, dims), dims)?
                .map(|p| p.with_transfer(&HEAD_TRANSFER))
        }
        _ => return Err(format!("the scale sweep's {dataset:?} is not of its kind")),
    };
    let Some(peer) = peer else {
        return Ok(None);
    };
    let (width, height) = IMAGES[0];
    let frame = Frame {
        width,
        height,
        dt: 0.5,
        span: span(n),
    };
    let mode = PeerMode::Composite;
    let r = peer.render(Request { mode, frame, runs }, true)?;
    let psnr = r
        .pixels
        .as_deref()
        .map_or(f64::NAN, |p| super::accuracy::compare(p, ours).0);
    let request = Request {
        mode,
        frame,
        runs: PAIR_FRAMES,
    };
    let mut ours = || median_frame(&mut frame_ours);
    let mut theirs = || peer.render(request, false).map(|r| r.median);
    let rounds = run_paired(runs, &mut theirs, &mut ours)?;
    let paired = sorted_ratios(rounds.iter().map(seconds));
    let (mine, vtk): (Vec<_>, Vec<_>) = rounds.into_iter().unzip();
    let paired_medians = Some((median(mine), median(vtk)));
    Ok(Some(VtkRow {
        dataset,
        volume: n,
        median: r.median,
        psnr,
        paired,
        paired_medians,
    }))
}

/// Measure every volume size and every image size, both tiers, on one node and on every
/// core; `runs` renders of each (the median kept), interleaved across machines.
pub fn run(runs: usize, out: &mut String) -> Result<Scale, ExperimentError> {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get() as u32);
    let cores = cores.next_power_of_two();
    // This machine's memory shared by its cores' nodes, as VTK beside them has it: then a
    // node holds the node field of a 512³ volume (1 GiB of a byte volume's, 2 GiB of the
    // head's), which a modern cluster node (1 GiB) has no room for beside the volume. A
    // system that does not say its memory gets modern nodes.
    let modern = crate::memory::budget::Profile::builtin("modern")
        .ok_or_else(|| ExperimentError::Missing("the shipped modern profile is missing".into()))?;
    let host = crate::memory::budget::Profile::host(cores).unwrap_or(modern);
    let machines = [
        (
            "direct, 1 node".to_string(),
            Machine {
                profile: modern,
                ..Machine::new(Fabric::Direct, 1, 1, 1)
            },
        ),
        (
            format!("threads, {cores} clusters of 1 ({} nodes)", host.name),
            Machine {
                profile: host,
                ..Machine::new(Fabric::Threads, cores, cores, 1)
            },
        ),
    ];
    let molecule = |(n, image)| (Dataset::Molecule, n, image);
    let mut work: Vec<(Dataset, u32, (u32, u32))> =
        VOLUMES.iter().map(|&n| molecule((n, IMAGES[0]))).collect();
    work.extend(IMAGES[1..].iter().map(|&i| molecule((VOLUMES[0], i))));
    work.extend(HEADS.iter().map(|&n| (Dataset::Head, n, IMAGES[0])));
    let mut rows = Vec::new();
    let mut vtk = Vec::new();
    let vtk_missing = (!Path::new(super::peer::VENV_PYTHON).is_file()).then(|| {
        format!(
            "VTK is not installed ({} missing; peers/setup.sh installs it): its rows are left out",
            super::peer::VENV_PYTHON
        )
    });
    let mut volume: Option<(Dataset, Volume)> = None;
    for (dataset, n, image) in work {
        if volume
            .as_ref()
            .is_none_or(|(d, v)| *d != dataset || v.grid.dims()[0] != n)
        {
            // The one before is dropped first: two 512³ volumes and their fields are not
            // held at once.
            drop(volume.take());
            volume = Some((dataset, dataset.volume(n)));
        }
        let Some((_, volume)) = volume.as_ref() else {
            continue;
        };
        // A placeholder dataset carries the views through the scene checks; they are then
        // built on the resampled grid.
        let text = format!(
            "[[datasets]]\nname = \"m\"\nbuiltin = \"sphere\"\n{}{}",
            view("exact", image, n, dataset),
            view("fast", image, n, dataset)
        );
        let jobs = Scene::parse(&text, "<bench --scale>", Path::new("."))?.load()?;
        for v in jobs.iter().flat_map(|j| &j.views) {
            let spec = v.view.spec().clone();
            let built = voxcube_kernel::trace::view::View::new(spec, &volume.grid)
                .map_err(|e| ExperimentError::Asked(format!("scale sweep: {e}")))?;
            let mut times: Vec<Vec<(Duration, Duration)>> = vec![Vec::new(); machines.len()];
            let mut samples = vec![0; machines.len()];
            let mut first = Vec::new();
            for (_, machine) in &machines {
                first.push(render_on(volume, &built, machine)?.wall);
            }
            let mut pixels = Vec::new();
            for _ in 0..runs.max(1) {
                for (m, (_, machine)) in machines.iter().enumerate() {
                    let r = render_on(volume, &built, machine)?;
                    times[m].push((r.wall, r.setup.unwrap_or_default()));
                    samples[m] = r.counters.samples;
                    pixels = r.pixels;
                }
            }
            if v.name == "fast" && image == IMAGES[0] && vtk_missing.is_none() {
                let every_core = &machines[1].1;
                let frame = || {
                    render_on(volume, &built, every_core)
                        .map(|r| r.wall)
                        .map_err(|e| e.to_string())
                };
                let row = vtk_on((dataset, volume), n, runs, &pixels, frame)
                    .map_err(ExperimentError::Missing)?;
                let label = dataset.label(n);
                if let Some(row) = row {
                    let _ = writeln!(
                        out,
                        "measured {label} VTK: {:.1} ms",
                        row.median.as_secs_f64() * 1e3
                    );
                    if let Some((ours, theirs)) = row.paired_medians {
                        let _ = writeln!(
                            out,
                            "paired {label}: the fast tier {:.1} ms against VTK's {:.1} ms (medians of the rounds)",
                            ours.as_secs_f64() * 1e3,
                            theirs.as_secs_f64() * 1e3
                        );
                    }
                    vtk.push(row);
                }
            }
            // Apart from the timed frames: the profiler's signals would be in their time.
            let mut profiles = Vec::new();
            for (config, machine) in &machines {
                let frame = || render_on(volume, &built, machine).map(drop);
                profiles.push(phases::noted(out, &format!("{} {config}", v.name), frame));
            }
            let measured = machines.iter().zip(times).zip(samples).zip(first);
            for (((((config, machine), mut t), samples), first), phases) in measured.zip(profiles) {
                t.sort();
                let (median, setup) = t[t.len() / 2];
                let row = ScaleRow {
                    dataset,
                    volume: n,
                    image,
                    tier: if v.name == "fast" { "fast" } else { "exact" },
                    config: config.clone(),
                    every_core: machine.fabric == Fabric::Threads,
                    median,
                    first,
                    setup,
                    samples,
                    phases,
                };
                let _ = writeln!(
                    out,
                    "measured {} {}x{} {} on {}: {:.1} ms",
                    dataset.label(n),
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
    Ok(Scale {
        rows,
        vtk,
        vtk_missing,
    })
}

/// The table: each row's time, samples, time per sample and per pixel, and its growth over
/// the first row of the same tier, machine and sweep; then VTK's frame of each volume beside
/// voxcube's on every core.
pub fn table(scale: &Scale, runs: usize) -> String {
    let rows = &scale.rows;
    let mut out = format!(
        "How the cost grows (composited molecule resampled to n³, dt 1/2, the cube across 86% of the width; medians of {runs} frames after the first, which builds what the volume keeps; set-up: of the median frame, before any ray):\n{:<9} {:<10} {:<6} {:<24} {:>10} {:>10} {:>10} {:>10} {:>10} {:>10} {:>9} {:>9}\n",
        "volume", "image", "tier", "machine", "first ms", "ms", "set-up ms", "samples", "ns/sample", "us/pixel", "time x", "samples x"
    );
    for sweep in ["volume", "image", "head"] {
        let _ = match sweep {
            "head" => writeln!(
                out,
                "-- the CT-like head (i16, Hounsfield units; skin and bone), growing the volume"
            ),
            _ => writeln!(out, "-- growing the {sweep}"),
        };
        let in_sweep = |r: &&ScaleRow| match sweep {
            "volume" => r.dataset == Dataset::Molecule && r.image == IMAGES[0],
            "image" => r.dataset == Dataset::Molecule && r.volume == VOLUMES[0],
            _ => r.dataset == Dataset::Head,
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
                "{} {:>10.1} {:>10.1} {:>10.1} {:>10} {:>10.2} {:>10.3} {:>9.2} {:>9.2}",
                r.head(),
                r.first.as_secs_f64() * 1e3,
                r.median.as_secs_f64() * 1e3,
                r.setup.as_secs_f64() * 1e3,
                r.samples,
                r.ns_per_sample(),
                r.us_per_pixel(),
                tx,
                sx
            );
        }
    }
    out.push_str(&where_it_goes(rows));
    out.push_str(&beside_vtk(scale));
    out
}

/// Each row's median frame by phase: its set-up as the frame timed it, and the rest
/// apportioned by the shares of a sampling profile of the threads tracing its rays
/// ([`phases`]), in the order of the growth table.
fn where_it_goes(rows: &[ScaleRow]) -> String {
    let mut out = format!(
        "-- where a frame's time goes, ms of the median frame: {} (samples: how many)\n{:<9} {:<10} {:<6} {:<24} {}\n",
        phases::method(),
        "volume",
        "image",
        "tier",
        "machine",
        phases::column_heads()
    );
    for r in rows {
        if let Some(p) = &r.phases {
            let _ = writeln!(
                out,
                "{} {}",
                r.head(),
                phases::columns(p, r.median, r.setup)
            );
        }
    }
    out
}

/// voxcube on every core (threads) against VTK on two threads, per volume at the paper's
/// image size, and each one's growth over the first of its dataset's sweep.
fn beside_vtk(scale: &Scale) -> String {
    if let Some(why) = &scale.vtk_missing {
        return format!("-- beside VTK: {why}\n");
    }
    let mut out = format!(
        "-- beside VTK (vtkFixedPointVolumeRayCastMapper, 2 threads, the same view and run) at {}x{}\n{:<9} {:>10} {:>9} {:>10} {:>10} {:>10} {:>10} {:>12} {:>24}\n",
        IMAGES[0].0, IMAGES[0].1, "volume", "VTK ms", "VTK x", "fast ms", "fast/VTK", "exact ms", "exact/VTK", "PSNR vs VTK", "fast/VTK paired"
    );
    for v in &scale.vtk {
        let first = scale
            .vtk
            .iter()
            .find(|f| f.dataset == v.dataset)
            .map(|f| f.median.as_secs_f64());
        let ours = |tier: &str| {
            scale
                .rows
                .iter()
                .find(|r| {
                    r.dataset == v.dataset
                        && r.volume == v.volume
                        && r.image == IMAGES[0]
                        && r.tier == tier
                        && r.every_core
                })
                .map_or(f64::NAN, |r| r.median.as_secs_f64())
        };
        let vtk = v.median.as_secs_f64();
        let (fast, exact) = (ours("fast"), ours("exact"));
        let paired = spread(&v.paired).map_or("-".into(), |(mid, least, most)| {
            format!("{mid:.2} ({least:.2}-{most:.2})")
        });
        let _ = writeln!(
            out,
            "{:<9} {:>10.1} {:>9.2} {:>10.1} {:>10.2} {:>10.1} {:>10.2} {:>9.1} dB {:>24}",
            v.dataset.label(v.volume),
            vtk * 1e3,
            first.map_or(f64::NAN, |f| vtk / f),
            fast * 1e3,
            fast / vtk,
            exact * 1e3,
            exact / vtk,
            v.psnr,
            paired
        );
    }
    out += "fast/VTK paired: the fast tier on every core over VTK in paired rounds (each side's \
            median of three frames, back to back, each first in turn), median (least-most); the \
            other ratios set medians taken minutes apart side by side\n";
    out
}

/// Two panels over the volume sweep at the paper's image size: each renderer's milliseconds
/// per frame, and voxcube's nanoseconds per evaluated sample (VTK counts no samples).
pub fn plot(path: &Path, scale: &Scale) -> Result<(), String> {
    let root = SVGBackend::new(path, (1100, 440)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let (left, right) = root.split_horizontally(550);
    let swept: Vec<&ScaleRow> = scale.rows.iter().filter(|r| r.image == IMAGES[0]).collect();
    let series = |dataset: Dataset,
                  tier: &str,
                  every_core: bool,
                  y: &dyn Fn(&ScaleRow) -> f64|
     -> Vec<(f64, f64)> {
        swept
            .iter()
            .filter(|r| r.dataset == dataset && r.tier == tier && r.every_core == every_core)
            .map(|r| (f64::from(r.volume), y(r)))
            .collect()
    };
    let ms = |r: &ScaleRow| r.median.as_secs_f64() * 1e3;
    let ns = |r: &ScaleRow| r.ns_per_sample();
    let edge = f64::from(VOLUMES[VOLUMES.len() - 1]);
    for (area, caption, unit, y) in [
        (
            &left,
            "ms per frame (a further frame)",
            "ms",
            &ms as &dyn Fn(&ScaleRow) -> f64,
        ),
        (&right, "ns per evaluated sample (voxcube)", "ns", &ns),
    ] {
        let (molecule, head) = (Dataset::Molecule, Dataset::Head);
        let mut lines = vec![
            ("fast, every core", molecule, "fast", true, GREEN),
            ("exact, every core", molecule, "exact", true, BLUE),
            ("fast, one node", molecule, "fast", false, CYAN),
            ("exact, one node", molecule, "exact", false, MAGENTA),
            (
                "head fast, every core",
                head,
                "fast",
                true,
                RGBColor(0, 110, 0),
            ),
            (
                "head fast, one node",
                head,
                "fast",
                false,
                RGBColor(0, 140, 140),
            ),
        ]
        .into_iter()
        .map(|(label, dataset, tier, every_core, colour)| Line {
            points: series(dataset, tier, every_core, y),
            colour,
            label: format!("voxcube {label}"),
        })
        .filter(|l| !l.points.is_empty())
        .collect::<Vec<_>>();
        for (dataset, colour, label) in [
            (molecule, RED, "VTK, 2 threads"),
            (head, RGBColor(150, 0, 0), "VTK head, 2 threads"),
        ] {
            let points: Vec<(f64, f64)> = scale
                .vtk
                .iter()
                .filter(|v| v.dataset == dataset)
                .map(|v| (f64::from(v.volume), v.median.as_secs_f64() * 1e3))
                .collect();
            if unit == "ms" && !points.is_empty() {
                lines.push(Line {
                    points,
                    colour,
                    label: label.into(),
                });
            }
        }
        let top = lines
            .iter()
            .flat_map(|l| l.points.iter().map(|p| p.1))
            .filter(|y| y.is_finite())
            .fold(1.0f64, f64::max);
        let mut chart = chart::linear(
            area,
            &format!("{caption}, {}x{}", IMAGES[0].0, IMAGES[0].1),
            ("volume edge n (n³ samples)", unit),
            (edge, top),
        )?;
        // The lines rise to the right: the upper left is free.
        chart::draw_at(&mut chart, lines, SeriesLabelPosition::UpperLeft)?;
    }
    root.present().map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::phases::Phase;
    use super::*;

    /// The profile of a real frame: the molecule at 64³ composited in the fast tier on one
    /// node, profiled for a while. Its samples fall in the frame's own phases (the controls
    /// that the classification sees the kernel's inlined source are `phases`' own tests);
    /// shares are not asserted, they move with the machine.
    #[test]
    fn a_profiled_frame_s_samples_fall_in_its_phases() {
        let volume = Dataset::Molecule.volume(64);
        let text = format!(
            "[[datasets]]\nname = \"m\"\nbuiltin = \"sphere\"\n{}",
            view("fast", IMAGES[0], 64, Dataset::Molecule)
        );
        let jobs = Scene::parse(&text, "<test>", Path::new("."))
            .and_then(Scene::load)
            .expect("the sweep's view parses");
        let spec = jobs[0].views[0].view.spec().clone();
        let view = voxcube_kernel::trace::view::View::new(spec, &volume.grid).expect("view");
        let machine = Machine {
            profile: crate::memory::budget::Profile::builtin("modern").expect("modern"),
            ..Machine::new(Fabric::Direct, 1, 1, 1)
        };
        let p = phases::profile(Duration::from_millis(600), || {
            render_on(&volume, &view, &machine).map(drop)
        })
        .expect("the profiler runs");
        assert!(p.total() > 0, "no samples in 0.6 s of frames");
        let frame = [
            Phase::Rays,
            Phase::Skipping,
            Phase::Sampling,
            Phase::Compositing,
        ];
        let in_frame: u64 = frame.iter().map(|&f| p.count(f)).sum();
        assert!(
            2 * in_frame > p.total(),
            "most samples of a frame's loop are outside its phases: {p:?}"
        );
    }

    fn row(volume: u32, tier: &'static str, config: &str, ms: u64) -> ScaleRow {
        ScaleRow {
            dataset: Dataset::Molecule,
            volume,
            image: IMAGES[0],
            tier,
            config: config.into(),
            every_core: config.starts_with("threads"),
            median: Duration::from_millis(ms),
            first: Duration::from_millis(ms),
            setup: Duration::ZERO,
            samples: 1000,
            phases: None,
        }
    }

    #[test]
    fn vtk_is_compared_with_every_core_at_the_same_volume_and_grows_from_its_first() {
        let scale = Scale {
            rows: vec![
                row(128, "fast", "direct, 1 node", 90),
                row(128, "fast", "threads, 2 clusters of 1", 50),
                row(128, "exact", "threads, 2 clusters of 1", 100),
                row(256, "fast", "threads, 2 clusters of 1", 60),
                row(256, "exact", "threads, 2 clusters of 1", 240),
                // The head's rows, at sizes the molecule's share: compared apart.
                ScaleRow {
                    dataset: Dataset::Head,
                    ..row(256, "fast", "threads, 2 clusters of 1", 80)
                },
                ScaleRow {
                    dataset: Dataset::Head,
                    ..row(512, "fast", "threads, 2 clusters of 1", 200)
                },
            ],
            vtk: vec![
                VtkRow {
                    dataset: Dataset::Molecule,
                    volume: 128,
                    median: Duration::from_millis(100),
                    psnr: 30.0,
                    paired: vec![0.4, 0.55, 0.7],
                    paired_medians: None,
                },
                VtkRow {
                    dataset: Dataset::Molecule,
                    volume: 256,
                    median: Duration::from_millis(300),
                    psnr: 31.0,
                    paired: vec![],
                    paired_medians: None,
                },
                VtkRow {
                    dataset: Dataset::Head,
                    volume: 256,
                    median: Duration::from_millis(200),
                    psnr: 25.0,
                    paired: vec![0.3],
                    paired_medians: None,
                },
                VtkRow {
                    dataset: Dataset::Head,
                    volume: 512,
                    median: Duration::from_millis(500),
                    psnr: 26.0,
                    paired: vec![],
                    paired_medians: None,
                },
            ],
            vtk_missing: None,
        };
        let text = beside_vtk(&scale);
        let line = |n: &str| {
            text.lines()
                .find(|l| l.starts_with(n))
                .map(|l| l.split_whitespace().collect::<Vec<_>>())
                .unwrap_or_default()
        };
        // volume, VTK ms, VTK x, fast ms, fast/VTK, exact ms, exact/VTK, PSNR, dB, paired
        assert_eq!(
            line("128³"),
            [
                "128³",
                "100.0",
                "1.00",
                "50.0",
                "0.50",
                "100.0",
                "1.00",
                "30.0",
                "dB",
                "0.55",
                "(0.40-0.70)"
            ]
        );
        assert_eq!(
            line("256³"),
            ["256³", "300.0", "3.00", "60.0", "0.20", "240.0", "0.80", "31.0", "dB", "-"]
        );
        // The head grows from its own first volume and has no exact row here.
        assert_eq!(
            line("head 256³"),
            [
                "head",
                "256³",
                "200.0",
                "1.00",
                "80.0",
                "0.40",
                "NaN",
                "NaN",
                "25.0",
                "dB",
                "0.30",
                "(0.30-0.30)"
            ]
        );
        assert_eq!(
            line("head 512³"),
            ["head", "512³", "500.0", "2.50", "200.0", "0.40", "NaN", "NaN", "26.0", "dB", "-"]
        );
        let missing = Scale {
            vtk: vec![],
            vtk_missing: Some("VTK is not installed".into()),
            ..scale
        };
        assert!(beside_vtk(&missing).contains("VTK is not installed"));
    }
}

//! `voxcube paper`: the experiments of the paper's Tables 1–4, in simulated nCUBE 2 time, each
//! printed beside the paper's numbers; speedup and efficiency plots; the image.
//!
//! Table 1 takes, for each node count, the best cluster size (as the paper's own times imply:
//! its 64- and 128-node rows are Table 2's best columns); it is the table the profile's two
//! constants are fitted on ([`crate::experiments::fit`]), and Tables 2–4 are held out. Its
//! one node is the paper's sequential tracer ([`sequential`]): the paper's node-seconds grow
//! 7% from one node to two in clusters of one, where every node runs the same work, which a
//! worker's per-sample slab test accounts for. Table 4 shows waiting as its own line, `idle`,
//! apart from the `ntest` calls that find work, and the primary rays' set-up as `generate`.
//!
//! Static load balancing follows the paper (see [`crate::run::balance`]): one cluster traces a
//! probe grid of primary rays, the workers' times set new slab sizes by the paper's formula,
//! and the new cuts are kept only if the probe runs faster with them. In the balanced runs
//! of Table 3 every node starts on its uniform slab and shifts planes to its neighbours in
//! slab-plane messages before rendering; the simulated time includes that shift.

use super::chart::{self, Line};
use super::error::ExperimentError;
pub use super::runs::{sequential, timed, traced};
use super::sod::{paper_surface_view, sod_source, SOD_FILE, SOD_ISO};
use crate::fabric::sim;
use crate::fabric::Category;
use crate::fabric::RunConfig;
use crate::fabric::RunError;
use crate::input::scene::{DatasetJob, Scene};
use crate::output::files::write_png;
use crate::profile::MachineProfile;
use crate::run::render::RenderError;
use plotters::prelude::*;
use std::fmt::Write as _;
use std::path::Path;
use voxcube_kernel::trace::view::View;

/// The paper's Table 1: nodes, seconds.
pub const TABLE1: [(u32, f64); 8] = [
    (1, 485.24),
    (2, 260.35),
    (4, 130.19),
    (8, 65.82),
    (16, 32.96),
    (32, 17.26),
    (64, 8.90),
    (128, 5.14),
];
/// The paper's Table 2: cluster sizes, then seconds at 64 and at 128 nodes.
pub const TABLE2: [(u32, f64, f64); 5] = [
    (16, 24.16, 12.32),
    (8, 17.16, 8.77),
    (4, 11.93, 6.70),
    (2, 10.10, 5.14),
    (1, 8.90, 6.42),
];
/// The paper's Table 3: cluster sizes, then balanced seconds at 64 and at 128 nodes.
pub const TABLE3: [(u32, f64, f64); 4] = [
    (16, 15.20, 7.94),
    (8, 12.26, 6.56),
    (4, 10.26, 6.04),
    (2, 9.27, 4.75),
];
/// The paper's Table 4: category, mean, min, max (percent of time), on one 16-node cluster.
pub const TABLE4: [(&str, f64, f64, f64); 6] = [
    ("ntest", 32.82, 0.77, 46.82),
    ("Interpolate", 31.48, 20.96, 55.55),
    ("Trace", 9.39, 6.60, 15.55),
    ("Voxel_Sample", 8.46, 5.60, 14.77),
    ("nread", 1.36, 1.02, 1.76),
    ("nwrite", 1.38, 0.83, 2.08),
];

/// Where the experiments take their volume from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Source<'a> {
    /// SOD: its file, or a folder holding [`SOD_FILE`]; an error if it is not there.
    Sod(&'a Path),
    /// The built-in molecule of SOD's size and character, asked for by name.
    Substitute,
}

impl Source<'_> {
    /// SOD's file: the one named, or [`SOD_FILE`] in the folder named; `None` for the
    /// substitute.
    pub fn file(&self) -> Option<std::path::PathBuf> {
        match self {
            Source::Sod(path) if path.is_dir() => Some(path.join(SOD_FILE)),
            Source::Sod(path) => Some(path.to_path_buf()),
            Source::Substitute => None,
        }
    }
}

/// The dataset: SOD from `source` (a missing file is an error), or the built-in substitute
/// when asked for (with a note).
pub fn dataset(source: Source<'_>, notes: &mut String) -> Result<DatasetJob, ExperimentError> {
    dataset_of(
        source,
        |iso| {
            paper_surface_view()
                .replace("NAME", "paper")
                .replace("ISO", iso)
        },
        notes,
    )
}

/// The dataset of [`dataset`] with the views `views` gives for the volume's iso value.
pub fn dataset_of(
    source: Source<'_>,
    views: impl FnOnce(&str) -> String,
    notes: &mut String,
) -> Result<DatasetJob, ExperimentError> {
    let (source, iso) = match (&source, source.file()) {
        (Source::Sod(path), Some(file)) => {
            if !file.is_file() {
                return Err(ExperimentError::NoSod(path.to_path_buf()));
            }
            (sod_source(&file), SOD_ISO)
        }
        _ => {
            let _ = writeln!(
                notes,
                "--substitute: using the built-in molecule of SOD's size and character"
            );
            // The default scene's iso value for the molecule.
            ("builtin = \"molecule\"".to_string(), "40.0")
        }
    };
    let text = format!("[[datasets]]\nname = \"sod\"\n{source}\n") + &views(iso);
    Ok(Scene::parse(&text, "<paper>", Path::new("."))?
        .load()?
        .remove(0))
}

/// The paper's static load balancing for one cluster of `size` (see [`crate::run::balance`]; the
/// paper's tracer had no empty-space skipping, and memory does not bind on SOD): the cuts.
pub fn balance(
    job: &DatasetJob,
    view: &View,
    profile: &MachineProfile,
    size: u32,
) -> Result<Vec<u32>, ExperimentError> {
    let nx = job.volume.grid.dims()[0];
    let b = crate::run::balance::balance(
        &job.volume,
        view,
        profile,
        size,
        crate::memory::storage::SkipMode::OFF,
        nx,
    )?;
    Ok(b.after)
}

/// Each image row's work on one node, in simulated seconds: a run with one single-node
/// cluster per row (rows are interleaved over clusters), each node's time less its idling.
pub fn row_costs(
    job: &DatasetJob,
    view: &View,
    profile: &MachineProfile,
) -> Result<Vec<f64>, ExperimentError> {
    let height = view.spec().height;
    let clusters = height.next_power_of_two();
    let run = timed(job, view, profile, clusters, 1, None)?;
    // With clusters of one, node `r` is cluster `r` and renders row `r` alone.
    Ok(run.parts[..height as usize]
        .iter()
        .map(|p| {
            Category::ALL
                .iter()
                .filter(|&&c| c != Category::Idle)
                .map(|&c| p[c as usize])
                .sum()
        })
        .collect())
}

/// The least time `clusters` clusters of `size` nodes can take over rows of these costs:
/// the busiest cluster's rows (row `r` goes to cluster `r mod clusters`), split evenly over
/// its nodes with nothing lost to messages or imbalance.
pub fn cluster_bound(rows: &[f64], clusters: u32, size: u32) -> f64 {
    let m = clusters.max(1) as usize;
    let mut work = vec![0.0f64; m];
    for (r, cost) in rows.iter().enumerate() {
        work[r % m] += cost;
    }
    work.into_iter().fold(0.0, f64::max) / f64::from(size.max(1))
}

/// One slab's share of a ring's frame: its planes and its node's busy and idle seconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SlabWork {
    /// The slab's planes, `from..to` along x.
    pub planes: (u32, u32),
    /// Seconds the slab's node spent tracing, testing, reading and writing.
    pub busy: f64,
    /// Seconds it waited.
    pub idle: f64,
}

/// Each slab's work in one cluster of `size` nodes rendering the whole image, on uniform
/// slabs or on `cuts` (reached by the plane shift, whose time is included).
pub fn slab_work(
    job: &DatasetJob,
    view: &View,
    profile: &MachineProfile,
    size: u32,
    cuts: Option<Vec<u32>>,
) -> Result<Vec<SlabWork>, ExperimentError> {
    let nx = job.volume.grid.dims()[0];
    let planes: Vec<u32> = match &cuts {
        Some(cuts) => cuts.clone(),
        None => voxcube_kernel::node::partition::Partition::uniform(nx, size as usize)
            .map_err(RunError::from)?
            .cuts()
            .to_vec(),
    };
    if planes.len() != size as usize + 1 {
        return Err(ExperimentError::Missing(format!(
            "{} cuts for a ring of {size}",
            planes.len()
        )));
    }
    let time = timed(job, view, profile, 1, size, cuts)?;
    let parts = time.by_position(size).map_err(ExperimentError::Missing)?;
    Ok(parts
        .iter()
        .zip(planes.windows(2))
        .map(|(part, cut)| {
            let idle = part[Category::Idle as usize];
            SlabWork {
                planes: (cut[0], cut[1]),
                busy: part.iter().sum::<f64>() - idle,
                idle,
            }
        })
        .collect())
}

/// One line of Table 4: a category's share of the frame, percent, over the ring's nodes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Share {
    /// The paper's name for it (`generate` and `idle` are not among the paper's lines).
    pub name: &'static str,
    /// Mean over the nodes.
    pub mean: f64,
    /// The least node's.
    pub min: f64,
    /// The most node's.
    pub max: f64,
}

/// Table 4: one cluster of 16 renders the whole view; each category's share of the frame on
/// its nodes, in the paper's order, then `generate` and `idle`. Also the frame's seconds.
pub fn table_4(
    job: &DatasetJob,
    view: &View,
    profile: &MachineProfile,
) -> Result<(f64, Vec<Share>), ExperimentError> {
    let sixteen = timed(job, view, profile, 1, 16, None)?;
    let lines = [
        Category::Test,
        Category::Interpolate,
        Category::Trace,
        Category::SampleShade,
        Category::Read,
        Category::Write,
        Category::Generate,
        Category::Idle,
    ];
    let shares = lines
        .iter()
        .map(|&category| {
            let v: Vec<f64> = sixteen
                .parts
                .iter()
                .map(|p| 100.0 * p[category as usize] / sixteen.frame)
                .collect();
            Share {
                name: category.name(),
                mean: v.iter().sum::<f64>() / v.len().max(1) as f64,
                min: v.iter().copied().fold(f64::INFINITY, f64::min),
                max: v.iter().copied().fold(0.0, f64::max),
            }
        })
        .collect();
    Ok((sixteen.frame, shares))
}

/// Run every experiment; append the tables to `out`, write plots and the image to `dir`.
/// With `fit`, the profile's two constants are first fitted on Table 1
/// ([`crate::experiments::fit`]) and every table uses the fitted profile.
pub fn run(
    job: &DatasetJob,
    profile: &MachineProfile,
    dir: &Path,
    out: &mut String,
    fit: bool,
) -> Result<(), ExperimentError> {
    let view = &job.views[0].view;
    std::fs::create_dir_all(dir).map_err(|e| output(dir, e))?;
    let fitted;
    let (profile, fitted_times) = if fit {
        let f = crate::experiments::fit::fit(job, view, profile, &TABLE1)?;
        let _ = writeln!(
            out,
            "Fit on Table 1 alone ({} evaluations of its {} node counts, every cluster size each): scale {:.4} (was {}), message_scale {:.4} (was {}); rms log-time error {:.3}.{}\n",
            f.evaluations,
            TABLE1.len(),
            f.profile.scale,
            profile.scale,
            f.profile.message_scale,
            profile.message_scale,
            f.rms,
            if f.at_bound {
                " message_scale is at its search bound: Table 1 asks for message software outside the range the machine's documentation allows."
            } else {
                ""
            }
        );
        fitted = f.profile;
        (&fitted, Some(f.times))
    } else {
        (profile, None)
    };
    let _ = writeln!(
        out,
        "Machine {}: scale {} on the tracer's compute, message_scale {} on the message primitives' software ({}).\n",
        profile.name,
        profile.scale,
        profile.message_scale,
        if fit {
            "fitted above"
        } else {
            "as the profile gives them; `voxcube paper --fit` fits them on Table 1"
        }
    );
    // The fit's last evaluation already timed every shape under the fitted profile.
    let times = match fitted_times {
        Some(times) => times,
        None => {
            let nodes: Vec<u32> = TABLE1.iter().map(|r| r.0).collect();
            crate::experiments::fit::shapes(job, view, profile, &nodes)?
        }
    };
    let t1 = times
        .get(&(1, 1))
        .copied()
        .ok_or_else(|| ExperimentError::Missing("no 1-node time".into()))?;
    let _ = writeln!(
        out,
        "Table 1: times (s), speedup and efficiency with increasing nodes (best cluster size); the fitted table"
    );
    let _ = writeln!(
        out,
        "{:>6} {:>9} {:>9} {:>8} {:>8} {:>9} {:>9} {:>8} {:>7}",
        "nodes", "cluster", "voxcube", "speedup", "effic.", "paper", "speedup", "effic.", "error"
    );
    let mut series = Vec::new();
    let mut fit_rows = Vec::new();
    for (p, paper) in TABLE1 {
        let (cs, t) = crate::experiments::fit::best(&times, p).unwrap_or((1, t1));
        let (speedup, eff) = (t1 / t, t1 / t / f64::from(p));
        let (psp, peff) = (TABLE1[0].1 / paper, TABLE1[0].1 / paper / f64::from(p));
        let flag = if (eff - peff).abs() > 0.05 { " *" } else { "" };
        let _ = writeln!(
            out,
            "{p:>6} {cs:>9} {t:>9.2} {speedup:>8.2} {eff:>8.2} {paper:>9.2} {psp:>9.2} {peff:>8.2} {:>+6.1}%{flag}",
            100.0 * (t / paper - 1.0)
        );
        series.push((f64::from(p), speedup, eff, psp, peff));
        fit_rows.push(crate::experiments::fit::Row {
            nodes: p,
            size: cs,
            model: t,
            paper,
        });
    }
    let _ = writeln!(
        out,
        "(1 node: the sequential tracer, without the workers' slab test on every sample; error: time against the paper's;\n * efficiency departs from the paper's by more than 0.05; rms log-time error {:.3})\n",
        crate::experiments::fit::rms(&fit_rows)
    );
    let _ = writeln!(
        out,
        "Table 2 (held out): times (s) and efficiency with decreasing cluster size"
    );
    let _ = writeln!(
        out,
        "{:>8} {:>10} {:>7} {:>7} {:>9} {:>10} {:>7} {:>7} {:>9}",
        "cluster", "64 nodes", "effic.", "bound", "paper", "128 nodes", "effic.", "bound", "paper"
    );
    let rows = row_costs(job, view, profile)?;
    let mut held = Vec::new();
    for (cs, p64, p128) in TABLE2 {
        let (a, b) = (times[&(64, cs)], times[&(128, cs)]);
        let _ = writeln!(
            out,
            "{cs:>8} {a:>10.2} {:>7.2} {:>7.2} {p64:>9.2} {b:>10.2} {:>7.2} {:>7.2} {p128:>9.2}",
            t1 / a / 64.0,
            cluster_bound(&rows, 64 / cs, cs),
            t1 / b / 128.0,
            cluster_bound(&rows, 128 / cs, cs),
        );
        for (model, paper) in [(a, p64), (b, p128)] {
            held.push(crate::experiments::fit::Row {
                nodes: 0,
                size: cs,
                model,
                paper,
            });
        }
    }
    // Per column of Table 2: the best cluster size and how much slower the slowest one is.
    let column = |p: u32, paper: fn(&(u32, f64, f64)) -> f64| {
        let model = TABLE2.iter().map(|r| (r.0, times[&(p, r.0)]));
        let ours = model.clone().min_by(|a, b| a.1.total_cmp(&b.1));
        let theirs = TABLE2.iter().min_by(|a, b| paper(a).total_cmp(&paper(b)));
        let spread = |best: f64, worst: f64| worst / best.max(1e-12);
        (
            ours.map_or(0, |b| b.0),
            theirs.map_or(0, |b| b.0),
            spread(
                ours.map_or(1.0, |b| b.1),
                model.map(|m| m.1).fold(0.0, f64::max),
            ),
            spread(
                theirs.map_or(1.0, paper),
                TABLE2.iter().map(paper).fold(0.0, f64::max),
            ),
        )
    };
    let (c64, c128) = (column(64, |r| r.1), column(128, |r| r.2));
    let _ = writeln!(
        out,
        "held out: rms log-time error {:.3}; best cluster size at 64 nodes {} (paper {}), at 128 {} (paper {}); the slowest size takes {:.2}x the best at 64, {:.2}x at 128 (paper {:.2}x, {:.2}x)",
        crate::experiments::fit::rms(&held),
        c64.0,
        c64.1,
        c128.0,
        c128.1,
        c64.2,
        c128.2,
        c64.3,
        c128.3,
    );
    let (lo, hi) = rows
        .iter()
        .filter(|&&c| c > 0.1 * t1 / rows.len() as f64)
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), &c| {
            (lo.min(c), hi.max(c))
        });
    let _ = writeln!(
        out,
        "(bound: the busiest cluster's rows, each timed alone on one node, split evenly over its nodes\n with no message cost; rows the volume covers take {lo:.2} to {hi:.2} s)"
    );
    let _ = writeln!(out, "\nTable 3 (held out): times (s) without and with static load balancing (balanced: the plane shift by message included); gain = 1 - balanced/standard");
    let _ = writeln!(
        out,
        "{:>8} {:>9} {:>9} {:>6} {:>6} {:>10} {:>9} {:>6} {:>6}",
        "cluster", "64 std", "64 bal", "gain", "paper", "128 std", "128 bal", "gain", "paper"
    );
    let mut ring_cuts = None;
    for (cs, p64, p128) in TABLE3 {
        let cuts = balance(job, view, profile, cs)?;
        let a = timed(job, view, profile, 64 / cs, cs, Some(cuts.clone()))?.frame;
        let b = timed(job, view, profile, 128 / cs, cs, Some(cuts.clone()))?.frame;
        let (s64, s128) = (times[&(64, cs)], times[&(128, cs)]);
        let paper2 = TABLE2
            .iter()
            .find(|r| r.0 == cs)
            .map_or((1.0, 1.0), |r| (r.1, r.2));
        let _ = writeln!(
            out,
            "{cs:>8} {s64:>9.2} {a:>9.2} {:>5.0}% {:>5.0}% {s128:>10.2} {b:>9.2} {:>5.0}% {:>5.0}%   cuts {cuts:?}",
            100.0 * (1.0 - a / s64),
            100.0 * (1.0 - p64 / paper2.0),
            100.0 * (1.0 - b / s128),
            100.0 * (1.0 - p128 / paper2.1),
        );
        if cs == 16 {
            ring_cuts = Some(cuts);
        }
    }
    let uniform = slab_work(job, view, profile, 16, None)?;
    let balanced = slab_work(job, view, profile, 16, ring_cuts)?;
    let _ = writeln!(
        out,
        "\nThe ring of 16 alone (one cluster, every row): each slab's busy and idle seconds, uniform and balanced"
    );
    let _ = writeln!(
        out,
        "{:>4} {:>9} {:>8} {:>8}   {:>9} {:>8} {:>8}",
        "slab", "planes", "busy", "idle", "planes", "busy", "idle"
    );
    for (i, (u, b)) in uniform.iter().zip(&balanced).enumerate() {
        let _ = writeln!(
            out,
            "{i:>4} {:>9} {:>8.2} {:>8.2}   {:>9} {:>8.2} {:>8.2}",
            format!("{}..{}", u.planes.0, u.planes.1),
            u.busy,
            u.idle,
            format!("{}..{}", b.planes.0, b.planes.1),
            b.busy,
            b.idle
        );
    }
    let spread = |w: &[SlabWork]| {
        let max = w.iter().map(|s| s.busy).fold(0.0, f64::max);
        let mean = w.iter().map(|s| s.busy).sum::<f64>() / w.len().max(1) as f64;
        max / mean.max(1e-12)
    };
    let _ = writeln!(
        out,
        "busiest slab / mean: {:.2} uniform, {:.2} balanced",
        spread(&uniform),
        spread(&balanced)
    );
    plot_slabs(dir, &uniform, &balanced)?;
    let (frame, shares) = table_4(job, view, profile)?;
    let _ = writeln!(
        out,
        "\nTable 4 (held out): profile of one 16-node cluster, percent of the frame time ({frame:.2} s); idle is waiting, apart from ntest",
    );
    let _ = writeln!(
        out,
        "{:<13} {:>7} {:>7} {:>7}   {:>7} {:>7} {:>7}",
        "", "mean", "min", "max", "paper", "min", "max"
    );
    for share in &shares {
        let (name, mean, min, max) = (share.name, share.mean, share.min, share.max);
        match TABLE4.iter().find(|r| r.0 == name) {
            Some((_, pm, pn, px)) => {
                let _ = writeln!(
                    out,
                    "{name:<13} {mean:>7.2} {min:>7.2} {max:>7.2}   {pm:>7.2} {pn:>7.2} {px:>7.2}"
                );
            }
            None => {
                let _ = writeln!(out, "{name:<13} {mean:>7.2} {min:>7.2} {max:>7.2}");
            }
        }
    }
    plot(dir, &series)?;
    let image = sim::run(
        &job.volume,
        view,
        &RunConfig::cluster(1, 1).map_err(RenderError::from)?,
    )?;
    let spec = view.spec();
    let bytes: Vec<u8> = image.pixels.iter().flatten().copied().collect();
    let png = dir.join("sod-paper.png");
    write_png(&png, spec.width, spec.height, &bytes).map_err(|e| output(&png, e))?;
    let tables = dir.join("tables.txt");
    std::fs::write(&tables, out.as_bytes()).map_err(|e| output(&tables, e))?;
    let _ = writeln!(
        out,
        "\nwrote {}/tables.txt, speedup.svg, efficiency.svg, slabs.svg, sod-paper.png",
        dir.display()
    );
    Ok(())
}

/// Each slab's busy seconds in the ring of 16, uniform and balanced.
fn plot_slabs(
    dir: &Path,
    uniform: &[SlabWork],
    balanced: &[SlabWork],
) -> Result<(), ExperimentError> {
    let path = dir.join("slabs.svg");
    let err = |e: String| output(&path, e);
    let root = SVGBackend::new(&path, (640, 420)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
    let top = uniform
        .iter()
        .chain(balanced)
        .map(|s| s.busy)
        .fold(0.0, f64::max)
        * 1.1;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            "A ring of 16 on SOD: each slab's busy time",
            ("sans-serif", 18),
        )
        .margin(12)
        .x_label_area_size(36)
        .y_label_area_size(48)
        .build_cartesian_2d(-0.5f64..(uniform.len() as f64 - 0.5), 0f64..top.max(1e-9))
        .map_err(|e| err(e.to_string()))?;
    chart
        .configure_mesh()
        .x_desc("slab (ring position, front to back along x)")
        .y_desc("busy seconds")
        .draw()
        .map_err(|e| err(e.to_string()))?;
    let lines = [
        (uniform, RED, "uniform slabs"),
        (balanced, BLUE, "balanced slabs"),
    ]
    .map(|(work, colour, label)| Line {
        points: work
            .iter()
            .enumerate()
            .map(|(i, s)| (i as f64, s.busy))
            .collect(),
        colour,
        label: label.into(),
    });
    chart::draw(&mut chart, lines.into()).map_err(err)?;
    root.present().map_err(|e| err(e.to_string()))?;
    Ok(())
}

/// An output at `path` not written, and why.
fn output(path: &Path, why: impl std::fmt::Display) -> ExperimentError {
    ExperimentError::Output {
        path: path.to_path_buf(),
        message: why.to_string(),
    }
}

/// Speedup and efficiency against nodes, voxcube beside the paper.
fn plot(dir: &Path, series: &[(f64, f64, f64, f64, f64)]) -> Result<(), ExperimentError> {
    for (file, title, ours, paper, top) in [
        (
            "speedup.svg",
            "Speedup on SOD (350x250, dt 1/2)",
            1usize,
            3usize,
            130.0,
        ),
        (
            "efficiency.svg",
            "Efficiency on SOD (350x250, dt 1/2)",
            2,
            4,
            1.05,
        ),
    ] {
        let path = dir.join(file);
        let err = |e: String| output(&path, e);
        let root = SVGBackend::new(&path, (640, 420)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(36)
            .y_label_area_size(48)
            .build_cartesian_2d((1f64..128f64).log_scale(), 0f64..top)
            .map_err(|e| err(e.to_string()))?;
        chart
            .configure_mesh()
            .x_desc("nodes")
            .draw()
            .map_err(|e| err(e.to_string()))?;
        let pick = |i: usize| {
            series
                .iter()
                .map(move |r| (r.0, [r.0, r.1, r.2, r.3, r.4][i]))
                .collect::<Vec<_>>()
        };
        let lines = vec![
            Line {
                points: pick(ours),
                colour: BLUE,
                label: "voxcube, simulated nCUBE 2".into(),
            },
            Line {
                points: pick(paper),
                colour: RED,
                label: "paper, Table 1".into(),
            },
        ];
        chart::draw(&mut chart, lines).map_err(err)?;
        root.present().map_err(|e| err(e.to_string()))?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_traced_row_keeps_every_node_s_timeline_and_a_bad_row_is_named() {
        let mut notes = String::new();
        let job = dataset(Source::Substitute, &mut notes).unwrap_or_else(|e| panic!("{e}"));
        let profile = MachineProfile::ncube2();
        let time = traced(&job, &profile, 4, 2).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(time.timeline.len(), 4);
        assert!(time.timeline.iter().all(|spans| !spans.is_empty()));
        // The untraced run keeps none, and takes the same virtual time.
        let plain =
            timed(&job, &job.views[0].view, &profile, 2, 2, None).unwrap_or_else(|e| panic!("{e}"));
        assert!(plain.timeline.iter().all(Vec::is_empty));
        assert_eq!(plain.frame, time.frame);
        let e = traced(&job, &profile, 6, 4)
            .map(|_| ())
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(e.contains("--trace 6/4"), "{e}");
    }

    #[test]
    fn a_ring_s_slabs_cover_the_planes_and_each_is_accounted_for_the_whole_frame() {
        let mut notes = String::new();
        let job = dataset(Source::Substitute, &mut notes).unwrap_or_else(|e| panic!("{e}"));
        let (view, profile) = (&job.views[0].view, MachineProfile::ncube2());
        let frame = timed(&job, view, &profile, 1, 4, None)
            .unwrap_or_else(|e| panic!("{e}"))
            .frame;
        let slabs = slab_work(&job, view, &profile, 4, None).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(slabs.len(), 4);
        assert_eq!(slabs[0].planes.0, 0);
        assert_eq!(slabs[3].planes.1, job.volume.grid.dims()[0]);
        assert!(slabs.windows(2).all(|w| w[0].planes.1 == w[1].planes.0));
        for s in &slabs {
            assert!(s.busy > 0.0, "{s:?}");
            // Every node is accounted for until the frame ends (and past it, when it still
            // hands in its statistics).
            assert!(s.busy + s.idle >= frame * (1.0 - 1e-9), "{s:?} in {frame}");
            assert!(s.busy < frame, "{s:?} in {frame}");
        }
        let cuts = vec![0, 20, 40, 60, job.volume.grid.dims()[0]];
        let given = slab_work(&job, view, &profile, 4, Some(cuts.clone()))
            .unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(given[1].planes, (20, 40));
        let e = slab_work(&job, view, &profile, 4, Some(vec![0, 97]))
            .map(|_| ())
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(e.contains("2 cuts for a ring of 4"), "{e}");
    }

    #[test]
    fn the_bound_is_the_busiest_cluster_s_rows_over_its_nodes() {
        let rows = [1.0, 2.0, 3.0, 4.0, 0.5];
        // Rows interleave: cluster 0 gets rows 0, 2, 4 (4.5); cluster 1 rows 1, 3 (6).
        assert_eq!(cluster_bound(&rows, 2, 1), 6.0);
        assert_eq!(cluster_bound(&rows, 2, 4), 1.5);
        assert_eq!(cluster_bound(&rows, 1, 5), 10.5 / 5.0);
        assert_eq!(cluster_bound(&rows, 8, 1), 4.0);
        assert_eq!(cluster_bound(&[], 4, 2), 0.0);
    }
}

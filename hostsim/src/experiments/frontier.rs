//! `voxcube accuracy --frontier`: for the error a user accepts, which renderer and which step
//! is fastest. SOD's paper view at 350×250, composited and as a surface, rendered in one run
//! by VTK's CPU ray caster ([`super::peer`]) and by voxcube's two tiers over a sweep of Δt
//! (composited also the fast tier pre-integrated, to show what integrating between samples
//! buys; on surfaces the exact tier with its crossings unrefined, to show what refining buys);
//! each image timed on every core (the median of several frames after a first) and measured
//! two ways: against its own renderer's converged image (Δt = 1/16; for voxcube, its tier's)
//! and against voxcube's exact one.
//!
//! Invariant: the images of one mode differ in the renderer and Δt only: the same camera,
//! size, transfer function or iso value, shading coefficients and light (VTK's headlight:
//! voxcube's views take a directional light along the camera's forward axis).

use super::accuracy::{compare, p99_error};
use super::bench::{
    cores, every_core_modern, median, median_frame, run_paired, sorted_ratios, spread, PAIR_FRAMES,
};
use super::chart::{self, Line};
use super::error::ExperimentError;
use super::paper::{dataset_of, Source};
use super::peer::{Frame, Peer, PeerMode, Request};
use super::sod::{composite, composite_through, sized, SURFACE_VIEW};
use crate::input::scene::DatasetJob;
use crate::run::render::{render_on, Machine};
use plotters::prelude::*;
use std::fmt::Write as _;
use std::path::Path;
use voxcube_kernel::optics::shade::Light;
use voxcube_kernel::trace::view::{Accuracy, Compositing, View};
use voxcube_kernel::Vec3;

/// The steps voxcube's tiers are rendered at, coarse to fine, in cell edges.
pub const STEPS: [f32; 10] = [2.0, 1.75, 1.5, 1.375, 1.25, 1.0, 0.75, 0.5, 0.25, 0.125];

/// The steps VTK is rendered at.
pub const VTK_STEPS: [f32; 5] = [2.0, 1.0, 0.5, 0.25, 0.125];

/// The step of every renderer's converged image.
pub const CONVERGED: f32 = 1.0 / 16.0;

/// The step of VTK's image the headline compares against: the paper's.
pub const VTK_HEADLINE_STEP: f32 = 0.5;

/// The issue's target for the composited view: the headline's time at most this fraction of
/// VTK's.
pub const TARGET: f64 = 0.33;

/// The 99th percentile over pixels of a pixel's largest channel difference, in 8-bit
/// levels, within which an image no longer changes: a level is what rounding a converged
/// colour can move. The percentile, not the maximum: a surface's silhouette keeps flipping a
/// few pixels between hit and miss at every step.
pub const UNCHANGED_LEVELS: u8 = 1;

/// Which view.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    /// Composited with SOD's transfer function.
    Composite,
    /// The iso-surface.
    Surface,
    /// Composited through a thin shell ([`SHELL_TRANSFER`]): opaque within four value units
    /// of one value, the transfer function's detail a step passes over. voxcube's only: the
    /// peer script composites SOD's own function.
    Shell,
}

impl Mode {
    /// Every view of the sweep, in the order it renders and reports them.
    pub const ALL: [Mode; 3] = [Mode::Composite, Mode::Surface, Mode::Shell];

    fn name(self) -> &'static str {
        match self {
            Mode::Composite => "composite",
            Mode::Surface => "surface",
            Mode::Shell => "shell",
        }
    }

    /// The peer's mode, where it renders this view.
    fn peer(self) -> Option<PeerMode> {
        match self {
            Mode::Composite => Some(PeerMode::Composite),
            Mode::Surface => Some(PeerMode::Surface),
            Mode::Shell => None,
        }
    }
}

/// The shell's transfer function: SOD's colours, opaque only within four value units of 50
/// (its surface view's iso value), so that a step of a cell or more passes over it between
/// two samples.
pub const SHELL_TRANSFER: &str = r#"[[datasets.views.transfer]]
value = 10.0
color = [0.2, 0.3, 0.8]
opacity = 0.0
[[datasets.views.transfer]]
value = 46.0
color = [0.9, 0.7, 0.3]
opacity = 0.0
[[datasets.views.transfer]]
value = 50.0
color = [0.9, 0.7, 0.3]
opacity = 0.6
[[datasets.views.transfer]]
value = 54.0
color = [0.9, 0.7, 0.3]
opacity = 0.0
[[datasets.views.transfer]]
value = 200.0
color = [1.0, 0.2, 0.1]
opacity = 0.0
"#;

/// Who rendered an image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Renderer {
    /// VTK's CPU ray caster.
    Vtk,
    /// voxcube in an accuracy tier.
    Voxcube(Accuracy),
    /// voxcube's exact tier with each surface crossing at its linear estimate, unrefined
    /// (`refine_steps = 0`): what the refinement buys, surfaces only.
    Unrefined,
    /// voxcube's fast tier compositing pre-integrated (`compositing = "pre-integrated"`),
    /// composited views only.
    PreIntegrated,
}

impl Renderer {
    fn name(self) -> String {
        match self {
            Renderer::Vtk => "VTK".into(),
            Renderer::Voxcube(tier) => format!("voxcube {}", tier.name()),
            Renderer::Unrefined => "voxcube unrefined".into(),
            Renderer::PreIntegrated => "voxcube pre-int.".into(),
        }
    }

    /// voxcube's renderers of `mode`: each tier, composited views also pre-integrated, and
    /// on surfaces the unrefined crossing.
    fn voxcube(mode: Mode) -> &'static [Renderer] {
        const BOTH: [Renderer; 2] = [
            Renderer::Voxcube(Accuracy::Exact),
            Renderer::Voxcube(Accuracy::Fast),
        ];
        const COMPOSITE: [Renderer; 3] = [BOTH[0], BOTH[1], Renderer::PreIntegrated];
        const SURFACE: [Renderer; 3] = [BOTH[0], BOTH[1], Renderer::Unrefined];
        match mode {
            Mode::Composite | Mode::Shell => &COMPOSITE,
            Mode::Surface => &SURFACE,
        }
    }
}

/// One image of the sweep.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point {
    /// Which view.
    pub mode: Mode,
    /// Who rendered it.
    pub renderer: Renderer,
    /// Its step, in cell edges.
    pub dt: f32,
    /// Median milliseconds per frame on every core.
    pub ms: f64,
    /// PSNR (dB) against its own renderer's converged image (infinite when identical).
    pub own: f64,
    /// The 99th percentile over pixels of a pixel's largest channel difference from that
    /// image, 8-bit levels.
    pub own_p99: u8,
    /// The largest difference in any channel from that image, 8-bit levels.
    pub own_max: u8,
    /// PSNR (dB) against voxcube's exact converged image.
    pub reference: f64,
}

/// The frontier's answer for one mode: VTK at the paper's step, and the voxcube image a user
/// accepting VTK's error there would render: [`headline`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Headline {
    /// VTK at [`VTK_HEADLINE_STEP`].
    pub vtk: Point,
    /// Of each voxcube renderer's coarsest step with `own` at least VTK's, the fastest;
    /// `None` where no step is that close.
    pub best: Option<Point>,
}

impl Headline {
    /// The best point's time over VTK's.
    pub fn ratio(&self) -> Option<f64> {
        self.best.map(|b| b.ms / self.vtk.ms)
    }
}

/// The headline of `mode` among `points`: `None` without VTK's image at its step. Each of
/// voxcube's renderers offers its coarsest step at least as close to its own converged image
/// as VTK's is to its own: the fewest samples, so never slower than a finer step, whatever
/// the sweep's single medians say (this machine's drift has put a neighbouring finer step
/// first); of those, the fastest by the sweep's times.
pub fn headline(points: &[Point], mode: Mode) -> Option<Headline> {
    let vtk = *points
        .iter()
        .find(|p| p.mode == mode && p.renderer == Renderer::Vtk && p.dt == VTK_HEADLINE_STEP)?;
    let close: Vec<Point> = points
        .iter()
        .filter(|p| p.mode == mode && p.renderer != Renderer::Vtk && p.own >= vtk.own)
        .copied()
        .collect();
    let coarsest = |p: &Point| {
        !close
            .iter()
            .any(|q| q.renderer == p.renderer && q.dt > p.dt)
    };
    let best = close
        .iter()
        .filter(|p| coarsest(p))
        .min_by(|a, b| a.ms.total_cmp(&b.ms))
        .copied();
    Some(Headline { vtk, best })
}

/// The largest step of `renderer` in `mode` from which on every finer step's image is within
/// [`UNCHANGED_LEVELS`] of the converged one (its 99th percentile); `None` where even the
/// finest is not.
pub fn unchanged_from(points: &[Point], mode: Mode, renderer: Renderer) -> Option<f32> {
    let mut steps: Vec<&Point> = points
        .iter()
        .filter(|p| p.mode == mode && p.renderer == renderer)
        .collect();
    // Fine to coarse: the run of unchanged images from the finest on.
    steps.sort_by(|a, b| a.dt.total_cmp(&b.dt));
    steps
        .iter()
        .take_while(|p| p.own_p99 <= UNCHANGED_LEVELS)
        .last()
        .map(|p| p.dt)
}

/// The sweep's points and what it had to leave out.
#[derive(Clone, Debug, Default)]
pub struct Frontier {
    /// Every image but the converged ones.
    pub points: Vec<Point>,
    /// What was left out, and why.
    pub notes: String,
    /// Each mode's headline timed again in paired rounds (`paired_rounds`): its best
    /// point's time over VTK's in each round, ascending.
    pub paired: Vec<(Mode, Vec<f64>)>,
}

/// The headline's two images timed again round by round, back to back ([`run_paired`]): in
/// each of `rounds` rounds VTK at its step ([`PAIR_FRAMES`] frames after a first, its
/// median) and voxcube's best point `best` (the same). The sweep times each renderer's
/// images minutes apart, and this machine's speed drifts by half over minutes; a round's two
/// medians lie seconds apart. Each round's ratio, ascending.
fn paired_rounds(
    rounds: usize,
    mut vtk: impl FnMut() -> Result<f64, ExperimentError>,
    mut best: impl FnMut() -> Result<f64, ExperimentError>,
) -> Result<Vec<f64>, ExperimentError> {
    Ok(sorted_ratios(run_paired(rounds, &mut vtk, &mut best)?))
}

/// The views: SOD's paper view as a surface and composited at 350×250, with its own
/// transfer function and through the shell, lit by a headlight.
fn job(source: Source<'_>, notes: &mut String) -> Result<DatasetJob, ExperimentError> {
    let frame = Frame::PAPER;
    let views = |iso: &str| {
        sized(
            &(SURFACE_VIEW.replace("NAME", Mode::Surface.name())
                + &composite(Mode::Composite.name(), "exact", true)
                + &composite_through(Mode::Shell.name(), "exact", true, SHELL_TRANSFER)),
            frame.width,
            frame.height,
            f64::from(frame.dt),
            frame.span,
        )
        .replace("ISO", iso)
    };
    dataset_of(source, views, notes)
}

/// `view` at step `dt` as `renderer` (one of voxcube's) renders it, lit by a headlight.
fn variant(
    view: &View,
    job: &DatasetJob,
    dt: f32,
    renderer: Renderer,
) -> Result<View, ExperimentError> {
    let mut spec = view.spec().clone();
    spec.dt = dt;
    match renderer {
        Renderer::Voxcube(tier) => spec.accuracy = tier,
        Renderer::Unrefined => {
            spec.accuracy = Accuracy::Exact;
            spec.refine_steps = 0;
        }
        Renderer::PreIntegrated => {
            spec.accuracy = Accuracy::Fast;
            spec.compositing = Compositing::PreIntegrated;
        }
        Renderer::Vtk => {
            return Err(ExperimentError::Asked(
                "VTK's views are the peer script's".into(),
            ))
        }
    }
    let headlight = Light::directional(spec.camera.forward(), Vec3::ONE, false)
        .map_err(|e| ExperimentError::Asked(format!("a headlight: {e}")))?;
    spec.lights.clear();
    let _ = spec.lights.push(headlight);
    View::new(spec, &job.volume.grid)
        .map_err(|e| ExperimentError::Asked(format!("the view at dt {dt}: {e}")))
}

/// The median time and last image of `runs` renders of `view` on `machine`, after one more
/// that builds what the volume keeps.
fn timed(
    job: &DatasetJob,
    view: &View,
    machine: &Machine,
    runs: usize,
) -> Result<(f64, Vec<[u8; 4]>), ExperimentError> {
    let mut pixels = render_on(&job.volume, view, machine)?.pixels;
    let mut times = Vec::new();
    for _ in 0..runs.max(1) {
        let r = render_on(&job.volume, view, machine)?;
        times.push(r.wall);
        pixels = r.pixels;
    }
    Ok((median(times).as_secs_f64() * 1e3, pixels))
}

/// The steps a sweep renders at.
#[derive(Clone, Copy, Debug)]
pub struct Steps<'a> {
    /// voxcube's, each in both tiers.
    pub voxcube: &'a [f32],
    /// VTK's.
    pub vtk: &'a [f32],
    /// Every renderer's converged image.
    pub converged: f32,
}

impl Steps<'static> {
    /// The frontier's: [`STEPS`], [`VTK_STEPS`] and [`CONVERGED`].
    pub const FRONTIER: Steps<'static> = Steps {
        voxcube: &STEPS,
        vtk: &VTK_STEPS,
        converged: CONVERGED,
    };
}

/// Sweep both modes: voxcube's tiers at [`STEPS`] and VTK at [`VTK_STEPS`] where it is
/// installed (and SOD read from its file), `runs` timed frames each.
pub fn sweep(source: Source<'_>, runs: usize) -> Result<Frontier, ExperimentError> {
    sweep_over(source, runs, Steps::FRONTIER)
}

/// [`sweep`] at `steps`.
pub fn sweep_over(
    source: Source<'_>,
    runs: usize,
    steps: Steps<'_>,
) -> Result<Frontier, ExperimentError> {
    let mut frontier = Frontier::default();
    let sod = source.file();
    let job = job(source, &mut frontier.notes)?;
    // The bench's best shape for SOD on every core.
    let machine = every_core_modern(cores());
    let peer = match &sod {
        Some(file) => Peer::open(file).map_err(ExperimentError::Missing)?,
        None => None,
    };
    if peer.is_none() {
        let _ = writeln!(
            frontier.notes,
            "VTK: not rendered ({}): its curve is left out",
            match sod {
                Some(_) => format!(
                    "not installed: peers/setup.sh makes {}",
                    super::peer::VENV_PYTHON
                ),
                None => "the substitute is not SOD's file".into(),
            }
        );
    }
    for mode in Mode::ALL {
        let base = job
            .views
            .iter()
            .find(|v| v.name == mode.name())
            .ok_or_else(|| ExperimentError::Missing(format!("the {} view", mode.name())))?;
        let exact = Renderer::Voxcube(Accuracy::Exact);
        let reference = variant(&base.view, &job, steps.converged, exact)?;
        let reference = render_on(&job.volume, &reference, &machine)?.pixels;
        for &voxcube in Renderer::voxcube(mode) {
            let converged = match voxcube == exact {
                true => reference.clone(),
                false => {
                    let view = variant(&base.view, &job, steps.converged, voxcube)?;
                    render_on(&job.volume, &view, &machine)?.pixels
                }
            };
            let against = Against {
                converged: &converged,
                reference: &reference,
            };
            let renderer = (mode, voxcube);
            measure(
                &mut frontier.points,
                renderer,
                steps.voxcube,
                against,
                |dt| {
                    let view = variant(&base.view, &job, dt, voxcube)?;
                    timed(&job, &view, &machine, runs)
                },
            )?;
        }
        if let (Some(peer), Some(peer_mode)) = (&peer, mode.peer()) {
            let render = |dt: f32, runs: usize| {
                let frame = Frame { dt, ..Frame::PAPER };
                let request = Request {
                    mode: peer_mode,
                    frame,
                    runs,
                };
                let r = peer
                    .render(request, true)
                    .map_err(ExperimentError::Missing)?;
                let pixels = r
                    .pixels
                    .ok_or_else(|| ExperimentError::Missing("VTK's image".into()))?;
                Ok::<_, ExperimentError>((r.median.as_secs_f64() * 1e3, pixels))
            };
            let (_, converged) = render(steps.converged, 1)?;
            let against = Against {
                converged: &converged,
                reference: &reference,
            };
            let renderer = (mode, Renderer::Vtk);
            measure(&mut frontier.points, renderer, steps.vtk, against, |dt| {
                render(dt, runs)
            })?;
            let best = headline(&frontier.points, mode).and_then(|h| h.best);
            if let Some(best) = best {
                let view = variant(&base.view, &job, best.dt, best.renderer)?;
                let ours = || {
                    median_frame(|| render_on(&job.volume, &view, &machine).map(|r| r.wall))
                        .map(|t| t.as_secs_f64() * 1e3)
                        .map_err(ExperimentError::from)
                };
                let theirs = || render(VTK_HEADLINE_STEP, PAIR_FRAMES).map(|(ms, _)| ms);
                let ratios = paired_rounds(runs, theirs, ours)?;
                frontier.paired.push((mode, ratios));
            }
        }
    }
    Ok(frontier)
}

/// What an image is measured against: its own renderer's converged image and voxcube's exact
/// one.
#[derive(Clone, Copy)]
struct Against<'a> {
    converged: &'a [[u8; 4]],
    reference: &'a [[u8; 4]],
}

/// The points of `renderer`'s images of `mode` at `steps`, each `render`ed (its median ms and
/// last image) and measured `against` the converged ones.
fn measure(
    points: &mut Vec<Point>,
    (mode, renderer): (Mode, Renderer),
    steps: &[f32],
    against: Against<'_>,
    mut render: impl FnMut(f32) -> Result<(f64, Vec<[u8; 4]>), ExperimentError>,
) -> Result<(), ExperimentError> {
    for &dt in steps {
        let (ms, pixels) = render(dt)?;
        points.push(point(mode, renderer, dt, ms, &pixels, against));
    }
    Ok(())
}

/// The point of an image `pixels`.
fn point(
    mode: Mode,
    renderer: Renderer,
    dt: f32,
    ms: f64,
    pixels: &[[u8; 4]],
    Against {
        converged,
        reference,
    }: Against<'_>,
) -> Point {
    let (own, own_max) = compare(pixels, converged);
    Point {
        mode,
        renderer,
        dt,
        ms,
        own,
        own_p99: p99_error(pixels, converged),
        own_max,
        reference: compare(pixels, reference).0,
    }
}

fn db(psnr: f64) -> String {
    match psnr.is_finite() {
        true => format!("{psnr:.1}"),
        false => "same".into(),
    }
}

/// The tables, a mode each, then the headlines.
pub fn table(frontier: &Frontier) -> String {
    let mut out = frontier.notes.clone();
    for mode in Mode::ALL {
        let _ = writeln!(
            out,
            "-- {}, 350x250\n{:<18} {:>7} {:>9} {:>10} {:>9} {:>9} {:>12}",
            mode.name(),
            "renderer",
            "dt",
            "ms",
            "PSNR own",
            "p99 own",
            "max own",
            "PSNR exact"
        );
        for p in frontier.points.iter().filter(|p| p.mode == mode) {
            let _ = writeln!(
                out,
                "{:<18} {:>7.4} {:>9.1} {:>10} {:>9} {:>9} {:>12}",
                p.renderer.name(),
                p.dt,
                p.ms,
                db(p.own),
                p.own_p99,
                p.own_max,
                db(p.reference)
            );
        }
        for &renderer in Renderer::voxcube(mode).iter().chain([&Renderer::Vtk]) {
            if frontier
                .points
                .iter()
                .any(|p| p.mode == mode && p.renderer == renderer)
            {
                let _ = writeln!(
                    out,
                    "{}: the image stops changing (99% of pixels within {UNCHANGED_LEVELS} level of dt 1/16) {}",
                    renderer.name(),
                    match unchanged_from(&frontier.points, mode, renderer) {
                        Some(dt) => format!("from dt {dt} on"),
                        None => "at no step swept".into(),
                    }
                );
            }
        }
    }
    out += "PSNR own: against the same renderer's (and tier's) image at dt 1/16; p99 own and \
            max own: the 99th percentile over pixels and the largest of a pixel's largest \
            channel difference from it, 8-bit levels; PSNR exact: against voxcube's exact \
            tier at dt 1/16. Times: median ms per frame, every core, one run.\n";
    for mode in Mode::ALL {
        if let Some(h) = headline(&frontier.points, mode) {
            let paired = frontier
                .paired
                .iter()
                .find(|(m, _)| *m == mode)
                .map(|(_, ratios)| ratios.as_slice());
            let _ = writeln!(out, "{}", headline_line(mode, &h, paired));
        }
    }
    out
}

/// The sentence of `h`; the target is judged on the median of the `paired` rounds' ratios
/// where they were run (ascending), on the sweep's own times otherwise.
fn headline_line(mode: Mode, h: &Headline, paired: Option<&[f64]>) -> String {
    let vtk = format!(
        "VTK at dt {} is {} dB from its converged image in {:.1} ms",
        h.vtk.dt,
        db(h.vtk.own),
        h.vtk.ms
    );
    match (h.best, h.ratio()) {
        (Some(best), Some(ratio)) => {
            let rounds = paired.and_then(|r| Some((r.len(), spread(r)?)));
            let judged = rounds.map_or(ratio, |(_, (mid, ..))| mid);
            format!(
                "{}: {vtk}; {} at dt {} is {} dB from its own in {:.1} ms: {ratio:.2}x VTK's time{}{}",
                mode.name(),
                best.renderer.name(),
                best.dt,
                db(best.own),
                best.ms,
                rounds.map_or(String::new(), |(n, (_, least, most))| format!(
                    "; {n} paired rounds: {judged:.2}x ({least:.2}-{most:.2})"
                )),
                match (mode, judged <= TARGET) {
                    (Mode::Composite, true) => format!(" (target: at most {TARGET}x, met)"),
                    (Mode::Composite, false) => format!(" (target: at most {TARGET}x, not met)"),
                    (Mode::Surface | Mode::Shell, _) => String::new(),
                }
            )
        }
        _ => format!(
            "{}: {vtk}; no voxcube image swept is that close to its own{}",
            mode.name(),
            match mode {
                Mode::Composite => " (target not met)",
                Mode::Surface | Mode::Shell => "",
            }
        ),
    }
}

/// Time against error (PSNR against each renderer's own converged image), a panel a mode, a
/// line per renderer and tier through its steps.
pub fn plot(path: &Path, frontier: &Frontier) -> Result<(), String> {
    let root = SVGBackend::new(path, (1650, 440)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let areas = root.split_evenly((1, Mode::ALL.len()));
    for (area, mode) in areas.iter().zip(Mode::ALL) {
        let points: Vec<&Point> = frontier
            .points
            .iter()
            .filter(|p| p.mode == mode && p.own.is_finite())
            .collect();
        let (tmax, pmax) = points
            .iter()
            .fold((1.0f64, 10.0f64), |(t, q), p| (t.max(p.ms), q.max(p.own)));
        let mut chart = chart::linear(
            area,
            &format!("SOD {}, 350x250, every core", mode.name()),
            ("ms per frame, one run", "PSNR (dB) vs its own dt 1/16"),
            (tmax, pmax),
        )?;
        let lines = [
            (Renderer::Voxcube(Accuracy::Exact), BLUE),
            (Renderer::Voxcube(Accuracy::Fast), GREEN),
            (Renderer::Unrefined, MAGENTA),
            (Renderer::PreIntegrated, CYAN),
            (Renderer::Vtk, RED),
        ]
        .into_iter()
        .filter(|(renderer, _)| points.iter().any(|p| p.renderer == *renderer))
        .map(|(renderer, colour)| Line {
            points: points
                .iter()
                .filter(|p| p.renderer == renderer)
                .map(|p| (p.ms, p.own))
                .collect(),
            colour,
            label: renderer.name(),
        })
        .collect();
        chart::draw(&mut chart, lines)?;
    }
    root.present().map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(renderer: Renderer, dt: f32, ms: f64, own: f64, own_p99: u8) -> Point {
        Point {
            mode: Mode::Composite,
            renderer,
            dt,
            ms,
            own,
            own_p99,
            own_max: 255,
            reference: own,
        }
    }

    const FAST: Renderer = Renderer::Voxcube(Accuracy::Fast);
    const EXACT: Renderer = Renderer::Voxcube(Accuracy::Exact);

    #[test]
    fn the_headline_is_the_fastest_of_each_renderer_s_coarsest_step_as_close_as_vtk_s() {
        let points = [
            at(Renderer::Vtk, 1.0, 40.0, 42.0, 9),
            at(Renderer::Vtk, 0.5, 75.0, 43.0, 8),
            at(FAST, 2.0, 20.0, 38.0, 30),
            at(FAST, 1.25, 30.0, 44.0, 6),
            at(EXACT, 1.25, 35.0, 44.0, 6),
            at(FAST, 0.5, 60.0, 55.0, 2),
        ];
        let h = headline(&points, Mode::Composite).unwrap();
        assert_eq!(h.vtk.ms, 75.0);
        assert_eq!(h.best, Some(points[3]));
        assert_eq!(h.ratio(), Some(0.4));
        assert!(headline_line(Mode::Composite, &h, None)
            .contains("0.40x VTK's time (target: at most 0.33x, not met)"));
        // Paired rounds, where they ran, judge the target on their median ratio.
        let line = headline_line(Mode::Composite, &h, Some(&[0.25, 0.3, 0.5]));
        assert!(
            line.contains(
                "0.40x VTK's time; 3 paired rounds: 0.30x (0.25-0.50) (target: at most 0.33x, met)"
            ),
            "{line}"
        );
        let line = headline_line(Mode::Composite, &h, Some(&[0.3, 0.34, 0.35]));
        assert!(
            line.contains("0.34x (0.30-0.35) (target: at most 0.33x, not met)"),
            "{line}"
        );
        // The target is the composited view's only.
        assert!(!headline_line(Mode::Surface, &h, None).contains("target"));
        // Negative control: a VTK closer than every voxcube image leaves no best, and says so.
        let mut closer = points;
        closer[1].own = 60.0;
        let h = headline(&closer, Mode::Composite).unwrap();
        assert_eq!(h.best, None);
        assert!(headline_line(Mode::Composite, &h, None).contains("target not met"));
        // Without VTK's image at its step there is no headline; the other mode has none.
        assert_eq!(headline(&points[2..], Mode::Composite), None);
        assert_eq!(headline(&points, Mode::Surface), None);
    }

    #[test]
    fn a_finer_step_timed_faster_by_the_machine_s_drift_does_not_make_the_headline() {
        let points = [
            at(Renderer::Vtk, 0.5, 100.0, 43.0, 8),
            // Too far from its own: not a candidate, however fast.
            at(FAST, 1.5, 25.0, 42.0, 11),
            // The fast tier's coarsest step as close as VTK's, timed slower than the next.
            at(FAST, 1.375, 31.0, 43.1, 10),
            at(FAST, 1.25, 29.0, 44.2, 9),
            // Another renderer's coarsest candidate, slower still.
            at(EXACT, 1.375, 45.0, 43.2, 10),
            at(EXACT, 1.25, 28.0, 44.4, 9),
        ];
        let h = headline(&points, Mode::Composite).unwrap();
        // Not the fastest close point (the fast tier's 1.25, or the exact tier's at 28 ms):
        // the fastest of the fast tier's 1.375 and the exact tier's 1.375.
        assert_eq!(h.best, Some(points[2]));
        assert_eq!(h.ratio(), Some(0.31));
        // Across renderers the sweep's times decide.
        let mut slower = points;
        slower[2].ms = 50.0;
        let h = headline(&slower, Mode::Composite).unwrap();
        assert_eq!(h.best, Some(points[4]));
    }

    #[test]
    fn paired_rounds_alternate_who_goes_first_and_keep_each_round_s_ratio() {
        // A machine that slows by a tenth at every render: the side that goes second pays.
        let clock = std::cell::Cell::new(1.0f64);
        let tick = |base: f64| {
            let t = base * clock.get();
            clock.set(clock.get() * 1.1);
            Ok(t)
        };
        let ratios = paired_rounds(4, || tick(100.0), || tick(50.0)).unwrap();
        // VTK first: 50·1.1 / 100; voxcube first: 50 / (100·1.1); twice each, ascending.
        let (second, first) = (0.5 * 1.1, 0.5 / 1.1);
        for (r, expected) in ratios.iter().zip([first, first, second, second]) {
            assert!((r - expected).abs() < 1e-12, "{ratios:?}");
        }
        // One round at least, however few are asked.
        assert_eq!(paired_rounds(0, || Ok(2.0), || Ok(1.0)).unwrap(), vec![0.5]);
    }

    #[test]
    fn an_image_stops_changing_where_every_finer_one_is_within_a_level() {
        let points = [
            at(FAST, 2.0, 1.0, 40.0, 9),
            at(FAST, 1.0, 1.0, 50.0, 1),
            at(FAST, 0.5, 1.0, 60.0, 3),
            at(FAST, 0.25, 1.0, 70.0, 1),
            at(FAST, 0.125, 1.0, 80.0, 0),
        ];
        // 1.0 is within a level, but 0.5 after it is not: the run from the finest ends at 0.25.
        assert_eq!(unchanged_from(&points, Mode::Composite, FAST), Some(0.25));
        assert_eq!(unchanged_from(&points, Mode::Composite, EXACT), None);
        let mut coarse = points;
        coarse[4].own_p99 = 2;
        assert_eq!(unchanged_from(&coarse, Mode::Composite, FAST), None);
    }

    #[test]
    fn a_sweep_measures_each_tier_against_its_own_converged_image() {
        // The substitute (no SOD file: no VTK) at two steps, the finer one as "converged".
        let steps = Steps {
            voxcube: &[2.0, 1.0],
            vtk: &VTK_STEPS,
            converged: 1.0,
        };
        let frontier = sweep_over(Source::Substitute, 1, steps).unwrap();
        assert!(
            frontier.notes.contains("VTK: not rendered"),
            "{}",
            frontier.notes
        );
        // Two steps of each tier in each mode, of the pre-integrated fast tier composited
        // (SOD's function and the shell) and of the unrefined crossing on surfaces.
        assert_eq!(
            frontier.points.len(),
            2 * (3 + 3 + 3),
            "{:?}",
            frontier.points
        );
        assert!(frontier
            .points
            .iter()
            .all(|p| p.renderer != Renderer::Vtk && p.ms > 0.0));
        for mode in Mode::ALL {
            for &renderer in Renderer::voxcube(mode) {
                let at = |dt: f32| {
                    *frontier
                        .points
                        .iter()
                        .find(|p| p.mode == mode && p.renderer == renderer && p.dt == dt)
                        .unwrap()
                };
                // The image at the converged step is that image, bit for bit; the coarser
                // one is not (its negative control).
                let (fine, coarse) = (at(1.0), at(2.0));
                assert_eq!(
                    (fine.own, fine.own_max, fine.own_p99),
                    (f64::INFINITY, 0, 0)
                );
                assert!(coarse.own.is_finite() && coarse.own_max > 0, "{coarse:?}");
                // Against voxcube's exact image: the exact tier's own is that image.
                match renderer {
                    EXACT => assert_eq!(fine.reference, f64::INFINITY),
                    FAST => assert!(fine.reference.is_finite(), "{fine:?}"),
                    _ => {}
                }
            }
        }
        // Without VTK there is no headline, and the table says why.
        assert_eq!(headline(&frontier.points, Mode::Composite), None);
        assert!(table(&frontier).contains("VTK: not rendered"));
    }

    #[test]
    fn the_views_differ_in_step_and_tier_only_and_take_a_headlight() {
        let mut notes = String::new();
        let job = job(Source::Substitute, &mut notes).unwrap();
        assert!(notes.contains("--substitute"));
        let view_of = |mode: Mode| {
            &job.views
                .iter()
                .find(|v| v.name == mode.name())
                .unwrap()
                .view
        };
        assert_ne!(
            view_of(Mode::Composite).spec().mode,
            view_of(Mode::Shell).spec().mode,
            "the shell has its own transfer function"
        );
        for mode in Mode::ALL {
            let base = &job
                .views
                .iter()
                .find(|v| v.name == mode.name())
                .unwrap()
                .view;
            let a = variant(base, &job, 0.5, EXACT).unwrap();
            let b = variant(base, &job, 1.25, FAST).unwrap();
            let (sa, sb) = (a.spec(), b.spec());
            assert_eq!((sa.width, sa.height), (350, 250));
            assert_eq!((sa.dt, sb.dt), (0.5, 1.25));
            assert_eq!(
                (sa.accuracy, sb.accuracy),
                (Accuracy::Exact, Accuracy::Fast)
            );
            assert_eq!(sa.camera, sb.camera);
            assert_eq!(sa.mode, sb.mode);
            assert_eq!(sa.lights.len(), 1);
            let toward = sa.lights[0].toward_everywhere().unwrap();
            assert!((toward + sa.camera.forward()).length() < 1e-6, "{toward}");
            // The scene's own light is not a headlight: the variant replaced it.
            let own = base.spec().lights[0].toward_everywhere().unwrap();
            assert!((own + sa.camera.forward()).length() > 0.1);
            // The unrefined renderer is the exact tier without the crossing's refinement.
            let u = variant(base, &job, 0.5, Renderer::Unrefined).unwrap();
            assert_eq!(
                (u.spec().accuracy, u.spec().refine_steps),
                (Accuracy::Exact, 0)
            );
            assert!(sa.refine_steps > 0);
            // Pre-integration is the fast tier's, composited views' only.
            let pre = variant(base, &job, 0.5, Renderer::PreIntegrated);
            match mode {
                Mode::Composite | Mode::Shell => assert_eq!(
                    pre.map(|v| (v.spec().accuracy, v.spec().compositing)).ok(),
                    Some((Accuracy::Fast, Compositing::PreIntegrated))
                ),
                Mode::Surface => assert!(pre.is_err()),
            }
            assert!(variant(base, &job, 0.5, Renderer::Vtk).is_err());
        }
    }
}

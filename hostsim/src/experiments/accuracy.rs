//! `voxcube accuracy`: what accuracy costs in time. Δt (1/2, 1/3, 1/5, 1/8 cell edge), the
//! voxel against the cell model, and the image size (350×250 up to
//! the paper's 1024×768 at Δt = 1/5, framed as the paper framed it) are swept on SOD. Each setting reports:
//! - wall time on this machine (median of 3), without empty-space skipping, like the paper's
//!   tracer;
//! - simulated 1-node nCUBE 2 time (the profile's costs times the counted operations);
//! - samples traced;
//! - error against a fine reference at the same image size (Δt = 1/16, cell model, exact
//!   tier): PSNR and maximum absolute error, in 8-bit levels.
//!
//! The accuracy tiers are swept too, on the first composited view: exact and fast at Δt = 1/2
//! and 1/5 against the same reference.

use super::chart::{self, Line};
use crate::input::scene::DatasetJob;
use crate::memory::storage::SkipMode;
use crate::profile::MachineProfile;
use crate::run::render::render_skipping;
use plotters::prelude::*;
use std::fmt::Write as _;
use std::path::Path;
use voxcube_kernel::counters::Counters;
use voxcube_kernel::optics::transfer::{ControlPoint, TransferFunction};
use voxcube_kernel::trace::camera::{Camera, Projection};
use voxcube_kernel::trace::view::{Accuracy, Mode, View};
use voxcube_kernel::volume::grid::Model;
use voxcube_kernel::Vec3;

/// One measured setting.
#[derive(Clone, Debug)]
pub struct Point {
    /// What was varied, as a label.
    pub label: String,
    /// Which sweep it belongs to.
    pub sweep: &'static str,
    /// Median wall time, milliseconds.
    pub wall_ms: f64,
    /// Simulated 1-node nCUBE 2 seconds.
    pub ncube_s: f64,
    /// Lattice samples.
    pub samples: u64,
    /// PSNR against the reference, dB (infinite when identical).
    pub psnr: f64,
    /// Largest absolute difference in any channel, 8-bit levels.
    pub max_error: u8,
    /// The 99th percentile over pixels of each pixel's largest channel difference, 8-bit
    /// levels: what a few silhouette pixels cannot saturate.
    pub p99_error: u8,
    /// Structural similarity to the reference (mean SSIM over 8×8 windows, RGB; 1 when
    /// identical), from the `image-compare` crate.
    pub ssim: f64,
}

/// Mean SSIM (8×8 windows, over the RGB channels) between two RGBA8 images of `width` ×
/// `height`; `NaN` when they are not that size.
pub fn ssim(a: &[[u8; 4]], b: &[[u8; 4]], width: u32, height: u32) -> f64 {
    let rgb = |p: &[[u8; 4]]| {
        if p.len() as u64 != u64::from(width) * u64::from(height) {
            return None;
        }
        image::RgbImage::from_raw(
            width,
            height,
            p.iter().flat_map(|q| [q[0], q[1], q[2]]).collect(),
        )
    };
    match (rgb(a), rgb(b)) {
        (Some(x), Some(y)) => {
            image_compare::rgb_similarity_structure(&image_compare::Algorithm::MSSIMSimple, &x, &y)
                .map_or(f64::NAN, |s| s.score)
        }
        _ => f64::NAN,
    }
}

/// Simulated 1-node seconds of `view`'s counted work on `profile`: the sequential tracer's
/// ([`MachineProfile::sequential`], scaled; no messages).
pub fn one_node_seconds(c: &Counters, view: &View, profile: &MachineProfile) -> f64 {
    let surfaces = MachineProfile::searched_surfaces(view);
    profile.sequential(c, surfaces).iter().sum::<f64>() * profile.scale
}

/// The 99th percentile, over the pixels of two RGBA8 images of the same size, of each
/// pixel's largest channel difference (8-bit levels).
pub fn p99_error(a: &[[u8; 4]], b: &[[u8; 4]]) -> u8 {
    let mut d: Vec<u8> = a
        .iter()
        .zip(b)
        .map(|(p, q)| (0..3).map(|c| p[c].abs_diff(q[c])).max().unwrap_or(0))
        .collect();
    if d.is_empty() {
        return 0;
    }
    let at = (d.len() - 1) * 99 / 100;
    *d.select_nth_unstable(at).1
}

/// PSNR (dB) and maximum absolute error between two RGBA8 images of the same size.
pub fn compare(a: &[[u8; 4]], b: &[[u8; 4]]) -> (f64, u8) {
    let (mut se, mut max, mut n) = (0f64, 0u8, 0usize);
    for (p, q) in a.iter().zip(b) {
        for ch in 0..3 {
            let d = p[ch].abs_diff(q[ch]);
            max = max.max(d);
            se += f64::from(d) * f64::from(d);
            n += 1;
        }
    }
    let mse = se / n.max(1) as f64;
    let psnr = if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (255.0f64 * 255.0 / mse).log10()
    };
    (psnr, max)
}

fn with(
    view: &View,
    job: &DatasetJob,
    f: impl FnOnce(&mut voxcube_kernel::trace::view::ViewSpec),
) -> Option<View> {
    let mut spec = view.spec().clone();
    f(&mut spec);
    View::new(spec, &job.volume.grid).ok()
}

/// `camera` with an orthographic image `span` world units wide (unchanged if it cannot be).
fn reframed(camera: &Camera, span: f32) -> Camera {
    let (_, up) = camera.image_axes();
    let eye = camera.eye();
    Camera::look_at(
        eye,
        eye + camera.forward(),
        up,
        Projection::Orthographic { width: span },
    )
    .unwrap_or(*camera)
}

fn measure(
    job: &DatasetJob,
    view: &View,
    reference: &[[u8; 4]],
    profile: &MachineProfile,
    label: String,
    sweep: &'static str,
) -> Option<Point> {
    let mut walls = Vec::new();
    let mut last = None;
    for _ in 0..3 {
        let r = render_skipping(&job.volume, view, SkipMode::OFF).ok()?;
        walls.push(r.wall.as_secs_f64() * 1e3);
        last = Some(r);
    }
    walls.sort_by(f64::total_cmp);
    let r = last?;
    let (psnr, max_error) = compare(&r.pixels, reference);
    Some(Point {
        label,
        sweep,
        wall_ms: walls[1],
        ncube_s: one_node_seconds(&r.counters, view, profile),
        samples: r.counters.samples,
        psnr,
        max_error,
        p99_error: p99_error(&r.pixels, reference),
        ssim: ssim(&r.pixels, reference, r.width, r.height),
    })
}

/// Run the sweeps on the first view of `job`; the points, in order.
pub fn sweep(job: &DatasetJob, profile: &MachineProfile) -> Vec<Point> {
    let base = &job.views[0].view;
    let mut points = Vec::new();
    let reference_of = |v: &View| {
        with(v, job, |s| {
            s.dt = 1.0 / 16.0;
            s.model = Model::Cell;
            s.accuracy = Accuracy::Exact;
        })
        .and_then(|r| render_skipping(&job.volume, &r, SkipMode::OFF).ok())
        .map(|r| r.pixels)
        .unwrap_or_default()
    };
    let reference = reference_of(base);
    for (name, dt) in [
        ("1/2", 0.5f32),
        ("1/3", 1.0 / 3.0),
        ("1/5", 0.2),
        ("1/8", 0.125),
    ] {
        for model in [Model::Cell, Model::Voxel] {
            if let Some(v) = with(base, job, |s| {
                s.dt = dt;
                s.model = model;
            }) {
                let label = format!(
                    "dt {name}, {}",
                    if model == Model::Cell {
                        "cell"
                    } else {
                        "voxel"
                    }
                );
                points.extend(measure(job, &v, &reference, profile, label, "dt and model"));
            }
        }
    }
    // The gradient distance is not swept: it costs no time (the same reads at any distance),
    // so it has no place on a chart of what accuracy costs in time.
    // The accuracy tiers, composited (the first view, with scenes/sod.toml's transfer
    // function): each tier at two steps against the same fine exact reference.
    if let Some(composite) = with(base, job, |s| {
        let point = |value, color: [f32; 3], opacity| ControlPoint {
            value,
            color: Vec3::from_array(color),
            opacity,
        };
        if let Ok(tf) = TransferFunction::new(&[
            point(10.0, [0.2, 0.3, 0.8], 0.0),
            point(60.0, [0.9, 0.7, 0.3], 0.15),
            point(200.0, [1.0, 0.2, 0.1], 0.8),
        ]) {
            s.mode = Mode::Composite(tf);
        }
        // Compositing casts no shadows.
        for light in s.lights.iter_mut() {
            light.shadows = false;
        }
    }) {
        let composite = &composite;
        let reference = reference_of(composite);
        for (name, dt) in [("1/2", 0.5f32), ("1/5", 0.2)] {
            for tier in [Accuracy::Exact, Accuracy::Fast] {
                if let Some(v) = with(composite, job, |s| {
                    s.dt = dt;
                    s.accuracy = tier;
                }) {
                    points.extend(measure(
                        job,
                        &v,
                        &reference,
                        profile,
                        format!("composite, dt {name}, {}", tier.name()),
                        "tier",
                    ));
                }
            }
        }
    }
    // 700×500 keeps the paper's framing at twice the pixels; 1024×768 is framed as the paper
    // framed it at that size (its voxels on 748×482 pixels).
    let large = crate::experiments::bench::Size::LARGE;
    for (w, h, dt, span) in [
        (350u32, 250u32, 0.5f32, None),
        (700, 500, 0.5, None),
        (large.width, large.height, 0.2, Some(large.span)),
    ] {
        let dt_name = if dt == 0.5 { "1/2" } else { "1/5" };
        if let Some(v) = with(base, job, |s| {
            s.width = w;
            s.height = h;
            s.dt = dt;
            if let Some(span) = span {
                s.camera = reframed(&s.camera, span);
            }
        }) {
            let reference = reference_of(&v);
            points.extend(measure(
                job,
                &v,
                &reference,
                profile,
                format!("{w}x{h}, dt {dt_name}"),
                "image size",
            ));
        }
    }
    points
}

/// The table.
pub fn table(points: &[Point]) -> String {
    let mut out = format!(
        "{:<30} {:>9} {:>12} {:>10} {:>9} {:>8} {:>9} {:>9}\n",
        "setting", "wall ms", "nCUBE 2 s", "samples", "PSNR dB", "SSIM", "p99 err", "max err"
    );
    let mut sweep = "";
    for p in points {
        if p.sweep != sweep {
            sweep = p.sweep;
            let _ = writeln!(out, "-- {sweep}");
        }
        let psnr = if p.psnr.is_finite() {
            format!("{:.1}", p.psnr)
        } else {
            "exact".into()
        };
        let _ = writeln!(
            out,
            "{:<30} {:>9.1} {:>12.1} {:>9.2}M {:>9} {:>8.4} {:>9} {:>9}",
            p.label,
            p.wall_ms,
            p.ncube_s,
            p.samples as f64 / 1e6,
            psnr,
            p.ssim,
            p.p99_error,
            p.max_error
        );
    }
    out.push_str("reference: dt 1/16, cell model, exact tier, same image size; errors in 8-bit levels (p99: the 99th percentile over pixels of a pixel's largest channel error); SSIM: mean structural similarity over 8x8 windows (1: identical)\n");
    out
}

/// Error (PSNR) against simulated nCUBE time for the Δt and model sweep.
pub fn plot(path: &Path, points: &[Point]) -> Result<(), String> {
    let sweep: Vec<&Point> = points
        .iter()
        .filter(|p| p.sweep == "dt and model" && p.psnr.is_finite())
        .collect();
    let (tmax, pmax) = sweep.iter().fold((1.0f64, 10.0f64), |(t, q), p| {
        (t.max(p.ncube_s), q.max(p.psnr))
    });
    let root = SVGBackend::new(path, (1100, 420)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let (left, right) = root.split_horizontally(640);
    let mut chart = chart::linear(
        &left,
        "Accuracy against time on SOD (1 node, nCUBE 2)",
        ("simulated seconds", "PSNR (dB) vs dt 1/16"),
        (tmax, pmax),
    )?;
    let lines = [("cell", BLUE), ("voxel", RED)].map(|(model, colour)| Line {
        points: sweep
            .iter()
            .filter(|p| p.label.ends_with(model))
            .map(|p| (p.ncube_s, p.psnr))
            .collect(),
        colour,
        label: format!("{model} model, dt 1/2 to 1/8"),
    });
    chart::draw(&mut chart, lines.into())?;
    tiers(&right, points)?;
    root.present().map_err(|e| e.to_string())
}

/// The tiers' panel: wall time against error, one line per tier through its steps (the
/// simulated nCUBE 2 prices counted operations, and a table lookup counts as the exact
/// evaluation it replaces, so only wall time tells the tiers apart).
fn tiers<DB: DrawingBackend>(
    area: &DrawingArea<DB, plotters::coord::Shift>,
    points: &[Point],
) -> Result<(), String> {
    let sweep: Vec<&Point> = points
        .iter()
        .filter(|p| p.sweep == "tier" && p.psnr.is_finite())
        .collect();
    let (tmax, pmax) = sweep.iter().fold((1.0f64, 10.0f64), |(t, q), p| {
        (t.max(p.wall_ms), q.max(p.psnr))
    });
    let mut chart = chart::linear(
        area,
        "Composited, by accuracy tier (1 node)",
        ("wall ms, this machine", "PSNR (dB) vs exact dt 1/16"),
        (tmax, pmax),
    )?;
    let lines = [("exact", BLUE), ("fast", GREEN)].map(|(tier, colour)| Line {
        points: sweep
            .iter()
            .filter(|p| p.label.ends_with(tier))
            .map(|p| (p.wall_ms, p.psnr))
            .collect(),
        colour,
        label: format!("{tier} tier, dt 1/2 and 1/5"),
    });
    chart::draw(&mut chart, lines.into())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_99th_percentile_ignores_a_few_saturated_pixels_and_not_a_broad_error() {
        let a = vec![[10u8, 10, 10, 255]; 1000];
        let mut b = a.clone();
        // Five silhouette pixels off by everything: the maximum sees them, the percentile not.
        for p in b.iter_mut().take(5) {
            *p = [255, 10, 10, 255];
        }
        assert_eq!(compare(&a, &b).1, 245);
        assert_eq!(p99_error(&a, &b), 0);
        // Every pixel off by 3 in one channel: both see it.
        let c: Vec<[u8; 4]> = a.iter().map(|p| [p[0], p[1] + 3, p[2], 255]).collect();
        assert_eq!(p99_error(&a, &c), 3);
        assert_eq!(p99_error(&[], &[]), 0);
        // SSIM: 1 for the same image, less for a changed one, NaN for a wrong size.
        let img: Vec<[u8; 4]> = (0..64u8).map(|i| [i * 3, 255 - i, i, 255]).collect();
        let mut other = img.clone();
        other[27] = [0, 0, 0, 255];
        assert_eq!(ssim(&img, &img, 8, 8), 1.0);
        let changed = ssim(&img, &other, 8, 8);
        assert!(changed < 1.0 && changed > 0.0, "{changed}");
        assert!(ssim(&img, &img, 4, 4).is_nan());
    }
}

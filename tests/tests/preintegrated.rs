//! Pre-integrated compositing (`compositing = "pre-integrated"`, fast tier): the table against
//! direct numerical integration of a segment (a constant medium, a ramp, a spike narrower
//! than Δt; a whole table is a megabyte, which the kernel's own tests cannot hold); a segment
//! over which the value runs linearly integrates the transfer function's thin features where
//! sampling misses them (an end-to-end analytic case); its images are bit-identical on every
//! cluster size, partition, fabric and way of skipping; and two faults are caught: a table
//! built for another step, and skipping that does not ask the segment's front.

use voxcube::fabric::{sim, threads, RunConfig};
use voxcube::input::dataset::{Volume, VolumeData};
use voxcube::input::scene::{DatasetJob, Scene};
use voxcube::memory::segments::SegmentTable;
use voxcube::memory::storage::SkipMode;
use voxcube::run::render::{render, render_skipping};
use voxcube_kernel::node::topology::Layout;
use voxcube_kernel::optics::segments::{self, Segments, SegmentsError};
use voxcube_kernel::optics::transfer::{ControlPoint, TransferFunction};
use voxcube_kernel::trace::view::{Accuracy, Approximation, Compositing, Mode, View, ViewSpec};
use voxcube_kernel::volume::grid::Model;
use voxcube_kernel::volume::slab::Slab;
use voxcube_kernel::{Vec3, Vec4};
use voxcube_tests::*;

/// The test scenes, on the built-in molecule, small images.
const SCENES: &str = include_str!("scenes.toml");

/// The molecule under a thin shell: opaque only within two value units of 120, so that
/// steps of a cell and more pass over it between samples.
const SHELL: &str = r#"
[[datasets]]
name = "shell"
builtin = "molecule"
[[datasets.views]]
name = "shell"
width = 40
height = 30
mode = "composite"
[[datasets.views.transfer]]
value = 0.0
color = [0.2, 0.3, 0.8]
opacity = 0.0
[[datasets.views.transfer]]
value = 118.0
color = [0.9, 0.7, 0.3]
opacity = 0.0
[[datasets.views.transfer]]
value = 120.0
color = [0.9, 0.7, 0.3]
opacity = 0.7
[[datasets.views.transfer]]
value = 122.0
color = [0.9, 0.7, 0.3]
opacity = 0.0
[[datasets.views.transfer]]
value = 255.0
color = [1.0, 0.2, 0.1]
opacity = 0.0
"#;

fn jobs(text: &str) -> Vec<DatasetJob> {
    Scene::parse(text, "test", std::path::Path::new("."))
        .and_then(Scene::load)
        .unwrap_or_else(|e| panic!("{e}"))
}

/// `view` composited pre-integrated in the fast tier at step `dt`, all else as it is.
fn pre_integrated(view: &View, volume: &Volume, dt: f32) -> View {
    let spec = ViewSpec {
        accuracy: Accuracy::Fast,
        compositing: Compositing::PreIntegrated,
        dt,
        ..view.spec().clone()
    };
    View::new(spec, &volume.grid).expect("a pre-integrated view")
}

/// Every composited view of the test scenes and the shell, pre-integrated at two steps, with
/// its dataset.
fn views() -> Vec<(String, std::rc::Rc<DatasetJob>, View)> {
    let mut out = Vec::new();
    for job in jobs(SCENES).into_iter().chain(jobs(SHELL)) {
        let job = std::rc::Rc::new(job);
        for v in &job.views {
            if !matches!(v.view.spec().mode, Mode::Composite(_)) {
                continue;
            }
            for dt in [0.5, 1.5] {
                let name = format!("{}/{} at dt {dt}", job.name, v.name);
                out.push((name, job.clone(), pre_integrated(&v.view, &job.volume, dt)));
            }
        }
    }
    out
}

#[test]
fn a_ramp_through_a_spike_narrower_than_the_step_composites_its_integral() {
    // The value rises ten units a cell along x; a ray along x meets every value once, and
    // the samples at whole and half cells fall on the table's entries (one per value unit).
    let volume = volume_f32([16, 8, 8], Vec3::ONE, |x, _, _| 10.0 * x as f32);
    // Transparent but for a spike four value units (0.4 cells) wide at 75, white.
    let points = [
        (0.0, 0.0),
        (73.0, 0.0),
        (75.0, 0.9),
        (77.0, 0.0),
        (255.0, 0.0),
    ];
    let points: Vec<ControlPoint> = points
        .iter()
        .map(|&(value, opacity)| ControlPoint {
            value,
            color: Vec3::ONE,
            opacity,
        })
        .collect();
    let tf = TransferFunction::new(&points).expect("valid");
    // Through the spike the extinction per value unit, −ln(1 − 0.45·u) on each flank,
    // integrates to 2·(0.1·ln 0.1 + 0.9)/0.45; a tenth of that per cell edge.
    let optical_depth = 2.0 * (0.1f64 * 0.1f64.ln() + 0.9) / 0.45 / 10.0;
    let expected = 1.0 - (-optical_depth).exp();
    let target = Vec3::new(7.5, 3.5, 3.5);
    let camera = ortho(target - Vec3::X * 50.0, target, Vec3::Y, 2.0);
    let mut sampled_errs = Vec::new();
    for dt in [0.5f32, 1.0, 2.0] {
        let base = spec(camera, 4, 4, Model::Cell, dt, Mode::Composite(tf.clone()));
        let pre = view(
            ViewSpec {
                accuracy: Accuracy::Fast,
                compositing: Compositing::PreIntegrated,
                ..base.clone()
            },
            &volume,
        );
        assert!(pre.approximations().contains(&Approximation::PreIntegrated));
        let (pixels, _) = trace_all(&volume, &pre);
        for c in &pixels {
            assert!(
                (f64::from(c.x) - expected).abs() < 1e-3,
                "dt {dt}: {} against {expected}",
                c.x
            );
        }
        let (sampled, _) = trace_all(&volume, &view(base, &volume));
        sampled_errs.push((f64::from(sampled[0].x) - expected).abs());
    }
    // Sampling meets the spike at one sample or none: far off at every step.
    assert!(
        sampled_errs.iter().all(|e| *e > 0.1),
        "sampling came within a tenth: {sampled_errs:?}"
    );
}

#[test]
fn pre_integration_is_bit_identical_on_every_cluster_size_partition_fabric_and_skipping() {
    let mut shows = 0;
    for (name, job, view) in views() {
        let one = render(&job.volume, &view).expect("renders").pixels;
        shows += usize::from(one.iter().any(|p| p[..3] != one[0][..3]));
        let off = render_skipping(&job.volume, &view, SkipMode::OFF).expect("renders");
        assert!(off.pixels == one, "{name}: skipping changed the image");
        assert_eq!(off.counters.skipped, 0);
        for mode in [SkipMode::BLOCKS, SkipMode::LEAPS] {
            let r = render_skipping(&job.volume, &view, mode).expect("renders");
            assert!(r.pixels == one, "{name}: {mode:?} changed the image");
        }
        for (size, seed) in [(2u32, 1u64), (3, 2), (8, 4)] {
            let cfg = RunConfig::cluster(size, seed).expect("layout");
            let run = sim::run(&job.volume, &view, &cfg).unwrap_or_else(|e| panic!("{e}"));
            assert!(run.pixels == one, "{name} on {size} nodes: image differs");
        }
        let nx = job.volume.grid.dims()[0];
        let cfg = RunConfig {
            layout: Layout::new(2, 3).expect("layout"),
            cuts: Some(vec![0, 5, nx - 9, nx]),
            ..RunConfig::machine(2, 3, 7).expect("layout")
        };
        let run = sim::run(&job.volume, &view, &cfg).unwrap_or_else(|e| panic!("{e}"));
        assert!(run.pixels == one, "{name} on uneven slabs: image differs");
        let cfg = RunConfig::machine(1, 4, 1).expect("layout");
        let run = threads::run(&job.volume, &view, &cfg, 2).unwrap_or_else(|e| panic!("{e}"));
        assert!(run.pixels == one, "{name} on threads: image differs");
    }
    assert!(shows >= 4, "too few test views show anything: {shows}");
}

#[test]
fn pre_integration_changes_the_image_where_the_step_passes_over_a_thin_shell() {
    let job = &jobs(SHELL)[0];
    let sampled = in_tier(&job.views[0].view, &job.volume, Accuracy::Fast);
    let sampled = View::new(
        ViewSpec {
            dt: 1.5,
            ..sampled.spec().clone()
        },
        &job.volume.grid,
    )
    .expect("view");
    let pre = pre_integrated(&job.views[0].view, &job.volume, 1.5);
    let (a, b) = (
        render(&job.volume, &sampled).expect("renders").pixels,
        render(&job.volume, &pre).expect("renders").pixels,
    );
    let differ = a.iter().zip(&b).filter(|(p, q)| p != q).count();
    assert!(
        differ > a.len() / 20,
        "{differ} of {} pixels differ",
        a.len()
    );
}

/// `view`'s pixels on `volume` as one whole slab carrying `cells` as its table.
fn with_table(volume: &Volume, view: &View, cells: &[Vec4]) -> Vec<[u32; 3]> {
    let VolumeData::U8(data) = &volume.data else {
        panic!("the molecule is bytes");
    };
    let layout = *view.segments().expect("pre-integrated");
    let table = Segments::new(layout, cells).expect("a table's length");
    let slab = Slab::whole(volume.grid, data)
        .expect("slab")
        .with_segments(table);
    colour_bits(view, &slab).0
}

#[test]
fn negative_control_a_table_for_another_step_changes_the_image() {
    let job = &jobs(SHELL)[0];
    let view = pre_integrated(&job.views[0].view, &job.volume, 1.0);
    let Mode::Composite(tf) = &view.spec().mode else {
        panic!("composited");
    };
    let own = SegmentTable::of(&view);
    assert_eq!(own.bytes(), segments::BYTES);
    let mut right = vec![Vec4::ZERO; segments::LEN];
    let layout = *view.segments().expect("pre-integrated");
    segments::build(tf, &layout, &mut right).expect("built");
    let half = segments::Layout::of(tf, 0.5).expect("a step");
    let mut wrong = vec![Vec4::ZERO; segments::LEN];
    segments::build(tf, &half, &mut wrong).expect("built");
    let (a, b) = (
        with_table(&job.volume, &view, &right),
        with_table(&job.volume, &view, &wrong),
    );
    // The right table is the one every host lends: the same bits as a render.
    let (lent, _) = trace_all(&job.volume, &view);
    assert!(a
        .iter()
        .zip(&lent)
        .all(|(p, q)| *p == q.to_array().map(f32::to_bits)));
    let differ = a.iter().zip(&b).filter(|(p, q)| p != q).count();
    assert!(
        differ > 0,
        "a table for half the step left every pixel as it was"
    );
}

#[test]
fn negative_control_skipping_that_ignores_the_segments_front_changes_the_image() {
    let mut caught = 0;
    for (name, job, view) in views() {
        let off = render_skipping(&job.volume, &view, SkipMode::OFF).expect("renders");
        let careless = view.clone().with_careless_segments();
        let on = render_skipping(&job.volume, &careless, SkipMode::ALL).expect("renders");
        let differ = off
            .pixels
            .iter()
            .zip(&on.pixels)
            .filter(|(a, b)| a != b)
            .count();
        eprintln!("{name}: careless skipping changed {differ} pixels");
        caught += usize::from(differ > 0);
    }
    assert!(
        caught > 0,
        "passing over a segment that shows changed no image"
    );
}

// The table itself.

fn tf(points: &[(f32, f32, f32)]) -> TransferFunction {
    let points: Vec<ControlPoint> = points
        .iter()
        .map(|&(value, c, opacity)| ControlPoint {
            value,
            color: Vec3::new(c, 1.0 - c, 0.5),
            opacity,
        })
        .collect();
    TransferFunction::new(&points).expect("valid")
}

fn table(tf: &TransferFunction, dt: f32) -> (segments::Layout, Vec<Vec4>) {
    let mut cells = vec![Vec4::ZERO; segments::LEN];
    let layout = segments::Layout::of(tf, dt).expect("a step");
    segments::build(tf, &layout, &mut cells).expect("built");
    (layout, cells)
}

/// The segment from `front` to `back` over `dt` edges of `tf` itself (its control
/// points, not the table's entries), integrated directly in `f64` by the midpoint rule
/// on `steps` pieces: emission `c·κ` and extinction `κ = −ln(1 − opacity)` per edge.
fn integrated(tf: &TransferFunction, front: f32, back: f32, dt: f32, steps: usize) -> Vec4 {
    let (mut color, mut through) = ([0.0f64; 3], 1.0f64);
    let h = f64::from(dt) / steps as f64;
    for s in 0..steps {
        let u = (s as f64 + 0.5) / steps as f64;
        let v = f64::from(front) + u * (f64::from(back) - f64::from(front));
        let (c, o) = tf.eval(v as f32);
        let kappa = -(1.0 - f64::from(o).min(1.0 - 1e-12)).ln();
        let piece = 1.0 - (-kappa * h).exp();
        for (acc, ch) in color.iter_mut().zip(c.to_array()) {
            *acc += through * piece * f64::from(ch);
        }
        through *= 1.0 - piece;
    }
    let alpha = 1.0 - through;
    let mean = |x: f64| if alpha > 0.0 { x / alpha } else { 0.0 };
    Vec4::new(
        mean(color[0]) as f32,
        mean(color[1]) as f32,
        mean(color[2]) as f32,
        alpha as f32,
    )
}

/// Entry `m`'s value in a table of `tf`, as the table spreads them.
fn entry(tf: &TransferFunction, m: usize) -> f32 {
    let (lo, hi) = tf.domain();
    lo + (hi - lo) * (m as f32 / (segments::ENTRIES - 1) as f32)
}

#[test]
fn a_constant_medium_is_beer_lambert_over_every_segment() {
    // Opacity 0.3 per edge everywhere: any segment of length dt lets through 0.7^dt.
    let f = tf(&[(0.0, 0.25, 0.3), (100.0, 0.25, 0.3)]);
    for dt in [0.125, 0.5, 1.0, 2.0] {
        let (layout, cells) = table(&f, dt);
        let t = Segments::new(layout, &cells).expect("table");
        let expected = 1.0 - 0.7f64.powf(f64::from(dt));
        for (a, b) in [(0.0, 0.0), (0.0, 100.0), (100.0, 3.0), (40.0, 41.0)] {
            let s = t.segment(a, b);
            assert!(
                (f64::from(s.w) - expected).abs() < 2e-5,
                "{dt} {a}->{b}: {s}"
            );
            assert!(
                (s.truncate() - Vec3::new(0.25, 0.75, 0.5))
                    .abs()
                    .max_element()
                    < 2e-5
            );
        }
    }
}

#[test]
fn a_ramp_matches_direct_integration() {
    // Opacity rising linearly from 0 to 0.6 per edge, colour from one end to the other.
    let f = tf(&[(0.0, 0.0, 0.0), (255.0, 1.0, 0.6)]);
    for dt in [0.25, 1.0, 2.0] {
        let (layout, cells) = table(&f, dt);
        let t = Segments::new(layout, &cells).expect("table");
        for (i, j) in [
            (0, 255),
            (255, 0),
            (10, 200),
            (200, 10),
            (100, 101),
            (128, 128),
        ] {
            let (a, b) = (entry(&f, i), entry(&f, j));
            let (got, want) = (t.segment(a, b), integrated(&f, a, b, dt, 20_000));
            // The pieces' mean extinction against the curve's: second order in the
            // entry spacing, and the opacity's curvature is small here.
            assert!(
                (got - want).abs().max_element() < 2e-4,
                "{dt} {i}->{j}: {got} {want}"
            );
        }
    }
}

#[test]
fn a_spike_narrower_than_the_step_is_integrated_where_sampling_misses_it() {
    // Transparent but for a spike four value units wide at 100.
    let f = tf(&[
        (0.0, 0.5, 0.0),
        (98.0, 0.5, 0.0),
        (100.0, 0.9, 0.9),
        (102.0, 0.5, 0.0),
        (255.0, 0.5, 0.0),
    ]);
    let dt = 2.0;
    let (layout, cells) = table(&f, dt);
    let t = Segments::new(layout, &cells).expect("table");
    // A segment from 50 to 150 crosses the spike in a twenty-fifth of its length; both
    // its samples are transparent.
    let (a, b) = (entry(&f, 50), entry(&f, 150));
    assert_eq!((f.opacity(a), f.opacity(b)), (0.0, 0.0));
    let (got, want) = (t.segment(a, b), integrated(&f, a, b, dt, 200_000));
    assert!(want.w > 0.05, "{want}");
    // The spike's control points sit on entries: the table holds its integral.
    assert!((got.w - want.w).abs() < 1e-3 * want.w, "{got} {want}");
    assert!(
        (got.truncate() - want.truncate()).abs().max_element() < 1e-3,
        "{got} {want}"
    );
    // Falling through it gives the same opacity.
    assert!((t.segment(b, a).w - got.w).abs() < 1e-5);
}

#[test]
fn segments_below_the_first_entry_that_shows_are_transparent() {
    let f = tf(&[(10.0, 0.2, 0.0), (60.0, 0.9, 0.15), (200.0, 1.0, 0.8)]);
    let (layout, cells) = table(&f, 1.5);
    let t = Segments::new(layout, &cells).expect("table");
    let first = layout.first_shown() as usize;
    assert!(first > 0 && first < segments::ENTRIES);
    assert!(f.opacity(entry(&f, first)) > 0.0 && f.opacity(entry(&f, first - 1)) == 0.0);
    for i in 0..first {
        for j in 0..first {
            assert_eq!(t.segment(entry(&f, i), entry(&f, j)).w, 0.0, "{i} {j}");
        }
        // A segment that reaches the first entry that shows is not.
        assert!(t.segment(entry(&f, i), entry(&f, first)).w > 0.0, "{i}");
    }
    assert!(layout.empty(-1e9, entry(&f, first - 1)));
    assert!(!layout.empty(-1e9, entry(&f, first)));
    assert!(!layout.empty(f32::NAN, 0.0) && !layout.empty(0.0, f32::NAN));
    assert!(
        layout.below(f32::NAN),
        "NaN reads entry 0, as the table does"
    );
}

#[test]
fn a_table_is_the_same_bits_built_twice_and_another_for_another_step() {
    let f = tf(&[(10.0, 0.2, 0.0), (60.0, 0.9, 0.15), (200.0, 1.0, 0.8)]);
    let (a, b) = (table(&f, 0.5), table(&f, 0.5));
    assert!(
        a.0 == b.0
            && a.1
                .iter()
                .zip(&b.1)
                .all(|(x, y)| x.to_array().map(f32::to_bits) == y.to_array().map(f32::to_bits))
    );
    let other = table(&f, 0.25);
    assert_ne!(a.1, other.1);
    assert_eq!(a.0.key(), other.0.key(), "the step moves no entry's place");
}

#[test]
fn every_cell_is_a_number_and_opacities_stay_in_range() {
    let f = tf(&[
        (0.0, 0.0, 0.0),
        (30.0, 1.0, 1.0),
        (31.0, 0.3, 0.0),
        (255.0, 0.7, 1.0),
    ]);
    for dt in [1.0 / 64.0, 0.5, 2.0] {
        let (_, cells) = table(&f, dt);
        for c in &cells {
            assert!(c.is_finite(), "{c}");
            assert!((0.0..=1.0).contains(&c.w), "{c}");
        }
    }
}

#[test]
fn storage_of_another_length_and_a_bad_step_are_refused() {
    let f = tf(&[(0.0, 0.0, 0.0), (1.0, 1.0, 1.0)]);
    let layout = segments::Layout::of(&f, 1.0).expect("a step");
    let mut short = vec![Vec4::ZERO; segments::LEN - 1];
    assert_eq!(
        segments::build(&f, &layout, &mut short),
        Err(SegmentsError::Length {
            got: segments::LEN - 1
        })
    );
    for dt in [f32::NAN, 0.0, -1.0, f32::INFINITY] {
        assert!(
            matches!(segments::Layout::of(&f, dt), Err(SegmentsError::Step(_))),
            "{dt}"
        );
    }
    assert!(Segments::new(layout, &short).is_err());
}

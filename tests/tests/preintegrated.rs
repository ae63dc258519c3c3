//! Pre-integrated compositing (`compositing = "pre-integrated"`, fast tier): a segment over
//! which the value runs linearly integrates the transfer function's thin features exactly
//! where sampling misses them (an end-to-end analytic case); its images are bit-identical on
//! every cluster size, partition, fabric and way of skipping; and two faults are caught: a
//! table built for another step, and skipping that does not ask the segment's front.

use voxcube::fabric::{sim, threads, RunConfig};
use voxcube::input::dataset::{Volume, VolumeData};
use voxcube::input::scene::{DatasetJob, Scene};
use voxcube::memory::segments::SegmentTable;
use voxcube::memory::storage::SkipMode;
use voxcube::run::render::{render, render_skipping};
use voxcube_kernel::node::topology::Layout;
use voxcube_kernel::optics::segments::{self, Segments};
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

//! Accuracy tiers: the fast tier is bit-identical on every cluster size, partition and fabric,
//! as the exact tier is; it stays within its bounds of the exact image (PSNR ≥ 40 dB and
//! coverage-mask IoU ≥ 0.995) on the test scenes, the default scene and SOD's views; and a
//! classification table built for another Δt changes the image, so the comparisons catch it.

use voxcube::fabric::{sim, threads, RunConfig};
use voxcube::input::scene::{DatasetJob, Scene};
use voxcube::run::render::render;
use voxcube_kernel::node::topology::Layout;
use voxcube_kernel::trace::view::{Accuracy, View};
use voxcube_tests::in_tier;

/// The test scenes, on the built-in molecule, small images.
const SCENES: &str = include_str!("scenes.toml");

fn scene(text: &str) -> Vec<DatasetJob> {
    Scene::parse(text, "test", std::path::Path::new("."))
        .and_then(Scene::load)
        .unwrap_or_else(|e| panic!("{e}"))
}

/// PSNR of `b` against `a` over the RGB channels, dB (infinite when equal).
fn psnr(a: &[[u8; 4]], b: &[[u8; 4]]) -> f64 {
    let (mut sum, mut n) = (0.0f64, 0usize);
    for (p, q) in a.iter().zip(b) {
        for c in 0..3 {
            let d = f64::from(p[c]) - f64::from(q[c]);
            sum += d * d;
            n += 1;
        }
    }
    let mse = sum / n.max(1) as f64;
    if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (255.0f64 * 255.0 / mse).log10()
    }
}

/// Intersection over union of the pixels that differ from `background` in either image.
fn mask_iou(a: &[[u8; 4]], b: &[[u8; 4]], background: [u8; 3]) -> f64 {
    let shows = |p: &[u8; 4]| p[..3] != background;
    let (mut both, mut either) = (0usize, 0usize);
    for (p, q) in a.iter().zip(b) {
        both += usize::from(shows(p) && shows(q));
        either += usize::from(shows(p) || shows(q));
    }
    if either == 0 {
        1.0
    } else {
        both as f64 / either as f64
    }
}

fn background(view: &View) -> [u8; 3] {
    let b = voxcube_kernel::trace::pixel::rgba8(view.spec().background);
    [b[0], b[1], b[2]]
}

/// Fast against exact on every view of `jobs`, within the bounds; the figures, printed.
fn within_bounds(jobs: &[DatasetJob]) -> usize {
    let mut approximated = 0;
    for job in jobs {
        for v in &job.views {
            let exact = render(&job.volume, &in_tier(&v.view, &job.volume, Accuracy::Exact))
                .expect("renders")
                .pixels;
            let fast_view = in_tier(&v.view, &job.volume, Accuracy::Fast);
            approximated += usize::from(!fast_view.approximations().is_empty());
            let fast = render(&job.volume, &fast_view).expect("renders").pixels;
            let (db, iou) = (
                psnr(&exact, &fast),
                mask_iou(&exact, &fast, background(&v.view)),
            );
            eprintln!(
                "{}/{}: fast against exact: PSNR {db:.1} dB, mask IoU {iou:.4}",
                job.name, v.name
            );
            assert!(db >= 40.0, "{}/{}: PSNR {db:.2} dB", job.name, v.name);
            assert!(iou >= 0.995, "{}/{}: mask IoU {iou:.4}", job.name, v.name);
        }
    }
    approximated
}

#[test]
fn the_fast_tier_is_bit_identical_on_every_cluster_size_partition_and_fabric() {
    let jobs = scene(SCENES);
    let job = &jobs[0];
    let mut approximated = 0;
    for v in &job.views {
        let view = in_tier(&v.view, &job.volume, Accuracy::Fast);
        approximated += usize::from(!view.approximations().is_empty());
        let one = render(&job.volume, &view).expect("renders").pixels;
        for (size, seed) in [(2u32, 1u64), (3, 2), (4, 3), (8, 4)] {
            let cfg = RunConfig::cluster(size, seed).expect("layout");
            let run = sim::run(&job.volume, &view, &cfg).unwrap_or_else(|e| panic!("{e}"));
            assert!(
                run.pixels == one,
                "{} on {size} nodes: image differs",
                v.name
            );
        }
        // Uneven slabs, and two clusters.
        let nx = job.volume.grid.dims()[0];
        let cfg = RunConfig {
            layout: Layout::new(2, 3).expect("layout"),
            cuts: Some(vec![0, 5, nx - 9, nx]),
            ..RunConfig::machine(2, 3, 7).expect("layout")
        };
        let run = sim::run(&job.volume, &view, &cfg).unwrap_or_else(|e| panic!("{e}"));
        assert!(
            run.pixels == one,
            "{} on uneven slabs: image differs",
            v.name
        );
        for (clusters, size) in [(2u32, 1u32), (1, 4)] {
            let cfg = RunConfig::machine(clusters, size, 1).expect("layout");
            let run = threads::run(&job.volume, &view, &cfg, 2).unwrap_or_else(|e| panic!("{e}"));
            assert!(
                run.pixels == one,
                "{} on threads, {clusters} clusters of {size}: image differs",
                v.name
            );
        }
    }
    assert!(approximated > 0, "no test view called for an approximation");
}

#[test]
fn the_fast_tier_stays_within_its_bounds_on_the_test_scenes_and_the_default() {
    let mut jobs = scene(SCENES);
    jobs.extend(
        Scene::default_scene()
            .and_then(Scene::load)
            .expect("default"),
    );
    assert!(
        within_bounds(&jobs) > 0,
        "no view called for an approximation"
    );
}

#[test]
fn the_fast_tier_stays_within_its_bounds_on_sod() {
    let Some(jobs) = voxcube_tests::sod_jobs() else {
        return;
    };
    assert!(
        within_bounds(&jobs) > 0,
        "SOD's composited view is approximated"
    );
}

#[test]
fn negative_control_a_table_for_another_step_changes_the_image() {
    let jobs = scene(SCENES);
    let job = &jobs[0];
    let v = job
        .views
        .iter()
        .find(|v| v.name == "composite")
        .expect("the composited test view");
    let view = in_tier(&v.view, &job.volume, Accuracy::Fast);
    let right = render(&job.volume, &view).expect("renders").pixels;
    let stale = view.clone().with_stale_table(view.spec().dt * 0.5);
    let wrong = render(&job.volume, &stale).expect("renders").pixels;
    let differ = right.iter().zip(&wrong).filter(|(a, b)| a != b).count();
    assert!(
        differ > 0,
        "a table for half the step left every pixel as it was"
    );
}

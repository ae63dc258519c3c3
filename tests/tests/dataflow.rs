//! Ray dataflow in a cluster: the image of `cd` nodes is bit-identical to the single-node
//! image, for every test scene, cluster size, scheduler seed and partition, uneven ones too; and
//! a negative control shows the comparison catches a sample that moves.

use proptest::prelude::*;
use voxcube::fabric::sim;
use voxcube::fabric::RunConfig;
use voxcube::input::scene::{DatasetJob, Scene};
use voxcube::memory::storage::SkipMode;
use voxcube::run::render::{render, render_skipping};
use voxcube_kernel::node::topology::Layout;
use voxcube_kernel::node::worker::{Generation, Mutants};
use voxcube_kernel::optics::shade::Light;
use voxcube_kernel::trace::view::View;
use voxcube_kernel::volume::grid::Model;
use voxcube_kernel::Vec3;
use voxcube_tests::*;

fn scene(text: &str) -> Vec<DatasetJob> {
    Scene::parse(text, "test", std::path::Path::new("."))
        .and_then(Scene::load)
        .unwrap_or_else(|e| panic!("{e}"))
}

fn config(size: u32, seed: u64) -> RunConfig {
    RunConfig::cluster(size, seed).expect("layout")
}

/// The test scenes of the issue, on the built-in molecule, small images.
const SCENES: &str = include_str!("scenes.toml");

#[test]
fn every_test_scene_is_bit_identical_on_every_cluster_size_and_seed() {
    let jobs = scene(SCENES);
    let job = &jobs[0];
    for (v, view) in job.views.iter().enumerate() {
        // Without skipping, so the work counters must match exactly too (skipping changes
        // which samples are evaluated, never the image: tests/skipping.rs).
        let one = render_skipping(&job.volume, &view.view, SkipMode::OFF).expect("renders");
        assert_eq!(one.counters.non_finite_pixels, 0);
        for size in [1u32, 2, 3, 4, 8, 16] {
            for seed in [1u64, 2, 3] {
                let run = sim::run(
                    &job.volume,
                    &view.view,
                    &RunConfig {
                        skipping: SkipMode::OFF,
                        ..config(size, seed + 100 * v as u64)
                    },
                )
                .unwrap_or_else(|e| panic!("{} on {size} nodes: {e}", view.name));
                assert!(
                    run.pixels == one.pixels,
                    "{} on {size} nodes, seed {seed}: image differs",
                    view.name
                );
                assert_eq!(
                    run.counters().samples,
                    one.counters.samples,
                    "{}: samples",
                    view.name
                );
                assert_eq!(
                    run.counters().slab_misses,
                    0,
                    "{}: a read left a slab",
                    view.name
                );
                assert_eq!(
                    run.counters().shadow_rays,
                    one.counters.shadow_rays,
                    "{}",
                    view.name
                );
                assert_eq!(
                    run.counters().transparency_rays,
                    one.counters.transparency_rays,
                    "{}",
                    view.name
                );
            }
        }
    }
}

#[test]
fn rays_really_cross_slabs_in_these_scenes() {
    // The identity above means something only if rays and results do travel between nodes.
    let jobs = scene(SCENES);
    let job = &jobs[0];
    for view in &job.views {
        let run = sim::run(&job.volume, &view.view, &config(8, 9)).expect("runs");
        let forwarded: u64 = run
            .nodes
            .iter()
            .map(|n| n.stats.forwarded_next + n.stats.forwarded_prev + n.stats.forwarded_far)
            .sum();
        let returned: u64 = run.nodes.iter().map(|n| n.stats.returned).sum();
        if view.name == "along-minus-y" {
            // Rays parallel to the slabs, and no shadow rays: nothing ever leaves its slab.
            assert_eq!((forwarded, returned), (0, 0), "{}", view.name);
        } else {
            assert!(forwarded > 0, "{}: no ray crossed a slab", view.name);
            assert!(returned > 0, "{}: no result went home", view.name);
        }
    }
}

#[test]
fn uneven_partitions_and_centralized_generation_are_identical() {
    let jobs = scene(SCENES);
    let job = &jobs[0];
    let ghost = job.views[0].view.ghost_planes();
    assert_eq!(ghost, 3);
    let partitions: [&[u32]; 4] = [
        &[0, 1, 2, 40, 41, 97], // slabs of one plane
        &[0, 45, 47, 48, 97],   // slabs narrower than the ghost width
        &[0, 96, 97],           // one plane at the far end
        &[0, 10, 11, 12, 13, 14, 15, 16, 17, 97],
    ];
    for (v, view) in job
        .views
        .iter()
        .enumerate()
        .filter(|(v, _)| v % 2 == 0 || *v == 5)
    {
        let one = render(&job.volume, &view.view).expect("renders").pixels;
        for cuts in partitions {
            for seed in [5u64, 6] {
                let cfg = RunConfig {
                    layout: Layout::new(1, cuts.len() as u32 - 1).expect("layout"),
                    cuts: Some(cuts.to_vec()),
                    ..config(1, seed + v as u64)
                };
                let run = sim::run(&job.volume, &view.view, &cfg)
                    .unwrap_or_else(|e| panic!("{}: {e}", view.name));
                assert!(
                    run.pixels == one,
                    "{} with cuts {cuts:?}: image differs",
                    view.name
                );
                assert_eq!(run.counters().slab_misses, 0);
            }
        }
        let cfg = RunConfig {
            generation: Generation::Centralized,
            ..config(4, 77)
        };
        let run = sim::run(&job.volume, &view.view, &cfg)
            .unwrap_or_else(|e| panic!("{}: {e}", view.name));
        assert!(
            run.pixels == one,
            "{} with centralized generation: image differs",
            view.name
        );
    }
}

#[test]
fn negative_control_a_shortened_step_at_a_boundary_changes_the_image() {
    let jobs = scene(SCENES);
    let job = &jobs[0];
    // Surfaces (few rays cross a boundary near a surface) and compositing (every crossing ray
    // integrates the moved samples).
    for (v, at_least) in [(0usize, 1usize), (2, 100)] {
        let view = &job.views[v].view;
        let one = render(&job.volume, view).expect("renders").pixels;
        let cfg = RunConfig {
            mutants: Mutants {
                shorten_step_at_boundary: true,
                ..Mutants::default()
            },
            ..config(8, 1)
        };
        // Caught either way: the image differs, or a ray bounced back against its direction
        // breaks the flow-control invariant.
        match sim::run(&job.volume, view, &cfg) {
            Ok(run) => {
                let differing = one.iter().zip(&run.pixels).filter(|(a, b)| a != b).count();
                assert!(
                    differing >= at_least,
                    "{}: the comparison must catch moved samples; {differing} pixels differ",
                    job.views[v].name
                );
            }
            Err(e) => assert!(e.to_string().contains("invariant"), "{e}"),
        }
        // And the same comparison passes without the fault.
        let run = sim::run(&job.volume, view, &config(8, 1)).expect("runs");
        assert!(run.pixels == one);
    }
}

#[test]
fn the_same_seed_gives_the_same_run() {
    let jobs = scene(SCENES);
    let view = &jobs[0].views[4].view;
    let a = sim::run(&jobs[0].volume, view, &config(4, 42)).expect("runs");
    let b = sim::run(&jobs[0].volume, view, &config(4, 42)).expect("runs");
    let c = sim::run(&jobs[0].volume, view, &config(4, 43)).expect("runs");
    assert_eq!(
        (a.events, a.messages, a.bytes),
        (b.events, b.messages, b.bytes)
    );
    assert_eq!(a.nodes, b.nodes);
    assert_ne!(
        a.events, c.events,
        "a different seed gives a different schedule"
    );
    assert!(a.pixels == c.pixels);
}

fn random_view(
    volume: &voxcube::input::dataset::Volume,
    pick: u8,
    eye: Vec3,
    dt: f32,
    voxel: bool,
) -> View {
    let dims = volume.grid.dims();
    let centre = Vec3::new(
        dims[0] as f32 - 1.0,
        dims[1] as f32 - 1.0,
        dims[2] as f32 - 1.0,
    ) * 0.5;
    let cam = if pick % 2 == 0 {
        ortho(eye, centre, Vec3::Y, 14.0)
    } else {
        perspective(eye, centre, Vec3::Y, 55.0)
    };
    let model = if voxel { Model::Voxel } else { Model::Cell };
    let spot = Light::point(centre + Vec3::new(0.5, 0.3, 0.2), Vec3::ONE, true).expect("light");
    let sun = Light::directional(Vec3::new(1.0, -0.5, 0.2), Vec3::splat(0.8), true).expect("light");
    let spec = match pick % 4 {
        0 | 1 => lit(
            spec(
                cam,
                10,
                8,
                model,
                dt,
                surfaces(&[(60.0, 0.5), (140.0, 0.2), (200.0, 0.0)]),
            ),
            &[spot, sun],
        ),
        2 => lit(spec(cam, 10, 8, model, dt, constant_transfer(0.15)), &[]),
        _ => spec(cam, 10, 8, model, dt, surfaces(&[(100.0, 0.6)])),
    };
    view(spec, volume)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Random small volumes, views, steps, partitions and seeds: bit-identical images.
    #[test]
    fn random_scenes_and_partitions_are_bit_identical(
        dims in (2u32..14, 2u32..8, 2u32..8),
        seed in any::<u64>(),
        pick in any::<u8>(),
        eye in prop::array::uniform3(-15.0f32..25.0),
        dt in 0.05f32..2.0,
        voxel in any::<bool>(),
        cut_bits in any::<u16>(),
    ) {
        let dims = [dims.0, dims.1, dims.2];
        let volume = volume_u8(dims, Vec3::ONE, |x, y, z| {
            let h = (seed ^ (u64::from(x) << 32 | u64::from(y) << 16 | u64::from(z))).wrapping_mul(0x9E37_79B9_7F4A_7C15);
            (h >> 56) as u8
        });
        let eye = Vec3::from_array(eye);
        let centre = Vec3::new(dims[0] as f32 - 1.0, dims[1] as f32 - 1.0, dims[2] as f32 - 1.0) * 0.5;
        prop_assume!((eye - centre).length() > 0.5 && (eye - centre).normalize().cross(Vec3::Y).length() > 0.05);
        let v = random_view(&volume, pick, eye, dt, voxel);
        let one = render(&volume, &v).expect("renders").pixels;
        // Cuts: plane x starts a new slab where bit x of cut_bits is set.
        let mut cuts = vec![0u32];
        cuts.extend((1..dims[0]).filter(|x| cut_bits & (1 << x) != 0));
        cuts.push(dims[0]);
        let cfg = RunConfig { layout: Layout::new(1, cuts.len() as u32 - 1).expect("layout"), cuts: Some(cuts.clone()), ..config(1, seed) };
        let run = sim::run(&volume, &v, &cfg).map_err(|e| TestCaseError::fail(e.to_string()))?;
        prop_assert!(run.pixels == one, "cuts {:?}: image differs", cuts);
        prop_assert_eq!(run.counters().slab_misses, 0);
    }
}

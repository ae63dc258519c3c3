//! Empty-space skipping changes no pixel: every test scene, directly and on clusters, and SOD,
//! render the same bits with skipping off, with one block per jump and with leaps over every
//! empty block around, while skipping really skips and leaping really leaps.

use voxcube::dataset::{Volume, VolumeData};
use voxcube::fabric::sim::{self, SimConfig};
use voxcube::fabric::{SkipMode, Skipping};
use voxcube::render::render_skipping;
use voxcube::scene::Scene;
use voxcube_kernel::grid::Grid;
use voxcube_kernel::pixel::rgba8;
use voxcube_kernel::sample::Sample;
use voxcube_kernel::slab::Slab;
use voxcube_kernel::trace::trace_pixel;
use voxcube_kernel::view::View;

fn check(text: &str, file: &str) {
    let jobs = Scene::parse(text, file, std::path::Path::new("."))
        .and_then(Scene::load)
        .unwrap_or_else(|e| panic!("{e}"));
    for job in &jobs {
        for v in &job.views {
            let off = render_skipping(&job.volume, &v.view, SkipMode::OFF).expect("renders");
            let blocks = render_skipping(&job.volume, &v.view, SkipMode::BLOCKS).expect("renders");
            let on = render_skipping(&job.volume, &v.view, SkipMode::LEAPS).expect("renders");
            for (mode, r) in [("skipping", &blocks), ("leaping", &on)] {
                assert!(
                    r.pixels == off.pixels,
                    "{}/{}: {mode} changed the image",
                    job.name,
                    v.name
                );
            }
            assert_eq!(off.counters.skipped, 0);
            // A leap skips exactly the samples that one-block jumps skip, only in fewer jumps.
            assert_eq!(on.counters, blocks.counters, "{}/{}", job.name, v.name);
            for (size, seed, leap) in [(3u32, 1u64, true), (8, 2, true), (3, 3, false)] {
                let cfg = SimConfig {
                    skipping: if leap {
                        SkipMode::LEAPS
                    } else {
                        SkipMode::BLOCKS
                    },
                    ..SimConfig::cluster(size, seed).expect("layout")
                };
                let run = sim::run(&job.volume, &v.view, &cfg).expect("runs");
                assert!(
                    run.pixels == off.pixels,
                    "{}/{} on {size} nodes (leap {leap}): skipping changed the image",
                    job.name,
                    v.name
                );
            }
            eprintln!(
                "{}/{}: {} of {} lattice samples skipped",
                job.name,
                v.name,
                on.counters.skipped,
                on.counters.skipped + on.counters.samples
            );
        }
    }
}

#[test]
fn skipping_changes_no_pixel_on_the_test_scenes() {
    check(include_str!("scenes.toml"), "scenes.toml");
    let jobs = Scene::default_scene()
        .and_then(Scene::load)
        .expect("default");
    let on =
        render_skipping(&jobs[0].volume, &jobs[0].views[0].view, SkipMode::LEAPS).expect("renders");
    assert!(
        on.counters.skipped > on.counters.samples,
        "most of the default scene is empty and is skipped"
    );
}

#[test]
fn skipping_changes_no_pixel_on_sod() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/sod.toml");
    if !path.is_file() || !voxcube_tests::shared_data().is_dir() {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI is set but the shared data is missing"
        );
        return;
    }
    let text = std::fs::read_to_string(&path).expect("scene").replace(
        "../../shared/data",
        &voxcube_tests::shared_data().display().to_string(),
    );
    check(&text, "sod.toml");
}

/// Every pixel of `traced` on `volume`, whose blocks leap by the distances built for
/// `leaps_of`.
fn trace_with_leaps_of(volume: &Volume, traced: &View, leaps_of: &View) -> Vec<[u8; 4]> {
    match &volume.data {
        VolumeData::U8(d) => trace_typed(volume.grid, d, traced, leaps_of),
        VolumeData::U16(d) => trace_typed(volume.grid, d, traced, leaps_of),
        VolumeData::F32(d) => trace_typed(volume.grid, d, traced, leaps_of),
    }
}

fn trace_typed<T: Sample>(grid: Grid, data: &[T], traced: &View, leaps_of: &View) -> Vec<[u8; 4]> {
    let slab = Slab::whole(grid, data).expect("slab");
    let skipping = Skipping::build(&slab, leaps_of, SkipMode::LEAPS);
    let slab = skipping.apply(slab);
    let mut counters = Default::default();
    (0..traced.pixel_count() as u32)
        .map(|p| rgba8(trace_pixel(traced, &slab, p, &mut counters)))
        .collect()
}

/// Negative control: the marcher really leaps by the map it is given. A map built for a
/// higher iso value, whose empty blocks reach further, makes it leap over the lower surface.
#[test]
fn a_leap_map_built_for_another_view_changes_the_image() {
    let text = r#"
[[datasets]]
name = "molecule"
builtin = "molecule"
[[datasets.views]]
name = "low"
width = 96
height = 72
[[datasets.views.surfaces]]
iso = 40.0
[[datasets.views]]
name = "high"
width = 96
height = 72
[[datasets.views.surfaces]]
iso = 200.0
"#;
    let jobs = Scene::parse(text, "<leaps>", std::path::Path::new("."))
        .and_then(Scene::load)
        .unwrap_or_else(|e| panic!("{e}"));
    let job = &jobs[0];
    let (low, high) = (&job.views[0].view, &job.views[1].view);
    let own = trace_with_leaps_of(&job.volume, low, low);
    let foreign = trace_with_leaps_of(&job.volume, low, high);
    let reference = render_skipping(&job.volume, low, SkipMode::OFF).expect("renders");
    assert!(
        own == reference.pixels,
        "the view's own map changes no pixel"
    );
    let changed = own.iter().zip(&foreign).filter(|(a, b)| a != b).count();
    assert!(
        changed > 0,
        "a map built for iso 200 must hide parts of the iso-40 surface"
    );
}

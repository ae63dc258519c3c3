//! Empty-space skipping changes no pixel: every test scene, directly and on clusters, and SOD,
//! render the same bits with skipping on and off, while skipping really skips.

use voxcube::fabric::sim::{self, SimConfig};
use voxcube::render::render_skipping;
use voxcube::scene::Scene;

fn check(text: &str, file: &str) {
    let jobs = Scene::parse(text, file, std::path::Path::new("."))
        .and_then(Scene::load)
        .unwrap_or_else(|e| panic!("{e}"));
    for job in &jobs {
        for v in &job.views {
            let off = render_skipping(&job.volume, &v.view, false).expect("renders");
            let on = render_skipping(&job.volume, &v.view, true).expect("renders");
            assert!(
                on.pixels == off.pixels,
                "{}/{}: skipping changed the image",
                job.name,
                v.name
            );
            assert_eq!(off.counters.skipped, 0);
            for (size, seed) in [(3u32, 1u64), (8, 2)] {
                let cfg = SimConfig {
                    skip: true,
                    ..SimConfig::cluster(size, seed).expect("layout")
                };
                let run = sim::run(&job.volume, &v.view, &cfg).expect("runs");
                assert!(
                    run.pixels == off.pixels,
                    "{}/{} on {size} nodes: skipping changed the image",
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
    let on = render_skipping(&jobs[0].volume, &jobs[0].views[0].view, true).expect("renders");
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

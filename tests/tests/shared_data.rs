//! The real volumes in `../shared/data` load with the right dimensions and value statistics
//! (as its README states them) and render through the example scenes. Without the folder the
//! tests skip with a message — except under CI (`CI` set), where a missing folder fails.

use std::path::{Path, PathBuf};
use voxcube::render::render;
use voxcube::scene::Scene;

fn data_or_skip() -> Option<PathBuf> {
    let dir = voxcube_tests::shared_data();
    if dir.is_dir() {
        return Some(dir);
    }
    assert!(
        std::env::var_os("CI").is_none(),
        "CI is set but the shared data folder {} is missing",
        dir.display()
    );
    eprintln!("skipping: {} not found", dir.display());
    None
}

fn scene_file(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scenes")
        .join(name)
}

/// Load a scene, check its one dataset's dims and statistics, render every view.
fn check(scene: &str, dims: [u32; 3], min: f64, max: f64, mean: f64) {
    if data_or_skip().is_none() {
        return;
    }
    let jobs = Scene::from_file(&scene_file(scene))
        .and_then(Scene::load)
        .unwrap_or_else(|e| panic!("{e}"));
    let job = &jobs[0];
    assert_eq!(job.volume.grid.dims(), dims);
    let s = job.volume.stats();
    assert_eq!((s.min, s.max), (min, max), "{scene}: {s}");
    assert!(
        (s.mean - mean).abs() < 0.005,
        "{scene}: mean {} vs {mean}",
        s.mean
    );
    for v in &job.views {
        let r = render(&job.volume, &v.view).expect("renders");
        assert_eq!(r.counters.non_finite_pixels, 0);
        assert_eq!(r.counters.slab_misses, 0);
        let lit = r.pixels.iter().filter(|p| p[..3] != [0, 0, 0]).count();
        assert!(
            lit > r.pixels.len() / 20,
            "{scene}/{}: only {lit} pixels show anything",
            v.name
        );
    }
}

#[test]
fn sod_loads_and_renders() {
    check("sod.toml", [97, 97, 116], 0.0, 255.0, 7.46);
}

#[test]
fn brainsmall_den_loads_and_renders() {
    check("brainsmall.toml", [128, 128, 84], 0.0, 202.0, 14.01);
}

#[test]
fn neghip_nrrd_loads_and_renders() {
    check("neghip.toml", [66, 66, 66], 0.0, 255.0, 16.78);
}

#[test]
fn sod_paper_view_projects_onto_the_papers_area() {
    if data_or_skip().is_none() {
        return;
    }
    let jobs = Scene::from_file(&scene_file("sod.toml"))
        .and_then(Scene::load)
        .unwrap_or_else(|e| panic!("{e}"));
    let v = &jobs[0].views[0];
    let r = render(&jobs[0].volume, &v.view).expect("renders");
    // The paper: "the projection of the dataset on the image plane covers 301x194 pixels".
    let (w, h) = (301.0 * 194.0, r.counters.primary_rays as f64);
    assert!(
        (h / w - 1.0).abs() < 0.02,
        "{h} primary rays vs the paper's {w}"
    );
}

#[test]
fn sod_renders_identically_on_one_and_sixteen_nodes() {
    use voxcube::render::{render_on, Fabric, Machine};
    if data_or_skip().is_none() {
        return;
    }
    let jobs = Scene::from_file(&scene_file("sod.toml"))
        .and_then(Scene::load)
        .unwrap_or_else(|e| panic!("{e}"));
    let job = &jobs[0];
    for v in &job.views {
        let one = render(&job.volume, &v.view).expect("renders");
        let machine = Machine::new(Fabric::Sim, 16, 1, 16);
        for (fabric, nodes, clusters) in [
            (Fabric::Threads, 16, 1),
            (Fabric::Threads, 128, 8),
            (Fabric::Sim, 128, 16),
            (Fabric::Sim, 64, 64),
        ] {
            let other = render_on(
                &job.volume,
                &v.view,
                &Machine::new(fabric, nodes, clusters, 5),
            )
            .unwrap_or_else(|e| panic!("{}: {e}", v.name));
            assert!(
                one.pixels == other.pixels,
                "sod/{} on {nodes}/{clusters} {fabric:?} differs from 1 node",
                v.name
            );
        }
        let sixteen =
            render_on(&job.volume, &v.view, &machine).unwrap_or_else(|e| panic!("{}: {e}", v.name));
        assert!(
            one.pixels == sixteen.pixels,
            "sod/{}: 16 nodes differ from 1",
            v.name
        );
        let crossings = &sixteen
            .distributed
            .as_ref()
            .expect("distributed")
            .boundary_crossings()[0];
        assert_eq!(crossings.len(), 15);
        assert!(
            crossings.iter().all(|&n| n > 0),
            "sod/{}: every boundary is crossed: {crossings:?}",
            v.name
        );
        eprintln!(
            "sod/{}: rays across the 15 slab boundaries: {crossings:?}",
            v.name
        );
    }
}

#[test]
fn the_ncube2_profile_is_calibrated_to_the_papers_one_node_time() {
    use voxcube::fabric::sim::{self, SimConfig};
    use voxcube::profile::MachineProfile;
    let Some(data) = data_or_skip() else { return };
    let mut notes = String::new();
    let job = voxcube::paper::dataset(Some(&data), &mut notes).expect("SOD");
    assert!(notes.is_empty(), "{notes}");
    // The paper's tracer, without empty-space skipping.
    let cfg = SimConfig {
        time: Some(MachineProfile::ncube2()),
        skip: false,
        ..SimConfig::cluster(1, 1).expect("layout")
    };
    let t = sim::run(&job.volume, &job.views[0].view, &cfg)
        .expect("runs")
        .time
        .expect("timed");
    assert!(
        (t.frame - 485.24).abs() < 0.01 * 485.24,
        "1-node SOD takes {:.2} s; the paper's is 485.24 s",
        t.frame
    );
}

#[test]
fn load_balancing_lowers_every_table_3_time_on_sod() {
    use voxcube::profile::MachineProfile;
    let Some(data) = data_or_skip() else { return };
    let mut notes = String::new();
    let job = voxcube::paper::dataset(Some(&data), &mut notes).expect("SOD");
    let (v, profile) = (&job.views[0].view, MachineProfile::ncube2());
    for cs in [16u32, 8, 4, 2] {
        let cuts = voxcube::paper::balance(&job, v, &profile, cs).expect("balances");
        for nodes in [64u32, 128] {
            let standard = voxcube::paper::timed(&job, v, &profile, nodes / cs, cs, None)
                .expect("runs")
                .frame;
            let balanced =
                voxcube::paper::timed(&job, v, &profile, nodes / cs, cs, Some(cuts.clone()))
                    .expect("runs")
                    .frame;
            assert!(
                balanced < standard,
                "{nodes} nodes, clusters of {cs}: balanced {balanced:.2} s against {standard:.2} s"
            );
        }
    }
}

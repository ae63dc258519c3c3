//! A node that stops answering mid-render is detected, not waited for forever: the run ends
//! with a report naming the node and the pixels lost, and the command exits non-zero.

use voxcube::fabric::sim;
use voxcube::fabric::{RunConfig, RunError};
use voxcube::scene::Scene;

#[test]
fn a_node_that_stops_is_named_with_the_pixels_lost() {
    let jobs = Scene::default_scene()
        .and_then(Scene::load)
        .expect("default scene");
    let job = &jobs[0];
    let view = &job.views[0].view;
    for (clusters, size, node) in [(1u32, 4u32, 2u16), (2, 4, 5), (4, 1, 3)] {
        let mut cfg = RunConfig::machine(clusters, size, 7).expect("layout");
        cfg.schedule.stop = Some((node, 40));
        let start = std::time::Instant::now();
        let err = sim::run(&job.volume, view, &cfg)
            .expect_err("a stopped node cannot complete the image");
        assert!(start.elapsed().as_secs() < 30, "detected in bounded time");
        match &err {
            RunError::Lost {
                node: n,
                missing,
                rows,
                ..
            } => {
                assert_eq!(*n, node, "{err}");
                assert!(*missing > 0 && !rows.is_empty(), "{err}");
            }
            other => panic!("expected a lost node, got {other}"),
        }
        eprintln!("{err}");
        // Control: the same run without the fault completes.
        cfg.schedule.stop = None;
        sim::run(&job.volume, view, &cfg).expect("completes without the fault");
    }
}

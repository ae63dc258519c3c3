//! Virtual time: timed simulated runs give the reference image, are repeatable, charge every
//! node's time to categories that add up to the frame time, and get faster with more nodes.

use voxcube::fabric::sim;
use voxcube::fabric::RunConfig;
use voxcube::input::scene::Scene;
use voxcube::memory::storage::SkipMode;
use voxcube::profile::MachineProfile;
use voxcube::run::render::render;

fn timed(clusters: u32, size: u32) -> RunConfig {
    RunConfig {
        time: Some(MachineProfile::ncube2()),
        ..RunConfig::machine(clusters, size, 1).expect("layout")
    }
}

#[test]
fn timed_runs_are_exact_repeatable_and_add_up() {
    let jobs = Scene::default_scene()
        .and_then(Scene::load)
        .expect("default scene");
    let job = &jobs[0];
    let v = &job.views[0].view;
    let reference = render(&job.volume, v).expect("renders").pixels;
    let mut frame = Vec::new();
    for (clusters, size) in [(1, 1), (2, 1), (4, 1), (1, 4), (2, 2)] {
        let run = sim::run(&job.volume, v, &timed(clusters, size)).expect("runs");
        assert!(run.pixels == reference, "{clusters}x{size}: image differs");
        let t = run.time.clone().expect("virtual time");
        let again = sim::run(&job.volume, v, &timed(clusters, size))
            .expect("runs")
            .time
            .expect("time");
        assert_eq!(t, again, "timed runs repeat exactly");
        for parts in &t.parts {
            let total: f64 = parts.iter().sum();
            assert!(
                total >= t.frame * (1.0 - 1e-9),
                "a node's categories ({total}) fall short of the frame ({})",
                t.frame
            );
        }
        frame.push(t.frame);
        eprintln!("{clusters} clusters of {size}: {:.2} s", t.frame);
    }
    assert!(
        frame[1] < frame[0] && frame[2] < frame[1],
        "image partition gets faster with nodes: {frame:?}"
    );
    assert!(
        frame[3] < frame[0],
        "ray dataflow on 4 nodes is faster than 1: {frame:?}"
    );
}

#[test]
fn static_load_balancing_lowers_the_time_of_an_unbalanced_cluster() {
    // Four slabs of the default scene's molecule are far from balanced: the paper's formula
    // (the plane shift included) must win clearly. (Table 3's claim on SOD is a data test.)
    let jobs = Scene::default_scene()
        .and_then(Scene::load)
        .expect("default scene");
    let job = &jobs[0];
    let v = &job.views[0].view;
    let profile = MachineProfile::ncube2();
    let uniform = voxcube::experiments::paper::timed(job, v, &profile, 1, 4, None)
        .expect("runs")
        .frame;
    let cuts = voxcube::experiments::paper::balance(job, v, &profile, 4).expect("balances");
    assert_eq!(cuts.len(), 5);
    let run = |shift: bool| {
        let cfg = RunConfig {
            time: Some(profile.clone()),
            cuts: Some(cuts.clone()),
            shift,
            skipping: SkipMode::OFF,
            ..RunConfig::cluster(4, 1).expect("layout")
        };
        sim::run(&job.volume, v, &cfg).expect("runs")
    };
    // The nodes shift planes by message; that takes time, and changes no pixel.
    let (shifted, loaded) = (run(true), run(false));
    let report = shifted.shift.as_ref().expect("a shift report");
    assert!(
        report.messages > 0 && report.seconds.is_some_and(|s| s > 0.0),
        "{report:?}"
    );
    let (a, b) = (shifted.time.expect("timed"), loaded.time.expect("timed"));
    assert!((a.frame - b.frame - report.seconds.unwrap_or(0.0)).abs() < 1e-9);
    assert_eq!(shifted.pixels, loaded.pixels);
    let balanced = voxcube::experiments::paper::timed(job, v, &profile, 1, 4, Some(cuts.clone()))
        .expect("runs")
        .frame;
    assert!((balanced - a.frame).abs() < 1e-9, "paper::timed shifts too");
    assert!(
        balanced < 0.95 * uniform,
        "balanced {balanced:.2} s (cuts {cuts:?}) against uniform {uniform:.2} s"
    );
}

#[test]
fn without_row_leaps_every_node_of_a_ring_sets_up_every_pixel_s_ray_once() {
    // The paper's distributed generation, which Table 2's large clusters pay for: a ring of
    // `size` sets up each primary ray `size` times, once on each node, however often a node
    // that could not start a ray yet sets it up again. Row leaps pass most of those a node
    // does not own (the control: far fewer set-ups, the same image).
    let jobs = Scene::default_scene()
        .and_then(Scene::load)
        .expect("default scene");
    let job = &jobs[0];
    let v = &job.views[0].view;
    let pixels = v.pixel_count();
    let run = |size: u32, skipping: SkipMode| {
        let cfg = RunConfig {
            skipping,
            ..RunConfig::machine(2, size, 1).expect("layout")
        };
        sim::run(&job.volume, v, &cfg).expect("runs")
    };
    let direct = render(&job.volume, v).expect("renders");
    for size in [1, 2, 4] {
        let off = run(size, SkipMode::OFF);
        assert_eq!(
            off.counters().rays_set_up,
            u64::from(size) * pixels,
            "{size} nodes a ring"
        );
        if size > 1 {
            let leaps = run(size, SkipMode::ALL);
            assert!(leaps.pixels == off.pixels && off.pixels == direct.pixels);
            assert!(
                leaps.counters().rays_set_up < off.counters().rays_set_up / 2,
                "row leaps set up {} rays, without them {}",
                leaps.counters().rays_set_up,
                off.counters().rays_set_up
            );
        }
    }
}

//! A node that stops answering mid-render loses no pixel when another cluster survives: the
//! host declares it lost, the surviving clusters re-trace its cluster's unfinished rows, and
//! the image is the fault-free one, every pixel once. With no cluster to spare the run ends
//! with a report naming the node and the pixels lost.

use voxcube::fabric::sim;
use voxcube::fabric::{RunConfig, RunError};
use voxcube::input::scene::{DatasetJob, Scene};

fn default_scene() -> Vec<DatasetJob> {
    Scene::default_scene()
        .and_then(Scene::load)
        .expect("default scene")
}

/// The fault-free image of `view`, rendered on one node.
fn fault_free(job: &DatasetJob, view: &voxcube_kernel::trace::view::View) -> Vec<[u8; 4]> {
    sim::run(
        &job.volume,
        view,
        &RunConfig::machine(1, 1, 1).expect("one"),
    )
    .expect("fault-free run")
    .pixels
}

#[test]
fn a_node_that_stops_in_the_only_cluster_is_named_with_the_pixels_lost() {
    let jobs = default_scene();
    let job = &jobs[0];
    let view = &job.views[0].view;
    let mut cfg = RunConfig::machine(1, 4, 7).expect("layout");
    cfg.schedule.stop = Some((2, 40));
    let start = std::time::Instant::now();
    let err = sim::run(&job.volume, view, &cfg).expect_err("no cluster survives");
    assert!(start.elapsed().as_secs() < 30, "detected in bounded time");
    match &err {
        RunError::Lost {
            node,
            missing,
            rows,
            ..
        } => {
            assert_eq!(*node, 2, "{err}");
            assert!(*missing > 0 && !rows.is_empty(), "{err}");
        }
        other => panic!("expected a lost node, got {other}"),
    }
    // Control: the same run without the fault completes.
    cfg.schedule.stop = None;
    sim::run(&job.volume, view, &cfg).expect("completes without the fault");
}

/// Stopped early, midway and late in the frame, on several cluster shapes up to rings of 16:
/// the fault-free image, the loss recorded, every re-traced pixel either filling a hole or
/// dropped as already held.
#[test]
fn surviving_clusters_re_trace_a_lost_cluster_s_rows_to_the_fault_free_image() {
    let jobs = default_scene();
    let job = &jobs[0];
    let view = &job.views[0].view;
    let pixels = view.pixel_count();
    for (clusters, size, node) in [(2u32, 4u32, 5u16), (4, 1, 3), (4, 2, 0), (2, 16, 20)] {
        let mut cfg = RunConfig::machine(clusters, size, 11).expect("layout");
        let clean = sim::run(&job.volume, view, &cfg).expect("fault-free run");
        assert!(clean.recovery.is_none());
        let steps = clean.nodes[usize::from(node)]
            .stats
            .sent
            .iter()
            .sum::<u64>();
        for after in [3, 40, steps.max(8) / 2] {
            cfg.schedule.stop = Some((node, after));
            let shape = format!("{clusters}x{size}, node {node} stopped after {after} steps");
            let run = sim::run(&job.volume, view, &cfg).unwrap_or_else(|e| panic!("{shape}: {e}"));
            assert!(run.pixels == clean.pixels, "{shape}: the image differs");
            let Some(r) = &run.recovery else {
                // Stopped after its cluster's last pixel: nothing to re-trace, nothing lost.
                continue;
            };
            assert_eq!(r.node, node, "{shape}");
            assert_eq!(u32::from(r.cluster), u32::from(node) / size, "{shape}");
            assert!(
                !r.by.contains(&r.cluster),
                "{shape}: the lost cluster re-traced"
            );
            assert!(r.retraced > 0 && r.retraced < pixels, "{shape}: {r}");
            let survivors = (clusters - 1) as usize;
            assert!(r.by.is_empty() || r.by.len() == survivors, "{shape}: {r}");
            eprintln!("{shape}: {r}");
        }
    }
}

/// On OS threads: a node no longer polled after so many polls is declared lost when it has
/// not been heard for `lost_after`, the surviving clusters re-trace its cluster's rows, and the
/// image is the simulator's fault-free one; with no cluster to spare the run fails naming it.
#[test]
fn on_threads_a_silent_node_is_declared_lost_and_its_rows_re_traced() {
    use voxcube::fabric::threads;
    let jobs = default_scene();
    let job = &jobs[0];
    let view = &job.views[0].view;
    let reference = fault_free(job, view);
    for (clusters, size, node, after) in [
        (2u32, 4u32, 5u16, 50u64),
        (4, 1, 3, 400),
        (4, 2, 0, 10),
        (2, 16, 20, 100),
    ] {
        let mut cfg = RunConfig::machine(clusters, size, 1).expect("layout");
        cfg.schedule.stop = Some((node, after));
        cfg.lost_after = std::time::Duration::from_secs(1);
        let shape = format!("{clusters}x{size}, node {node} silent after {after} polls");
        let run =
            threads::run(&job.volume, view, &cfg, 2).unwrap_or_else(|e| panic!("{shape}: {e}"));
        assert!(run.pixels == reference, "{shape}: the image differs");
        let r = run
            .recovery
            .as_ref()
            .unwrap_or_else(|| panic!("{shape}: nothing lost"));
        assert_eq!(r.node, node, "{shape}: {r}");
        assert!(
            r.declared_after_ms.is_some_and(|ms| ms >= 1000.0),
            "{shape}: {r}"
        );
        assert!(r.retraced > 0, "{shape}: {r}");
        eprintln!("{shape}: {r}");
    }
    let mut alone = RunConfig::machine(1, 4, 1).expect("layout");
    alone.schedule.stop = Some((2, 30));
    alone.lost_after = std::time::Duration::from_secs(1);
    match threads::run(&job.volume, view, &alone, 2) {
        Err(RunError::Lost {
            node: 2, missing, ..
        }) => assert!(missing > 0),
        other => panic!("one cluster cannot recover: {other:?}"),
    }
}

/// Exploration with a node stopped at a random step of every run, on every configuration of
/// two clusters or more: no run fails, every image is the fault-free one, and some runs had
/// rows to re-trace (the others' node stopped after its work was done).
#[test]
fn explored_with_a_node_stopped_in_every_run_no_pixel_is_lost() {
    use voxcube::experiments::explore::{configs, explore, inject_stop, recoverable, scenes};
    let job = scenes().expect("exploration scenes");
    let all = recoverable(&configs(&job));
    assert!(all.len() >= 20, "{} configurations", all.len());
    let found = explore(&job, &all, 1, &inject_stop);
    eprintln!("{found}");
    assert_eq!(found.failures(), 0, "{found}");
    assert_eq!(found.faults, found.runs);
    assert!(
        found.recovered > found.runs / 4 && found.retraced > 0,
        "{found}"
    );
}

/// In virtual time a loss costs time, and what it costs adds up: the host declares the node
/// lost `lost_after` after it stopped (or once the others are done), the survivors re-trace
/// after that, the image is the fault-free one, every node's categories still cover the
/// frame, and the timeline shows the lost node silent from its stop and the re-tracers busy
/// after the declaration.
#[test]
fn a_timed_run_recovers_and_prices_the_loss() {
    let jobs = default_scene();
    let job = &jobs[0];
    let view = &job.views[0].view;
    let timed = |stop| {
        let mut cfg = RunConfig {
            time: Some(voxcube::profile::MachineProfile::ncube2()),
            timeline: true,
            ..RunConfig::machine(2, 4, 3).expect("layout")
        };
        cfg.schedule.stop = stop;
        cfg.lost_after = std::time::Duration::from_secs(2);
        sim::run(&job.volume, view, &cfg).expect("runs")
    };
    let clean = timed(None);
    let lost = timed(Some((5, 60)));
    assert!(lost.pixels == clean.pixels, "the fault-free image");
    let recovery = lost.recovery.as_ref().expect("recovered");
    assert_eq!(recovery.node, 5);
    let (t0, t) = (
        clean.time.as_ref().expect("time"),
        lost.time.as_ref().expect("time"),
    );
    assert!(t.frame > t0.frame, "{} against {}", t.frame, t0.frame);
    for (n, parts) in t.parts.iter().enumerate() {
        let total: f64 = parts.iter().sum();
        assert!(
            total >= t.frame * (1.0 - 1e-9) && total <= t.end * (1.0 + 1e-9),
            "node {n}: categories {total} against the frame {} and the end {}",
            t.frame,
            t.end
        );
    }
    // The lost node computes nothing after it stopped; a re-tracer computes after the
    // declaration, at least `lost_after` after the stop.
    let computes = |n: usize| t.timeline[n].iter().filter(|s| s.kind == "compute");
    let stopped = computes(5).map(|s| s.end).fold(0.0, f64::max);
    let resumed = computes(0)
        .map(|s| s.start)
        .filter(|&s| s > stopped + 2.0)
        .count();
    assert!(resumed > 0, "node 0 re-traces after the declaration");
    assert!(stopped < t0.frame, "node 5 stopped early");
}

/// A second node lost during the re-trace takes its cluster out of it too: the clusters left
/// re-trace again and the frame is still the fault-free one, on the simulator and on threads.
/// With no cluster left the run fails, naming the pixels lost.
#[test]
fn a_node_lost_during_the_re_trace_takes_its_cluster_out_and_the_rest_finish() {
    use voxcube::fabric::threads;
    let jobs = default_scene();
    let job = &jobs[0];
    let view = &job.views[0].view;
    let reference = fault_free(job, view);
    // Node 3 (cluster 1) stops in the frame, node 0 (cluster 0) early in the re-trace.
    let faulty = |clusters| {
        let mut cfg = RunConfig::machine(clusters, 2, 5).expect("layout");
        cfg.schedule.stop = Some((3, 40));
        cfg.schedule.retrace_stop = Some((0, 5));
        cfg.lost_after = std::time::Duration::from_millis(500);
        cfg
    };
    type Run<'a> = dyn Fn(&RunConfig) -> Result<voxcube::fabric::Distributed, RunError> + 'a;
    let fabrics: [(&str, &Run<'_>); 2] = [
        ("sim", &|cfg| sim::run(&job.volume, view, cfg)),
        ("threads", &|cfg| threads::run(&job.volume, view, cfg, 2)),
    ];
    for (fabric, run) in fabrics {
        let done = run(&faulty(3)).unwrap_or_else(|e| panic!("{fabric}: {e}"));
        assert!(done.pixels == reference, "{fabric}: the image differs");
        let r = done.recovery.as_ref().expect("recovered");
        assert_eq!((r.node, r.cluster), (3, 1), "{fabric}: {r}");
        assert_eq!(r.also_lost, vec![0], "{fabric}: {r}");
        assert_eq!(r.by, vec![2], "{fabric}: {r}");
        assert!(r.retraced > 0, "{fabric}: {r}");
        // Two clusters: none is left for the second re-trace.
        match run(&faulty(2)) {
            Err(RunError::Lost { missing, .. }) => assert!(missing > 0, "{fabric}"),
            other => panic!("{fabric}: no cluster is left: {other:?}"),
        }
    }
}

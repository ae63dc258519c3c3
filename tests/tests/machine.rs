//! The whole machine: the 4 MiB node budget (refused up front, with the smallest cluster that
//! fits; measured high-water marks within budget), and images bit-identical for every cube
//! size and cluster size.

use voxcube::input::scene::Scene;
use voxcube::memory::budget::Profile;
use voxcube::run::render::{render, render_on, Fabric, Machine, RenderError};
use voxcube_kernel::volume::grid::Model;
use voxcube_kernel::Vec3;
use voxcube_tests::*;

#[test]
fn a_volume_too_big_for_one_node_renders_once_the_cluster_is_large_enough() {
    // 208³ u8: 9 MB, more than two 4 MiB nodes can hold.
    let n = 208u32;
    let volume = volume_u8([n; 3], Vec3::ONE, |x, y, z| {
        let d = [x, y, z].map(|v| v as f32 - 103.5);
        let r = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        (255.0 * (-(r - 60.0).powi(2) / 200.0).exp()) as u8
    });
    assert_eq!(volume.data.len(), 208 * 208 * 208);
    let c = Vec3::splat(103.5);
    let cam = ortho(
        c + Vec3::new(1.0, 0.6, 0.8).normalize() * 400.0,
        c,
        Vec3::Y,
        260.0,
    );
    let v = view(
        lit(
            spec(cam, 24, 20, Model::Cell, 1.0, surfaces(&[(100.0, 0.0)])),
            &[],
        ),
        &volume,
    );
    let reference = render(&volume, &v).expect("renders").pixels;
    for size in [1u32, 2] {
        let err = render_on(&volume, &v, &Machine::new(Fabric::Sim, size, 1, 1))
            .expect_err("does not fit");
        let msg = err.to_string();
        assert!(matches!(err, RenderError::Budget(_)), "{msg}");
        assert!(
            msg.contains("4194304 bytes per node")
                && msg.contains("smallest cluster that fits has 4 nodes"),
            "{msg}"
        );
    }
    for size in [4u32, 8, 16] {
        let run = render_on(&volume, &v, &Machine::new(Fabric::Sim, size, 1, 3))
            .unwrap_or_else(|e| panic!("{size}: {e}"));
        assert!(run.pixels == reference, "{size} nodes: image differs");
        let d = run.distributed.expect("distributed");
        for node in &d.nodes {
            assert!(
                node.memory.total() <= Profile::ncube2().node_memory,
                "node {}: {:?}",
                node.stats.node,
                node.memory
            );
            assert!(node.memory.slab > 0 && node.memory.buffer > 0);
        }
        // The threads fabric counts each node's slab, blocks, maps and masks alike.
        let threads = render_on(&volume, &v, &Machine::new(Fabric::Threads, size, 1, 3))
            .unwrap_or_else(|e| panic!("{size} on threads: {e}"));
        let t = threads.distributed.expect("distributed");
        for (s, t) in d.nodes.iter().zip(&t.nodes) {
            assert_eq!(
                s.memory.slab, t.memory.slab,
                "{size} nodes: node {}",
                s.stats.node
            );
        }
    }
}

/// The dataflow suite's test scenes, loaded.
fn test_scenes() -> Vec<voxcube::input::scene::DatasetJob> {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/tests/scenes.toml"))
        .expect("scenes");
    Scene::parse(&text, "scenes.toml", std::path::Path::new("."))
        .and_then(Scene::load)
        .expect("scenes")
}

#[test]
fn every_cube_and_cluster_size_gives_the_same_image() {
    // The test scenes of the dataflow suite, on 1 to 128 nodes in every cluster size.
    let job = &test_scenes()[0];
    for (i, v) in job.views.iter().enumerate() {
        let reference = render(&job.volume, &v.view).expect("renders").pixels;
        for k in 0..=7u32 {
            let nodes = 1u32 << k;
            for clusters in (0..=k).map(|i| 1u32 << i) {
                // Every cube size for the first views; a sample of shapes for the others.
                if i > 1 && (clusters != 1 && clusters != nodes && clusters != nodes / 2) {
                    continue;
                }
                // The threads fabric on every shape of the first view, and on the pure shapes.
                let fabric =
                    if (i == 0 || clusters == 1 || clusters == nodes) && (k + i as u32) % 2 == 0 {
                        Fabric::Threads
                    } else {
                        Fabric::Sim
                    };
                let m = Machine::new(fabric, nodes, clusters, u64::from(k) * 31 + i as u64);
                let result = render_on(&job.volume, &v.view, &m);
                if nodes / clusters > job.volume.grid.dims()[0] {
                    // More slabs than X planes: refused up front, clearly.
                    let err = result.expect_err("more slabs than planes");
                    assert!(err.to_string().contains("X planes"), "{err}");
                    continue;
                }
                let run =
                    result.unwrap_or_else(|e| panic!("{} on {nodes}/{clusters}: {e}", v.name));
                assert!(
                    run.pixels == reference,
                    "{} on {nodes} nodes in {clusters} clusters differs",
                    v.name
                );
            }
        }
    }
}

/// A ring of one holds the whole volume, and its worker traces each pixel's whole ray tree in
/// place, with no records or messages: the direct render's image and work, counted alike, on
/// every test view (shadows and transparency among them), on either in-process fabric.
#[test]
fn a_ring_of_one_does_the_direct_renders_work() {
    for job in &test_scenes() {
        for v in &job.views {
            let direct = render(&job.volume, &v.view).expect("renders");
            for fabric in [Fabric::Sim, Fabric::Threads] {
                let run = render_on(&job.volume, &v.view, &Machine::new(fabric, 2, 2, 0))
                    .unwrap_or_else(|e| panic!("{} on {fabric:?}: {e}", v.name));
                assert!(run.pixels == direct.pixels, "{} on {fabric:?}", v.name);
                assert_eq!(run.counters, direct.counters, "{} on {fabric:?}", v.name);
            }
        }
    }
}

#[test]
fn the_threads_fabric_matches_on_every_cube_size() {
    let job = &test_scenes()[0];
    for v in &job.views {
        let reference = render(&job.volume, &v.view).expect("renders").pixels;
        for k in 0..=7u32 {
            let nodes = 1u32 << k;
            for clusters in [1, nodes.min(2), nodes] {
                if nodes / clusters > job.volume.grid.dims()[0] {
                    continue;
                }
                let run = render_on(
                    &job.volume,
                    &v.view,
                    &Machine::new(Fabric::Threads, nodes, clusters, 0),
                )
                .unwrap_or_else(|e| panic!("{} on {nodes}/{clusters} threads: {e}", v.name));
                assert!(
                    run.pixels == reference,
                    "{} on {nodes} nodes in {clusters} clusters (threads) differs",
                    v.name
                );
            }
        }
    }
}

#[test]
fn the_threads_fabric_matches_on_any_number_of_threads() {
    // One thread: the calling thread polls every node and the host itself. Three and five:
    // more threads than this machine's cores, and shares of unequal size (16 nodes over 3
    // threads), with the host between the calling thread's rounds all the same.
    let job = &test_scenes()[0];
    for v in &job.views {
        let reference = render(&job.volume, &v.view).expect("renders").pixels;
        for threads in [1, 3, 5] {
            for (nodes, clusters) in [(2, 1), (4, 2), (16, 4)] {
                let mut m = Machine::new(Fabric::Threads, nodes, clusters, 0);
                m.threads = threads;
                let run = render_on(&job.volume, &v.view, &m).unwrap_or_else(|e| {
                    panic!("{} on {nodes}/{clusters}, {threads} threads: {e}", v.name)
                });
                assert!(
                    run.pixels == reference,
                    "{} on {nodes} nodes in {clusters} clusters, {threads} threads, differs",
                    v.name
                );
                // Every node reports, each with the busy time of whichever thread polled it.
                let d = run.distributed.expect("distributed");
                assert_eq!(d.nodes.len(), nodes as usize);
                for n in d.nodes.iter().filter(|n| n.stats.counters.samples > 0) {
                    assert!(n.busy > std::time::Duration::ZERO, "node {}", n.stats.node);
                }
            }
        }
    }
}

#[test]
fn every_in_process_fabric_says_how_much_of_its_wall_time_was_set_up() {
    let n = 24u32;
    let volume = volume_u8([n; 3], Vec3::ONE, |x, y, z| {
        ((x * 7 + y * 3 + z) % 200) as u8
    });
    let c = Vec3::splat(11.5);
    let cam = ortho(c + Vec3::new(1.0, 0.5, 0.7) * 60.0, c, Vec3::Y, 40.0);
    let v = view(
        spec(cam, 16, 12, Model::Cell, 0.5, surfaces(&[(120.0, 0.0)])),
        &volume,
    );
    for machine in [
        Machine::new(Fabric::Direct, 1, 1, 1),
        Machine::new(Fabric::Sim, 2, 1, 1),
        Machine::new(Fabric::Threads, 2, 2, 1),
    ] {
        let run = render_on(&volume, &v, &machine).expect("renders");
        let setup = run
            .setup
            .unwrap_or_else(|| panic!("{machine:?}: no set-up time"));
        assert!(
            setup <= run.wall,
            "{machine:?}: {setup:?} of {:?}",
            run.wall
        );
    }
}

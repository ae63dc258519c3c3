//! The real volumes in `../shared/data` load with the right dimensions and value statistics
//! (as its README states them) and render through the example scenes. Without the folder the
//! tests skip with a message — except under CI (`CI` set), where a missing folder fails.

use std::path::{Path, PathBuf};
use voxcube::input::scene::Scene;
use voxcube::run::render::render;

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

/// SOD as the paper's experiments load it, from the shared data folder.
fn paper_job() -> voxcube::input::scene::DatasetJob {
    let mut notes = String::new();
    let data = voxcube_tests::shared_data();
    let source = voxcube::experiments::paper::Source::Sod(&data);
    let job = voxcube::experiments::paper::dataset(source, &mut notes).expect("SOD loads");
    assert!(notes.is_empty(), "{notes}");
    job
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
    // That is 2 pixels per grid unit: the 97x97x116 voxels span (97 + 116)·cos 45° = 150.6
    // units across and 97 down. The rays sample the cell model, whose box is one unit
    // smaller each way: (96 + 115)·cos 45°·2 = 298.4 by 96·2 = 192 pixels.
    let px = 2.0;
    let cells = (96.0 + 115.0) * std::f64::consts::FRAC_1_SQRT_2 * px * 96.0 * px;
    let rays = r.counters.primary_rays as f64;
    assert!(
        (rays / cells - 1.0).abs() < 0.01,
        "{rays} primary rays against the cell box's {cells:.0} pixels"
    );
}

#[test]
fn sod_renders_identically_on_one_and_sixteen_nodes() {
    use voxcube::run::render::{render_on, Fabric, Machine};
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
fn the_experiments_take_sod_as_its_folder_or_its_file() {
    use voxcube::experiments::paper::{dataset, Source};
    use voxcube::experiments::sod::SOD_FILE;
    let Some(data) = data_or_skip() else { return };
    let mut notes = String::new();
    let folder = dataset(Source::Sod(&data), &mut notes).expect("SOD's folder");
    let file = dataset(Source::Sod(&data.join(SOD_FILE)), &mut notes).expect("SOD's file");
    assert_eq!(folder.volume.grid.dims(), [97, 97, 116]);
    assert_eq!(file.volume.stats().mean, folder.volume.stats().mean);
    assert!(notes.is_empty(), "{notes}");
}

#[test]
fn the_side_that_bench_instructions_counts_renders_each_sod_view_it_names() {
    use voxcube::experiments::instructions::count_frames;
    use voxcube::experiments::sod::SOD_FILE;
    let Some(data) = data_or_skip() else { return };
    let sod = data.join(SOD_FILE);
    // The counts are differences of runs that differ in their frames alone: without a frame
    // there is nothing to count; a frame of the surface view evaluates and skips samples.
    assert_eq!(
        count_frames("surfaces", 0, &sod).expect("loads"),
        "samples 0 skipped 0\n"
    );
    let line = count_frames("surfaces", 1, &sod).expect("renders");
    let counts: Vec<u64> = line
        .split_whitespace()
        .filter_map(|w| w.parse().ok())
        .collect();
    assert!(
        line.starts_with("samples ") && counts.len() == 2 && counts.iter().all(|&n| n > 0),
        "{line}"
    );
    let err = count_frames("no-such-view", 1, &sod).expect_err("an unknown view");
    assert!(err.contains("\"no-such-view\""), "{err}");
    let missing = voxcube::experiments::instructions::run(&data.join("absent.raw"))
        .expect_err("no SOD there")
        .to_string();
    assert!(missing.contains("absent.raw: SOD not found"), "{missing}");
}

/// Table 1 under `profile`: the one node (the sequential tracer) and each node count in the
/// cluster size that wins it, seconds.
fn table_1(profile: &voxcube::profile::MachineProfile) -> Vec<(u32, f64)> {
    use voxcube::experiments::paper::{sequential, timed, TABLE1};
    let job = paper_job();
    let view = &job.views[0].view;
    TABLE1
        .iter()
        .map(|&(p, _)| {
            let t = match p {
                1 => sequential(&job, view, profile).expect("renders"),
                // The winning sizes (`voxcube paper` tries every one): pure image partition
                // up to 64 nodes, pairs at 128.
                128 => timed(&job, view, profile, 64, 2, None).expect("runs").frame,
                _ => timed(&job, view, profile, p, 1, None).expect("runs").frame,
            };
            (p, t)
        })
        .collect()
}

#[test]
fn table_1_is_fitted_within_five_percent_and_its_efficiency_to_64_nodes_within_005() {
    use voxcube::experiments::paper::TABLE1;
    use voxcube::profile::MachineProfile;
    let Some(_) = data_or_skip() else { return };
    let efficiency =
        |rows: &[(u32, f64)], at: usize| rows[0].1 / rows[at].1 / f64::from(rows[at].0);
    let shipped = MachineProfile::ncube2();
    let ours = table_1(&shipped);
    for (at, (&(p, t), &(_, paper))) in ours.iter().zip(&TABLE1).enumerate() {
        // 128 nodes is the one row the model misses (+19%, efficiency 0.60 against 0.74:
        // docs/results.md says why); the fit weighs it like any other.
        if p == 128 {
            continue;
        }
        assert!(
            (t / paper - 1.0).abs() < 0.05,
            "{p} nodes take {t:.2} s; the paper's {paper:.2} s"
        );
        let (e, theirs) = (efficiency(&ours, at), efficiency(&TABLE1, at));
        assert!(
            (e - theirs).abs() <= 0.05,
            "{p} nodes: efficiency {e:.3}, the paper's {theirs:.3}"
        );
    }
    // Negative control: price the one node as a worker, a slab test on every sample as the
    // workers do, and the paper's 7% loss from one node to two is gone: efficiency 1.00
    // where the paper has 0.93.
    let mut worker = shipped.clone();
    worker.costs.sample += worker.costs.slab_test;
    worker.costs.slab_test = 0.0;
    let rows = table_1(&worker);
    let e = efficiency(&rows, 1);
    assert!(
        e - efficiency(&TABLE1, 1) > 0.05,
        "a one-node worker: 2 nodes at efficiency {e:.3}"
    );
}

#[test]
fn load_balancing_lowers_every_table_3_time_on_sod() {
    use voxcube::profile::MachineProfile;
    let Some(_) = data_or_skip() else { return };
    let job = paper_job();
    let (v, profile) = (&job.views[0].view, MachineProfile::ncube2());
    // Clusters of 16 at 64 nodes: their cuts and uniform time, for the negative control.
    let mut sixteen = None;
    for cs in [16u32, 8, 4, 2] {
        let cuts = voxcube::experiments::paper::balance(&job, v, &profile, cs).expect("balances");
        for nodes in [64u32, 128] {
            let standard =
                voxcube::experiments::paper::timed(&job, v, &profile, nodes / cs, cs, None)
                    .expect("runs")
                    .frame;
            let balanced = voxcube::experiments::paper::timed(
                &job,
                v,
                &profile,
                nodes / cs,
                cs,
                Some(cuts.clone()),
            )
            .expect("runs")
            .frame;
            assert!(
                balanced < standard,
                "{nodes} nodes, clusters of {cs}: balanced {balanced:.2} s against {standard:.2} s"
            );
            if (cs, nodes) == (16, 64) {
                sixteen = Some((cuts.clone(), standard));
            }
        }
    }
    // Negative control: the same cuts mirrored give the slabs nearest the viewer, which carry
    // the most work, the most planes, and the ring of 16 is slower than with uniform slabs.
    let (cuts, standard) = sixteen.expect("clusters of 16 at 64 nodes ran");
    let last = *cuts.last().expect("cuts");
    let mirrored: Vec<u32> = cuts.iter().rev().map(|c| last - c).collect();
    let worse =
        voxcube::experiments::paper::timed(&job, v, &profile, 4, 16, Some(mirrored.clone()))
            .expect("runs")
            .frame;
    assert!(
        worse > standard,
        "cuts {mirrored:?}: {worse:.2} s against uniform {standard:.2} s"
    );
}

#[test]
fn table_4_ranks_the_papers_routines_and_prices_voxel_sample_per_sample() {
    // Held out from the fit: one cluster of 16 on the whole view. The five routines that do
    // the work rank as the paper's, and the four the model prices as the paper counts them
    // are each within 5 points of its share. (Interpolate is 6 points short and `ntest`
    // holds none of the waiting, which is `idle` here: docs/results.md says why.)
    use voxcube::experiments::paper::{table_4, Share, TABLE4};
    let Some(_) = data_or_skip() else { return };
    let job = paper_job();
    let view = &job.views[0].view;
    let mean = |shares: &[Share], name: &str| {
        shares
            .iter()
            .find(|s| s.name == name)
            .map(|s| s.mean)
            .expect("a line of Table 4")
    };
    let paper = |name: &str| {
        TABLE4
            .iter()
            .find(|r| r.0 == name)
            .map(|r| r.1)
            .expect("a line of the paper's Table 4")
    };
    let shipped = voxcube::profile::MachineProfile::ncube2();
    let (_, shares) = table_4(&job, view, &shipped).expect("runs");
    let ranked = ["Interpolate", "Trace", "Voxel_Sample"];
    for pair in ranked.windows(2) {
        assert!(
            mean(&shares, pair[0]) > mean(&shares, pair[1]),
            "{} {:.2}% against {} {:.2}%",
            pair[0],
            mean(&shares, pair[0]),
            pair[1],
            mean(&shares, pair[1])
        );
    }
    let messages = mean(&shares, "nread").max(mean(&shares, "nwrite"));
    assert!(mean(&shares, "Voxel_Sample") > messages, "{shares:?}");
    let within = |shares: &[Share], name: &str| (mean(shares, name) - paper(name)).abs() <= 5.0;
    for name in ["Trace", "Voxel_Sample", "nread", "nwrite"] {
        assert!(
            within(&shares, name),
            "{name}: {:.2}% against the paper's {:.2}%",
            mean(&shares, name),
            paper(name)
        );
    }
    // Negative control: the crossing test priced per crossing found rather than per sample
    // tested, and the call per sample not priced (the model before it priced the routines as
    // the paper's profile counts them): Voxel_Sample falls far under the paper's share.
    let mut per_crossing = shipped.clone();
    per_crossing.costs.crossing = 0.0;
    per_crossing.costs.call = 0.0;
    let (_, shares) = table_4(&job, view, &per_crossing).expect("runs");
    assert!(
        !within(&shares, "Voxel_Sample"),
        "priced per crossing found, Voxel_Sample takes {:.2}%",
        mean(&shares, "Voxel_Sample")
    );
}

#[test]
fn at_128_nodes_a_small_cluster_beats_pure_dataflow_and_pure_image_partition() {
    use voxcube::profile::MachineProfile;
    let Some(_) = data_or_skip() else { return };
    let profile = MachineProfile::ncube2();
    // Table 2 at 128 nodes: clusters of 16 (pure ray dataflow), 2, and 1 (pure image
    // partition), on SOD framed as `sod.toml` frames it and as the paper did.
    let times = |text: &str| -> [f64; 3] {
        let jobs = Scene::parse(text, "sod.toml", &scene_file(""))
            .and_then(Scene::load)
            .unwrap_or_else(|e| panic!("{e}"));
        let (job, v) = (&jobs[0], &jobs[0].views[0].view);
        [(8, 16), (64, 2), (128, 1)].map(|(m, cs)| {
            voxcube::experiments::paper::timed(job, v, &profile, m, cs, None)
                .expect("runs")
                .frame
        })
    };
    let text = std::fs::read_to_string(scene_file("sod.toml")).expect("sod.toml");
    let [sixteen, two, one] = times(&text);
    assert!(
        two < sixteen && two < one,
        "clusters of 2 take {two:.2} s, of 16 {sixteen:.2} s, of 1 {one:.2} s"
    );
    // Negative control: the trend rests on how the rows divide. Framed 1% larger, the rays
    // cover 194 rows instead of 192, two of the 64 clusters of 2 get a fourth row, and pure
    // image partition wins.
    assert!(
        text.contains("width = 175.0"),
        "sod.toml frames the paper's view"
    );
    let [_, two, one] = times(&text.replace("width = 175.0", "width = 173.5"));
    assert!(
        one < two,
        "framed larger: clusters of 2 take {two:.2} s, of 1 {one:.2} s"
    );
}

/// Table 2's times at 64 and 128 nodes for each of its cluster sizes, under `profile`.
fn table_2(profile: &voxcube::profile::MachineProfile) -> [[f64; 5]; 2] {
    let job = paper_job();
    let view = &job.views[0].view;
    [64, 128].map(|nodes| {
        voxcube::experiments::paper::TABLE2.map(|(cs, _, _)| {
            voxcube::experiments::paper::timed(&job, view, profile, nodes / cs, cs, None)
                .expect("runs")
                .frame
        })
    })
}

/// The cluster size of the least time in a row of Table 2, and the slowest over the fastest.
fn best_and_spread(times: &[f64; 5]) -> (u32, f64) {
    let sizes = voxcube::experiments::paper::TABLE2.map(|r| r.0);
    let (best, fastest) = sizes
        .iter()
        .zip(times)
        .min_by(|a, b| a.1.total_cmp(b.1))
        .map(|(&s, &t)| (s, t))
        .expect("five sizes");
    (best, times.iter().copied().fold(0.0, f64::max) / fastest)
}

#[test]
fn table_2_is_predicted_from_the_papers_distributed_generation() {
    // Held out from the fit: the best cluster size at 64 and 128 nodes as in the paper, and at
    // 64 nodes the slowest size within 25% of the paper's 2.71x the best.
    let Some(_) = data_or_skip() else { return };
    let profile = voxcube::profile::MachineProfile::ncube2();
    let [at64, at128] = table_2(&profile);
    let (best64, spread64) = best_and_spread(&at64);
    let (best128, _) = best_and_spread(&at128);
    assert_eq!(
        (best64, best128),
        (1, 2),
        "64 nodes: {at64:?}; 128: {at128:?}"
    );
    let paper = 24.16 / 8.90;
    assert!(
        (spread64 / paper - 1.0).abs() <= 0.25,
        "at 64 nodes the slowest size takes {spread64:.2}x the best; the paper's {paper:.2}x"
    );
    // Negative control: price the paper's distributed generation at nothing (every node of a
    // ring checking every pixel of its cluster's rows) and large rings cost as little as the
    // paper's data rule out: the spread falls out of the band.
    let mut free = profile.clone();
    free.costs.ray_setup = 0.0;
    let [at64, _] = table_2(&free);
    let (_, spread64) = best_and_spread(&at64);
    assert!(
        spread64 / paper - 1.0 < -0.25,
        "without the checks the slowest size takes {spread64:.2}x the best"
    );
}

#[test]
fn the_shipped_ncube2_constants_are_what_the_fit_on_table_1_finds() {
    // The fit takes about a minute on a release build: the long mode only.
    if std::env::var_os("VOXCUBE_LONG").is_none() {
        eprintln!("skipping: VOXCUBE_LONG=1 runs the fit");
        return;
    }
    let Some(_) = data_or_skip() else { return };
    let job = paper_job();
    let shipped = voxcube::profile::MachineProfile::ncube2();
    let fit = voxcube::experiments::fit::fit(
        &job,
        &job.views[0].view,
        &shipped,
        &voxcube::experiments::paper::TABLE1,
    )
    .expect("fits");
    assert!(
        (fit.profile.scale / shipped.scale - 1.0).abs() < 0.002
            && fit.profile.message_scale == shipped.message_scale,
        "the fit finds scale {} and message_scale {}; ncube2.toml ships {} and {}",
        fit.profile.scale,
        fit.profile.message_scale,
        shipped.scale,
        shipped.message_scale
    );
}

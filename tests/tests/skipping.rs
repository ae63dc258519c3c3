//! Empty-space skipping changes no pixel: every test scene, directly and on clusters, and SOD,
//! in each accuracy tier, render the same bits with skipping off, with one block per jump, with leaps over every
//! empty block around, and with single empty cells skipped too, while skipping really skips,
//! leaping really leaps and cell masks really mask; and passing over the pixels of a row that
//! a node certainly does not start, or that certainly miss, changes no pixel or count either,
//! nor does passing a primary ray at once over the samples before its pixel's depth bound.
//! A cluster, however it is cut into slabs, skips every sample one node skips. Cell leap maps
//! and depth bounds are held only where they fit, and maps only where they pay.

use proptest::prelude::*;
use voxcube::fabric::sim;
use voxcube::fabric::RunConfig;
use voxcube::input::dataset::{Volume, VolumeData};
use voxcube::input::scene::{DatasetJob, Scene};
use voxcube::memory::storage::{cell_leap_octants, SkipMode, Skipping};
use voxcube::run::render::render_skipping;
use voxcube_kernel::optics::transfer::{ControlPoint, TransferFunction};
use voxcube_kernel::skip::scan;
use voxcube_kernel::trace::pixel::rgba8;
use voxcube_kernel::trace::tracer::trace_pixel;
use voxcube_kernel::trace::view::{Accuracy, Mode, View, ViewSpec};
use voxcube_kernel::volume::grid::{Grid, Model};
use voxcube_kernel::volume::sample::Sample;
use voxcube_kernel::volume::slab::Slab;
use voxcube_kernel::Vec3;

/// A view as the check reads it: its name, in one tier.
struct Named<'a> {
    name: &'a str,
    view: View,
}

/// `view` in each tier whose image may differ: the exact tier, and the fast tier where it
/// makes an approximation (elsewhere it is the exact image).
fn in_each_tier(view: &View, job: &DatasetJob) -> Vec<View> {
    let fast = voxcube_tests::in_tier(view, &job.volume, Accuracy::Fast);
    let exact = voxcube_tests::in_tier(view, &job.volume, Accuracy::Exact);
    match fast.approximations().is_empty() {
        true => vec![exact],
        false => vec![exact, fast],
    }
}

/// Skipping in every mode changes no pixel and skips what it should, in each tier, on one
/// node and on clusters.
fn check(text: &str, file: &str) {
    let jobs = Scene::parse(text, file, std::path::Path::new("."))
        .and_then(Scene::load)
        .unwrap_or_else(|e| panic!("{e}"));
    for job in &jobs {
        for (v, view) in job
            .views
            .iter()
            .flat_map(|v| in_each_tier(&v.view, job).into_iter().map(move |t| (v, t)))
        {
            let v = Named {
                name: &v.name,
                view,
            };
            let off = render_skipping(&job.volume, &v.view, SkipMode::OFF).expect("renders");
            let blocks = render_skipping(&job.volume, &v.view, SkipMode::BLOCKS).expect("renders");
            let on = render_skipping(&job.volume, &v.view, SkipMode::LEAPS).expect("renders");
            let all = render_skipping(&job.volume, &v.view, SkipMode::ALL).expect("renders");
            // Cell masks without cell leaps: runs through empty cells scanned or jumped.
            let cells_only = SkipMode {
                leap: false,
                cell_leaps: false,
                ..SkipMode::ALL
            };
            let cells = render_skipping(&job.volume, &v.view, cells_only).expect("renders");
            let no_cell_leaps = SkipMode {
                cell_leaps: false,
                ..SkipMode::ALL
            };
            let masked = render_skipping(&job.volume, &v.view, no_cell_leaps).expect("renders");
            for (mode, r) in [
                ("skipping", &blocks),
                ("leaping", &on),
                ("skipping cells", &cells),
                ("leaping and skipping cells", &masked),
                ("leaping from cell to cell", &all),
            ] {
                assert!(
                    r.pixels == off.pixels,
                    "{}/{}: {mode} changed the image",
                    job.name,
                    v.name
                );
            }
            assert_eq!(off.counters.skipped, 0);
            // A leap skips exactly the samples that one-block jumps skip, only in fewer jumps,
            // with cell masks or without.
            assert_eq!(on.counters, blocks.counters, "{}/{}", job.name, v.name);
            assert_eq!(masked.counters, cells.counters, "{}/{}", job.name, v.name);
            // Cell leaps skip exactly the samples in the cells the masks clear.
            assert_eq!(all.counters, cells.counters, "{}/{}", job.name, v.name);
            assert!(
                all.counters.skipped >= on.counters.skipped,
                "{}/{}: cell masks skip more, never less",
                job.name,
                v.name
            );
            for (size, seed, mode) in [
                (3u32, 1u64, SkipMode::ALL),
                (8, 2, SkipMode::ALL),
                (3, 3, SkipMode::BLOCKS),
                (8, 4, SkipMode::LEAPS),
            ] {
                let cfg = RunConfig {
                    skipping: mode,
                    ..RunConfig::cluster(size, seed).expect("layout")
                };
                let run = sim::run(&job.volume, &v.view, &cfg).expect("runs");
                assert!(
                    run.pixels == off.pixels,
                    "{}/{} on {size} nodes ({mode:?}): skipping changed the image",
                    job.name,
                    v.name
                );
                // A slab skips every sample one node skips: the blocks at its ends, stored in
                // part, hold the range of what they store. With cell masks, a cell-model
                // cluster evaluates exactly one node's samples; a partial block's range can
                // only be narrower than the whole block's.
                let one = match mode {
                    SkipMode::ALL => &all,
                    SkipMode::BLOCKS => &blocks,
                    _ => &on,
                };
                let (ours, theirs) = (run.counters().samples, one.counters.samples);
                match mode.cells && v.view.spec().model == Model::Cell {
                    true => assert_eq!(ours, theirs, "{}/{} on {size} nodes", job.name, v.name),
                    false => assert!(
                        ours <= theirs,
                        "{}/{} on {size} nodes ({mode:?}): {ours} samples, one node {theirs}",
                        job.name,
                        v.name
                    ),
                }
            }
            // Row leaps change which primary rays are set up (fewer), and depth bounds pass a
            // primary ray over samples the masks clear as the turns would: never a pixel or
            // another count.
            let no_rows = SkipMode {
                rows: false,
                ..SkipMode::ALL
            };
            let no_depths = SkipMode {
                depths: false,
                ..SkipMode::ALL
            };
            for (what, mode) in [("row leaps", no_rows), ("depth bounds", no_depths)] {
                let without = render_skipping(&job.volume, &v.view, mode).expect("renders");
                assert!(
                    without.pixels == all.pixels,
                    "{}/{}: {what}",
                    job.name,
                    v.name
                );
                assert_eq!(
                    but_set_ups(without.counters),
                    but_set_ups(all.counters),
                    "{}/{}: {what}",
                    job.name,
                    v.name
                );
                assert!(all.counters.rays_set_up <= without.counters.rays_set_up);
            }
            for size in [2u32, 8] {
                let runs = [SkipMode::ALL, no_rows].map(|mode| {
                    let cfg = RunConfig {
                        skipping: mode,
                        ..RunConfig::cluster(size, 5).expect("layout")
                    };
                    sim::run(&job.volume, &v.view, &cfg).expect("runs")
                });
                assert!(
                    runs[0].pixels == runs[1].pixels && runs[0].pixels == off.pixels,
                    "{}/{} on {size} nodes: row leaps changed the image",
                    job.name,
                    v.name
                );
                let [leaps, none] = runs.map(|r| r.counters());
                assert_eq!(
                    but_set_ups(leaps),
                    but_set_ups(none),
                    "{}/{}",
                    job.name,
                    v.name
                );
                assert!(leaps.rays_set_up <= none.rays_set_up);
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

/// Where scanning does not pay (steps short of [`scan::MIN_STEP`] cells), a run through empty
/// cells jumps over the box of empty cells ahead (`cells::empty_box`) instead. Those jumps
/// change no pixel and skip exactly the samples the masks and the cell leaps skip. The test
/// scenes and SOD's views step too far for that path; the default scene's view at a fifth of
/// a cell does not: surfaces and composited, from the paper's side and from one where the
/// rays move up an axis.
#[test]
fn jumps_through_empty_cells_change_no_pixel_where_scanning_does_not_pay() {
    let jobs = Scene::default_scene()
        .and_then(Scene::load)
        .expect("default");
    let (volume, paper) = (&jobs[0].volume, jobs[0].views[0].view.spec());
    let composite = {
        let point = |value: f32, opacity: f32| ControlPoint {
            value,
            color: Vec3::splat(0.8),
            opacity,
        };
        Mode::Composite(
            TransferFunction::new(&[point(20.0, 0.0), point(60.0, 0.3)]).expect("sorted"),
        )
    };
    // The paper's camera looks down X and Z; the other one up X, down Y and Z.
    let centre = Vec3::new(48.0, 48.0, 57.5);
    let other = voxcube_tests::ortho(
        centre + Vec3::new(-90.0, 60.0, 80.0),
        centre,
        Vec3::Y,
        175.0,
    );
    for (camera, mode) in [
        (paper.camera, paper.mode.clone()),
        (paper.camera, composite.clone()),
        (other, paper.mode.clone()),
        (other, composite),
    ] {
        let view = View::new(
            ViewSpec {
                width: 120,
                height: 86,
                dt: 0.2,
                camera,
                mode,
                ..paper.clone()
            },
            &volume.grid,
        )
        .expect("view");
        let ray = view.primary_ray(view.spec().width * 43 + 60).expect("hits");
        assert!(
            !scan::pays(&ray.ray, &ray.lattice),
            "the test needs short steps"
        );
        let off = render_skipping(volume, &view, SkipMode::OFF).expect("renders");
        let cells_only = SkipMode {
            leap: false,
            cell_leaps: false,
            ..SkipMode::ALL
        };
        let no_cell_leaps = SkipMode {
            cell_leaps: false,
            ..SkipMode::ALL
        };
        let runs = [cells_only, no_cell_leaps, SkipMode::ALL]
            .map(|mode| render_skipping(volume, &view, mode).expect("renders"));
        for r in &runs {
            assert!(r.pixels == off.pixels, "skipping changed the image");
        }
        assert_eq!(runs[0].counters, runs[1].counters);
        assert_eq!(runs[1].counters, runs[2].counters);
        assert!(runs[0].counters.skipped > runs[0].counters.samples);
    }
}

/// In the fast tier a sample reads its table's nearest entry, which may show where the
/// transfer function itself shows nothing: here a constant medium at the value where the
/// function's opacity starts to rise from zero, whose nearest entry lies just above it.
/// Skipping asks the table, so it skips none of the medium and the image is the one without
/// skipping; skipping by the function instead (a fault) skips all of it, and the image loses
/// the medium.
#[test]
fn skipping_asks_the_fast_tiers_own_table_where_the_function_shows_nothing() {
    let volume = voxcube_tests::volume_f32([40, 16, 16], Vec3::ONE, |_, _, _| 1.0);
    let point = |value: f32, opacity: f32| ControlPoint {
        value,
        color: Vec3::ONE,
        opacity,
    };
    let tf = TransferFunction::new(&[point(0.0, 0.0), point(1.0, 0.0), point(1.01, 1.0)])
        .expect("valid transfer function");
    assert_eq!(
        tf.max_opacity(1.0, 1.0),
        0.0,
        "the function shows nothing at 1"
    );
    let camera = voxcube_tests::ortho(
        Vec3::new(-30.0, 7.5, 7.5),
        Vec3::new(20.0, 7.5, 7.5),
        Vec3::Y,
        24.0,
    );
    let spec = voxcube_tests::spec(camera, 24, 24, Model::Cell, 0.5, Mode::Composite(tf));
    let exact = voxcube_tests::view(spec.clone(), &volume);
    let fast = voxcube_tests::in_tier(&exact, &volume, Accuracy::Fast);
    let lit = |pixels: &[[u8; 4]]| pixels.iter().filter(|p| p[..3] != [0, 0, 0]).count();
    let image = |view: &View, mode| render_skipping(&volume, view, mode).expect("renders");
    assert_eq!(
        lit(&image(&exact, SkipMode::OFF).pixels),
        0,
        "exact: nothing shows"
    );
    let off = image(&fast, SkipMode::OFF);
    assert!(
        lit(&off.pixels) > 100,
        "fast: the medium shows by its entry"
    );
    for mode in [SkipMode::BLOCKS, SkipMode::LEAPS, SkipMode::ALL] {
        let on = image(&fast, mode);
        assert!(on.pixels == off.pixels, "{mode:?} changed the image");
        assert_eq!(
            on.counters.samples, off.counters.samples,
            "{mode:?} skipped a sample"
        );
    }
    let wrong = image(&fast.clone().with_exact_emptiness(), SkipMode::ALL);
    assert_eq!(
        lit(&wrong.pixels),
        0,
        "skipping by the function skips the medium"
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

/// Every pixel of `traced` on `volume`, whose blocks skip by the storage `mode` builds for
/// `built_for` (its leap map or its cell masks).
fn trace_with_skipping_of(
    volume: &Volume,
    traced: &View,
    built_for: &View,
    mode: SkipMode,
) -> Vec<[u8; 4]> {
    match &volume.data {
        VolumeData::U8(d) => trace_typed(volume.grid, d, traced, built_for, mode),
        VolumeData::U16(d) => trace_typed(volume.grid, d, traced, built_for, mode),
        VolumeData::I16(d) => trace_typed(volume.grid, d, traced, built_for, mode),
        VolumeData::F32(d) => trace_typed(volume.grid, d, traced, built_for, mode),
    }
}

fn trace_typed<T: Sample + Sync>(
    grid: Grid,
    data: &[T],
    traced: &View,
    built_for: &View,
    mode: SkipMode,
) -> Vec<[u8; 4]> {
    let slab = Slab::whole(grid, data).expect("slab");
    let ranges = voxcube::memory::ranges::SlabRanges::build(&slab, mode.ranges, 1);
    let skipping = Skipping::build(&slab, &ranges, built_for, mode);
    trace_all(traced, &skipping.apply(slab))
}

/// Every pixel of `view`, traced on `slab` alone.
fn trace_all<T: Sample>(view: &View, slab: &Slab<'_, T>) -> Vec<[u8; 4]> {
    trace_counted(view, slab).0
}

/// [`trace_all`]'s pixels and what tracing them counted.
fn trace_counted<T: Sample>(
    view: &View,
    slab: &Slab<'_, T>,
) -> (Vec<[u8; 4]>, voxcube_kernel::counters::Counters) {
    let mut counters = voxcube_kernel::counters::Counters::default();
    let pixels = (0..view.pixel_count() as u32)
        .map(|p| rgba8(trace_pixel(view, slab, p, &mut counters)))
        .collect();
    (pixels, counters)
}

/// Negative controls: the marcher really leaps by the map it is given, really skips the cells
/// its masks clear, and really leaps by the cell leap map it is given. A map, masks or a cell
/// leap map built for a higher iso value, whose empty blocks and cells reach further, make it
/// skip parts of the lower surface.
#[test]
fn a_leap_map_or_cell_masks_built_for_another_view_change_the_image() {
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
    let reference = render_skipping(&job.volume, low, SkipMode::OFF).expect("renders");
    let cells_only = SkipMode {
        leap: false,
        cell_leaps: false,
        ..SkipMode::ALL
    };
    for (what, mode) in [
        ("leap map", SkipMode::LEAPS),
        ("cell masks", cells_only),
        ("cell leap map", SkipMode::ALL),
    ] {
        let own = trace_with_skipping_of(&job.volume, low, low, mode);
        let foreign = trace_with_skipping_of(&job.volume, low, high, mode);
        assert!(
            own == reference.pixels,
            "the view's own {what} change no pixel"
        );
        let changed = own.iter().zip(&foreign).filter(|(a, b)| a != b).count();
        assert!(
            changed > 0,
            "{what} built for iso 200 must hide parts of the iso-40 surface"
        );
    }
}

/// Blobs over a noise floor: blocks that are neither empty nor full, and cells of both kinds
/// inside them.
fn blobs(dims: [u32; 3], spacing: Vec3, seed: u64) -> Volume {
    let centre = |i: u64| (seed >> (i * 8) & 0xff) as u32 % dims[i as usize].max(1);
    let (cx, cy, cz) = (centre(0), centre(1), centre(2));
    voxcube_tests::volume_u8(dims, spacing, |x, y, z| {
        let d2 = x.abs_diff(cx).pow(2) + y.abs_diff(cy).pow(2) + z.abs_diff(cz).pow(2);
        let h = seed ^ (u64::from(x) * 0x9E37_79B9 + u64::from(y) * 0x85EB_CA6B + u64::from(z));
        let noise = (h.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 59) as u32;
        (230u32.saturating_sub(d2 * 9) + noise).min(255) as u8
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Skipping changes no pixel on hard cases too: random blobby volumes with anisotropic
    /// spacing, cameras inside and outside and along an axis, steps from 1/64 to 2 cell edges
    /// (long runs through empty cells), both models, surfaces and compositing (of a band
    /// too, zero again above it). And a leap skips exactly the samples one-block jumps skip,
    /// with cell masks, and cell leaps exactly the samples the masks skip. On a cluster cut
    /// at random planes, the same image and one node's evaluated samples.
    #[test]
    fn skipping_changes_no_pixel_on_random_hard_cases(
        dims in prop::array::uniform3(1u32..14),
        spacing in prop::array::uniform3(prop_oneof![Just(1.0f32), 0.05f32..20.0]),
        seed in any::<u64>(),
        eye in prop::array::uniform3(-30.0f32..40.0),
        on_axis in 0usize..4,
        persp in any::<bool>(),
        voxel in any::<bool>(),
        dt in prop_oneof![Just(1.0f32 / 64.0), 1.0f32 / 64.0..2.0],
        iso in 20.0f32..240.0,
        composite in any::<bool>(),
        band in any::<bool>(),
        cut_bits in any::<u16>(),
    ) {
        let volume = blobs(dims, Vec3::from_array(spacing), seed);
        let target = Vec3::from_array(dims.map(|n| n as f32 / 2.0)) * Vec3::from_array(spacing);
        // Along an axis (rays parallel to two pairs of faces), or anywhere.
        let mut eye = Vec3::from_array(eye);
        if on_axis < 3 {
            eye = target;
            eye[on_axis] += 50.0;
        }
        prop_assume!((eye - target).length() > 1e-3);
        let up = if (eye - target).normalize().cross(Vec3::Y).length() > 1e-3 { Vec3::Y } else { Vec3::Z };
        let cam = if persp {
            voxcube_tests::perspective(eye, target, up, 50.0)
        } else {
            voxcube_tests::ortho(eye, target, up, 12.0)
        };
        let mode = if composite {
            let point = |value: f32, opacity: f32| ControlPoint { value, color: Vec3::splat(0.8), opacity };
            // A band, zero again above it, where a cell's least corner proves it empty too.
            let mut points = vec![point(iso - 15.0, 0.0), point(iso, 0.4)];
            if band {
                points.push(point(iso + 15.0, 0.0));
            }
            Mode::Composite(TransferFunction::new(&points).expect("sorted"))
        } else {
            voxcube_tests::surfaces(&[(iso, 0.5), (iso + 10.0, 0.0)])
        };
        let model = if voxel { Model::Voxel } else { Model::Cell };
        let s = voxcube_tests::spec(cam, 12, 9, model, dt, mode);
        let view = voxcube_tests::view(s, &volume);
        let off = render_skipping(&volume, &view, SkipMode::OFF).expect("renders");
        let cells_only = SkipMode { leap: false, cell_leaps: false, ..SkipMode::ALL };
        let no_cell_leaps = SkipMode { cell_leaps: false, ..SkipMode::ALL };
        let mut counters = Vec::new();
        let no_depths = SkipMode { depths: false, ..SkipMode::ALL };
        let cells_no_depths = SkipMode { depths: false, ..cells_only };
        for mode in [SkipMode::BLOCKS, SkipMode::LEAPS, cells_only, no_cell_leaps, SkipMode::ALL, no_depths, cells_no_depths] {
            let r = render_skipping(&volume, &view, mode).expect("renders");
            prop_assert!(r.pixels == off.pixels, "{mode:?} changed the image");
            prop_assert_eq!(r.counters.slab_misses, 0);
            counters.push(r.counters);
        }
        prop_assert_eq!(&counters[0], &counters[1]);
        prop_assert_eq!(&counters[2], &counters[3]);
        prop_assert_eq!(&counters[3], &counters[4]);
        // Depth bounds change no count, with cell leaps or with scans and jumps.
        prop_assert_eq!(&counters[4], &counters[5]);
        prop_assert_eq!(&counters[2], &counters[6]);
        // On a cluster cut anywhere (plane x starts a slab where bit x of `cut_bits` is set),
        // the same image, and the slabs skip every sample one node skips: on the cell model
        // exactly one node's samples are evaluated, on the voxel model at most those (a block
        // at a slab's end holds the range of the planes the slab stores, which can be
        // narrower than the whole block's).
        let mut cuts = vec![0u32];
        cuts.extend((1..dims[0]).filter(|x| cut_bits & (1 << x) != 0));
        cuts.push(dims[0]);
        let cfg = RunConfig {
            layout: voxcube_kernel::node::topology::Layout::new(1, cuts.len() as u32 - 1).expect("layout"),
            cuts: Some(cuts.clone()),
            ..RunConfig::cluster(1, seed).expect("layout")
        };
        let run = sim::run(&volume, &view, &cfg).map_err(|e| TestCaseError::fail(e.to_string()))?;
        prop_assert!(run.pixels == off.pixels, "cuts {:?}: the image differs", cuts);
        let (ours, theirs) = (run.counters().samples, counters[4].samples);
        match voxel {
            false => prop_assert_eq!(ours, theirs, "cuts {:?}", cuts),
            true => prop_assert!(ours <= theirs, "cuts {:?}: {} samples, one node {}", cuts, ours, theirs),
        }
    }
}

/// The skipping storage a machine builds on several threads, split by block columns, is the
/// storage built on one: whole volumes and partial slabs, surfaces and compositing, both
/// models, more threads than columns too.
#[test]
fn skipping_built_on_threads_is_the_same_storage() {
    let mut compared = 0;
    // The last two are long in Z, seen from both sides: a cell leap map built in parts of
    // planes needs the planes ahead of each part, below it or above it.
    for (dims, seed, side) in [
        ([37, 21, 30], 7u64, 1.0),
        ([9, 40, 13], 0x3c_1d_05, 1.0),
        ([5, 6, 7], 11, 1.0),
        ([10, 9, 150], 0x7e, 1.0),
        ([10, 9, 150], 0x7e, -1.0),
    ] {
        let volume = blobs(dims, Vec3::ONE, seed);
        let VolumeData::U8(data) = &volume.data else {
            unreachable!("blobs are bytes")
        };
        let grid = volume.grid;
        let target = Vec3::from_array(dims.map(|n| n as f32 / 2.0));
        let cam = voxcube_tests::ortho(
            target + Vec3::new(40.0, 9.0, 17.0) * side,
            target,
            Vec3::Y,
            30.0,
        );
        let point = |value: f32, opacity: f32| ControlPoint {
            value,
            color: Vec3::ONE,
            opacity,
        };
        let composite = Mode::Composite(
            TransferFunction::new(&[point(90.0, 0.0), point(120.0, 0.4)]).expect("sorted"),
        );
        for (mode, model) in [
            (voxcube_tests::surfaces(&[(120.0, 0.0)]), Model::Cell),
            (composite, Model::Cell),
            (voxcube_tests::surfaces(&[(120.0, 0.0)]), Model::Voxel),
        ] {
            let view =
                voxcube_tests::view(voxcube_tests::spec(cam, 4, 4, model, 0.5, mode), &volume);
            let plane = grid.plane_len();
            let [nx, ..] = dims;
            let mut slabs = vec![Slab::whole(grid, data.as_slice()).expect("slab")];
            for owned in [1..nx / 2, nx / 3..nx] {
                let s = voxcube_kernel::volume::slab::stored_planes(&grid, owned.clone(), 1);
                let stored = &data[s.start as usize * plane..s.end as usize * plane];
                slabs.push(Slab::new(grid, owned, 1, stored).expect("slab"));
            }
            for slab in &slabs {
                // Without depth bounds this small image's view takes cell leap maps.
                let no_depths = SkipMode {
                    depths: false,
                    ..SkipMode::ALL
                };
                for skipping in [SkipMode::ALL, no_depths, SkipMode::LEAPS, SkipMode::BLOCKS] {
                    // One thread reading the nodes for the masks; several classifying the
                    // cells' ranges, themselves built on as many threads.
                    let nodes = voxcube::memory::ranges::SlabRanges::build(slab, false, 1);
                    let one = Skipping::build(slab, &nodes, &view, skipping);
                    assert_ne!(one, Skipping::default(), "{dims:?}: blocks are built");
                    for threads in [2, 3, 8] {
                        let ranges =
                            voxcube::memory::ranges::SlabRanges::build(slab, true, threads);
                        assert!(ranges.holds_cells());
                        let many = Skipping::build_on(slab, &ranges, &view, skipping, threads);
                        // Not assert_eq: the storage runs to thousands of entries.
                        assert!(
                            many == one,
                            "{dims:?} {side} {model:?} {skipping:?} on {threads}"
                        );
                        compared += 1;
                    }
                }
            }
        }
    }
    assert_eq!(compared, 5 * 3 * 3 * 4 * 3);
}

/// A byte volume's masks and cell leap maps kept with its ranges serve the next view only
/// when its verdicts are the same: views taking turns on one volume's ranges each get the
/// storage a fresh build gives them, bit for bit, whether it was kept or built again.
#[test]
fn kept_masks_and_cell_leap_maps_serve_only_views_of_the_same_verdicts() {
    let volume = blobs([37, 21, 30], Vec3::ONE, 7);
    let VolumeData::U8(data) = &volume.data else {
        unreachable!("blobs are bytes")
    };
    let slab = Slab::whole(volume.grid, data.as_slice()).expect("slab");
    let target = Vec3::new(18.5, 10.5, 15.0);
    let point = |value: f32, opacity: f32| ControlPoint {
        value,
        color: Vec3::ONE,
        opacity,
    };
    let composite = |clear: f32| {
        Mode::Composite(
            TransferFunction::new(&[point(clear, 0.0), point(clear + 30.0, 0.4)]).expect("sorted"),
        )
    };
    let view = |mode: Mode, eye: Vec3| {
        let cam = voxcube_tests::ortho(target + eye, target, Vec3::Y, 30.0);
        voxcube_tests::view(
            voxcube_tests::spec(cam, 4, 4, Model::Cell, 0.5, mode),
            &volume,
        )
    };
    let (ahead, behind) = (Vec3::new(40.0, 9.0, 17.0), Vec3::new(-40.0, 9.0, -17.0));
    let views = [
        view(composite(90.0), ahead),
        // The same verdicts from the other side: the masks kept, the maps of another octant.
        view(composite(90.0), behind),
        view(composite(60.0), ahead),
        view(voxcube_tests::surfaces(&[(120.0, 0.0)]), ahead),
        view(composite(90.0), ahead),
    ];
    let fresh = |v: &View| {
        let ranges = voxcube::memory::ranges::SlabRanges::build(&slab, true, 1);
        Skipping::build(&slab, &ranges, v, SkipMode::ALL)
    };
    // The negative control: the views' storages differ, so one handed another's is caught.
    assert_ne!(fresh(&views[0]), fresh(&views[1]), "maps of two octants");
    assert_ne!(fresh(&views[0]), fresh(&views[2]), "masks of two functions");
    assert_ne!(fresh(&views[2]), fresh(&views[3]), "masks of two modes");
    let shared = voxcube::memory::ranges::SlabRanges::build(&slab, true, 2);
    for (i, v) in views.iter().chain(views.iter().rev()).enumerate() {
        let turn = Skipping::build_on(&slab, &shared, v, SkipMode::ALL, 2);
        assert!(turn == fresh(v), "turn {i}");
    }
}

/// `volume`'s whole slab (of blobs, bytes) and its blocks' ranges.
fn whole_slab_blocks(volume: &Volume) -> (Slab<'_, u8>, Vec<voxcube_kernel::skip::blocks::Range>) {
    use voxcube_kernel::skip::blocks::Range;
    use voxcube_kernel::skip::minmax::extent;
    let VolumeData::U8(data) = &volume.data else {
        unreachable!("blobs are bytes")
    };
    let slab = Slab::whole(volume.grid, data.as_slice()).expect("slab");
    let mut ranges = vec![Range::UNKNOWN; extent(&slab).2];
    voxcube_kernel::skip::minmax::build(&slab, &mut ranges).expect("storage");
    (slab, ranges)
}

/// Every pixel of `view` traced directly on `volume`'s whole slab, its blocks leaping by
/// `maps` of the octants in `label` (each map built for the octant `built_for` says of it).
fn trace_with_octant_maps(
    volume: &Volume,
    view: &View,
    label: u8,
    built_for: &dyn Fn(usize) -> usize,
) -> Vec<[u8; 4]> {
    use voxcube_kernel::skip::blocks::Blocks;
    use voxcube_kernel::skip::leaps;
    use voxcube_kernel::skip::octant::Octant;
    let (slab, ranges) = whole_slab_blocks(volume);
    let blocks = Blocks::new(slab.grid(), slab.stored(), &ranges).expect("storage");
    let len = ranges.len();
    let mut maps = vec![0u8; len * label.count_ones() as usize];
    let octants = (0..voxcube_kernel::skip::octant::OCTANTS).filter(|o| label >> o & 1 == 1);
    for (map, octant) in maps.chunks_mut(len).zip(octants) {
        leaps::build(&blocks, view, Octant::from_index(built_for(octant)), map).expect("storage");
    }
    trace_all(
        view,
        &slab.with_blocks(blocks.with_leaps(&maps, label).expect("storage")),
    )
}

/// A 40×30 view of the iso-150 surface of `volume` through `cam`.
fn blob_view(cam: voxcube_kernel::trace::camera::Camera, volume: &Volume) -> View {
    let surface = voxcube_tests::surfaces(&[(150.0, 0.0)]);
    voxcube_tests::view(
        voxcube_tests::spec(cam, 40, 30, Model::Cell, 0.5, surface),
        volume,
    )
}

/// A camera inside a volume sends rays into all eight octants. With maps for only some of
/// them (or none), the rays of the others leap by no map, and the image keeps its bits.
#[test]
fn rays_without_a_map_for_their_octant_leap_by_none() {
    let volume = blobs([21, 19, 23], Vec3::ONE, 0x51_0a_07);
    let inside = Vec3::new(10.3, 9.1, 11.7);
    let cam = voxcube_tests::perspective(inside, inside + Vec3::new(1.0, 0.2, 0.3), Vec3::Y, 150.0);
    let view = blob_view(cam, &volume);
    assert_eq!(
        voxcube_kernel::skip::leaps::octants(&view),
        u8::MAX,
        "the rays take every octant"
    );
    let off = render_skipping(&volume, &view, SkipMode::OFF).expect("renders");
    for label in [u8::MAX, 0b0000_0001, 0b1010_0101, 0b0101_1010, 0] {
        let pixels = trace_with_octant_maps(&volume, &view, label, &|o| o);
        assert!(
            pixels == off.pixels,
            "maps for octants {label:08b} changed the image"
        );
    }
}

/// Negative control: a leap map ignores the obstacles behind a ray, so the map of the
/// opposite octant, read by the rays of this one, leaps over surfaces they must hit.
#[test]
fn a_leap_map_built_for_another_octant_changes_the_image() {
    let volume = blobs([21, 19, 23], Vec3::ONE, 0x51_0a_07);
    let centre = Vec3::new(10.0, 9.0, 11.0);
    let cam = voxcube_tests::ortho(centre + Vec3::new(30.0, 11.0, 19.0), centre, Vec3::Y, 30.0);
    let view = blob_view(cam, &volume);
    let octants = voxcube_kernel::skip::leaps::octants(&view);
    assert_eq!(
        octants.count_ones(),
        1,
        "a parallel projection takes one octant"
    );
    let off = render_skipping(&volume, &view, SkipMode::OFF).expect("renders");
    let own = trace_with_octant_maps(&volume, &view, octants, &|o| o);
    assert!(own == off.pixels, "the rays' own map changes no pixel");
    let opposite = trace_with_octant_maps(&volume, &view, octants, &|o| o ^ 0b111);
    let changed = own.iter().zip(&opposite).filter(|(a, b)| a != b).count();
    assert!(
        changed > 0,
        "the opposite octant's map must leap over some of the surface"
    );
}

/// A ray reads its slab's blocks in place where they face its octant (the host turns them
/// toward the view's primary rays) and turns a copy where they face another (maps for both
/// octants in the blocks): the same image, the one without skipping, and the same counts.
/// Which way the slab's blocks face is a matter of speed alone: a leap's box is checked
/// sample by sample, so even blocks read facing the opposite octant unturned (tried: they
/// leap by the blocks behind the ray) skip the same samples, in more turns, which no
/// counter counts.
#[test]
fn blocks_facing_the_rays_or_turned_for_them_give_one_image() {
    use voxcube_kernel::skip::blocks::Blocks;
    use voxcube_kernel::skip::leaps;
    use voxcube_kernel::skip::octant::Octant;
    let volume = blobs([21, 19, 23], Vec3::ONE, 0x51_0a_07);
    let centre = Vec3::new(10.0, 9.0, 11.0);
    let cam = voxcube_tests::ortho(centre + Vec3::new(30.0, 11.0, 19.0), centre, Vec3::Y, 30.0);
    let view = blob_view(cam, &volume);
    let own = leaps::octants(&view);
    assert_eq!(
        own.count_ones(),
        1,
        "a parallel projection takes one octant"
    );
    let own = own.trailing_zeros() as usize;
    let opposite = own ^ 0b111;
    let (slab, ranges) = whole_slab_blocks(&volume);
    let blocks = Blocks::new(slab.grid(), slab.stored(), &ranges).expect("storage");
    let len = ranges.len();
    let mut maps = vec![0u8; 2 * len];
    // In octant order: the lower index's map first.
    for (map, octant) in maps
        .chunks_mut(len)
        .zip([own.min(opposite), own.max(opposite)])
    {
        leaps::build(&blocks, &view, Octant::from_index(octant), map).expect("storage");
    }
    let label = (1u8 << own) | (1u8 << opposite);
    let blocks = blocks.with_leaps(&maps, label).expect("storage");
    let facing = blocks.toward(Octant::from_index(own));
    let away = blocks.toward(Octant::from_index(opposite));
    assert_eq!(facing.octant(), Octant::from_index(own));
    assert_eq!(away.octant(), Octant::from_index(opposite));
    let off = render_skipping(&volume, &view, SkipMode::OFF).expect("renders");
    let (in_place, in_place_counts) = trace_counted(&view, &slab.with_blocks(facing));
    let (turned, turned_counts) = trace_counted(&view, &slab.with_blocks(away));
    assert!(in_place == off.pixels, "read in place");
    assert!(turned == off.pixels, "turned per ray");
    assert!(in_place_counts.skipped > 0, "{in_place_counts:?}");
    assert_eq!(in_place_counts, turned_counts);
}

/// A machine's nodes get the same skipping storage whether each ring position's is built on
/// one thread or split over several, more threads than block columns too.
#[test]
fn every_node_skips_by_the_same_storage_however_the_build_is_threaded() {
    use voxcube::memory::storage::NodeStorage;
    use voxcube_kernel::node::partition::Partition;
    use voxcube_kernel::node::topology::Layout;
    let volume = blobs([37, 21, 30], Vec3::ONE, 0x7e_4d_11);
    let VolumeData::U8(data) = &volume.data else {
        unreachable!("blobs are bytes")
    };
    let centre = Vec3::new(18.0, 10.0, 15.0);
    let cam = voxcube_tests::ortho(centre + Vec3::new(40.0, 9.0, 17.0), centre, Vec3::Y, 30.0);
    let view = blob_view(cam, &volume);
    let grid = volume.grid;
    let mut compared = 0;
    // With depth bounds, and without them (then with cell leap maps).
    let modes = [
        SkipMode::ALL,
        SkipMode {
            depths: false,
            ..SkipMode::ALL
        },
    ];
    for ((clusters, size), mode) in [(1u32, 8u32), (2, 2), (1, 1)]
        .into_iter()
        .flat_map(|shape| modes.map(|mode| (shape, mode)))
    {
        let layout = Layout::new(clusters, size).expect("layout");
        let partition = Partition::uniform(grid.dims()[0], size as usize).expect("partition");
        let ghost = view.ghost_planes();
        let storage = |threads: usize| {
            NodeStorage::new(&grid, layout, &partition, ghost, data.as_slice(), None).with_skipping(
                &view,
                mode,
                threads,
                &voxcube::memory::built::Built::default(),
            )
        };
        let one = storage(1);
        for threads in [2, 3, 16] {
            let many = storage(threads);
            for node in 0..layout.nodes() as u16 {
                let (a, b) = (
                    one.slab(node).expect("slab"),
                    many.slab(node).expect("slab"),
                );
                assert!(a.blocks().is_some(), "node {node} skips");
                assert!(
                    a.blocks() == b.blocks(),
                    "{clusters}x{size} node {node} on {threads}"
                );
                compared += 1;
            }
        }
    }
    assert_eq!(compared, 2 * 3 * (8 + 4 + 1));
}

/// Whether a cell holds fewer of `view`'s samples than cell leap maps built for each frame need
/// beside depth bounds.
fn samples_below(view: &View) -> bool {
    voxcube::memory::storage::samples_per_cell(view)
        .is_some_and(|n| n < voxcube::memory::storage::MAP_SAMPLES_PER_CELL)
}

/// Cell leap maps are an acceleration, not a need: a node holds them only where its memory has
/// room beside everything it needs, and a machine that has no room for them renders without
/// them. A byte a cell takes about what a byte sample does: a small volume's nodes hold them,
/// one that alone fills most of an nCUBE 2 node does not, on one node or balanced.
#[test]
fn nodes_hold_cell_leap_maps_only_where_they_fit() {
    use voxcube::run::render::{node_skipping, preflight, Fabric, Machine};
    let cam = |n: f32| {
        voxcube_tests::ortho(
            Vec3::new(n * 2.5, n * 0.4, n * 0.5),
            Vec3::splat(n / 2.0),
            Vec3::Y,
            n * 1.5,
        )
    };
    // This small image's rays are few per cell: with depth bounds it takes no maps (below).
    let machine = Machine {
        skipping: SkipMode {
            depths: false,
            ..SkipMode::ALL
        },
        ..Machine::new(Fabric::Sim, 1, 1, 1)
    };
    let small = blobs([40, 40, 40], Vec3::ONE, 7);
    let view = blob_view(cam(40.0), &small);
    assert!(node_skipping(&small, &view, &machine, false).cell_leaps);
    assert!(node_skipping(&small, &view, &machine, true).cell_leaps);
    let big = voxcube_tests::volume_u8([140, 140, 140], Vec3::ONE, |x, y, z| (x ^ y ^ z) as u8);
    let view = blob_view(cam(140.0), &big);
    preflight(&big, &view, &machine).expect("fits without cell leap maps");
    assert!(!node_skipping(&big, &view, &machine, false).cell_leaps);
    assert!(!node_skipping(&big, &view, &machine, true).cell_leaps);
    // Turned off, they stay off; the direct render is the host's own, not a node.
    let off = Machine {
        skipping: SkipMode {
            cell_leaps: false,
            ..machine.skipping
        },
        ..machine
    };
    assert!(!node_skipping(&small, &blob_view(cam(40.0), &small), &off, false).cell_leaps);
    let direct = Machine::new(Fabric::Direct, 1, 1, 1);
    assert!(node_skipping(&big, &view, &direct, false).cell_leaps);
    // Primary rays of one octant, and of several: the latter hold no maps, anywhere.
    let parallel = blob_view(cam(40.0), &small);
    assert_eq!(
        cell_leap_octants(&parallel, machine.skipping, false).count_ones(),
        1
    );
    // With depth bounds, maps built for each frame only where a cell holds enough of the
    // rays' samples: not at 40×30 pixels over 60 units (0.9 samples a cell) nor at 160×120
    // (14.2), at 240×180 (32); maps kept for later frames from one sample a cell.
    let few = voxcube::memory::storage::samples_per_cell(&parallel).expect("parallel");
    assert!((few - 1.0 / (1.5 * 1.5 * 0.5)).abs() < 1e-9, "{few}");
    assert_eq!(cell_leap_octants(&parallel, SkipMode::ALL, false), 0);
    assert_eq!(cell_leap_octants(&parallel, SkipMode::ALL, true), 0);
    let sized = |w: u32, h: u32| {
        let surface = voxcube_tests::surfaces(&[(150.0, 0.0)]);
        let spec = voxcube_tests::spec(cam(40.0), w, h, Model::Cell, 0.5, surface);
        voxcube_tests::view(spec, &small)
    };
    let (under, over) = (sized(160, 120), sized(240, 180));
    assert!(samples_below(&under) && !samples_below(&over));
    assert_eq!(cell_leap_octants(&under, SkipMode::ALL, false), 0);
    assert_eq!(
        cell_leap_octants(&over, SkipMode::ALL, false).count_ones(),
        1
    );
    assert_eq!(
        cell_leap_octants(&under, SkipMode::ALL, true).count_ones(),
        1
    );
    // Composited, a cell must hold one sample: not at 40×30 (0.9 a cell), at 48×36 (1.28);
    // without depth bounds the first keeps its map too.
    let composited = |w: u32, h: u32| {
        let spec = voxcube_tests::spec(
            cam(40.0),
            w,
            h,
            Model::Cell,
            0.5,
            voxcube_tests::constant_transfer(0.2),
        );
        voxcube_tests::view(spec, &small)
    };
    let (thin, dense) = (composited(40, 30), composited(48, 36));
    let per_cell = |v: &View| voxcube::memory::storage::samples_per_cell(v).expect("parallel");
    let least = voxcube::memory::storage::COMPOSITE_MAP_SAMPLES_PER_CELL;
    assert!(per_cell(&thin) < least && per_cell(&dense) >= least);
    for kept in [false, true] {
        assert_eq!(cell_leap_octants(&thin, SkipMode::ALL, kept), 0);
        assert_eq!(
            cell_leap_octants(&dense, SkipMode::ALL, kept).count_ones(),
            1
        );
        assert_eq!(
            cell_leap_octants(&thin, machine.skipping, kept).count_ones(),
            1
        );
    }
    let eye = Vec3::splat(20.0);
    let inside = voxcube_tests::perspective(eye, eye + Vec3::new(1.0, 0.3, 0.2), Vec3::Y, 100.0);
    let spread = blob_view(inside, &small);
    assert_eq!(cell_leap_octants(&spread, SkipMode::ALL, true), 0);
    assert!(!node_skipping(&small, &spread, &machine, false).cell_leaps);
}

/// Depth bounds are an acceleration too: a node holds them, a bound a pixel of its cluster's
/// rows, only where its memory has room beside everything else it holds; a perspective view
/// has none.
#[test]
fn nodes_hold_depth_bounds_only_where_they_fit() {
    use voxcube::memory::storage::depth_bytes;
    use voxcube::run::render::{node_skipping, preflight, Fabric, Machine};
    let small = blobs([40, 40, 40], Vec3::ONE, 7);
    let cam = voxcube_tests::ortho(
        Vec3::new(100.0, 16.0, 20.0),
        Vec3::splat(20.0),
        Vec3::Y,
        60.0,
    );
    let surface = || voxcube_tests::surfaces(&[(150.0, 0.0)]);
    let sized = |cam, w: u32, h: u32| {
        voxcube_tests::view(
            voxcube_tests::spec(cam, w, h, Model::Cell, 0.5, surface()),
            &small,
        )
    };
    let machine = Machine::new(Fabric::Sim, 1, 1, 1);
    let (fits, huge) = (sized(cam, 40, 30), sized(cam, 1200, 1000));
    assert_eq!(depth_bytes(&fits, SkipMode::ALL, 1), 40 * 30 * 4);
    assert_eq!(depth_bytes(&fits, SkipMode::ALL, 4), 40 * 8 * 4);
    assert!(node_skipping(&small, &fits, &machine, false).depths);
    assert!(node_skipping(&small, &fits, &machine, true).depths);
    // 4.8 MB of bounds: more than an nCUBE 2 node's 4 MiB.
    preflight(&small, &huge, &machine).expect("fits without depth bounds");
    assert!(!node_skipping(&small, &huge, &machine, false).depths);
    assert!(node_skipping(&small, &huge, &machine, false).cell_leaps);
    // In four clusters a node holds a quarter of the rows: 1.2 MB.
    let four = Machine::new(Fabric::Sim, 4, 4, 1);
    preflight(&small, &huge, &four).expect("fits");
    assert!(node_skipping(&small, &huge, &four, false).depths);
    let direct = Machine::new(Fabric::Direct, 1, 1, 1);
    assert!(node_skipping(&small, &huge, &direct, false).depths);
    let eye = Vec3::new(100.0, 16.0, 20.0);
    let persp = sized(
        voxcube_tests::perspective(eye, Vec3::splat(20.0), Vec3::Y, 40.0),
        40,
        30,
    );
    assert_eq!(depth_bytes(&persp, SkipMode::ALL, 1), 0);
    assert!(!node_skipping(&small, &persp, &machine, false).depths);
    let no_cells = SkipMode {
        cells: false,
        ..SkipMode::ALL
    };
    assert_eq!(depth_bytes(&fits, no_cells, 1), 0);
}

/// A cell leap map built in parts of planes, each with [`MAX_DISTANCE`] planes more ahead of
/// it, is the map built whole, in every octant; the same parts built without the planes
/// ahead are not (the negative control: the planes ahead are what makes the parts exact).
///
/// [`MAX_DISTANCE`]: voxcube_kernel::skip::cell_leaps::MAX_DISTANCE
#[test]
fn a_cell_leap_map_built_in_parts_of_planes_is_the_whole_map() {
    use voxcube_kernel::skip::blocks::Blocks;
    use voxcube_kernel::skip::cell_leaps::with_planes_ahead;
    use voxcube_kernel::skip::cell_leaps::{build, build_planes, part, plane_len, planes};
    use voxcube_kernel::skip::octant::Octant;
    let volume = blobs([10, 9, 150], Vec3::ONE, 0x7e);
    let (slab, ranges) = whole_slab_blocks(&volume);
    let blocks = Blocks::new(slab.grid(), slab.stored(), &ranges).expect("storage");
    let cam = voxcube_tests::ortho(Vec3::new(60.0, 10.0, 90.0), Vec3::splat(5.0), Vec3::Y, 30.0);
    let view = voxcube_tests::view(
        voxcube_tests::spec(
            cam,
            4,
            4,
            Model::Cell,
            0.5,
            voxcube_tests::surfaces(&[(150.0, 0.0)]),
        ),
        &volume,
    );
    let mut masks = vec![0; ranges.len()];
    voxcube_kernel::skip::cells::build(&slab, &blocks, &view, &mut masks).expect("storage");
    let blocks = blocks.with_cells(&masks).expect("storage");
    let (all, plane) = (planes(&blocks), plane_len(&blocks));
    let mut differs = 0;
    for octant in (0..8).map(Octant::from_index) {
        let mut whole = vec![0; ranges.len() * 64];
        build(&blocks, octant, &mut whole).expect("storage");
        // Parts as the host splits a build, and parts of equal length.
        for (n, balanced) in [2, 3, 5].into_iter().flat_map(|n| [(n, true), (n, false)]) {
            let mut parts = vec![0; whole.len()];
            let mut bare = vec![0; whole.len()];
            let part_of = |i: usize| match balanced {
                true => part(i, n, all, octant),
                false => i * all / n..(i + 1) * all / n,
            };
            for part in (0..n).map(part_of) {
                let region = with_planes_ahead(part.clone(), all, octant);
                let mut built = vec![0; region.len() * plane];
                build_planes(&blocks, octant, region.clone(), &mut built).expect("storage");
                let at = (part.start - region.start) * plane;
                parts[part.start * plane..part.end * plane]
                    .copy_from_slice(&built[at..at + part.len() * plane]);
                build_planes(
                    &blocks,
                    octant,
                    part.clone(),
                    &mut bare[part.start * plane..part.end * plane],
                )
                .expect("storage");
            }
            assert!(
                parts == whole,
                "{octant:?} in {n} parts (balanced: {balanced})"
            );
            differs += usize::from(bare != whole);
        }
    }
    assert!(
        differs > 0,
        "parts built without the planes ahead differ somewhere"
    );
}

/// Every count but the primary rays set up: what row leaps change, and all they change.
fn but_set_ups(c: voxcube_kernel::counters::Counters) -> voxcube_kernel::counters::Counters {
    voxcube_kernel::counters::Counters {
        rays_set_up: 0,
        ..c
    }
}

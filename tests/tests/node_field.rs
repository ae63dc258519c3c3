//! The fast tier's node field is an acceleration, not an approximation of its own: a slab
//! that holds it and one that computes the same lanes on the fly give every pixel's colour in
//! the same bits, for every sample kind, mode and projection, and machines that hold it on
//! some nodes and not on others give the same image. A field whose differences are off
//! changes the image, so the comparisons would catch a field that is not the slab's own.

use voxcube::fabric::{sim, threads, RunConfig};
use voxcube::input::dataset::{Volume, VolumeData};
use voxcube::memory::storage::{holds_node_field, SkipMode};
use voxcube::run::render::render;
use voxcube_kernel::counters::Counters;
use voxcube_kernel::optics::shade::Light;
use voxcube_kernel::optics::transfer::{ControlPoint, TransferFunction};
use voxcube_kernel::trace::tracer::trace_pixel;
use voxcube_kernel::trace::view::{Accuracy, Approximation, Mode, View};
use voxcube_kernel::volume::grid::Model;
use voxcube_kernel::volume::lanes::Lanes;
use voxcube_kernel::volume::nodes;
use voxcube_kernel::volume::sample::Sample;
use voxcube_kernel::volume::slab::Slab;
use voxcube_kernel::Vec3;
use voxcube_tests::{
    constant_transfer, lit, ortho, perspective, spec, surfaces, volume_f32, volume_u8,
};

/// A field with hills and valleys along every axis: differences of every sign.
fn hills(x: u32, y: u32, z: u32) -> f32 {
    let (x, y, z) = (x as f32, y as f32, z as f32);
    100.0 + 60.0 * (x * 0.41).sin() * (y * 0.23 + 0.3).cos() + 50.0 * (z * 0.37 - x * 0.11).sin()
}

fn volumes() -> Vec<Volume> {
    let dims = [17, 13, 15];
    let spacing = Vec3::new(1.0, 0.8, 1.3);
    let bytes = volume_u8(dims, spacing, |x, y, z| hills(x, y, z) as u8);
    let floats = volume_f32(dims, spacing, |x, y, z| hills(x, y, z) * 0.37);
    let words = Volume::new(
        bytes.grid,
        VolumeData::U16(match &bytes.data {
            VolumeData::U8(d) => d.iter().map(|&v| u16::from(v) * 257).collect(),
            _ => unreachable!("a byte volume"),
        }),
    );
    // Signed, as CT's Hounsfield units: every value at or below zero.
    let signed = Volume::new(bytes.grid, VolumeData::I16(signed_of(&bytes)));
    vec![bytes, floats, words, signed]
}

/// A byte volume's samples times [`SIGNED`], in `i16`.
fn signed_of(bytes: &Volume) -> Vec<i16> {
    match &bytes.data {
        VolumeData::U8(d) => d.iter().map(|&v| i16::from(v) * SIGNED as i16).collect(),
        _ => unreachable!("a byte volume"),
    }
}

/// The scale of the signed volume's values: negative, so its gradients turn about too.
const SIGNED: f32 = -97.0;

/// A transfer function that changes along the hills' values (`scale` times the bytes'): a
/// colour and an opacity that a value read amiss moves, where a constant one shows only the
/// gradients.
fn ramp(scale: f32) -> Mode {
    let (a, b) = (40.0 * scale, 160.0 * scale);
    let points = [
        (a.min(b), Vec3::new(0.2, 0.4, 0.9), 0.0),
        (a.max(b), Vec3::new(1.0, 0.6, 0.2), 0.2),
    ];
    Mode::Composite(
        TransferFunction::new(&points.map(|(value, color, opacity)| ControlPoint {
            value,
            color,
            opacity,
        }))
        .expect("valid transfer function"),
    )
}

/// Views of `volume` in `tier` that read gradients from the node field (the fast tier's
/// definition, the exact tier's re-associated): composited and surfaces, parallel and
/// perspective, a directional and a point light.
fn views(volume: &Volume, tier: Accuracy) -> Vec<View> {
    let [nx, ny, nz] = volume.grid.dims().map(|n| n as f32);
    let centre = Vec3::new(nx * 0.5, ny * 0.4, nz * 0.65);
    let scale = match &volume.data {
        VolumeData::U16(_) => 257.0,
        VolumeData::I16(_) => SIGNED,
        VolumeData::F32(_) => 0.37,
        VolumeData::U8(_) => 1.0,
    };
    let lights = [
        Light::directional(Vec3::new(0.3, -0.6, -1.0), Vec3::ONE, false).expect("light"),
        Light::point(Vec3::new(-4.0, 20.0, 9.0), Vec3::splat(0.6), false).expect("light"),
    ];
    let cameras = [
        ortho(centre + Vec3::new(30.0, 11.0, -17.0), centre, Vec3::Y, 26.0),
        perspective(centre + Vec3::new(-20.0, 25.0, 14.0), centre, Vec3::Z, 45.0),
    ];
    let mut out = Vec::new();
    for camera in cameras {
        for mode in [
            constant_transfer(0.05),
            ramp(scale),
            surfaces(&[(120.0 * scale, 0.5), (150.0 * scale, 0.0)]),
        ] {
            let mut s = lit(spec(camera, 48, 40, Model::Cell, 0.5, mode), &lights);
            s.accuracy = tier;
            let view = View::new(s, &volume.grid).expect("valid view");
            match tier {
                Accuracy::Fast => assert!(view
                    .approximations()
                    .contains(&Approximation::NodeGradients)),
                Accuracy::Exact => assert!(view.exact_node_gradients()),
            }
            out.push(view);
        }
    }
    out
}

/// Every pixel's unquantised colour as bits, from the whole volume with or without its node
/// field, skipping as `mode` says; the field's bytes; and the counters.
fn colours(
    volume: &Volume,
    view: &View,
    mode: SkipMode,
    held: bool,
) -> (Vec<[u32; 3]>, usize, Counters) {
    fn go<T: Sample + Sync>(
        volume: &Volume,
        data: &[T],
        view: &View,
        mode: SkipMode,
        held: bool,
    ) -> (Vec<[u32; 3]>, usize, Counters) {
        let slab = Slab::whole(volume.grid, data).expect("whole slab");
        let mode = SkipMode {
            nodes: held,
            ..mode
        };
        let field = volume.built.field(&slab, holds_node_field(view, mode), 2);
        // Built once for the volume: asked again, the same field.
        let again = volume.built.field(&slab, holds_node_field(view, mode), 1);
        assert!(std::sync::Arc::ptr_eq(&field, &again) || !held);
        let slab = field.apply(slab);
        assert_eq!(slab.nodes().is_some(), held);
        let (colours, c) = voxcube_tests::colour_bits(view, &slab);
        assert_eq!(c.slab_misses, 0);
        (colours, field.bytes(), c)
    }
    match &volume.data {
        VolumeData::U8(d) => go(volume, d, view, mode, held),
        VolumeData::U16(d) => go(volume, d, view, mode, held),
        VolumeData::I16(d) => go(volume, d, view, mode, held),
        VolumeData::F32(d) => go(volume, d, view, mode, held),
    }
}

#[test]
fn held_or_computed_on_the_fly_the_node_field_gives_every_colour_in_the_same_bits() {
    // With cell leap maps most composited samples are read by the runs through the slab's
    // interior; without them every sample by the general step, which reads value and
    // gradient from the field's lanes in both tiers where the field is held.
    let general_step = SkipMode {
        cell_leaps: false,
        ..SkipMode::ALL
    };
    for volume in volumes() {
        let kind = volume.data.kind();
        for tier in [Accuracy::Fast, Accuracy::Exact] {
            for view in views(&volume, tier) {
                for mode in [SkipMode::ALL, general_step] {
                    let (held, bytes, counted) = colours(&volume, &view, mode, true);
                    let (fly, none, also) = colours(&volume, &view, mode, false);
                    let case = format!("{kind:?}, {tier:?}, cell leaps {}", mode.cell_leaps);
                    // The same work counted: the counters do not say whether a node held
                    // the field.
                    assert_eq!(counted, also, "{case}");
                    let nodes = volume.grid.dims().iter().product::<u32>() as usize;
                    assert_eq!((bytes, none), (nodes * kind.node_bytes(), 0), "{case}");
                    // Not a blank image: the comparison sees the shading.
                    let lit = held.iter().filter(|c| **c != [0; 3]).count();
                    assert!(lit > held.len() / 10, "{case}: {lit} pixels lit");
                    assert!(held == fly, "{case}: a colour differs");
                }
            }
        }
    }
}

#[test]
fn a_signed_16_bit_volume_gives_what_its_values_as_floats_give_in_every_bit() {
    // The same values in the kind a scaled file gets: each read, range and lane converts to
    // f32 exactly, so every colour is the same bits, field held or not, in each tier.
    let bytes = &volumes()[0];
    let signed = signed_of(bytes);
    let words = Volume::new(bytes.grid, VolumeData::I16(signed.clone()));
    let floats = Volume::new(
        bytes.grid,
        VolumeData::F32(signed.iter().map(|&v| f32::from(v)).collect()),
    );
    for accuracy in [Accuracy::Fast, Accuracy::Exact] {
        for view in views(&words, accuracy) {
            for held in [true, false] {
                let (a, bytes16, _) = colours(&words, &view, SkipMode::ALL, held);
                let (b, bytes32, _) = colours(&floats, &view, SkipMode::ALL, held);
                assert!(a == b, "{accuracy:?}, field held {held}: a colour differs");
                assert_eq!(bytes16, bytes32, "both hold four f32 lanes a node");
                let lit = a.iter().filter(|c| **c != [0; 3]).count();
                assert!(lit > a.len() / 10, "{lit} pixels lit");
            }
        }
    }
}

#[test]
fn machines_that_hold_the_field_and_machines_that_do_not_give_the_same_image() {
    // SOD: the direct render holds the field; eight simulated nodes hold theirs; nodes on
    // threads that hold none (as a 4 MiB nCUBE 2 node holding the whole volume cannot)
    // compute the lanes on the fly.
    let Some(jobs) = voxcube_tests::sod_jobs() else {
        return;
    };
    let job = &jobs[0];
    let v = job
        .views
        .iter()
        .find(|v| matches!(v.view.spec().mode, Mode::Composite(_)))
        .expect("SOD's composited view");
    let view = voxcube_tests::in_tier(&v.view, &job.volume, Accuracy::Fast);
    assert!(view.node_gradients(), "SOD's composited view is shaded");
    let direct = render(&job.volume, &view).expect("renders").pixels;
    let eight = RunConfig::cluster(8, 5).expect("layout");
    let run = sim::run(&job.volume, &view, &eight).unwrap_or_else(|e| panic!("{e}"));
    assert!(
        run.pixels == direct,
        "8 nodes holding the field: image differs"
    );
    let whole = RunConfig {
        skipping: SkipMode {
            nodes: false,
            ..SkipMode::ALL
        },
        ..RunConfig::machine(2, 1, 1).expect("layout")
    };
    let run = threads::run(&job.volume, &view, &whole, 2).unwrap_or_else(|e| panic!("{e}"));
    assert!(
        run.pixels == direct,
        "nodes computing on the fly: image differs"
    );
}

#[test]
fn negative_control_a_field_whose_values_or_differences_are_off_changes_the_image() {
    let volume = &volumes()[0];
    let VolumeData::U8(data) = &volume.data else {
        unreachable!("a byte volume")
    };
    let slab = Slab::whole(volume.grid, data).expect("whole slab");
    let planes = nodes::planes_for(&volume.grid, slab.owned());
    let mut lanes = vec![<[i16; 4]>::default(); nodes::len_for(&volume.grid, slab.owned())];
    nodes::fill(&slab, planes.clone(), &mut lanes).expect("fills");
    // Both tiers read the field where it is held: the value and the gradient in the fast
    // tier, and in the exact tier the gradient and, at points in the grid, the value too.
    for tier in [Accuracy::Fast, Accuracy::Exact] {
        // Parallel, composited by the ramp: both the values and the gradients show.
        let view = &views(volume, tier)[1];
        let trace = |slab: &Slab<'_, u8>| {
            let mut c = Counters::default();
            (0..view.pixel_count() as u32)
                .map(|p| trace_pixel(view, slab, p, &mut c))
                .collect::<Vec<_>>()
        };
        let own = voxcube_kernel::volume::lanes::Nodes::new(&volume.grid, planes.clone(), &lanes)
            .expect("field");
        let right = trace(&slab.with_nodes(own));
        assert_eq!(right, trace(&slab), "{tier:?}: the slab's own field");
        // One more unit in every node's value, or in its difference along X: a field off
        // by a little.
        for (lane, what) in [(0, "value"), (1, "difference along X")] {
            let mut unit = voxcube_kernel::Vec4::ZERO;
            unit[lane] = 1.0;
            let off: Vec<[i16; 4]> = lanes
                .iter()
                .map(|l| <[i16; 4]>::pack(l.unpack() + unit))
                .collect();
            let off = voxcube_kernel::volume::lanes::Nodes::new(&volume.grid, planes.clone(), &off)
                .expect("field");
            let wrong = trace(&slab.with_nodes(off));
            let differ = right.iter().zip(&wrong).filter(|(a, b)| a != b).count();
            assert!(
                differ > 0,
                "{tier:?}: a field whose {what} is off by one unit left every colour as it was"
            );
        }
    }
}

//! Hard cases stay finite and behave as documented: axis-parallel rays, rays on cell faces and
//! box faces, grazing rays, the eye inside the volume, constant volumes, iso values equal to
//! the data, 1×1×1 and 2×2×2 volumes, extreme spacing; and a property test that no colour is
//! ever NaN over random volumes, views and steps.

use proptest::prelude::*;
use voxcube::input::builtin;
use voxcube::input::dataset::Volume;
use voxcube_kernel::counters::Counters;
use voxcube_kernel::optics::shade::Light;
use voxcube_kernel::optics::transfer::{ControlPoint, TransferFunction};
use voxcube_kernel::trace::view::{Mode, ViewSpec};
use voxcube_kernel::volume::grid::Model;
use voxcube_kernel::Vec3;
use voxcube_tests::*;

fn all_finite(colors: &[Vec3]) -> bool {
    colors.iter().all(|c| c.is_finite())
}

fn render(volume: &Volume, s: ViewSpec) -> (Vec<Vec3>, Counters) {
    let v = view(s, volume);
    let out = trace_all(volume, &v);
    assert!(all_finite(&out.0), "a colour is not finite");
    assert_eq!(out.1.slab_misses, 0);
    out
}

fn headlight() -> Light {
    Light::directional(Vec3::new(0.3, -0.4, -1.0), Vec3::ONE, true).expect("light")
}

#[test]
fn axis_parallel_views_of_a_sphere_agree() {
    let volume = builtin::sphere(32, 12.0);
    let c = Vec3::splat(15.5);
    let mut hits = Vec::new();
    for dir in [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z] {
        let up = if dir.y == 0.0 { Vec3::Y } else { Vec3::Z };
        let s = lit(
            spec(
                ortho(c + dir * 40.0, c, up, 32.0),
                32,
                32,
                Model::Cell,
                0.5,
                surfaces(&[(0.0, 0.0)]),
            ),
            &[headlight()],
        );
        let (colors, _) = render(&volume, s);
        hits.push(colors.iter().filter(|c| **c != Vec3::ZERO).count());
    }
    // A sphere looks the same along every axis: the same number of pixels covered.
    assert!(hits.iter().all(|&h| h == hits[0]), "{hits:?}");
    assert!(hits[0] > 400, "{hits:?}");
}

#[test]
fn rays_exactly_on_cell_faces_and_box_faces() {
    // Pixel centres land on integer planes: x = 0..15, including the box faces x = 0 and 15.
    let volume = volume_u8([16, 16, 16], Vec3::ONE, |x, y, _| (x * 7 + y * 3) as u8);
    let cam = ortho(
        Vec3::new(7.5, 7.5, 40.0),
        Vec3::new(7.5, 7.5, 0.0),
        Vec3::Y,
        16.0,
    );
    for model in [Model::Cell, Model::Voxel] {
        let s = lit(
            spec(cam, 16, 16, model, 0.5, surfaces(&[(40.0, 0.5)])),
            &[headlight()],
        );
        let (colors, c) = render(&volume, s);
        assert_eq!(
            c.primary_rays, 256,
            "every ray on a face or inside enters the closed box"
        );
        assert!(colors.iter().any(|c| *c != Vec3::ZERO));
    }
}

#[test]
fn grazing_rays_along_a_face_stay_finite() {
    let volume = builtin::sphere(16, 6.0);
    // Rays travelling along the face y = 0 of the box (the first row) and just outside it.
    let cam = ortho(
        Vec3::new(7.5, 0.0, 30.0),
        Vec3::new(7.5, 0.0, 0.0),
        Vec3::Y,
        16.0,
    );
    let s = lit(
        spec(cam, 16, 1, Model::Cell, 0.5, surfaces(&[(-6.0, 0.0)])),
        &[headlight()],
    );
    let (_, c) = render(&volume, s);
    assert!(c.primary_rays > 0);
    let cam = ortho(
        Vec3::new(30.0, 30.0, 30.0),
        Vec3::new(15.0, 15.0, 15.0),
        Vec3::Y,
        0.001,
    );
    render(
        &volume,
        lit(
            spec(cam, 1, 1, Model::Voxel, 0.5, surfaces(&[(0.0, 0.0)])),
            &[headlight()],
        ),
    );
}

#[test]
fn eye_inside_the_volume_sees_the_cut_face() {
    let volume = builtin::sphere(32, 12.0);
    let centre = Vec3::splat(15.5);
    let cam = perspective(centre, centre + Vec3::Z, Vec3::Y, 60.0);
    let (colors, c) = render(
        &volume,
        lit(
            spec(cam, 16, 16, Model::Cell, 0.5, surfaces(&[(0.0, 0.0)])),
            &[headlight()],
        ),
    );
    assert_eq!(c.primary_rays, 256);
    // The eye is inside the sphere: every ray starts inside the surface and shows the cut face.
    assert!(colors.iter().all(|c| *c != Vec3::ZERO));
    // Compositing from inside integrates from the eye.
    let cam = perspective(centre, centre + Vec3::X, Vec3::Y, 60.0);
    render(
        &volume,
        spec(cam, 8, 8, Model::Voxel, 0.25, constant_transfer(0.05)),
    );
}

#[test]
fn constant_volumes_and_iso_values_equal_to_the_data() {
    let volume = volume_u8([8, 8, 8], Vec3::ONE, |_, _, _| 100);
    let cam = ortho(Vec3::new(20.0, 15.0, 25.0), Vec3::splat(3.5), Vec3::Y, 20.0);
    for (iso, expect_hits) in [(50.0, true), (100.0, true), (150.0, false)] {
        let s = lit(
            spec(cam, 24, 24, Model::Cell, 0.5, surfaces(&[(iso, 0.0)])),
            &[headlight()],
        );
        let (colors, c) = render(&volume, s);
        let hits = colors.iter().filter(|c| **c != Vec3::ZERO).count();
        assert_eq!(hits > 0, expect_hits, "iso {iso}");
        // Cut faces are lit by their face normal: no gradient of the constant field is used.
        assert_eq!(c.normal_fallbacks, 0);
    }
    // Compositing with shading needs the gradient of a constant field: zero, so the fallback.
    let s = lit(
        spec(cam, 8, 8, Model::Cell, 0.5, constant_transfer(0.2)),
        &[],
    );
    let (_, c) = render(&volume, s);
    assert!(c.normal_fallbacks > 0);
}

#[test]
fn tiny_volumes_render() {
    for dims in [[1, 1, 1], [2, 2, 2], [1, 4, 4]] {
        let volume = volume_u8(dims, Vec3::ONE, |x, y, z| (20 * (x + y + z) + 10) as u8);
        let c = Vec3::new(
            dims[0] as f32 - 1.0,
            dims[1] as f32 - 1.0,
            dims[2] as f32 - 1.0,
        ) * 0.5;
        for model in [Model::Cell, Model::Voxel] {
            let cam = ortho(c + Vec3::new(3.0, 2.0, 5.0), c, Vec3::Y, 4.0);
            let (colors, _) = render(
                &volume,
                lit(
                    spec(
                        cam,
                        16,
                        16,
                        model,
                        0.25,
                        surfaces(&[(5.0, 0.3), (60.0, 0.0)]),
                    ),
                    &[headlight()],
                ),
            );
            if model == Model::Voxel {
                assert!(
                    colors.iter().any(|c| *c != Vec3::ZERO),
                    "{dims:?}: a voxel volume has extent"
                );
            }
            render(
                &volume,
                spec(cam, 8, 8, model, 0.25, constant_transfer(0.5)),
            );
        }
    }
}

#[test]
fn extreme_spacing_stays_finite() {
    for spacing in [
        Vec3::new(1e-6, 1.0, 1e6),
        Vec3::new(1e4, 1e4, 1e-4),
        Vec3::splat(1e-20),
    ] {
        let volume = volume_u8([6, 5, 4], spacing, |x, y, z| (x * 40 + y * 10 + z) as u8);
        let (lo, hi) = volume.grid.world_box(Model::Cell);
        let c = (lo + hi) * 0.5;
        let r = (hi - lo).length().max(1e-30);
        let cam = ortho(
            c + Vec3::new(0.5, 0.4, 0.8).normalize() * 2.0 * r,
            c,
            Vec3::Y,
            2.0 * r,
        );
        render(
            &volume,
            lit(
                spec(cam, 12, 12, Model::Cell, 0.5, surfaces(&[(60.0, 0.5)])),
                &[headlight()],
            ),
        );
        render(
            &volume,
            lit(
                spec(cam, 12, 12, Model::Voxel, 1.0, constant_transfer(0.3)),
                &[],
            ),
        );
    }
}

fn arb_mode() -> impl Strategy<Value = Mode> {
    prop_oneof![
        prop::collection::vec(
            (0.0f32..255.0, prop_oneof![Just(0.0f32), 0.0f32..1.0]),
            1..4
        )
        .prop_map(|s| surfaces(&s)),
        prop::collection::vec((0.0f32..255.0, 0.0f32..1.0, 0.0f32..1.0), 1..5).prop_map(
            |mut pts| {
                pts.sort_by(|a, b| a.0.total_cmp(&b.0));
                pts.dedup_by(|a, b| a.0 <= b.0);
                let pts: Vec<ControlPoint> = pts
                    .into_iter()
                    .map(|(value, c, opacity)| ControlPoint {
                        value,
                        color: Vec3::splat(c),
                        opacity,
                    })
                    .collect();
                Mode::Composite(TransferFunction::new(&pts).expect("sorted points"))
            }
        ),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    /// No NaN, ever: random volumes, cameras (inside and outside), steps, modes and lights.
    #[test]
    fn no_colour_is_ever_nan(
        dims in prop::array::uniform3(1u32..7),
        spacing in prop::array::uniform3(prop_oneof![Just(1.0f32), 0.01f32..100.0]),
        seed in any::<u64>(),
        eye in prop::array::uniform3(-20.0f32..20.0),
        look in prop::array::uniform3(-2.0f32..8.0),
        persp in any::<bool>(),
        voxel in any::<bool>(),
        dt in 0.02f32..2.0,
        mode in arb_mode(),
        shaded in any::<bool>(),
        point_light in prop::array::uniform3(-5.0f32..10.0),
    ) {
        let volume = volume_u8(dims, Vec3::from_array(spacing), |x, y, z| {
            let h = seed ^ (u64::from(x) * 0x9E37_79B9 + u64::from(y) * 0x85EB_CA6B + u64::from(z) * 0xC2B2_AE35);
            (h.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 56) as u8
        });
        let (eye, look) = (Vec3::from_array(eye), Vec3::from_array(look));
        prop_assume!((eye - look).length() > 1e-3 && (eye - look).normalize().cross(Vec3::Y).length() > 1e-3);
        let cam = if persp { perspective(eye, look, Vec3::Y, 50.0) } else { ortho(eye, look, Vec3::Y, 10.0) };
        let model = if voxel { Model::Voxel } else { Model::Cell };
        let composite = matches!(mode, Mode::Composite(_));
        let mut s = spec(cam, 8, 8, model, dt, mode);
        if shaded {
            let lights = [
                Light::directional(Vec3::new(0.2, -1.0, 0.3), Vec3::ONE, !composite).expect("light"),
                Light::point(Vec3::from_array(point_light), Vec3::splat(0.7), !composite).expect("light"),
            ];
            s = lit(s, &lights);
        }
        let v = view(s, &volume);
        let (colors, c) = trace_all(&volume, &v);
        prop_assert!(all_finite(&colors), "{colors:?}");
        prop_assert_eq!(c.slab_misses, 0);
    }
}

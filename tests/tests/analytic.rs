//! Tests against analytic answers: the silhouette of a sphere and Beer–Lambert attenuation.

use voxcube::input::builtin;
use voxcube_kernel::trace::view::{Accuracy, Approximation, ViewSpec};
use voxcube_kernel::volume::grid::Model;
use voxcube_kernel::Vec3;
use voxcube_tests::*;

/// Every pixel farther than half a pixel from the exact silhouette is on the right side of it.
fn check_sphere_silhouette(toward_eye: Vec3) {
    let (n, radius) = (64u32, 24.0f32);
    let volume = builtin::sphere(n, f64::from(radius));
    let centre = Vec3::splat((n - 1) as f32 / 2.0);
    let (size, width) = (128u32, 64.0f32);
    let pixel = width / size as f32;
    let up = if toward_eye.cross(Vec3::Y).length() > 0.1 {
        Vec3::Y
    } else {
        Vec3::Z
    };
    let cam = ortho(centre + toward_eye.normalize() * 100.0, centre, up, width);
    let v = view(
        spec(cam, size, size, Model::Cell, 0.5, surfaces(&[(0.0, 0.0)])),
        &volume,
    );
    let (colors, counters) = trace_all(&volume, &v);
    let mut checked = 0;
    for (i, c) in colors.iter().enumerate() {
        let (px, py) = ((i as u32 % size) as f32, (i as u32 / size) as f32);
        // Distance of the pixel centre from the image centre, in world units.
        let (dx, dy) = (
            (px + 0.5 - size as f32 / 2.0) * pixel,
            (py + 0.5 - size as f32 / 2.0) * pixel,
        );
        let r = (dx * dx + dy * dy).sqrt();
        let hit = *c != Vec3::ZERO;
        if (r - radius).abs() > 0.5 * pixel {
            assert_eq!(
                hit,
                r < radius,
                "pixel ({px}, {py}) at r = {r}: hit = {hit}"
            );
            checked += 1;
        }
    }
    assert!(checked > (size * size) as usize * 9 / 10);
    assert_eq!(counters.slab_misses, 0);
}

#[test]
fn sphere_silhouette_is_within_half_a_pixel_along_an_axis() {
    check_sphere_silhouette(Vec3::Z);
}

#[test]
fn sphere_silhouette_is_within_half_a_pixel_obliquely() {
    check_sphere_silhouette(Vec3::new(0.6, 0.5, 0.8));
    check_sphere_silhouette(Vec3::new(-1.0, 0.0, 0.0));
}

/// Compositing through a constant medium: the pixel is `1 − (1 − α)^L` for a path of `L` cell
/// edges, whatever the step, in each tier: the fast tier's table holds the opacity of a whole
/// segment, and a ray's last, shorter segment corrects the entry's opacity for its own length.
#[test]
fn compositing_a_constant_slab_matches_beer_lambert() {
    let volume = volume_f32([16, 8, 8], Vec3::ONE, |_, _, _| 1.0);
    let alpha = 0.1f32;
    let tiers = [Accuracy::Exact, Accuracy::Fast];
    for (dt, tier) in [0.5f32, 0.2, 0.125]
        .into_iter()
        .flat_map(|dt| tiers.map(|t| (dt, t)))
    {
        for (toward_eye, what) in [
            (Vec3::new(-1.0, 0.0, 0.0), "along x"),
            (Vec3::new(-1.0, 0.3, 0.2), "oblique"),
        ] {
            let target = Vec3::new(7.5, 3.5, 3.5);
            let cam = ortho(
                target + toward_eye.normalize() * 50.0,
                target,
                Vec3::Y,
                0.01,
            );
            let v = view(
                ViewSpec {
                    accuracy: tier,
                    ..spec(cam, 1, 1, Model::Cell, dt, constant_transfer(alpha))
                },
                &volume,
            );
            let tabled = v.approximations().contains(&Approximation::PreClassified);
            assert_eq!(tabled, tier == Accuracy::Fast);
            let (colors, _) = trace_all(&volume, &v);
            // The exact path length through the box [0, 15]×[0, 7]×[0, 7].
            let d = -toward_eye.normalize();
            let o = target - d * 50.0;
            let (mut t0, mut t1) = (f32::MIN, f32::MAX);
            for a in 0..3 {
                let hi = [15.0, 7.0, 7.0][a];
                let (ta, tb) = ((0.0 - o[a]) / d[a], (hi - o[a]) / d[a]);
                t0 = t0.max(ta.min(tb));
                t1 = t1.min(ta.max(tb));
            }
            let expected = 1.0 - (1.0 - f64::from(alpha)).powf(f64::from(t1 - t0));
            let got = f64::from(colors[0].x);
            assert!(
                (got - expected).abs() < 1e-3,
                "dt {dt} {what} {tier:?}: {got} vs Beer–Lambert {expected}"
            );
        }
    }
}

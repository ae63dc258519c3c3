//! The fast tier's shading by table, as production ray casters shade: where a composited
//! view's rays are parallel and its lights all directional, the light a point reflects
//! depends on its normal's direction alone, so it is tabulated once per view over
//! [`NORMAL_STEPS`]² directions (the octahedral map of the sphere), and a sample reads the
//! entry of its gradient's direction, `base · scale + add`, instead of normalising the
//! gradient and evaluating each light.
//!
//! Invariants: an entry holds the exact tier's terms (Lambert, and Phong by `powf`) for the
//! direction at the centre of its cell of the map, the normal facing the view's direction as
//! [`shade::face_viewer`] turns it; a gradient that [`shade::normal`] would replace by the
//! fallback normal reads the fallback's entry; every gradient, NaN and infinities too, reads
//! an entry of the table. Built from the view alone, the same bits on every node.

use crate::optics::shade::{self, Light, Shading, MAX_LIGHTS};
use glam::{Vec3, Vec4};

/// Cells of the octahedral map along each of its two axes.
pub const NORMAL_STEPS: usize = 64;

/// How far from its cell's centre a direction may lie, in radians per cell width (`2 /
/// NORMAL_STEPS`) of the map: at most 2.1 measured on 2 million directions (where a face of
/// the octahedron is seen most obliquely), and this bound above it is tested. At 64 steps,
/// 3.8° at most, 1.4° on average.
pub const MAX_ERROR_WIDTHS: f32 = 2.2;

/// Directions in the table; the fallback normal's entry follows them.
const DIRECTIONS: usize = NORMAL_STEPS * NORMAL_STEPS;

/// What one direction reflects: `base · scale + add` for a point of colour `base`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Entry {
    /// The ambient coefficient plus each light's colour times its diffuse term.
    scale: Vec3,
    /// Each light's colour times its highlight.
    add: Vec3,
}

/// A view's shading by normal direction.
#[derive(Clone, Debug, PartialEq)]
pub struct ShadingTable {
    /// The direction of the rays the table is built for.
    view_dir: Vec3,
    entries: [Entry; DIRECTIONS + 1],
}

impl ShadingTable {
    /// The table of `shading` under `lights`, seen along `view_dir` (unit); `None` when some
    /// light is a point light, whose direction changes from point to point.
    pub fn new(shading: &Shading, lights: &[Light], view_dir: Vec3) -> Option<ShadingTable> {
        let lights: heapless::Vec<(Vec3, Vec3), MAX_LIGHTS> = lights
            .iter()
            .map(|light| Some((light.toward_everywhere()?, light.color)))
            .collect::<Option<_>>()?;
        let entry = |n: Vec3| {
            let mut e = Entry {
                scale: Vec3::splat(shading.ambient),
                add: Vec3::ZERO,
            };
            for &(toward, color) in &lights {
                let (diffuse, specular) = shade::terms(shading, n, view_dir, toward);
                e.scale += color * diffuse;
                e.add += color * specular;
            }
            e
        };
        let mut entries = [Entry::default(); DIRECTIONS + 1];
        for (i, e) in entries.iter_mut().take(DIRECTIONS).enumerate() {
            let direction = centre(i / NORMAL_STEPS, i % NORMAL_STEPS);
            // The normal points down the gradient, and toward the viewer.
            *e = entry(shade::face_viewer(-direction, view_dir));
        }
        entries[DIRECTIONS] = entry(-view_dir);
        Some(ShadingTable { view_dir, entries })
    }

    /// The direction of the rays the table shades for.
    #[inline]
    pub fn view_dir(&self) -> Vec3 {
        self.view_dir
    }

    /// The colour of a point of colour `base` whose gradient is `gradient`, and whether it
    /// took the fallback normal.
    #[inline(always)]
    pub fn color(&self, base: Vec3, gradient: Vec3) -> (Vec3, bool) {
        self.color_at(base, index(gradient))
    }

    /// The colour of a point of colour `base` whose gradient's entry is `i` ([`indices`]),
    /// and whether that is the fallback normal's.
    #[inline(always)]
    pub fn color_at(&self, base: Vec3, i: usize) -> (Vec3, bool) {
        // `i` is never past the fallback's entry: the `min` only lets the compiler see it.
        let i = i.min(DIRECTIONS);
        let e = &self.entries[i];
        (base * e.scale + e.add, i == DIRECTIONS)
    }
}

/// The entries of four gradients at once, one in each lane of `x`, `y` and `z`: lane for
/// lane the operations of a single gradient's entry, so each lane's entry is its gradient's
/// in every bit (tested); the division and the folding of four gradients then take one
/// instruction each.
#[inline(always)]
pub fn indices(x: Vec4, y: Vec4, z: Vec4) -> [usize; 4] {
    // `shade::usable`'s test: the squared length, summed as `Vec3::length_squared` sums it.
    let len2 = x * x + y * y + z * z;
    let usable = len2.cmpgt(Vec4::splat(shade::MIN_GRADIENT_SQUARED)) & len2.is_finite_mask();
    let sum = x.abs() + y.abs() + z.abs();
    let (px, py) = (x / sum, y / sum);
    let (fx, fy) = (
        (Vec4::ONE - py.abs()).copysign(px),
        (Vec4::ONE - px.abs()).copysign(py),
    );
    let down = z.cmplt(Vec4::ZERO);
    let (px, py) = (Vec4::select(down, fx, px), Vec4::select(down, fy, py));
    let half = Vec4::splat(NORMAL_STEPS as f32 * 0.5);
    // An unusable lane's NaN or infinity gives some integer, which the `select` replaces.
    let u = voxcube_simd::lanes(voxcube_simd::trunc(px * half + half));
    let v = voxcube_simd::lanes(voxcube_simd::trunc(py * half + half));
    let last = NORMAL_STEPS as u32 - 1;
    let usable = usable.bitmask();
    core::array::from_fn(|l| {
        if usable & (1 << l) != 0 {
            u[l].min(last) as usize * NORMAL_STEPS + v[l].min(last) as usize
        } else {
            DIRECTIONS
        }
    })
}

/// The entry of a gradient: its direction's cell of the octahedral map, which projects the
/// direction onto the octahedron `|x| + |y| + |z| = 1` and unfolds the lower half (`z < 0`)
/// over the corners of the upper; [`DIRECTIONS`] where the gradient gives no direction.
#[inline(always)]
fn index(g: Vec3) -> usize {
    if !shade::usable(g) {
        return DIRECTIONS;
    }
    let a = g.abs();
    // Finite and above zero: the gradient is usable.
    let p = Vec4::new(g.x, g.y, 0.0, 0.0) / (a.x + a.y + a.z);
    // Folded, `(1 − |y|, 1 − |x|)` with the signs of `(x, y)`; chosen without a branch, as
    // half of all gradients point down.
    let folded = (Vec4::ONE - Vec4::new(p.y, p.x, 0.0, 0.0).abs()).copysign(p);
    let p = Vec4::select(Vec4::splat(g.z).cmplt(Vec4::ZERO), folded, p);
    // In [0, NORMAL_STEPS] on both axes, the top edge read by the last cell.
    let half = NORMAL_STEPS as f32 * 0.5;
    let (_, [u, v, _]) = voxcube_simd::trunc_lanes(p * half + Vec4::splat(half));
    let last = NORMAL_STEPS as u32 - 1;
    u.min(last) as usize * NORMAL_STEPS + v.min(last) as usize
}

/// The unit direction at the centre of cell `(u, v)` of the octahedral map.
fn centre(u: usize, v: usize) -> Vec3 {
    let at = |i: usize| (i as f32 + 0.5) / NORMAL_STEPS as f32 * 2.0 - 1.0;
    let (x, y) = (at(u), at(v));
    let z = 1.0 - x.abs() - y.abs();
    let (x, y) = if z < 0.0 {
        (
            libm::copysignf(1.0 - y.abs(), x),
            libm::copysignf(1.0 - x.abs(), y),
        )
    } else {
        (x, y)
    };
    Vec3::new(x, y, z).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(lights: &[Light], view_dir: Vec3) -> ShadingTable {
        ShadingTable::new(&Shading::default(), lights, view_dir).unwrap()
    }

    /// The exact shading of unit normal `n` (facing the viewer) for a white point.
    fn exact(lights: &[Light], n: Vec3, view_dir: Vec3) -> Vec3 {
        let s = Shading::default();
        let mut c = Vec3::splat(s.ambient);
        for l in lights {
            let toward = l.toward_everywhere().unwrap();
            c += shade::direct(&s, None, Vec3::ONE, n, view_dir, toward, l.color);
        }
        c
    }

    #[test]
    fn each_cells_centre_reads_its_own_entry_and_the_exact_shading() {
        let view_dir = Vec3::new(0.3, -0.2, -0.9).normalize();
        let lights = [
            Light::directional(Vec3::new(0.4, -0.5, 1.0), Vec3::new(1.0, 0.9, 0.8), false).unwrap(),
            Light::directional(Vec3::new(-1.0, 0.2, -0.3), Vec3::splat(0.5), false).unwrap(),
        ];
        let t = table(&lights, view_dir);
        for u in 0..NORMAL_STEPS {
            for v in 0..NORMAL_STEPS {
                let d = centre(u, v);
                // Any length: the direction alone counts.
                assert_eq!(index(d * 7.5), u * NORMAL_STEPS + v, "{u} {v}");
                let (c, fallback) = t.color(Vec3::ONE, d * 0.25);
                let want = exact(&lights, shade::face_viewer(-d, view_dir), view_dir);
                assert!(!fallback);
                assert!((c - want).abs().max_element() < 1e-5, "{u} {v}: {c} {want}");
            }
        }
    }

    #[test]
    fn a_gradient_reads_the_cell_its_direction_lies_in() {
        // The octahedral map in f64, written apart: a direction reads the cell its point on
        // the map lies in (points within rounding of a cell's edge may read either side).
        let map = |g: Vec3| {
            let [x, y, z] = g.to_array().map(f64::from);
            let l1 = x.abs() + y.abs() + z.abs();
            let (x, y) = (x / l1, y / l1);
            if z < 0.0 {
                ((1.0 - y.abs()).copysign(x), (1.0 - x.abs()).copysign(y))
            } else {
                (x, y)
            }
        };
        let steps = NORMAL_STEPS as f64;
        let mut next = crate::testing::xorshift(0x0c7a_4ed2);
        let unit = |n: u32| (n >> 8) as f32 / (1 << 24) as f32 * 2.0 - 1.0;
        let mut read = 0;
        for _ in 0..100_000 {
            let g = Vec3::new(unit(next()), unit(next()), unit(next()));
            if !shade::usable(g) {
                continue;
            }
            let (u, v) = map(g);
            let (u, v) = ((u + 1.0) * steps / 2.0, (v + 1.0) * steps / 2.0);
            let near_edge = |c: f64| (c - c.round()).abs() < 1e-4;
            if near_edge(u) || near_edge(v) {
                continue;
            }
            let cell = |c: f64| (c as usize).min(NORMAL_STEPS - 1);
            assert_eq!(index(g), cell(u) * NORMAL_STEPS + cell(v), "{g}");
            // And on the sphere, the cell's centre lies within [`MAX_ERROR_WIDTHS`] cell
            // widths of the direction.
            let i = index(g);
            let c = centre(i / NORMAL_STEPS, i % NORMAL_STEPS);
            let width = 2.0 / NORMAL_STEPS as f32;
            assert!(
                c.dot(g.normalize()) > libm::cosf(MAX_ERROR_WIDTHS * width),
                "{g}: {c}"
            );
            read += 1;
        }
        assert!(read > 50_000, "{read}");
    }

    #[test]
    fn gradients_without_a_direction_read_the_fallback_normal() {
        let view_dir = Vec3::new(0.0, 0.0, -1.0);
        let lights = [Light::directional(Vec3::new(0.4, -0.5, 1.0), Vec3::ONE, false).unwrap()];
        let t = table(&lights, view_dir);
        let want = exact(&lights, -view_dir, view_dir);
        let base = Vec3::new(0.9, 0.5, 0.25);
        for g in [
            Vec3::ZERO,
            Vec3::splat(1e-7),
            Vec3::new(f32::NAN, 1.0, 0.0),
            Vec3::new(0.0, f32::INFINITY, 0.0),
            Vec3::splat(f32::MAX),
        ] {
            let (c, fallback) = t.color(base, g);
            assert!(fallback, "{g}");
            assert!((c - base * want).abs().max_element() < 1e-6, "{g}: {c}");
        }
        // A point light changes direction from point to point: no table.
        let point = Light::point(Vec3::ONE, Vec3::ONE, false).unwrap();
        assert!(ShadingTable::new(&Shading::default(), &[point], view_dir).is_none());
    }

    #[test]
    fn four_gradients_in_lanes_read_the_entries_each_reads_alone() {
        let mut next = crate::testing::xorshift(0x1a4e_5eed);
        // Any bits: every sign, exponent, NaN and infinity, as well as the usual gradients.
        let mut any = || f32::from_bits(next());
        let special = [
            0.0,
            -0.0,
            1e-7,
            -1e-7,
            1.0,
            -1.0,
            0.5,
            f32::MIN_POSITIVE,
            f32::MAX,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        let mut pick = crate::testing::xorshift(0x0c7a_4ed1);
        let mut checked = 0;
        for n in 0..40_000 {
            let mut g = [[0.0f32; 3]; 4];
            for lane in g.iter_mut() {
                for c in lane.iter_mut() {
                    *c = match n % 3 {
                        // Gradients as the node field gives them.
                        0 => (pick() >> 8) as f32 / (1 << 24) as f32 * 80.0 - 40.0,
                        1 => special[pick() as usize % special.len()],
                        _ => any(),
                    };
                }
            }
            let lane = |c: usize| Vec4::from_array(core::array::from_fn(|l| g[l][c]));
            let got = indices(lane(0), lane(1), lane(2));
            for (l, &entry) in got.iter().enumerate() {
                let alone = Vec3::from_array(g[l]);
                assert_eq!(entry, index(alone), "{alone}");
                checked += usize::from(entry < DIRECTIONS);
            }
        }
        // Most lanes read a direction, not only the fallback.
        assert!(checked > 40_000, "{checked}");
    }
}

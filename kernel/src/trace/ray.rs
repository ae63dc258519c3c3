//! Rays and their robust clipping against an axis-aligned box.
//!
//! A [`Ray`] lives in index space but is parameterised by world distance: `dir` is the world
//! unit direction scaled by `1/spacing`. Clipping handles axis-parallel rays (a zero direction
//! component never divides), rays lying on a face or an edge (the box is closed), grazing rays
//! (an interval of zero length is a hit), and non-finite input (no hit, never NaN).
//!
//! Invariant: a clipped span is finite and ordered (`t_near ≤ t_far`) or there is none.

use glam::{Vec3, Vec4};

/// A ray: `origin + t·dir` in index space, `t` in world units along `dir_world`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Start point, index space.
    pub origin: Vec3,
    /// Direction in index space: the world unit direction times `1/spacing`.
    pub dir: Vec3,
    /// Unit direction in world space (for shading).
    pub dir_world: Vec3,
}

impl Ray {
    /// The ray from a world-space origin along a world-space unit direction.
    pub fn from_world(origin_world: Vec3, dir_world: Vec3, inv_spacing: Vec3) -> Ray {
        Ray {
            origin: origin_world * inv_spacing,
            dir: dir_world * inv_spacing,
            dir_world,
        }
    }

    /// The index-space point at parameter `t`. Every node evaluates a sample's position with
    /// this one expression, so every node gets the same bits.
    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.dir * t
    }

    /// [`Ray::at`] in the first three lanes of a vector (`w` is zero): each lane the same
    /// multiply and add, so the same bits, ready for [`crate::volume::field::locate4`].
    #[inline]
    pub fn at4(&self, t: f32) -> Vec4 {
        self.origin.extend(0.0) + self.dir.extend(0.0) * Vec4::splat(t)
    }
}

/// `1 + 2γ₃` with `γₙ = nε/(1 − nε)`, ε half of `f32::EPSILON`: the relative widening that
/// covers the rounding of computing a slab bound.
const FAR_WIDENING: f32 =
    1.0 + 2.0 * (3.0 * (f32::EPSILON * 0.5)) / (1.0 - 3.0 * (f32::EPSILON * 0.5));

/// Which part of the box a ray enters through.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Entry {
    /// Through the face perpendicular to `axis`, on its low (`high == false`) or high side.
    Face {
        /// 0 = X, 1 = Y, 2 = Z.
        axis: u8,
        /// The high face of that axis.
        high: bool,
    },
    /// The ray starts inside the box (at `t_min`, e.g. the eye is inside the volume).
    Inside,
}

impl Entry {
    /// The outward normal of the entry face in world space, or `None` for [`Entry::Inside`].
    pub fn outward_normal(self) -> Option<Vec3> {
        match self {
            Entry::Face { axis, high } => {
                let mut n = Vec3::ZERO;
                n[usize::from(axis % 3)] = if high { 1.0 } else { -1.0 };
                Some(n)
            }
            Entry::Inside => None,
        }
    }
}

/// The part of a ray inside a box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Span {
    /// Where the ray enters, `t_near ≥ t_min`.
    pub t_near: f32,
    /// Where it leaves, `t_far ≥ t_near`.
    pub t_far: f32,
    /// What it enters through.
    pub entry: Entry,
}

/// Clip `ray` against the closed box `[lo, hi]` restricted to `t ∈ [t_min, t_max]`.
///
/// The three axes in the lanes of one vector (each lane the operations of the per-axis
/// definition, so the same bits; the tests keep that definition): every pixel clips its ray,
/// and one axis at a time took half the set-up of a frame's primary rays.
pub fn clip(ray: &Ray, lo: Vec3, hi: Vec3, t_min: f32, t_max: f32) -> Option<Span> {
    // `w` is a zero direction inside the closed slab [0, 0]: it never clips.
    let (o, d) = (ray.origin.extend(0.0), ray.dir.extend(0.0));
    // Every coordinate finite, in lanes: `|x| < ∞` fails for the infinities and NaN.
    if !(o.abs().cmplt(Vec4::INFINITY) & d.abs().cmplt(Vec4::INFINITY)).all() {
        return None;
    }
    let (lo, hi) = (lo.extend(0.0), hi.extend(0.0));
    let parallel = d.cmpeq(Vec4::ZERO);
    // Parallel to a pair of faces: inside the closed slab or never.
    if (parallel & (o.cmplt(lo) | o.cmpgt(hi))).any() {
        return None;
    }
    // Parallel lanes divide by zero here; their quotients are never read.
    let (t_lo, t_hi) = ((lo - o) / d, (hi - o) / d);
    let ordered = t_lo.cmple(t_hi);
    // A parallel lane bounds neither end: its entry at −∞ and its exit at +∞, which no
    // comparison below takes.
    let t0 = Vec4::select(
        parallel,
        Vec4::NEG_INFINITY,
        Vec4::select(ordered, t_lo, t_hi),
    );
    // Widen the far bound by the rounding error of the three operations behind it (pbrt's
    // 1 + 2γ₃), so a ray through an edge or corner is not lost to one ulp.
    let t1 = Vec4::select(
        parallel,
        Vec4::INFINITY,
        Vec4::select(ordered, t_hi, t_lo) * FAR_WIDENING,
    );
    let (t0, t1, high) = (t0.to_array(), t1.to_array(), (!ordered).bitmask());
    let mut t_near = t_min;
    let mut t_far = t_max;
    // The axis whose face the ray enters through; 3: none, it starts inside.
    let mut through = 3;
    // In axis order, so that of equal entry parameters the first axis names the face; each
    // step a choice of values rather than a branch, as every pixel clips its ray.
    for axis in 0..3 {
        let nearer = t0[axis] > t_near;
        t_near = if nearer { t0[axis] } else { t_near };
        through = if nearer { axis } else { through };
        t_far = if t1[axis] < t_far { t1[axis] } else { t_far };
    }
    let entry = match through {
        3 => Entry::Inside,
        axis => Entry::Face {
            axis: axis as u8,
            high: high >> axis & 1 == 1,
        },
    };
    (t_near <= t_far && t_near.is_finite() && t_far.is_finite()).then_some(Span {
        t_near,
        t_far,
        entry,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_point_in_four_lanes_is_the_point_in_every_bit() {
        let mut next = crate::testing::xorshift(0x0a74_0004);
        let mut float = || {
            let r = next();
            // Ordinary magnitudes mostly, any bit pattern sometimes.
            if r % 8 == 0 {
                f32::from_bits(next())
            } else {
                (r >> 8) as f32 / 65_536.0 - 128.0
            }
        };
        for _ in 0..20_000 {
            let r = Ray {
                origin: Vec3::new(float(), float(), float()),
                dir: Vec3::new(float(), float(), float()),
                dir_world: Vec3::X,
            };
            let t = float();
            let (three, four) = (r.at(t), r.at4(t));
            for a in 0..3 {
                assert_eq!(three[a].to_bits(), four[a].to_bits(), "{r:?} at {t}");
            }
        }
    }

    /// The definition [`clip`] keeps, one axis at a time.
    fn clip_by_axis(ray: &Ray, lo: Vec3, hi: Vec3, t_min: f32, t_max: f32) -> Option<Span> {
        let mut t_near = t_min;
        let mut t_far = t_max;
        let mut entry = Entry::Inside;
        for axis in 0..3 {
            let (o, d) = (ray.origin[axis], ray.dir[axis]);
            if !(o.is_finite() && d.is_finite()) {
                return None;
            }
            if d == 0.0 {
                if o < lo[axis] || o > hi[axis] {
                    return None;
                }
                continue;
            }
            let (t_lo, t_hi) = ((lo[axis] - o) / d, (hi[axis] - o) / d);
            let (t0, t1, high) = if t_lo <= t_hi {
                (t_lo, t_hi, false)
            } else {
                (t_hi, t_lo, true)
            };
            let t1 = t1 * FAR_WIDENING;
            if t0 > t_near {
                t_near = t0;
                entry = Entry::Face {
                    axis: axis as u8,
                    high,
                };
            }
            if t1 < t_far {
                t_far = t1;
            }
        }
        (t_near <= t_far && t_near.is_finite() && t_far.is_finite()).then_some(Span {
            t_near,
            t_far,
            entry,
        })
    }

    #[test]
    fn clipping_in_lanes_is_clipping_by_axis_in_every_bit() {
        let mut next = crate::testing::xorshift(0xc11f_0004);
        let mut float = || {
            let r = next();
            match r % 16 {
                // Axis-parallel, on a face, and every kind of f32 sometimes.
                0 => 0.0,
                1 => -0.0,
                2 => 4.0,
                3 => f32::from_bits(next()),
                4 => f32::INFINITY,
                _ => (r >> 8) as f32 / 65_536.0 * 8.0 - 96.0 / 4.0,
            }
        };
        let (mut hits, mut faces) = (0, [0u32; 6]);
        for _ in 0..200_000 {
            let r = Ray {
                origin: Vec3::new(float(), float(), float()),
                dir: Vec3::new(float(), float(), float()),
                dir_world: Vec3::X,
            };
            let lo = Vec3::new(float(), float(), float()).min(Vec3::ZERO);
            let hi = lo + Vec3::new(float(), float(), float()).abs();
            let (t_min, t_max) = (float().min(0.0), float().abs());
            let (lanes, axes) = (
                clip(&r, lo, hi, t_min, t_max),
                clip_by_axis(&r, lo, hi, t_min, t_max),
            );
            let bits =
                |s: Option<Span>| s.map(|s| (s.t_near.to_bits(), s.t_far.to_bits(), s.entry));
            assert_eq!(
                bits(lanes),
                bits(axes),
                "{r:?} [{lo}, {hi}] t in [{t_min}, {t_max}]"
            );
            if let Some(Span {
                entry: Entry::Face { axis, high },
                ..
            }) = axes
            {
                faces[usize::from(axis) * 2 + usize::from(high)] += 1;
            }
            hits += usize::from(axes.is_some());
        }
        // Hits through every face, and misses, were compared.
        assert!(
            hits > 10_000 && hits < 190_000 && faces.iter().all(|&n| n > 100),
            "{hits} {faces:?}"
        );
    }

    fn ray(o: [f32; 3], d: [f32; 3]) -> Ray {
        let d = Vec3::from_array(d).normalize();
        Ray::from_world(Vec3::from_array(o), d, Vec3::ONE)
    }

    const LO: Vec3 = Vec3::ZERO;
    const HI: Vec3 = Vec3::splat(4.0);

    #[test]
    fn axis_parallel_rays_clip_without_dividing_by_zero() {
        let s = clip(
            &ray([-1.0, 1.0, 1.0], [1.0, 0.0, 0.0]),
            LO,
            HI,
            0.0,
            f32::MAX,
        )
        .unwrap();
        assert_eq!(s.t_near, 1.0);
        assert!((s.t_far - 5.0).abs() < 1e-5);
        assert_eq!(
            s.entry,
            Entry::Face {
                axis: 0,
                high: false
            }
        );
        assert!(clip(
            &ray([-1.0, 5.0, 1.0], [1.0, 0.0, 0.0]),
            LO,
            HI,
            0.0,
            f32::MAX
        )
        .is_none());
    }

    #[test]
    fn rays_on_faces_and_edges_hit_the_closed_box() {
        let s = clip(
            &ray([-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]),
            LO,
            HI,
            0.0,
            f32::MAX,
        )
        .unwrap();
        assert_eq!(s.t_near, 1.0);
        let s = clip(
            &ray([-1.0, 4.0, 4.0], [1.0, 0.0, 0.0]),
            LO,
            HI,
            0.0,
            f32::MAX,
        )
        .unwrap();
        assert_eq!(s.t_near, 1.0);
    }

    #[test]
    fn grazing_a_corner_is_a_zero_length_hit() {
        // The line x − y = 4 touches the box only along its edge at (4, 0, z).
        let s = clip(
            &ray([6.0, 2.0, 2.0], [-1.0, -1.0, 0.0]),
            LO,
            HI,
            0.0,
            f32::MAX,
        )
        .unwrap();
        assert!((s.t_far - s.t_near).abs() < 1e-5, "{s:?}");
        assert!((s.t_near - 8.0f32.sqrt()).abs() < 1e-5);
        // A hair to the side it misses.
        assert!(clip(
            &ray([6.1, 2.0, 2.0], [-1.0, -1.0, 0.0]),
            LO,
            HI,
            0.0,
            f32::MAX
        )
        .is_none());
    }

    #[test]
    fn eye_inside_starts_at_t_min_and_high_faces_are_reported() {
        let s = clip(
            &ray([2.0, 2.0, 2.0], [0.0, 0.0, -1.0]),
            LO,
            HI,
            0.0,
            f32::MAX,
        )
        .unwrap();
        assert_eq!((s.t_near, s.entry), (0.0, Entry::Inside));
        assert!((s.t_far - 2.0).abs() < 1e-5);
        let s = clip(
            &ray([2.0, 2.0, 9.0], [0.0, 0.0, -1.0]),
            LO,
            HI,
            0.0,
            f32::MAX,
        )
        .unwrap();
        assert_eq!(
            s.entry,
            Entry::Face {
                axis: 2,
                high: true
            }
        );
        assert_eq!(s.entry.outward_normal(), Some(Vec3::Z));
    }

    #[test]
    fn non_finite_rays_miss() {
        let r = Ray {
            origin: Vec3::NAN,
            dir: Vec3::X,
            dir_world: Vec3::X,
        };
        assert!(clip(&r, LO, HI, 0.0, f32::MAX).is_none());
        let r = Ray {
            origin: Vec3::ONE,
            dir: Vec3::new(f32::INFINITY, 0.0, 0.0),
            dir_world: Vec3::X,
        };
        assert!(clip(&r, LO, HI, 0.0, f32::MAX).is_none());
    }

    #[test]
    fn a_point_box_is_hit_only_through_its_point() {
        let s = clip(
            &ray([-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]),
            Vec3::ZERO,
            Vec3::ZERO,
            0.0,
            f32::MAX,
        );
        let s = s.unwrap();
        assert_eq!(s.t_near, 1.0);
        assert!(s.t_far - 1.0 < 1e-6);
    }
}

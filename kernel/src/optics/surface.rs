//! Iso-surfaces and surface searching: where a ray crosses an iso value between two
//! consecutive lattice samples, and how that crossing is refined.
//!
//! Conventions, fixed here for every node:
//! - the *inside* of a surface is `{ f ≥ iso }`; a crossing between samples `a` and `b` is a
//!   change of inside-ness. A sample exactly at the iso value is inside, so its crossing is
//!   found on the segment that arrives at it, refined to that very sample (`f = 1`); a ray that
//!   touches the value and turns back crosses twice at the same place (in, then out);
//! - the crossing is refined by regula falsi with the Illinois modification on the true field
//!   along the segment, starting from the linear estimate; every iterate stays inside the
//!   bracket, so the result is in `[0, 1]` even for the voxel model's step-shaped field;
//! - features thinner than one step can be missed: a smaller Δt costs time and buys accuracy.

use glam::Vec3;

/// Most iso-surfaces one view searches for.
pub const MAX_SURFACES: usize = 8;

/// An iso-surface and its appearance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IsoSurface {
    /// The iso value.
    pub iso: f32,
    /// Colour, each channel in `[0, 1]`.
    pub color: Vec3,
    /// Transparency coefficient in `[0, 1]`: 0 is opaque.
    pub transparency: f32,
}

impl IsoSurface {
    /// `1 - transparency`.
    #[inline]
    pub fn opacity(&self) -> f32 {
        1.0 - self.transparency
    }
}

/// Is value `v` inside the surface of iso value `iso`?
#[inline]
pub fn inside(v: f32, iso: f32) -> bool {
    v >= iso
}

/// Does the segment from value `a` to value `b` cross `iso`?
#[inline]
pub fn crosses(a: f32, b: f32, iso: f32) -> bool {
    inside(a, iso) != inside(b, iso)
}

/// Where along a crossing segment (fraction in `[0, 1]`) the field equals `iso`. `a` and `b`
/// are the field at the ends (they must cross `iso`), `eval` evaluates the field at a fraction,
/// `steps` is the number of field evaluations to spend.
pub fn refine(iso: f32, a: f32, b: f32, steps: u8, mut eval: impl FnMut(f32) -> f32) -> f32 {
    let (mut lo, mut hi) = (0.0f32, 1.0f32);
    let (mut f_lo, mut f_hi) = (a - iso, b - iso);
    let hi_inside = f_hi >= 0.0;
    // Which end the previous step moved (for Illinois' halving), 0 = none.
    let mut last_moved = 0i8;
    let mut x = secant(lo, hi, f_lo, f_hi);
    for _ in 0..steps {
        let fx = eval(x) - iso;
        if (fx >= 0.0) == hi_inside {
            hi = x;
            f_hi = fx;
            if last_moved == 1 {
                f_lo *= 0.5;
            }
            last_moved = 1;
        } else {
            lo = x;
            f_lo = fx;
            if last_moved == -1 {
                f_hi *= 0.5;
            }
            last_moved = -1;
        }
        x = secant(lo, hi, f_lo, f_hi);
    }
    x
}

/// The secant point of a bracket, kept inside it; the midpoint if it is not finite.
#[inline]
fn secant(lo: f32, hi: f32, f_lo: f32, f_hi: f32) -> f32 {
    let x = lo + (hi - lo) * (f_lo / (f_lo - f_hi));
    if x.is_finite() {
        x.clamp(lo, hi)
    } else {
        0.5 * (lo + hi)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_sample_at_the_iso_value_is_inside() {
        assert!(crosses(0.0, 5.0, 5.0));
        assert!(!crosses(5.0, 6.0, 5.0));
        assert!(crosses(5.0, 4.0, 5.0));
        assert_eq!(refine(5.0, 0.0, 5.0, 3, |f| 5.0 * f), 1.0);
    }

    #[test]
    fn refinement_converges_on_a_curved_field() {
        // f(s) = s^3 on [0, 1] crossing 0.125 at s = 0.5.
        let linear = refine(0.125, 0.0, 1.0, 0, |s| s * s * s);
        let refined = refine(0.125, 0.0, 1.0, 6, |s| s * s * s);
        assert!((linear - 0.125).abs() < 1e-6);
        assert!((refined - 0.5).abs() < 1e-3, "{refined}");
    }

    #[test]
    fn refinement_of_a_step_stays_in_the_bracket() {
        let step = |s: f32| if s < 0.3 { 0.0 } else { 10.0 };
        let f = refine(5.0, 0.0, 10.0, 8, step);
        assert!((0.0..=1.0).contains(&f));
        assert!((f - 0.3).abs() < 0.1, "{f}");
        let f = refine(5.0, 10.0, 0.0, 8, |s| step(1.0 - s));
        assert!((f - 0.7).abs() < 0.1, "{f}");
    }
}

//! The one formula that combines a ray tree into a colour.
//!
//! Floating-point addition is not associative, so a distributed evaluation is bit-identical to
//! an in-process one only if both evaluate the same expression in the same order. Both use
//! exactly these two functions:
//! - a surface point's colour is its ambient term plus each light's direct term times that
//!   light's visibility (shadow-ray transmittance, 1 for lights without shadows), lights in
//!   scene order;
//! - what a ray sees at a surface of opacity `a` is `c·a + behind·(1 − a)`, applied from the
//!   deepest hit outward, `behind` of the deepest being the background.
//!
//! Invariant: the same parts give the same bits, whatever node traced them and in whatever
//! order they arrived.

use glam::Vec3;

/// Colour of a lit surface point: `ambient + Σ_l visibility_l · direct_l`, in light order.
#[inline]
pub fn surface_color(ambient: Vec3, direct: &[Vec3], visibility: &[f32]) -> Vec3 {
    let mut c = ambient;
    for (d, v) in direct.iter().zip(visibility) {
        c += *d * *v;
    }
    c
}

/// What a ray sees at a surface of opacity `alpha` and colour `color` with `behind` seen
/// through it.
#[inline]
pub fn through(alpha: f32, color: Vec3, behind: Vec3) -> Vec3 {
    color * alpha + behind * (1.0 - alpha)
}

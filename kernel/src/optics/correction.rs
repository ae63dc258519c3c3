//! The exact tier's opacity correction for four samples at once: [`corrected_opacity`]'s
//! `1 − exp(length · ln(1 − α))` in four lanes, `libm`'s `log1pf` and then its `expf` written
//! out lane by lane, the same operations in the same order on each lane's path. One sample at
//! a time the two calls were a fifth of the exact tier's composited frame (each a chain of
//! range tests, a division or two and a polynomial); in four lanes the tests become selects
//! and the chains share their instructions. (`wide`'s own `exp` and `ln` are other
//! approximations, so other bits.)
//!
//! Invariant: each lane is [`corrected_opacity`]'s result for its inputs in every bit, for
//! any inputs (NaN, infinite, negative, subnormal): the exact tier is defined by those bits.
//! The lanes follow `libm` 0.2.16's `log1pf` and `expf` (FreeBSD's `s_log1pf.c` and
//! `e_expf.c`) on the only domain the correction asks of them, `log1pf` of `−α` for `α` in
//! `(0, 1)` and `expf` of a product that is not positive; other inputs take the scalar
//! function's early answers. `Cargo.lock` holds `libm` at that version, and the tests compare
//! the lanes with it (every opacity in `(0, 1]` for several lengths, and inputs of any bits),
//! so an update that changes its functions fails them.
//!
//! [`corrected_opacity`]: crate::optics::transfer::corrected_opacity

use wide::{f32x4, i32x4, CmpGe, CmpGt, CmpLt};

/// Each lane's `alpha` over its `length_in_edges`, corrected as
/// [`crate::optics::transfer::corrected_opacity`] corrects it, in every bit.
#[inline]
pub fn corrected_opacities(alpha: [f32; 4], length_in_edges: [f32; 4]) -> [f32; 4] {
    let (alpha, length) = (f32x4::from(alpha), f32x4::from(length_in_edges));
    let zero = f32x4::splat(0.0);
    let one = f32x4::splat(1.0);
    let corrected = one - exp_not_positive(length * log1p_of_negative(zero - alpha));
    // The early answers, as `corrected_opacity` gives them: nothing where either input is not
    // above zero (NaN included), all where the opacity is.
    let shows = alpha.cmp_gt(zero) & length.cmp_gt(zero);
    let whole = alpha.cmp_ge(one).blend(one, corrected);
    shows.blend(whole, zero).to_array()
}

/// `libm::log1pf(x)` for each lane `x` in `(−1, 0)`.
#[inline(always)]
fn log1p_of_negative(x: f32x4) -> f32x4 {
    // `libm`'s constants, by their bits.
    const LN2_HI: f32 = f32::from_bits(0x3f31_7180);
    const LN2_LO: f32 = f32::from_bits(0x3717_f7d1);
    const LG1: f32 = f32::from_bits(0x3f2a_aaaa);
    const LG2: f32 = f32::from_bits(0x3ecc_ce13);
    const LG3: f32 = f32::from_bits(0x3e91_e9ee);
    const LG4: f32 = f32::from_bits(0x3e78_9e26);
    let one = f32x4::splat(1.0);
    let ix = bits(x);
    // Below 2⁻²⁴ in magnitude `log1pf` is `x` itself.
    let tiny = (ix & int(0x7fff_ffff)).cmp_lt(int(0x3380_0000));
    // Below −(1 − √2/2) it reduces `1 + x` by its exponent `k` (at most 0 here), with the
    // rounding of `1 + x` carried in `c`; above, `k = 0`, `c = 0` and `f = x`. The bits of a
    // negative lane order as a signed integer's.
    let reduced = ix.cmp_gt(int(0xbe95_f619));
    let u = one + x;
    let iu = bits(u) + int(0x3f80_0000 - 0x3f35_04f3);
    let k = reduced.blend((iu >> 23) - int(0x7f), i32x4::splat(0));
    let c = floats(reduced).blend((x - (u - one)) / u, f32x4::splat(0.0));
    let reduced_f = floats((iu & int(0x007f_ffff)) + int(0x3f35_04f3)) - one;
    let f = floats(reduced).blend(reduced_f, x);
    let s = f / (f32x4::splat(2.0) + f);
    let z = s * s;
    let w = z * z;
    let t1 = w * (f32x4::splat(LG2) + w * f32x4::splat(LG4));
    let t2 = z * (f32x4::splat(LG1) + w * f32x4::splat(LG3));
    let r = t2 + t1;
    let hfsq = f32x4::splat(0.5) * f * f;
    let dk = k.round_float();
    let log =
        s * (hfsq + r) + (dk * f32x4::splat(LN2_LO) + c) - hfsq + f + dk * f32x4::splat(LN2_HI);
    floats(tiny).blend(x, log)
}

/// `libm::expf(x)` for each lane `x` at or below zero (−∞ included), but for results below
/// 2⁻¹²⁶, given as 0: the caller subtracts them from 1, which any result below 2⁻²⁵ leaves 1.
#[inline(always)]
fn exp_not_positive(x: f32x4) -> f32x4 {
    // `libm`'s constants, by their bits.
    const LN2_HI: f32 = f32::from_bits(0x3f31_7200);
    const LN2_LO: f32 = f32::from_bits(0x35bf_be8e);
    const INV_LN2: f32 = f32::from_bits(0x3fb8_aa3b);
    const P1: f32 = f32::from_bits(0x3e2a_aa8f);
    const P2: f32 = f32::from_bits(0xbb35_5215);
    let one = f32x4::splat(1.0);
    let hx = bits(x) & int(0x7fff_ffff);
    // Above ½·ln 2 in magnitude the argument is reduced by `k·ln 2`: `k` rounded from
    // `x / ln 2` above 1½·ln 2, else −1; below, `k = 0` and nothing is subtracted.
    let reduced = hx.cmp_gt(int(0x3eb1_7218));
    let far = hx.cmp_gt(int(0x3f85_1592));
    let rounded = (f32x4::splat(INV_LN2) * x - f32x4::splat(0.5)).trunc_int();
    let k = far.blend(rounded, reduced.blend(i32x4::splat(-1), i32x4::splat(0)));
    let kf = k.round_float();
    let hi_reduced = x - kf * f32x4::splat(LN2_HI);
    let lo_reduced = kf * f32x4::splat(LN2_LO);
    let reduced = floats(reduced);
    let hi = reduced.blend(hi_reduced, x);
    let lo = reduced.blend(lo_reduced, f32x4::splat(0.0));
    let r = reduced.blend(hi_reduced - lo_reduced, x);
    let rr = r * r;
    let c = r - rr * (f32x4::splat(P1) + rr * f32x4::splat(P2));
    let y = one + (r * c / (f32x4::splat(2.0) - c) - lo + hi);
    // `scalbnf(y, k)`: one multiplication by 2ᵏ while that is a normal number.
    let scaled = y * floats((k.max(i32x4::splat(-126)) + int(0x7f)) << 23);
    // Below 2⁻¹⁴ in magnitude `expf` is `1 + x`.
    let e = floats(hx.cmp_gt(int(0x3900_0000))).blend(scaled, one + x);
    // From about −103.97 on `expf` is 0 (and from −87.3 a subnormal, taken as 0 here).
    let gone = hx.cmp_gt(int(0x42cf_f1b4)) | k.cmp_lt(i32x4::splat(-126));
    floats(gone).blend(f32x4::splat(0.0), e)
}

/// Each lane's bits as an integer.
#[inline(always)]
fn bits(x: f32x4) -> i32x4 {
    bytemuck::cast(x)
}

/// Each lane's integer as the bits of a float.
#[inline(always)]
fn floats(x: i32x4) -> f32x4 {
    bytemuck::cast(x)
}

/// The bit pattern `v` in every lane.
#[inline(always)]
fn int(v: u32) -> i32x4 {
    i32x4::splat(v as i32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optics::transfer::corrected_opacity;

    /// Lengths a correction is asked for: the lattice's usual steps, a last segment's
    /// fractions, and extremes on both sides.
    const LENGTHS: [f32; 9] = [0.5, 1.0, 1.375, 0.2, 3.7, 1e-3, 100.0, 1e-30, 1e30];

    /// Every `stride`-th opacity bit pattern from 0 to 1, four lanes at a time, each against
    /// the scalar function: the count of lanes that differ.
    fn differing(length: f32, stride: u32, batch: impl Fn([f32; 4], [f32; 4]) -> [f32; 4]) -> u64 {
        let mut differ = 0;
        let end = 1.0f32.to_bits();
        let mut bits = 0u32;
        while bits <= end {
            let lanes = [0, 1, 2, 3].map(|i| f32::from_bits((bits + i * stride).min(end)));
            let got = batch(lanes, [length; 4]);
            for (a, g) in lanes.iter().zip(got) {
                differ += u64::from(corrected_opacity(*a, length).to_bits() != g.to_bits());
            }
            bits += 4 * stride;
        }
        differ
    }

    #[test]
    fn the_lanes_give_the_scalar_correction_in_every_bit_over_opacities() {
        // A prime stride visits every exponent and most of each one's mantissas; the
        // exhaustive sweep (stride 1) is `the_lanes_give_every_opacity_s_correction`.
        for length in LENGTHS {
            assert_eq!(differing(length, 4099, corrected_opacities), 0, "{length}");
        }
    }

    #[test]
    #[ignore = "a billion opacities for each length: about a minute in release"]
    fn the_lanes_give_every_opacity_s_correction() {
        for length in LENGTHS {
            assert_eq!(differing(length, 1, corrected_opacities), 0, "{length}");
        }
    }

    #[test]
    fn the_lanes_give_the_scalar_correction_for_inputs_of_any_bits() {
        let mut next = crate::testing::xorshift(0xc0_77ec);
        let special = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::MIN_POSITIVE,
            f32::from_bits(1),
            1.0 - f32::EPSILON / 2.0,
        ];
        for n in 0..400_000u32 {
            let mut lane = |i: u32| -> f32 {
                let r = next();
                match (n + i) % 4 {
                    0 => f32::from_bits(r),
                    1 => special[(r % special.len() as u32) as usize],
                    // Opacities and lengths of the usual range.
                    _ => (r >> 8) as f32 / (1u32 << 24) as f32 * 4.0,
                }
            };
            let alpha = [0, 1, 2, 3].map(&mut lane);
            let length = [3, 2, 1, 0].map(&mut lane);
            let got = corrected_opacities(alpha, length);
            for i in 0..4 {
                let want = corrected_opacity(alpha[i], length[i]);
                assert_eq!(
                    got[i].to_bits(),
                    want.to_bits(),
                    "alpha {:#x}, length {:#x}",
                    alpha[i].to_bits(),
                    length[i].to_bits()
                );
            }
        }
    }

    #[test]
    fn negative_control_the_same_function_by_other_operations_is_seen() {
        // `ln(1 − α)` as `logf(1 − α)` rather than `log1pf(−α)`: equal in exact arithmetic,
        // and the sweep tells them apart, so it checks operations, not only the function.
        let other = |alpha: [f32; 4], length: [f32; 4]| {
            [0, 1, 2, 3].map(|i| {
                let (a, l) = (alpha[i], length[i]);
                if !(a > 0.0) || !(l > 0.0) {
                    return 0.0;
                }
                if a >= 1.0 {
                    return 1.0;
                }
                1.0 - libm::expf(l * libm::logf(1.0 - a))
            })
        };
        assert!(differing(0.5, 4099, other) > 0);
        assert_eq!(differing(0.5, 4099, corrected_opacities), 0);
    }
}

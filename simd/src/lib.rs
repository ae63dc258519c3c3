//! Whole numbers from the lanes of a vector of grid coordinates: truncated to whole floats,
//! and taken as integers, which voxcube's sample loop does on every sample. On x86-64 with
//! SSE4.1 (the x86-64-v2 level voxcube builds for) that is one conversion to integers, one
//! back, and a lane move per integer, through `core::arch`; elsewhere the portable forms:
//! glam's `trunc` (six instructions with SSE4.1, for lanes of any sign and size) and the
//! integers by adding 2^23 (seven).
//!
//! Beside them, [`prefetch`]: a hint that an item is read soon, which a sample loop over a
//! volume larger than the caches asks for a few samples ahead, at any place, in the items or
//! not, without the cost of a bounds check.
//!
//! This crate holds the sample loop's `unsafe` (the workspace's only other is the benchmarks'
//! profiler, `voxcube-sampler`), so that the kernel keeps `forbid(unsafe_code)`: an
//! intrinsic is an `unsafe` call unless its caller declares the CPU features it needs, and a
//! caller that declares them cannot be inlined into one that does not. Each block here calls
//! an intrinsic that needs only a feature this build enables, which the `cfg` above it
//! checks (the binary requires that feature of its CPU anyway), and takes no pointer, but
//! for the prefetch, which takes an address (computed by wrapping arithmetic and never read
//! through) and can neither fault nor change what the program reads.
//!
//! Invariant: on lanes in `[0, 2^23]` (every caller's: coordinates clamped into the grid,
//! or inside it) both forms give the same bits, the truncation and the integers being exact
//! there (tested against each other). Other lanes give some value, never a panic.
#![no_std]
#![deny(missing_docs)]

use glam::Vec4;

/// `v` truncated toward zero, lane by lane, and the first three lanes of that as integers:
/// exact for lanes in `[0, 2^23]`.
#[inline(always)]
pub fn trunc_lanes(v: Vec4) -> (Vec4, [u32; 3]) {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse4.1"))]
    {
        use core::arch::x86_64::{__m128, _mm_cvtepi32_ps, _mm_cvttps_epi32};
        // SAFETY: SSE2, all these need, is enabled (the cfg); no pointer is taken.
        let (whole, back) = unsafe {
            let whole = _mm_cvttps_epi32(__m128::from(v));
            (whole, _mm_cvtepi32_ps(whole))
        };
        (Vec4::from(back), sse41::first_three(whole))
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse4.1")))]
    {
        let t = portable::trunc(v);
        let [x, y, z, _] = portable::lanes(t);
        (t, [x, y, z])
    }
}

/// `v` truncated toward zero, lane by lane: exact for lanes in `[0, 2^23]`.
#[inline(always)]
pub fn trunc(v: Vec4) -> Vec4 {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse4.1"))]
    {
        use core::arch::x86_64::{__m128, _mm_cvtepi32_ps, _mm_cvttps_epi32};
        // SAFETY: SSE2, all these need, is enabled (the cfg); no pointer is taken.
        Vec4::from(unsafe { _mm_cvtepi32_ps(_mm_cvttps_epi32(__m128::from(v))) })
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse4.1")))]
    portable::trunc(v)
}

/// The lanes of `v` as integers: exact for whole numbers in `[0, 2^23]`.
#[inline(always)]
pub fn lanes(v: Vec4) -> [u32; 4] {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse4.1"))]
    {
        use core::arch::x86_64::{__m128, _mm_cvttps_epi32, _mm_extract_epi32};
        // SAFETY: SSE2 and SSE4.1, all these need, are enabled (the cfg); no pointer is
        // taken.
        let (whole, w) = unsafe {
            let whole = _mm_cvttps_epi32(__m128::from(v));
            (whole, _mm_extract_epi32::<3>(whole))
        };
        let [x, y, z] = sse41::first_three(whole);
        [x, y, z, w as u32]
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse4.1")))]
    portable::lanes(v)
}

/// `x` truncated toward zero, as an integer: exact for `x` in `[0, 2^31)` (a table index
/// clamped into its table as a float first), where `as` spends a comparison and a select on
/// each end of its saturation.
#[inline(always)]
pub fn trunc_u32(x: f32) -> u32 {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse4.1"))]
    {
        use core::arch::x86_64::{_mm_cvttss_si32, _mm_set_ss};
        // SAFETY: SSE and SSE2, all these need, are enabled (the cfg); no pointer is taken.
        unsafe { _mm_cvttss_si32(_mm_set_ss(x)) as u32 }
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse4.1")))]
    portable::trunc_u32(x)
}

/// A hint that the item `index` places past the start of `items` is read soon: on x86-64 a
/// `prefetcht0` of the cache line that holds it, so that a read some samples later finds it
/// in the caches rather than waiting on memory; nothing on other targets. `index` may lie
/// outside `items`: no bounds are checked, so that a loop may ask at every sample for a few
/// instructions. The address is computed with wrapping arithmetic and never read through;
/// the program's values are the same either way.
#[inline(always)]
pub fn prefetch<T>(items: &[T], index: usize) {
    #[cfg(all(target_arch = "x86_64", target_feature = "sse"))]
    {
        use core::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
        let at = items.as_ptr().wrapping_add(index);
        // SAFETY: SSE, all this needs, is enabled (the cfg). A prefetch changes no register,
        // flag or memory, raises no fault whatever its address (one outside every mapping is
        // dropped), and the program never reads through `at`.
        unsafe { _mm_prefetch::<_MM_HINT_T0>(at.cast::<i8>()) }
    }
    #[cfg(not(all(target_arch = "x86_64", target_feature = "sse")))]
    let _ = (items, index);
}

#[cfg(all(target_arch = "x86_64", target_feature = "sse4.1"))]
mod sse41 {
    use core::arch::x86_64::{__m128i, _mm_cvtsi128_si32, _mm_extract_epi32};

    /// The first three lanes, their bits as they are.
    #[inline(always)]
    pub(super) fn first_three(v: __m128i) -> [u32; 3] {
        // SAFETY: SSE2 and SSE4.1, all these need, are enabled (the cfg on this module); no
        // pointer is taken.
        let lanes = unsafe {
            [
                _mm_cvtsi128_si32(v),
                _mm_extract_epi32::<1>(v),
                _mm_extract_epi32::<2>(v),
            ]
        };
        lanes.map(|lane| lane as u32)
    }
}

/// The forms for every target, and the reference the tests hold the vector forms to.
#[cfg(any(test, not(all(target_arch = "x86_64", target_feature = "sse4.1"))))]
mod portable {
    use glam::Vec4;

    /// `2^23`: the least `f32` from which on every representable number is whole, so adding
    /// it to a number in `[0, 2^23]` leaves that number in the mantissa's low bits.
    const MAGIC: f32 = (1u32 << 23) as f32;

    #[inline(always)]
    pub(super) fn trunc(v: Vec4) -> Vec4 {
        v.trunc()
    }

    #[inline(always)]
    pub(super) fn trunc_u32(x: f32) -> u32 {
        x as u32
    }

    #[inline(always)]
    pub(super) fn lanes(v: Vec4) -> [u32; 4] {
        (v + Vec4::splat(MAGIC))
            .to_array()
            .map(|lane| lane.to_bits().wrapping_sub(MAGIC.to_bits()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Lanes across `[0, 2^23]`: whole numbers, their neighbours in the last bit, halves and
    /// fractions of every size, zero and the ends.
    fn lane(next: &mut impl FnMut() -> u32) -> f32 {
        const TOP: u32 = 1 << 23;
        let whole = (next() % (TOP + 1)) as f32;
        let v = match next() % 6 {
            0 => whole,
            1 => f32::from_bits(whole.to_bits().saturating_sub(1)),
            2 => f32::from_bits(whole.to_bits() + 1),
            3 => (next() % 4096) as f32 + 0.5,
            4 => (next() >> 8) as f32 / (1 << 24) as f32 * (next() % 600) as f32,
            _ => [0.0, 1.0, TOP as f32, (TOP - 1) as f32][(next() % 4) as usize],
        };
        v.clamp(0.0, TOP as f32)
    }

    #[test]
    fn the_vector_forms_are_the_portable_ones_in_every_bit() {
        let mut state = 0x3b0_1e5u32;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state
        };
        for _ in 0..400_000 {
            let v = Vec4::new(
                lane(&mut next),
                lane(&mut next),
                lane(&mut next),
                lane(&mut next),
            );
            let t = portable::trunc(v);
            assert_eq!(
                trunc(v).to_array().map(f32::to_bits),
                t.to_array().map(f32::to_bits)
            );
            let whole = portable::lanes(t);
            assert_eq!(lanes(t), whole, "{v}");
            let (cell, lo) = trunc_lanes(v);
            assert_eq!(
                cell.to_array().map(f32::to_bits),
                t.to_array().map(f32::to_bits)
            );
            assert_eq!(lo, [whole[0], whole[1], whole[2]], "{v}");
            // The integers are the truncation's.
            assert_eq!(lo, [t.x, t.y, t.z].map(|c| c as u32), "{v}");
            assert_eq!(trunc_u32(v.x), portable::trunc_u32(v.x), "{v}");
        }
        // And single values up to 2^31, past the lanes' range.
        for _ in 0..400_000 {
            let x = f32::from_bits(next() % 0x4f00_0000);
            assert_eq!(trunc_u32(x), portable::trunc_u32(x), "{x}");
        }
    }

    #[test]
    fn a_prefetch_anywhere_past_its_items_is_nothing() {
        // A form that indexed `items[index]` would panic here.
        let items = [1u16, 2, 3];
        for index in [0, 2, 3, 4096, usize::MAX] {
            prefetch(&items, index);
            prefetch::<u16>(&[], index);
        }
        assert_eq!(items, [1, 2, 3]);
    }

    #[test]
    #[cfg(all(target_arch = "x86_64", target_feature = "sse4.1"))]
    fn a_lane_past_the_range_is_where_the_forms_part() {
        // The negative control of the test above: the forms agree on the callers' range
        // only. Past 2^31 the conversion has no integer to give and returns its marker.
        let v = Vec4::new(3.0e9, 1.5, 2.5, 3.5);
        assert_eq!(portable::trunc(v).x, 3.0e9);
        assert_eq!(trunc(v).x, i32::MIN as f32);
        assert_ne!(trunc_u32(3.0e9), portable::trunc_u32(3.0e9));
    }

    #[test]
    fn a_hint_near_any_place_reads_and_changes_nothing() {
        let items: [u64; 64] = core::array::from_fn(|i| i as u64 * 0x9e37_79b9);
        // Inside, just past, far past and, wrapping, before the items: never a fault.
        for index in [
            0,
            63,
            64,
            4096,
            1 << 40,
            usize::MAX,
            usize::MAX - 7,
            usize::MAX / 2,
        ] {
            prefetch(&items, index);
        }
        assert!(items
            .iter()
            .enumerate()
            .all(|(i, &v)| v == i as u64 * 0x9e37_79b9));
    }
}

//! Pre-classified samples, the fast tier's approximation of compositing: a view's transfer
//! function and its opacity corrected for one full Δt segment, tabulated at [`ENTRIES`]
//! values spread evenly over the function's control points and read at the nearest entry,
//! as production ray casters keep their classification tables.
//!
//! Invariants: a table is built from the transfer function and Δt alone, by the same
//! arithmetic on every node, so its entries, and the pixels, are the same bits wherever it is
//! built; a sample's entry is a monotone function of its value, so the entries a value range
//! can reach are one run of indices, and [`Classified::empty`] is exactly "every sample in
//! the range reads an entry of zero opacity" (skipping stays a bound, never an
//! approximation of the tier's own image); an entry's opacity is zero exactly where its
//! corrected opacity is.

use crate::optics::transfer::{corrected_opacity, TransferFunction};
use glam::Vec3;

/// Entries of a table. 512 over a byte's 256 values is half a value unit apart.
pub const ENTRIES: usize = 512;

/// The nearest of `N` entries to value `v`, entry 0 at `lo` and `per_unit` entries per
/// value unit: clamped to the table, NaN reading entry 0. Every table over a transfer
/// function's values finds its entries so.
#[inline]
pub(crate) fn nearest<const N: usize>(v: f32, lo: f32, per_unit: f32) -> usize {
    let x = (v - lo) * per_unit + 0.5;
    // Clamped into [0, last] first (`x > 0` is false for NaN), then truncated by one
    // instruction where `as` would saturate again, on every sample of a composited frame;
    // the remainder tells the compiler the index is in the table.
    let x = if x > 0.0 { x.min((N - 1) as f32) } else { 0.0 };
    voxcube_simd::trunc_u32(x) as usize % N
}

/// One entry: the transfer function at the entry's value.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Entry {
    color: Vec3,
    /// Opacity per cell edge.
    opacity: f32,
    /// Opacity of one full Δt segment: `corrected_opacity(opacity, Δt)`.
    alpha: f32,
}

/// Of a table, what tells whether a range is empty ([`Classified::shown`]): where its index
/// starts and how it scales (their bits), and how many entries before each show.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Shown {
    lo: u32,
    per_unit: u32,
    shown: [u16; ENTRIES + 1],
}

/// A view's pre-classified transfer function.
#[derive(Clone, Debug, PartialEq)]
pub struct Classified {
    /// The value of entry 0, and entries per value unit.
    lo: f32,
    per_unit: f32,
    entries: [Entry; ENTRIES],
    /// `shown[i]`: entries before `i` with opacity above zero.
    shown: [u16; ENTRIES + 1],
}

impl Classified {
    /// The table of `tf` for segments `dt` cell edges long.
    pub fn new(tf: &TransferFunction, dt: f32) -> Classified {
        let (lo, hi) = tf.domain();
        let last = (ENTRIES - 1) as f32;
        let per_unit = if hi > lo { last / (hi - lo) } else { 0.0 };
        let mut entries = [Entry::default(); ENTRIES];
        let mut shown = [0u16; ENTRIES + 1];
        for (i, e) in entries.iter_mut().enumerate() {
            // From both ends' values, so the last entry is the last control point exactly.
            let f = i as f32 / last;
            let (color, opacity) = tf.eval(lo + (hi - lo) * f);
            *e = Entry {
                color,
                opacity,
                alpha: corrected_opacity(opacity, dt),
            };
            shown[i + 1] = shown[i] + u16::from(opacity > 0.0);
        }
        Classified {
            lo,
            per_unit,
            entries,
            shown,
        }
    }

    /// The entry value `v` reads: the nearest, clamped to the table (NaN reads entry 0).
    #[inline]
    fn index(&self, v: f32) -> usize {
        nearest::<ENTRIES>(v, self.lo, self.per_unit)
    }

    /// Colour and corrected opacity of a full segment at value `v`.
    #[inline]
    pub fn full(&self, v: f32) -> (Vec3, f32) {
        let e = &self.entries[self.index(v)];
        (e.color, e.alpha)
    }

    /// Colour and opacity per cell edge at value `v` (for a segment shorter than Δt, whose
    /// opacity the caller corrects for its own length).
    #[inline]
    pub fn per_edge(&self, v: f32) -> (Vec3, f32) {
        let e = &self.entries[self.index(v)];
        (e.color, e.opacity)
    }

    /// What [`Classified::empty`] reads of the table, apart from it: two tables with equal
    /// ones call every range alike.
    pub fn shown(&self) -> Shown {
        Shown {
            lo: self.lo.to_bits(),
            per_unit: self.per_unit.to_bits(),
            shown: self.shown,
        }
    }

    /// Whether every value in `[min, max]` reads an entry of zero opacity.
    #[inline]
    pub fn empty(&self, min: f32, max: f32) -> bool {
        if !(min <= max) {
            // A NaN bound proves nothing.
            return false;
        }
        let (a, b) = (self.index(min), self.index(max));
        self.shown[b + 1] == self.shown[a]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optics::transfer::ControlPoint;

    fn tf() -> TransferFunction {
        let p = |value, c, opacity| ControlPoint {
            value,
            color: Vec3::splat(c),
            opacity,
        };
        TransferFunction::new(&[p(20.0, 0.0, 0.0), p(100.0, 1.0, 0.5), p(200.0, 0.5, 0.0)])
            .expect("valid")
    }

    #[test]
    fn entries_are_the_function_at_their_values_and_the_ends_are_exact() {
        let t = Classified::new(&tf(), 0.5);
        let exact = tf();
        assert_eq!(t.per_edge(20.0), exact.eval(20.0));
        assert_eq!(t.per_edge(200.0), exact.eval(200.0));
        assert_eq!(
            t.per_edge(-1e9),
            exact.eval(20.0),
            "below clamps to the first"
        );
        assert_eq!(t.per_edge(f32::NAN), exact.eval(20.0), "NaN reads entry 0");
        let (_, a) = t.full(100.0);
        let (_, o) = exact.eval(100.0);
        assert!((a - corrected_opacity(o, 0.5)).abs() < 2e-3, "{a}");
    }

    #[test]
    fn the_index_is_the_saturating_nearest_entry_for_every_kind_of_value() {
        let t = Classified::new(&tf(), 0.5);
        // The definition: round half up, then saturate into the table, NaN to 0.
        let reference =
            |v: f32| (((v - t.lo) * t.per_unit + 0.5).max(0.0) as usize).min(ENTRIES - 1);
        let mut next = crate::testing::xorshift(0x00c1_a551);
        let specials = [
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            -0.0,
            0.0,
            f32::MAX,
            f32::MIN,
            f32::MIN_POSITIVE,
            20.0,
            200.0,
        ];
        // Values at and around every entry's rounding boundary, and arbitrary bit patterns.
        let boundaries = (0..ENTRIES).flat_map(|i| {
            let v = t.lo + (i as f32 + 0.5) / t.per_unit;
            [v.next_down(), v, v.next_up()]
        });
        let random = (0..100_000).map(|_| f32::from_bits(next()));
        for v in specials.into_iter().chain(boundaries).chain(random) {
            assert_eq!(t.index(v), reference(v), "{v:e}");
        }
    }

    #[test]
    fn the_nearest_entry_errs_by_at_most_half_a_step_of_the_function() {
        let (t, exact) = (Classified::new(&tf(), 1.0), tf());
        let step = 180.0 / (ENTRIES - 1) as f32;
        // The function's steepest opacity slope is 0.5 / 80 per value unit.
        let bound = 0.5 * step * 0.5 / 80.0 + 1e-6;
        for i in 0..=2000 {
            let v = 20.0 + 180.0 * i as f32 / 2000.0;
            let (o_table, o_exact) = (t.per_edge(v).1, exact.eval(v).1);
            assert!(
                (o_table - o_exact).abs() <= bound,
                "{v}: {o_table} {o_exact}"
            );
        }
    }

    #[test]
    fn a_range_is_empty_exactly_when_every_value_in_it_reads_zero_opacity() {
        let t = Classified::new(&tf(), 0.5);
        for (min, max) in [
            (0.0, 20.0),
            (0.0, 20.1),
            (150.0, 300.0),
            (199.9, 300.0),
            (300.0, 400.0),
        ] {
            let every_zero = (0..=1000)
                .map(|i| min + (max - min) * i as f32 / 1000.0)
                .all(|v| t.per_edge(v).1 == 0.0);
            assert_eq!(t.empty(min, max), every_zero, "[{min}, {max}]");
        }
        assert!(!t.empty(f32::NAN, 1.0));
        assert!(!t.empty(f32::NEG_INFINITY, f32::INFINITY));
    }

    #[test]
    fn a_table_for_another_step_holds_other_opacities() {
        let (half, fifth) = (Classified::new(&tf(), 0.5), Classified::new(&tf(), 0.2));
        assert_ne!(half.full(100.0).1, fifth.full(100.0).1);
        assert_eq!(half.per_edge(100.0), fifth.per_edge(100.0));
    }
}

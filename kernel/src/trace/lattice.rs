//! The global sample lattice of a ray: `t_k = t_entry + k·Δt` for integer `k`.
//!
//! Invariants: positions are never accumulated; `t_k` is one multiply and one add from the
//! same inputs on every node. `last` is capped at [`MAX_SAMPLES`] so that `k` converts to
//! `f32` exactly. Sample `k` stands for the segment `[t_k, min(t_{k+1}, t_exit)]`, so the
//! segments tile the span exactly and compositing integrates the whole ray, no more.

/// The most samples one ray takes: `k` must stay exactly representable in `f32` (2^24).
pub const MAX_SAMPLES: u32 = 1 << 24;

/// A ray's sample positions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lattice {
    /// `t` of sample 0 (the entry into the whole dataset's box, or the ray's start).
    pub t_entry: f32,
    /// `t` where the ray leaves the box (or reaches its end); `t_last ≤ t_exit` up to rounding.
    pub t_exit: f32,
    /// World distance between samples.
    pub dt: f32,
    /// Index of the last sample.
    pub last: u32,
}

impl Lattice {
    /// The lattice over `[t_entry, t_exit]` with step `dt > 0`. `None` for a non-finite or
    /// empty span or a non-positive step.
    pub fn new(t_entry: f32, t_exit: f32, dt: f32) -> Option<Lattice> {
        if !(t_entry.is_finite()
            && t_exit.is_finite()
            && dt.is_finite()
            && dt > 0.0
            && t_exit >= t_entry)
        {
            return None;
        }
        // Not negative (the span is not empty), so the saturating conversion's truncation is
        // the floor; capped so `k as f32` is exact. (`libm::floorf` before it is a call.)
        let steps = (t_exit - t_entry) / dt;
        let last = (steps.max(0.0) as u32).min(MAX_SAMPLES);
        Some(Lattice {
            t_entry,
            t_exit,
            dt,
            last,
        })
    }

    /// `t` of sample `k`.
    #[inline]
    pub fn t(&self, k: u32) -> f32 {
        self.t_entry + k as f32 * self.dt
    }

    /// Whether sample `k` stands for a whole Δt segment: another sample follows it inside
    /// the span. An integer rule on `k` and the lattice, the same on every node.
    #[inline]
    pub fn is_full(&self, k: u32) -> bool {
        k < self.last && !(self.t(k + 1) > self.t_exit)
    }

    /// The samples before this index are exactly those [`Lattice::is_full`] holds for: `t_k`
    /// never decreases with `k` (each of its two roundings is monotone), so the rule holds
    /// for a prefix, and the march asks this once a call instead of once a sample.
    pub fn full_below(&self) -> u32 {
        let mut k = self.last;
        // `t(last)` lies past the exit by rounding at most: a step or two back, seldom more.
        while k > 0 && self.t(k) > self.t_exit {
            k -= 1;
        }
        k
    }

    /// World length of the segment sample `k` stands for (zero past the exit).
    #[inline]
    pub fn segment(&self, k: u32) -> f32 {
        let end = if k >= self.last {
            self.t_exit
        } else {
            self.t(k + 1).min(self.t_exit)
        };
        (end - self.t(k)).max(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn segments_tile_the_span() {
        for (t0, t1, dt) in [
            (0.0f32, 10.0f32, 0.5f32),
            (1.25, 7.0, 0.2),
            (3.0, 3.0, 0.125),
            (0.1, 96.0, 0.125),
        ] {
            let l = Lattice::new(t0, t1, dt).unwrap();
            let total: f64 = (0..=l.last).map(|k| f64::from(l.segment(k))).sum();
            assert!(
                (total - f64::from(t1 - t0)).abs() < 1e-4,
                "{t0} {t1} {dt}: {total}"
            );
            assert!(l.t(l.last) <= t1 + 1e-4);
        }
    }

    #[test]
    fn the_full_samples_are_those_below_full_below() {
        let mut next = crate::testing::xorshift(0x1a77_1ce5);
        let unit = |n: u32| (n >> 8) as f32 / (1 << 24) as f32;
        for case in 0..20_000 {
            // Spans from a few steps to many, far from the origin too, where `t_k` rounds
            // coarsely and several samples can share one `t`.
            let t_entry = (unit(next()) - 0.5) * if case % 3 == 0 { 4e6 } else { 400.0 };
            let dt = 0.01 + unit(next()) * 2.0;
            let t_exit = t_entry + unit(next()) * dt * 60.0;
            let Some(l) = Lattice::new(t_entry, t_exit, dt) else {
                continue;
            };
            let below = l.full_below();
            for k in 0..=l.last + 1 {
                assert_eq!(l.is_full(k), k < below, "{l:?} k {k}");
            }
        }
    }

    #[test]
    fn degenerate_lattices_are_refused() {
        assert!(Lattice::new(0.0, 1.0, 0.0).is_none());
        assert!(Lattice::new(0.0, f32::NAN, 0.5).is_none());
        assert!(Lattice::new(2.0, 1.0, 0.5).is_none());
        assert_eq!(
            Lattice::new(0.0, 1e30, 1e-3).map(|l| l.last),
            Some(MAX_SAMPLES)
        );
    }
}

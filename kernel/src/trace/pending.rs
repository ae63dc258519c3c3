//! The exact tier's samples in a run through the slab's interior that wait for their opacity's
//! correction, which is then made four at a time ([`corrected_opacities`]): one sample at a
//! time, `libm`'s `log1pf` and `expf` of each sample's opacity were a fifth of the tier's
//! composited frame. A sample's correction needs nothing of the samples before it, but its
//! compositing needs their transmittance, so the run reads on while up to three samples that
//! may show wait, and composites them in order when a fourth comes or the run stops.
//!
//! Invariants: each sample is composited in sample order with the bits the one-at-a-time
//! loop gives it (the lanes are [`crate::optics::transfer::corrected_opacity`]'s bits). Where a
//! sample's compositing ends the ray, the reads the run made after it are taken back (between
//! two reads a run counts nothing but `samples` and the read's `interpolations`) and the run
//! stands at the sample after it, as the one-at-a-time loop would: the same image and the
//! same counts. Nothing waits when the run returns.

use crate::counters::Counters;
use crate::optics::correction::corrected_opacities;
use crate::trace::lighting::Unshadowed;
use crate::volume::field::Site;
use crate::volume::sample::Sample;
use crate::volume::slab::Slab;
use glam::{Vec3, Vec4};

/// Samples corrected at once: the lanes of one vector.
const LANES: usize = 4;

/// A sample read whose opacity is above zero before its correction: what compositing it
/// takes, and the run's counts just after its read.
#[derive(Clone, Copy)]
pub(crate) struct Waiting {
    /// Its lattice index.
    pub(crate) k: u32,
    /// Its value.
    pub(crate) v: f32,
    /// Its colour by the transfer function.
    pub(crate) base: Vec3,
    /// Its gradient, where the read gives one (then every read of the run does).
    pub(crate) gradient: Vec3,
    /// Its index-space point, its cell's low corner and its fractions there.
    pub(crate) q: Vec4,
    pub(crate) lo: [u32; 3],
    pub(crate) frac: Vec3,
    /// The run's `samples` and `interpolations` once it was read.
    pub(crate) counted: (u64, u64),
}

/// Where compositing a waiting sample ended the ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Ended {
    /// That sample's lattice index.
    pub(crate) k: u32,
    /// Its value.
    pub(crate) v: f32,
}

/// Up to [`LANES`] samples waiting, in sample order: the first `len` of each array.
pub(crate) struct Pending {
    len: usize,
    /// Their opacities for one cell edge, and their segments' lengths in cell edges.
    opacity: [f32; LANES],
    length: [f32; LANES],
    /// The rest of each [`Waiting`], a field to an array: where the reads give gradients,
    /// the sites are not kept.
    k: [u32; LANES],
    v: [f32; LANES],
    base: [Vec3; LANES],
    gradient: [Vec3; LANES],
    q: [Vec4; LANES],
    lo: [[u32; 3]; LANES],
    frac: [Vec3; LANES],
    counted: [(u64, u64); LANES],
}

/// What compositing a waiting sample takes besides the sample: the light, whether the run's
/// reads give gradients, the slab its shading may read, the ray's colour and transmittance,
/// and the view's cutoff.
pub(crate) struct Compositing<'c, 'l, 's, T: Sample> {
    pub(crate) light: &'c Unshadowed<'l>,
    pub(crate) gradients: bool,
    pub(crate) slab: &'c Slab<'s, T>,
    pub(crate) color: &'c mut Vec3,
    pub(crate) weight: &'c mut f32,
    pub(crate) cutoff: f32,
}

impl<'c, 'l, 's, T: Sample> Compositing<'c, 'l, 's, T> {
    /// What a waiting sample's compositing takes, from a run's state.
    #[inline(always)]
    pub(crate) fn new(
        light: &'c Unshadowed<'l>,
        gradients: bool,
        slab: &'c Slab<'s, T>,
        (color, weight): (&'c mut Vec3, &'c mut f32),
        cutoff: f32,
    ) -> Self {
        Compositing {
            light,
            gradients,
            slab,
            color,
            weight,
            cutoff,
        }
    }
}

impl Pending {
    /// Nothing waiting.
    #[inline(always)]
    pub(crate) fn new() -> Self {
        Pending {
            len: 0,
            opacity: [0.0; LANES],
            length: [0.0; LANES],
            k: [0; LANES],
            v: [0.0; LANES],
            base: [Vec3::ZERO; LANES],
            gradient: [Vec3::ZERO; LANES],
            q: [Vec4::ZERO; LANES],
            lo: [[0; 3]; LANES],
            frac: [Vec3::ZERO; LANES],
            counted: [(0, 0); LANES],
        }
    }

    /// Add `sample`, whose opacity is `opacity` for one cell edge over a segment `length`
    /// cell edges long; once [`LANES`] wait, composite them ([`Pending::settle`]).
    #[inline(always)]
    pub(crate) fn push<T: Sample>(
        &mut self,
        (sample, opacity, length): (Waiting, f32, f32),
        into: Compositing<'_, '_, '_, T>,
        counters: &mut Counters,
    ) -> Option<Ended> {
        // Below `LANES` (settled as soon as it fills): the `min` only lets the compiler see it.
        let i = self.len.min(LANES - 1);
        self.opacity[i] = opacity;
        self.length[i] = length;
        self.k[i] = sample.k;
        self.v[i] = sample.v;
        self.base[i] = sample.base;
        self.counted[i] = sample.counted;
        self.q[i] = sample.q;
        if into.gradients {
            self.gradient[i] = sample.gradient;
        } else {
            self.lo[i] = sample.lo;
            self.frac[i] = sample.frac;
        }
        self.len = i + 1;
        if self.len < LANES {
            return None;
        }
        self.settle(into, counters)
    }

    /// Correct the waiting samples' opacities and composite them in order into `into`'s
    /// colour and transmittance, emptying the batch: `None`, or the sample whose compositing
    /// ended the ray, with the reads counted after it taken back out of `counters`.
    #[inline(always)]
    pub(crate) fn settle<T: Sample>(
        &mut self,
        into: Compositing<'_, '_, '_, T>,
        counters: &mut Counters,
    ) -> Option<Ended> {
        let n = self.len.min(LANES);
        self.len = 0;
        if n == 0 {
            return None;
        }
        // Lanes past `n` hold earlier samples' inputs, corrected and not looked at.
        let alpha = corrected_opacities(self.opacity, self.length);
        let read = (counters.samples, counters.interpolations);
        // In registers for the batch, as the loop holds them.
        let (mut color, mut weight) = (*into.color, *into.weight);
        let mut ended = None;
        for (i, &alpha) in alpha.iter().enumerate().take(n) {
            if !(alpha > 0.0) {
                continue;
            }
            let lit = if into.gradients {
                // The site is not asked where the gradient is given (the point is, by lights
                // whose direction depends on it).
                let site = Site {
                    lo: [0; 3],
                    hi: [1; 3],
                    frac: Vec3::ZERO,
                };
                let at = (self.q[i].truncate(), &site, Some(self.gradient[i]));
                into.light.color(into.slab, self.base[i], at, counters)
            } else {
                let site = Site {
                    lo: self.lo[i],
                    hi: self.lo[i].map(|c| c + 1),
                    frac: self.frac[i],
                };
                let at = (self.q[i].truncate(), &site, None);
                into.light.color(into.slab, self.base[i], at, counters)
            };
            color += lit * (weight * alpha);
            weight *= 1.0 - alpha;
            if !(weight > into.cutoff) {
                // The reads after this sample's, counted by `settle`'s start, taken back.
                let take_back = |count: &mut u64, at_start: u64, then: u64| {
                    *count = count.saturating_sub(at_start.saturating_sub(then));
                };
                take_back(&mut counters.samples, read.0, self.counted[i].0);
                take_back(&mut counters.interpolations, read.1, self.counted[i].1);
                ended = Some(Ended {
                    k: self.k[i],
                    v: self.v[i],
                });
                break;
            }
        }
        (*into.color, *into.weight) = (color, weight);
        ended
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optics::shade::{Light, Shading};
    use crate::optics::transfer::corrected_opacity;
    use crate::volume::slab::Slab;

    #[test]
    fn samples_waiting_in_fours_composite_as_each_would_one_at_a_time() {
        let (data, grid) = crate::testing::hashed_field();
        let slab = Slab::whole(grid, &data).unwrap();
        // A point light: its direction depends on the sample's point, which must wait too.
        let lights = [
            Light::directional(Vec3::new(0.4, -0.5, 1.0), Vec3::new(1.0, 0.9, 0.8), false).unwrap(),
            Light::point(Vec3::new(2.0, 9.0, 3.0), Vec3::splat(0.6), false).unwrap(),
        ];
        let view = crate::testing::composited_view(&grid, Some(Shading::default()), &lights);
        let light = Unshadowed::new(&view, view.spec().camera.forward());
        let cutoff = 0.05;
        let mut next = crate::testing::xorshift(0x9e4d_1e55);
        let mut draw = move || next();
        let unit = |r: u32| (r >> 8) as f32 / (1 << 24) as f32;
        let bits = |c: Vec3| c.to_array().map(f32::to_bits);
        let mut read_past_the_end = false;
        for case in 0..400 {
            let n = case % 13;
            let gradients = case % 2 == 0;
            let samples: heapless::Vec<(Waiting, f32, f32), 13> = (0..n)
                .map(|i| {
                    let mut u = || unit(draw());
                    let q = Vec4::new(1.0 + 6.0 * u(), 1.0 + 4.0 * u(), 1.0 + 5.0 * u(), 0.0);
                    let lo = [q.x as u32, q.y as u32, q.z as u32];
                    let sample = Waiting {
                        k: 10 + 2 * i as u32,
                        v: u(),
                        base: Vec3::new(u(), u(), u()),
                        gradient: (Vec3::new(u(), u(), u()) - 0.5) * 9.0,
                        q,
                        lo,
                        frac: (q - Vec4::new(lo[0] as f32, lo[1] as f32, lo[2] as f32, 0.0))
                            .truncate(),
                        // Set as the sample is read, below.
                        counted: (0, 0),
                    };
                    // Some opacities as good as opaque, some that round to nothing.
                    let opacity = match draw() % 9 {
                        0 => 0.999,
                        1 => 1e-30,
                        _ => unit(draw()) * 0.6,
                    };
                    let length = [0.5, 1.0, 0.37][(draw() % 3) as usize];
                    (sample, opacity, length)
                })
                .collect();
            // One at a time.
            let (mut want_color, mut want_weight) = (Vec3::new(0.1, 0.0, 0.2), 0.9f32);
            let mut want_counts = Counters::default();
            let mut want_end = None;
            // Each sample two reads, and a third interpolation: a sample whose own value shows
            // nothing between each two (the reads of the loop's count).
            let reads = |c: &mut Counters| {
                c.samples += 2;
                c.interpolations += 3;
            };
            for (s, opacity, length) in &samples {
                reads(&mut want_counts);
                let alpha = corrected_opacity(*opacity, *length);
                if alpha > 0.0 {
                    let site = Site {
                        lo: s.lo,
                        hi: s.lo.map(|c| c + 1),
                        frac: s.frac,
                    };
                    let g = gradients.then_some(s.gradient);
                    let at = (s.q.truncate(), &site, g);
                    let lit = light.color(&slab, s.base, at, &mut want_counts);
                    want_color += lit * (want_weight * alpha);
                    want_weight *= 1.0 - alpha;
                    if !(want_weight > cutoff) {
                        want_end = Some(Ended { k: s.k, v: s.v });
                        break;
                    }
                }
            }
            // Waiting in fours, the reads counted as they are made.
            let (mut color, mut weight) = (Vec3::new(0.1, 0.0, 0.2), 0.9f32);
            let mut counts = Counters::default();
            let mut pending = Pending::new();
            let mut end = None;
            for &(mut s, opacity, length) in &samples {
                reads(&mut counts);
                s.counted = (counts.samples, counts.interpolations);
                let into =
                    Compositing::new(&light, gradients, &slab, (&mut color, &mut weight), cutoff);
                end = pending.push((s, opacity, length), into, &mut counts);
                if end.is_some() {
                    break;
                }
            }
            let read = counts.samples;
            if end.is_none() {
                let into =
                    Compositing::new(&light, gradients, &slab, (&mut color, &mut weight), cutoff);
                end = pending.settle(into, &mut counts);
            }
            assert_eq!(end, want_end, "case {case}");
            assert_eq!(bits(color), bits(want_color), "case {case}");
            assert_eq!(weight.to_bits(), want_weight.to_bits(), "case {case}");
            assert_eq!(counts, want_counts, "case {case}");
            assert_eq!(pending.len, 0, "case {case}");
            read_past_the_end |= read > want_counts.samples;
        }
        // Reads made after the sample that ended a ray were taken back in some case: a
        // batch that forgot them would fail the counts above.
        assert!(
            read_past_the_end,
            "no ray ended with reads after its last sample"
        );
    }
}

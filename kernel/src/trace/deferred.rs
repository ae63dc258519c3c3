//! The fast tier's composited samples whose light is found after the sample loop has moved
//! on: a shaded sample's colour, gradient and share of the pixel (`w·α`, known as soon as it
//! is classified) wait in a short batch, and the batch is lit by the shading table and added
//! to the ray's colour when it is full or the loop stops. A sample's shading is a long chain
//! of dependent operations (its gradient's direction on the octahedral map, a division
//! among them, then the table's entry) that nothing in the loop waits for but the colour,
//! which the loop never reads: in the loop each chain holds the core's window of
//! instructions and stalls the samples behind it; in a batch the chains of four samples
//! share their instructions, lane by lane ([`shading_table::indices`]), and the batch's
//! groups overlap.
//!
//! Invariant: the batch is lit in sample order and each sample adds `lit · (w·α)` to the
//! colour with the `w·α` the loop computed, and each lane's entry is the one the sample's
//! own gradient reads, so the colour is the same in every bit as when each sample is lit as
//! it is read; nothing is left in the batch when the loop returns.

use crate::counters::Counters;
use crate::optics::shading_table;
use crate::trace::lighting::Unshadowed;
use glam::{Vec3, Vec4};

/// Samples a batch holds, a whole number of four-lane groups: enough that a batch's chains
/// overlap, few enough that the batch stays in the first-level cache beside the loop's own
/// data.
const BATCH: usize = 16;

/// The samples waiting for their light, in sample order: the first `len` of each array.
pub(crate) struct Deferred {
    len: usize,
    /// Their gradients, a coordinate to an array, as the shading table's four lanes read them.
    g: [[f32; BATCH]; 3],
    /// Their colours before shading.
    base: [Vec3; BATCH],
    /// Their weights in the pixel, `w·α`.
    share: [f32; BATCH],
}

impl Deferred {
    /// An empty batch.
    #[inline(always)]
    pub(crate) fn new() -> Self {
        Deferred {
            len: 0,
            g: [[0.0; BATCH]; 3],
            base: [Vec3::ZERO; BATCH],
            share: [0.0; BATCH],
        }
    }

    /// Add the sample of colour `base`, gradient `g` (read with its value) and share
    /// `share` of the pixel; lights the batch into `color` by `light` once it is full.
    #[inline(always)]
    pub(crate) fn push(
        &mut self,
        (g, base, share): (Vec3, Vec3, f32),
        light: &Unshadowed<'_>,
        color: &mut Vec3,
        counters: &mut Counters,
    ) {
        // Below `BATCH` (lit as soon as it fills): the `min` only lets the compiler see it.
        let i = self.len.min(BATCH - 1);
        self.g[0][i] = g.x;
        self.g[1][i] = g.y;
        self.g[2][i] = g.z;
        self.base[i] = base;
        self.share[i] = share;
        self.len = i + 1;
        if self.len == BATCH {
            self.light(light, color, counters);
        }
    }

    /// Light every waiting sample, in order, into `color`, and empty the batch.
    #[inline(always)]
    pub(crate) fn light(
        &mut self,
        light: &Unshadowed<'_>,
        color: &mut Vec3,
        counters: &mut Counters,
    ) {
        let n = self.len.min(BATCH);
        self.len = 0;
        let Some(table) = light.table() else {
            // Never holding samples: only a loop whose light has a table puts them here.
            debug_assert_eq!(n, 0, "samples waiting for a table that is not there");
            return;
        };
        let mut fallbacks = 0;
        for group in 0..n.div_ceil(4) {
            let lanes = |c: usize| {
                let mut lane = [0.0; 4];
                lane.copy_from_slice(&self.g[c][group * 4..group * 4 + 4]);
                Vec4::from_array(lane)
            };
            let entries = shading_table::indices(lanes(0), lanes(1), lanes(2));
            for (l, &entry) in entries.iter().enumerate().take(n - group * 4) {
                let i = group * 4 + l;
                let (lit, fallback) = table.color_at(self.base[i], entry);
                fallbacks += u64::from(fallback);
                *color += lit * self.share[i];
            }
        }
        light.count_tabled(n as u64, fallbacks, counters);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optics::shade::{Light, Shading};
    use crate::trace::view::{Accuracy, View, ViewSpec};
    use crate::volume::field::Site;
    use crate::volume::slab::Slab;

    /// A fast composited view with parallel rays and directional lights: one with a table.
    fn fast_view(grid: &crate::volume::grid::Grid) -> View {
        let lights = [
            Light::directional(Vec3::new(0.4, -0.5, 1.0), Vec3::new(1.0, 0.9, 0.8), false).unwrap(),
            Light::directional(Vec3::new(-1.0, 0.2, -0.3), Vec3::splat(0.5), false).unwrap(),
        ];
        let view = crate::testing::composited_view(grid, Some(Shading::default()), &lights);
        let spec = ViewSpec {
            accuracy: Accuracy::Fast,
            ..view.spec().clone()
        };
        View::new(spec, grid).unwrap()
    }

    #[test]
    fn a_batch_lights_its_samples_into_the_colour_each_would_give_lit_as_it_is_read() {
        let (data, grid) = crate::testing::hashed_field();
        let slab = Slab::whole(grid, &data).unwrap();
        let view = fast_view(&grid);
        let along = view.spec().camera.forward();
        let light = Unshadowed::new(&view, along);
        assert!(light.table().is_some(), "parallel rays, directional lights");
        // Where the immediate shading reads it; with a gradient given, the table ignores it.
        let p = Vec3::new(4.0, 3.0, 5.0);
        let site = Site {
            lo: [4, 3, 5],
            hi: [5, 4, 6],
            frac: Vec3::ZERO,
        };
        let mut next = crate::testing::xorshift(0xdefe_77ed);
        let mut unit = || (next() >> 8) as f32 / (1 << 24) as f32;
        let bits = |c: Vec3| c.to_array().map(f32::to_bits);
        let mut order_told = false;
        // Runs of every length around the batch's: none, part of one, one, and several.
        for len in [0, 1, 3, 4, 5, 15, 16, 17, 31, 32, 33, 70] {
            let samples: heapless::Vec<(Vec3, Vec3, f32), 70> = (0..len)
                .map(|n| {
                    let g = match n % 7 {
                        // No direction: the fallback normal's entry.
                        3 => Vec3::ZERO,
                        5 => Vec3::new(f32::NAN, 1.0, 0.0),
                        _ => (Vec3::new(unit(), unit(), unit()) - 0.5) * 40.0,
                    };
                    let base = Vec3::new(unit(), unit(), unit());
                    (g, base, unit() * unit())
                })
                .collect();
            let (mut want, mut counted) = (Vec3::ZERO, Counters::default());
            for &(g, base, share) in &samples {
                want += light.color(&slab, base, (p, &site, Some(g)), &mut counted) * share;
            }
            let (mut got, mut counters) = (Vec3::ZERO, Counters::default());
            let mut waiting = Deferred::new();
            for &(g, base, share) in &samples {
                waiting.push((g, base, share), &light, &mut got, &mut counters);
            }
            waiting.light(&light, &mut got, &mut counters);
            assert_eq!(bits(got), bits(want), "{len} samples");
            assert_eq!(counters, counted, "{len} samples");
            assert_eq!(waiting.len, 0);
            // The test tells the order: summed the other way round, some run's colour differs.
            let mut reversed = Vec3::ZERO;
            for &(g, base, share) in samples.iter().rev() {
                reversed += light.color(&slab, base, (p, &site, Some(g)), &mut counted) * share;
            }
            order_told |= bits(reversed) != bits(want);
        }
        assert!(order_told, "no run's colour depends on its order");
    }
}

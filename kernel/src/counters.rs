//! Work counters: rays by type and operations by kind, so reports can show what a scene cost
//! and tests can prove that no work is done for an effect the scene does not call for.
//!
//! Invariant: counters only grow; [`Counters::add`] is the only way two sets combine.

/// What a trace did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counters {
    /// Primary rays that entered the volume's box.
    pub primary_rays: u64,
    /// Primary rays set up (camera ray, box clip, first sample) to find whether and where
    /// they start: on every node that walks the pixel, whether the ray is its own, another
    /// slab's or a miss, as the paper's distributed generation does on every node of a ring.
    /// Pixels passed over by row leaps or runs of certain misses set up none.
    pub rays_set_up: u64,
    /// Transparency rays: continuations past a semi-transparent surface.
    pub transparency_rays: u64,
    /// Shadow rays toward shadow-casting lights.
    pub shadow_rays: u64,
    /// Lattice samples taken (one field value each).
    pub samples: u64,
    /// Lattice samples skipped as provably empty (min/max blocks).
    pub skipped: u64,
    /// Trilinear interpolations (cell model), for any purpose.
    pub interpolations: u64,
    /// Nearest-node lookups (voxel model), for any purpose.
    pub lookups: u64,
    /// Field evaluations spent refining surface crossings.
    pub refinements: u64,
    /// Gradient evaluations.
    pub gradients: u64,
    /// Shading evaluations (one per lit point).
    pub shadings: u64,
    /// Surface crossings found by primary and transparency rays.
    pub crossings: u64,
    /// Rays stopped early because what is behind can no longer show.
    pub early_terminations: u64,
    /// Zero or non-finite gradients replaced by the fallback normal.
    pub normal_fallbacks: u64,
    /// Reads outside a slab's stored planes (a ghost region too narrow): must stay zero.
    pub slab_misses: u64,
    /// Pixels whose colour was not finite before quantisation: must stay zero.
    pub non_finite_pixels: u64,
}

impl Counters {
    /// What was counted since `before` (each counter's difference, never below zero).
    pub fn since(&self, before: &Counters) -> Counters {
        let mut d = *self;
        for (now, then) in d.fields_mut().into_iter().zip(before.fields()) {
            *now = now.saturating_sub(then);
        }
        d
    }

    /// Every counter, in one fixed order (the order of the statistics message).
    pub(crate) fn fields(&self) -> [u64; 16] {
        let c = *self;
        [
            c.primary_rays,
            c.rays_set_up,
            c.transparency_rays,
            c.shadow_rays,
            c.samples,
            c.skipped,
            c.interpolations,
            c.lookups,
            c.refinements,
            c.gradients,
            c.shadings,
            c.crossings,
            c.early_terminations,
            c.normal_fallbacks,
            c.slab_misses,
            c.non_finite_pixels,
        ]
    }

    /// Every counter, mutably, in the order of [`Counters::fields`].
    pub(crate) fn fields_mut(&mut self) -> [&mut u64; 16] {
        [
            &mut self.primary_rays,
            &mut self.rays_set_up,
            &mut self.transparency_rays,
            &mut self.shadow_rays,
            &mut self.samples,
            &mut self.skipped,
            &mut self.interpolations,
            &mut self.lookups,
            &mut self.refinements,
            &mut self.gradients,
            &mut self.shadings,
            &mut self.crossings,
            &mut self.early_terminations,
            &mut self.normal_fallbacks,
            &mut self.slab_misses,
            &mut self.non_finite_pixels,
        ]
    }

    /// Add `other` into `self` (saturating: counters never wrap).
    pub fn add(&mut self, other: &Counters) {
        for (total, more) in self.fields_mut().into_iter().zip(other.fields()) {
            *total = total.saturating_add(more);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn since_undoes_add() {
        let a = Counters {
            samples: 7,
            skipped: 2,
            shadings: 1,
            ..Counters::default()
        };
        let mut b = a;
        b.add(&Counters {
            samples: 3,
            non_finite_pixels: 4,
            ..Counters::default()
        });
        assert_eq!(
            b.since(&a),
            Counters {
                samples: 3,
                non_finite_pixels: 4,
                ..Counters::default()
            }
        );
        assert_eq!(a.since(&b).samples, 0, "never below zero");
    }
}

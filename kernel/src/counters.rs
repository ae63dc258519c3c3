//! Work counters: rays by type and operations by kind, so reports can show what a scene cost
//! and tests can prove that no work is done for an effect the scene does not call for.
//!
//! Invariant: counters only grow; [`Counters::add`] is the only way two sets combine.

/// What a trace did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counters {
    /// Primary rays that entered the volume's box.
    pub primary_rays: u64,
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
    /// Add `other` into `self` (saturating: counters never wrap).
    pub fn add(&mut self, other: &Counters) {
        let Counters {
            primary_rays,
            transparency_rays,
            shadow_rays,
            samples,
            skipped,
            interpolations,
            lookups,
            refinements,
            gradients,
            shadings,
            crossings,
            early_terminations,
            normal_fallbacks,
            slab_misses,
            non_finite_pixels,
        } = *other;
        self.primary_rays = self.primary_rays.saturating_add(primary_rays);
        self.transparency_rays = self.transparency_rays.saturating_add(transparency_rays);
        self.shadow_rays = self.shadow_rays.saturating_add(shadow_rays);
        self.samples = self.samples.saturating_add(samples);
        self.skipped = self.skipped.saturating_add(skipped);
        self.interpolations = self.interpolations.saturating_add(interpolations);
        self.lookups = self.lookups.saturating_add(lookups);
        self.refinements = self.refinements.saturating_add(refinements);
        self.gradients = self.gradients.saturating_add(gradients);
        self.shadings = self.shadings.saturating_add(shadings);
        self.crossings = self.crossings.saturating_add(crossings);
        self.early_terminations = self.early_terminations.saturating_add(early_terminations);
        self.normal_fallbacks = self.normal_fallbacks.saturating_add(normal_fallbacks);
        self.slab_misses = self.slab_misses.saturating_add(slab_misses);
        self.non_finite_pixels = self.non_finite_pixels.saturating_add(non_finite_pixels);
    }
}

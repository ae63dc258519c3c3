//! Work counters: rays by type and operations by kind, so reports can show what a scene cost
//! and tests can prove that no work is done for an effect the scene does not call for.
//!
//! Invariant: counters only grow; [`Counters::add`] is the only way two sets combine.

/// Where a report shows a counter: the host's JSON groups each trace's counters under "rays"
/// and "operations" by this table, so a counter added here reaches the report without a
/// second list.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Group {
    /// Rays by type.
    Rays,
    /// Work by kind.
    Operations,
    /// Not in a group: a check the report names on its own (`nan_pixels`), or a count that
    /// feeds the machine's cost model rather than the report (`rays_set_up`).
    Apart,
}

impl Group {
    /// The groups a report lists, in its order.
    pub const LISTED: [Group; 2] = [Group::Rays, Group::Operations];

    /// The group's key in a report.
    pub fn name(self) -> &'static str {
        match self {
            Group::Rays => "rays",
            Group::Operations => "operations",
            Group::Apart => "apart",
        }
    }
}

/// Declares every counter once: its doc, field, report group and report key. The struct, the
/// fixed order of the statistics message and the report's table all come from this list.
macro_rules! counters {
    ($($(#[doc = $doc:literal])* $field:ident: $group:ident $key:literal,)*) => {
        /// What a trace did.
        #[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
        pub struct Counters {
            $($(#[doc = $doc])* pub $field: u64,)*
        }

        impl Counters {
            /// How many counters there are.
            pub const COUNT: usize = [$(stringify!($field)),*].len();

            /// Each counter's report group and key, in the order of [`Counters::fields`].
            pub const REPORTED: [(Group, &'static str); Self::COUNT] =
                [$((Group::$group, $key)),*];

            /// Every counter, in one fixed order (the order of the statistics message).
            pub fn fields(&self) -> [u64; Self::COUNT] {
                [$(self.$field),*]
            }

            /// Every counter, mutably, in the order of [`Counters::fields`].
            pub(crate) fn fields_mut(&mut self) -> [&mut u64; Self::COUNT] {
                [$(&mut self.$field),*]
            }
        }
    };
}

counters! {
    /// Primary rays that entered the volume's box.
    primary_rays: Rays "primary",
    /// Primary rays set up (camera ray, box clip, first sample) to find whether and where
    /// they start: on every node that walks the pixel, whether the ray is its own, another
    /// slab's or a miss, as the paper's distributed generation does on every node of a ring.
    /// Pixels passed over by row leaps or runs of certain misses set up none.
    rays_set_up: Apart "rays_set_up",
    /// Transparency rays: continuations past a semi-transparent surface.
    transparency_rays: Rays "transparency",
    /// Shadow rays toward shadow-casting lights.
    shadow_rays: Rays "shadow",
    /// Lattice samples taken (one field value each).
    samples: Operations "samples",
    /// Lattice samples skipped as provably empty (min/max blocks).
    skipped: Operations "skipped",
    /// Trilinear interpolations (cell model), for any purpose.
    interpolations: Operations "interpolations",
    /// Nearest-node lookups (voxel model), for any purpose.
    lookups: Operations "lookups",
    /// Field evaluations spent refining surface crossings.
    refinements: Operations "refinements",
    /// Gradient evaluations.
    gradients: Operations "gradients",
    /// Shading evaluations (one per lit point).
    shadings: Operations "shadings",
    /// Surface crossings found by primary and transparency rays.
    crossings: Operations "crossings",
    /// Rays stopped early because what is behind can no longer show.
    early_terminations: Operations "early_terminations",
    /// Zero or non-finite gradients replaced by the fallback normal.
    normal_fallbacks: Operations "normal_fallbacks",
    /// Reads outside a slab's stored planes (a ghost region too narrow): must stay zero.
    slab_misses: Operations "slab_misses",
    /// Pixels whose colour was not finite before quantisation: must stay zero.
    non_finite_pixels: Apart "nan_pixels",
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

    /// The counters a report lists under `group`, with their keys, in the kernel's order.
    pub fn in_group(&self, group: Group) -> impl Iterator<Item = (&'static str, u64)> {
        Self::REPORTED
            .into_iter()
            .zip(self.fields())
            .filter(move |((g, _), _)| *g == group)
            .map(|((_, key), value)| (key, value))
    }

    /// Add `other` into `self` (saturating: counters never wrap).
    #[inline]
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
    fn each_counter_has_one_key_in_its_group_and_reads_its_own_field() {
        let mut c = Counters::default();
        for (i, slot) in c.fields_mut().into_iter().enumerate() {
            *slot = 100 + i as u64;
        }
        let mut seen = 0;
        for group in [Group::Rays, Group::Operations, Group::Apart] {
            for (i, (key, _)) in c.in_group(group).enumerate() {
                assert!(
                    c.in_group(group).take(i).all(|(k, _)| k != key),
                    "{key} twice in {}",
                    group.name()
                );
                seen += 1;
            }
        }
        assert_eq!(seen, Counters::COUNT, "every counter in exactly one group");
        assert!(c.in_group(Group::Rays).eq([
            ("primary", c.primary_rays),
            ("transparency", c.transparency_rays),
            ("shadow", c.shadow_rays)
        ]));
        let nan = c.in_group(Group::Apart).find(|(k, _)| *k == "nan_pixels");
        assert_eq!(nan, Some(("nan_pixels", c.non_finite_pixels)));
    }

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

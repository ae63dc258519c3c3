//! The slice partition of a cluster: ring position `j` owns X planes `[cuts[j], cuts[j+1])`.
//!
//! Invariants: `cuts[0] = 0`, the last cut is the grid's `nx`, cuts strictly increase (every
//! slab owns at least one plane), at most [`MAX_CLUSTER`] slabs. Partitions may be uneven, as
//! load balancing moves the cuts.

use core::fmt;
use core::ops::Range;
use heapless::Vec;

/// Most nodes in one cluster (ring).
pub const MAX_CLUSTER: usize = 1024;

/// Why a partition is unusable.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PartitionError {
    /// No slabs, or more than [`MAX_CLUSTER`].
    Count(usize),
    /// More slabs than planes: some slab would own nothing.
    TooManySlabs {
        /// Slabs asked for.
        slabs: usize,
        /// Planes available.
        planes: u32,
    },
    /// The cuts do not run from 0 to `nx` strictly increasing.
    Cuts {
        /// Index of the first bad cut.
        index: usize,
    },
}

impl fmt::Display for PartitionError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            PartitionError::Count(n) => write!(f, "{n} slabs; a cluster has 1 to {MAX_CLUSTER}"),
            PartitionError::TooManySlabs { slabs, planes } => {
                write!(
                    f,
                    "{slabs} slabs of {planes} X planes: every slab needs at least one plane"
                )
            }
            PartitionError::Cuts { index } => {
                write!(
                    f,
                    "cut {index}: cuts must run from 0 to nx, strictly increasing"
                )
            }
        }
    }
}

impl core::error::Error for PartitionError {}

/// Where a cluster's slabs begin and end.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Partition {
    cuts: Vec<u32, { MAX_CLUSTER + 1 }>,
}

impl Partition {
    /// A partition from its cuts (`slabs + 1` of them), checked against `nx` planes.
    pub fn new(cuts: &[u32], nx: u32) -> Result<Partition, PartitionError> {
        let slabs = cuts.len().saturating_sub(1);
        if slabs == 0 || slabs > MAX_CLUSTER {
            return Err(PartitionError::Count(slabs));
        }
        for (index, pair) in cuts.windows(2).enumerate() {
            if pair[0] >= pair[1] {
                return Err(PartitionError::Cuts { index: index + 1 });
            }
        }
        if cuts[0] != 0 {
            return Err(PartitionError::Cuts { index: 0 });
        }
        if cuts[slabs] != nx {
            return Err(PartitionError::Cuts { index: slabs });
        }
        let cuts = Vec::from_slice(cuts).map_err(|()| PartitionError::Count(slabs))?;
        Ok(Partition { cuts })
    }

    /// `slabs` slabs of as equal a number of planes as `nx` allows (the first ones larger).
    pub fn uniform(nx: u32, slabs: usize) -> Result<Partition, PartitionError> {
        if slabs == 0 || slabs > MAX_CLUSTER {
            return Err(PartitionError::Count(slabs));
        }
        if slabs as u64 > u64::from(nx) {
            return Err(PartitionError::TooManySlabs { slabs, planes: nx });
        }
        let mut cuts: Vec<u32, { MAX_CLUSTER + 1 }> = Vec::new();
        let (base, extra) = (nx / slabs as u32, nx % slabs as u32);
        let mut at = 0;
        for j in 0..=slabs as u32 {
            // Capacity is MAX_CLUSTER + 1 and slabs ≤ MAX_CLUSTER.
            let _ = cuts.push(at);
            at += base + u32::from(j < extra);
        }
        Ok(Partition { cuts })
    }

    /// Number of slabs.
    pub fn slabs(&self) -> usize {
        self.cuts.len() - 1
    }

    /// The planes slab `j` owns (empty for `j` out of range).
    pub fn planes(&self, j: usize) -> Range<u32> {
        match (self.cuts.get(j), self.cuts.get(j + 1)) {
            (Some(&a), Some(&b)) => a..b,
            _ => 0..0,
        }
    }

    /// The cuts.
    pub fn cuts(&self) -> &[u32] {
        &self.cuts
    }

    /// The slab owning `plane` (planes past the end belong to the last slab).
    pub fn owner(&self, plane: u32) -> usize {
        // The number of cuts at or below `plane`, minus one, is the slab.
        let at_or_below = self.cuts.partition_point(|&c| c <= plane);
        at_or_below.saturating_sub(1).min(self.slabs() - 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn uniform_partitions_cover_every_plane_once() {
        let p = Partition::uniform(10, 3).unwrap();
        assert_eq!(p.cuts(), &[0, 4, 7, 10]);
        let owners: [usize; 11] = core::array::from_fn(|x| p.owner(x as u32));
        assert_eq!(owners, [0, 0, 0, 0, 1, 1, 1, 2, 2, 2, 2]);
        assert_eq!(p.planes(1), 4..7);
        assert_eq!(p.planes(3), 0..0);
    }

    #[test]
    fn bad_partitions_are_refused() {
        assert_eq!(
            Partition::uniform(2, 3),
            Err(PartitionError::TooManySlabs {
                slabs: 3,
                planes: 2
            })
        );
        assert_eq!(
            Partition::new(&[0, 3, 3, 5], 5),
            Err(PartitionError::Cuts { index: 2 })
        );
        assert_eq!(
            Partition::new(&[1, 5], 5),
            Err(PartitionError::Cuts { index: 0 })
        );
        assert_eq!(
            Partition::new(&[0, 4], 5),
            Err(PartitionError::Cuts { index: 1 })
        );
        assert_eq!(Partition::new(&[0], 5), Err(PartitionError::Count(0)));
        assert!(Partition::new(&[0, 1, 5], 5).is_ok());
    }
}

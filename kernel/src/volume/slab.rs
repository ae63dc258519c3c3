//! A slab: the X planes `[x0, x1)` a node owns, plus up to `g` ghost planes on each side, read
//! from caller-provided storage. The whole volume is the slab that owns every plane.
//!
//! Storage is plane-major: plane `x` is one contiguous block of `ny · nz` samples, Y fastest,
//! so moving planes between nodes moves whole blocks. Invariants: `x0 < x1 ≤ nx`; the stored
//! planes are `[max(0, x0 - g), min(nx, x1 + g))`; the storage holds exactly those planes.
//! A read outside the stored planes returns 0 and is counted, never a panic: the bit-identity
//! tests assert the count stays zero, which proves `g` wide enough.

use crate::optics::segments::Segments;
use crate::skip::blocks::Blocks;
use crate::volume::cells::{corners, Cells};
use crate::volume::grid::Grid;
use crate::volume::lanes::Nodes;
use crate::volume::sample::Sample;
use core::fmt;
use core::ops::Range;

/// Why a slab cannot be built over the given storage.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SlabError {
    /// The owned range is empty or runs past the grid.
    BadRange {
        /// First owned plane.
        x0: u32,
        /// One past the last owned plane.
        x1: u32,
        /// Planes in the grid.
        nx: u32,
    },
    /// The storage does not hold exactly the stored planes.
    StorageLength {
        /// Samples needed.
        expected: usize,
        /// Samples given.
        actual: usize,
    },
}

impl fmt::Display for SlabError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            SlabError::BadRange { x0, x1, nx } => write!(
                f,
                "slab planes [{x0}, {x1}) are not a non-empty range inside the grid's {nx} planes"
            ),
            SlabError::StorageLength { expected, actual } => {
                write!(
                    f,
                    "slab storage holds {actual} samples, the stored planes need {expected}"
                )
            }
        }
    }
}

impl core::error::Error for SlabError {}

/// The planes `[x0 - g, x1 + g)` clamped to the grid: what a slab owning `[x0, x1)` stores.
pub fn stored_planes(grid: &Grid, owned: Range<u32>, ghost: u32) -> Range<u32> {
    let nx = grid.dims()[0];
    owned.start.saturating_sub(ghost)..owned.end.saturating_add(ghost).min(nx)
}

/// A node's part of the volume.
#[derive(Clone, Copy, Debug)]
pub struct Slab<'a, T: Sample> {
    grid: Grid,
    owned_start: u32,
    owned_end: u32,
    stored_start: u32,
    stored_end: u32,
    data: &'a [T],
    blocks: Option<Blocks<'a>>,
    nodes: Option<Nodes<'a, T::Node>>,
    /// The pre-integration table of the view being traced, where it composites so.
    segments: Option<Segments<'a>>,
    /// The least bytes of a node field from which a sample loop prefetches it ahead.
    prefetch_from: usize,
}

/// The least bytes of a node field from which a composited ray asks for cells of it a few
/// samples ahead ([`Slab::prefetched_field`]), well above a core's second-level cache (1–2 MiB
/// on current x86-64 processors), below which the field stays in the caches between rays.
/// Asked for each sample a run through the interior looks at, with the cell's map byte, SOD's
/// 8.7 MiB field took 6% off the fast tier's composited frame on two threads; asked for each
/// evaluated sample from its lattice position (what the general step still does), it gained
/// nothing on SOD and took a fifth to a quarter off the fast tier's frame at 256³ (128 MiB)
/// and 512³ (1 GiB), where the runs' asking timed alike (docs/speed-log.md).
pub const PREFETCH_FROM_BYTES: usize = 4 << 20;

/// A neighbourhood of a slab's nodes checked once by [`Slab::window`]: rows addressed from its
/// first node, plane by plane and row by row.
#[derive(Clone, Copy, Debug)]
pub struct Window<'a, T> {
    /// The slab's storage from the window's first node on.
    data: &'a [T],
    /// Samples from one plane to the next.
    plane: usize,
    /// Samples from one row to the next.
    row: usize,
}

impl<'a, T: Sample> Window<'a, T> {
    /// `N` nodes along Y of the row `dz` rows and `dx` planes past the first node, from `dy`
    /// nodes along it; `None` only past the end of the storage (the window's own offsets are
    /// in the slab by construction).
    #[inline(always)]
    pub fn nodes<const N: usize>(&self, dx: usize, dz: usize, dy: usize) -> Option<&'a [T; N]> {
        let start = dx * self.plane + dz * self.row + dy;
        self.data.get(start..start + N)?.try_into().ok()
    }
}

impl<'a, T: Sample> Slab<'a, T> {
    /// A slab owning planes `owned`, with `ghost` planes each side, over `data` (plane-major,
    /// exactly the stored planes of [`stored_planes`]).
    pub fn new(
        grid: Grid,
        owned: Range<u32>,
        ghost: u32,
        data: &'a [T],
    ) -> Result<Self, SlabError> {
        let nx = grid.dims()[0];
        if owned.start >= owned.end || owned.end > nx {
            return Err(SlabError::BadRange {
                x0: owned.start,
                x1: owned.end,
                nx,
            });
        }
        let stored = stored_planes(&grid, owned.clone(), ghost);
        let expected = (stored.end - stored.start) as usize * grid.plane_len();
        if data.len() != expected {
            return Err(SlabError::StorageLength {
                expected,
                actual: data.len(),
            });
        }
        Ok(Slab {
            grid,
            owned_start: owned.start,
            owned_end: owned.end,
            stored_start: stored.start,
            stored_end: stored.end,
            data,
            blocks: None,
            nodes: None,
            segments: None,
            prefetch_from: PREFETCH_FROM_BYTES,
        })
    }

    /// The slab that owns every plane: the whole volume, plane-major.
    pub fn whole(grid: Grid, data: &'a [T]) -> Result<Self, SlabError> {
        Slab::new(grid, 0..grid.dims()[0], 0, data)
    }

    /// The same slab, skipping empty space with `blocks` (built from this slab's planes).
    pub fn with_blocks(self, blocks: Blocks<'a>) -> Self {
        Slab {
            blocks: Some(blocks),
            ..self
        }
    }

    /// The same slab, reading the fast tier's node field from `nodes` (built from this
    /// slab's planes by [`crate::volume::nodes::fill`]).
    pub fn with_nodes(self, nodes: Nodes<'a, T::Node>) -> Self {
        Slab {
            nodes: Some(nodes),
            ..self
        }
    }

    /// The same slab, compositing pre-integrated by `segments` (built for the view traced).
    pub fn with_segments(self, segments: Segments<'a>) -> Self {
        Slab {
            segments: Some(segments),
            ..self
        }
    }

    /// The pre-integration table the slab was given, if any.
    #[inline]
    pub fn segments(&self) -> Option<&Segments<'a>> {
        self.segments.as_ref()
    }

    /// The same slab, prefetching node fields of `bytes` and more rather than of
    /// [`PREFETCH_FROM_BYTES`]: a prefetch changes no pixel, so this is for tests and
    /// measurements that compare the two.
    pub fn prefetching_from(self, bytes: usize) -> Self {
        Slab {
            prefetch_from: bytes,
            ..self
        }
    }

    /// The node field's cells where a sample loop asks for them ahead: where the slab holds a
    /// field of [`PREFETCH_FROM_BYTES`] or more (or as [`Slab::prefetching_from`] says).
    #[inline]
    pub fn prefetched_field(&self) -> Option<Cells<'a, T::Node>> {
        let cells = self.nodes.as_ref()?.cells();
        (cells.bytes() >= self.prefetch_from).then_some(cells)
    }

    /// The fast tier's node field, where this slab holds one.
    #[inline(always)]
    pub fn nodes(&self) -> Option<&Nodes<'a, T::Node>> {
        self.nodes.as_ref()
    }

    /// The min/max blocks, when empty space is skipped.
    pub fn blocks(&self) -> Option<&Blocks<'a>> {
        self.blocks.as_ref()
    }

    /// The dataset's grid.
    pub fn grid(&self) -> &Grid {
        &self.grid
    }

    /// The planes this slab owns.
    pub fn owned(&self) -> Range<u32> {
        self.owned_start..self.owned_end
    }

    /// Does this slab own plane `x`?
    #[inline]
    pub fn owns(&self, x: u32) -> bool {
        self.owned_start <= x && x < self.owned_end
    }

    /// The planes held in storage (owned plus ghosts).
    pub fn stored(&self) -> Range<u32> {
        self.stored_start..self.stored_end
    }

    /// The stored nodes from `(x, y, z)` through `(x, y, z) + span - 1` on every axis, for
    /// many reads of one neighbourhood: its bounds are checked here once, and each row is
    /// then an offset from the first node. `None` where any node is outside the stored
    /// planes or the grid.
    #[inline(always)]
    pub fn window(&self, [x, y, z]: [u32; 3], span: u32) -> Option<Window<'a, T>> {
        let [_, ny, nz] = self.grid.dims();
        let reach = span.checked_sub(1)?;
        let fits = |first: u32, end: u32| first.checked_add(reach).is_some_and(|last| last < end);
        if x < self.stored_start || !(fits(x, self.stored_end) && fits(y, ny) && fits(z, nz)) {
            return None;
        }
        let (ny, nz) = (ny as usize, nz as usize);
        let start = ((x - self.stored_start) as usize * nz + z as usize) * ny + y as usize;
        Some(Window {
            data: self.data.get(start..)?,
            plane: nz * ny,
            row: ny,
        })
    }

    /// The samples of row `z` of plane `x`, in Y order; `None` outside the stored planes or
    /// the grid.
    #[inline(always)]
    pub fn row(&self, x: u32, z: u32) -> Option<&'a [T]> {
        let [_, ny, nz] = self.grid.dims();
        if x < self.stored_start || x >= self.stored_end || z >= nz {
            return None;
        }
        let start = ((x - self.stored_start) as usize * nz as usize + z as usize) * ny as usize;
        self.data.get(start..start + ny as usize)
    }

    /// The eight nodes of the cell spanned by `x`, `y` and `z` (each a pair of equal or
    /// adjacent node indices, low first), ordered by corner bits `z y x` from 000 to 111; `None`
    /// when any lies outside the stored planes or the grid. One range check for the cell,
    /// where eight [`Slab::get`] calls would each recompute an index.
    #[inline]
    pub fn cell(&self, x: (u32, u32), y: (u32, u32), z: (u32, u32)) -> Option<[T; 8]> {
        let [_, ny, nz] = self.grid.dims();
        // Equal or adjacent, low first, in one comparison: `b < a` wraps to a large value.
        let ordered = |(a, b): (u32, u32)| b.wrapping_sub(a) <= 1;
        if !(ordered(x) && ordered(y) && ordered(z))
            || x.0 < self.stored_start
            || x.1 >= self.stored_end
            || y.1 >= ny
            || z.1 >= nz
        {
            return None;
        }
        let (ny, nz) = (ny as usize, nz as usize);
        let base = ((x.0 - self.stored_start) as usize * nz + z.0 as usize) * ny + y.0 as usize;
        let steps = [
            (x.1 - x.0) as usize * nz * ny,
            (y.1 - y.0) as usize,
            (z.1 - z.0) as usize * ny,
        ];
        corners(self.data, base, steps)
    }

    /// The stored planes as whole cells: what a run through the slab's interior reads.
    #[inline]
    pub fn cells(&self) -> Cells<'a, T> {
        let [_, ny, nz] = self.grid.dims();
        Cells::new(self.data, self.stored(), ny, nz)
    }

    /// The sample at grid node `(x, y, z)`, or `None` outside the stored planes or the grid.
    #[inline]
    pub fn get(&self, x: u32, y: u32, z: u32) -> Option<T> {
        let [_, ny, nz] = self.grid.dims();
        if x < self.stored_start || x >= self.stored_end || y >= ny || z >= nz {
            return None;
        }
        let index = ((x - self.stored_start) as usize * nz as usize + z as usize) * ny as usize
            + y as usize;
        self.data.get(index).copied()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn a_window_reads_the_nodes_get_reads_and_only_stored_ones() {
        let grid = Grid::new([6, 5, 4], Vec3::ONE).unwrap();
        let data: [u8; 4 * 20] = core::array::from_fn(|i| i as u8);
        // Planes 2 and 3 owned, 1 to 4 stored.
        let slab = Slab::new(grid, 2..4, 1, &data).unwrap();
        let window = slab.window([1, 1, 0], 4).unwrap();
        for (dx, dz, dy) in [(0, 0, 0), (3, 3, 0), (2, 1, 1), (1, 3, 2)] {
            let nodes = window.nodes::<2>(dx, dz, dy).unwrap();
            for (n, &v) in nodes.iter().enumerate() {
                let (x, y, z) = (1 + dx as u32, 1 + (dy + n) as u32, dz as u32);
                assert_eq!(Some(v), slab.get(x, y, z), "({x}, {y}, {z})");
            }
        }
        // Any node of the span outside the stored planes or the grid: no window.
        assert!(slab.window([0, 0, 0], 2).is_none());
        assert!(slab.window([3, 0, 0], 3).is_none());
        assert!(slab.window([1, 2, 0], 4).is_none());
        assert!(slab.window([1, 0, 1], 4).is_none());
        assert!(slab.window([1, 0, 0], 0).is_none());
        assert!(slab.window([1, u32::MAX, 0], 2).is_none());
        assert!(slab.window([4, 4, 3], 1).is_some());
    }

    #[test]
    fn slab_reads_only_its_stored_planes() {
        let grid = Grid::new([6, 2, 3], Vec3::ONE).unwrap();
        let stored = stored_planes(&grid, 2..4, 1);
        assert_eq!(stored, 1..5);
        let data: [u8; 4 * 6] = core::array::from_fn(|i| i as u8);
        let slab = Slab::new(grid, 2..4, 1, &data).unwrap();
        assert_eq!(slab.get(1, 0, 0), Some(0));
        assert_eq!(slab.get(1, 1, 0), Some(1));
        assert_eq!(slab.get(1, 0, 1), Some(2));
        assert_eq!(slab.get(2, 0, 0), Some(6));
        assert_eq!(slab.get(0, 0, 0), None);
        assert_eq!(slab.get(5, 0, 0), None);
        assert_eq!(slab.get(2, 2, 0), None);
        assert!(slab.owns(3) && !slab.owns(4) && !slab.owns(1));
    }

    #[test]
    fn wrong_storage_or_range_is_refused() {
        let grid = Grid::new([4, 1, 1], Vec3::ONE).unwrap();
        assert!(matches!(
            Slab::new(grid, 0..4, 0, &[0u8; 3]),
            Err(SlabError::StorageLength {
                expected: 4,
                actual: 3
            })
        ));
        assert!(matches!(
            Slab::new(grid, 2..2, 0, &[0u8; 0]),
            Err(SlabError::BadRange { .. })
        ));
        assert!(matches!(
            Slab::new(grid, 3..5, 0, &[0u8; 2]),
            Err(SlabError::BadRange { .. })
        ));
    }
}

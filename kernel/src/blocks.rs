//! Min/max blocks for empty-space skipping: for each block of `BLOCK`³ cells, the least and
//! greatest value of its nodes, so every value the field takes inside the block (nearest or
//! trilinear) lies in that range.
//!
//! A node builds its blocks from its own stored planes into storage it provides. A block that
//! needs a plane the node does not store is marked unknown (an infinite range) and is never
//! skipped. The tracer skips a sample only when the block says it provably contributes
//! nothing, and skipping never changes an image; which samples a node skips is therefore free
//! to differ from node to node. Blocks may carry one view's chessboard distances
//! ([`crate::leaps`]), so that a jump crosses every empty block around at once.

use crate::field::Site;
use crate::grid::Model;
use crate::sample::Sample;
use crate::slab::Slab;
use core::fmt;
use glam::Vec3;

/// Cells per block edge.
pub const BLOCK: u32 = 4;

/// The values a block's field can take.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Range {
    /// Least value.
    pub min: f32,
    /// Greatest value.
    pub max: f32,
}

impl Range {
    /// A range that proves nothing.
    pub const UNKNOWN: Range = Range {
        min: f32::NEG_INFINITY,
        max: f32::INFINITY,
    };
}

/// Why blocks cannot be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BlocksError {
    /// Entries needed.
    pub needed: usize,
    /// Entries given.
    pub given: usize,
}

impl fmt::Display for BlocksError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "block storage holds {} ranges, the slab needs {}",
            self.given, self.needed
        )
    }
}

impl core::error::Error for BlocksError {}

/// A slab's blocks: global block columns `[x0, x1)` × all Y × all Z.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Blocks<'a> {
    data: &'a [Range],
    /// One view's chessboard distances ([`crate::leaps`]), when the marcher may leap.
    leaps: Option<&'a [u8]>,
    x0: u32,
    x1: u32,
    ny: u32,
    nz: u32,
}

/// How far below an integer coordinate `i` the points reading cell or node `i` begin under
/// `model`: a voxel-model node is read from half a unit before it, a cell from its corner.
pub fn face_shift(model: Model) -> f32 {
    match model {
        Model::Voxel => 0.5,
        Model::Cell => 0.0,
    }
}

/// Blocks along an axis of `n` nodes (`n − 1` cells, at least one block).
fn count(n: u32) -> u32 {
    n.saturating_sub(1).div_ceil(BLOCK).max(1)
}

/// The global block columns a slab's stored planes touch, and the storage they need.
pub fn extent<T: Sample>(slab: &Slab<'_, T>) -> (u32, u32, usize) {
    extent_for(slab.grid(), slab.stored())
}

/// [`extent`] for stored planes `stored` of `grid`, before any slab exists (for budgets).
pub fn extent_for(grid: &crate::grid::Grid, stored: core::ops::Range<u32>) -> (u32, u32, usize) {
    let [nx, ny, nz] = grid.dims();
    let x0 = (stored.start / BLOCK).min(count(nx) - 1);
    let x1 = (stored.end.saturating_sub(1) / BLOCK + 1)
        .min(count(nx))
        .max(x0 + 1);
    (
        x0,
        x1,
        (x1 - x0) as usize * count(ny) as usize * count(nz) as usize,
    )
}

impl<'a> Blocks<'a> {
    /// The blocks in `data`, filled for `slab` by [`Blocks::build`].
    pub fn new<T: Sample>(
        slab: &Slab<'_, T>,
        data: &'a [Range],
    ) -> Result<Blocks<'a>, BlocksError> {
        let (x0, x1, needed) = extent(slab);
        if data.len() != needed {
            return Err(BlocksError {
                needed,
                given: data.len(),
            });
        }
        let [_, ny, nz] = slab.grid().dims();
        Ok(Blocks {
            data,
            leaps: None,
            x0,
            x1,
            ny: count(ny),
            nz: count(nz),
        })
    }

    /// Fill `out` (exactly [`extent`]'s length) with `slab`'s blocks.
    pub fn build<T: Sample>(slab: &Slab<'_, T>, out: &mut [Range]) -> Result<(), BlocksError> {
        let (x0, x1, needed) = extent(slab);
        if out.len() != needed {
            return Err(BlocksError {
                needed,
                given: out.len(),
            });
        }
        let [nx, ny, nz] = slab.grid().dims();
        let (by, bz) = (count(ny), count(nz));
        let stored = slab.stored();
        let mut i = 0;
        for bx in x0..x1 {
            let xs = bx * BLOCK..((bx + 1) * BLOCK).min(nx - 1) + 1;
            let known = stored.start <= xs.start && xs.end <= stored.end;
            for cz in 0..bz {
                for cy in 0..by {
                    let mut r = Range {
                        min: f32::INFINITY,
                        max: f32::NEG_INFINITY,
                    };
                    if known {
                        let ys = (cy * BLOCK) as usize..((cy + 1) * BLOCK).min(ny - 1) as usize + 1;
                        for x in xs.clone() {
                            for z in cz * BLOCK..((cz + 1) * BLOCK).min(nz - 1) + 1 {
                                // The block's nodes on one Y row lie side by side in storage.
                                match slab.row(x, z).and_then(|row| row.get(ys.clone())) {
                                    Some(values) => {
                                        for v in values {
                                            let v = v.to_f32();
                                            r.min = r.min.min(v);
                                            r.max = r.max.max(v);
                                        }
                                    }
                                    None => r = Range::UNKNOWN,
                                }
                            }
                        }
                    } else {
                        r = Range::UNKNOWN;
                    }
                    out[i] = r;
                    i += 1;
                }
            }
        }
        Ok(())
    }

    /// The global block coordinates of the cell or node a sample reads at `site`: what
    /// [`Blocks::at`] reads. Monotone along a ray, as the site's corners are.
    #[inline]
    pub fn block_of(&self, site: &Site) -> (u32, u32, u32) {
        // A voxel-model node on the grid's last face belongs to the last block (X needs no
        // clamp: a column past the slab's reads as unknown).
        let [x, y, z] = site.lo;
        (
            x / BLOCK,
            (y / BLOCK).min(self.ny - 1),
            (z / BLOCK).min(self.nz - 1),
        )
    }

    /// The index-space box of the blocks within chessboard distance `reach` of block
    /// `(bx, by, bz)` under `model`, for estimating where a ray leaves it (the estimate is
    /// always checked exactly).
    pub fn bounds(&self, block: (u32, u32, u32), reach: u32, model: Model) -> (Vec3, Vec3) {
        let shift = face_shift(model);
        let corner = |b: u32| b.saturating_sub(reach) as f32;
        let lo = Vec3::new(corner(block.0), corner(block.1), corner(block.2)) * BLOCK as f32
            - Vec3::splat(shift);
        let far = |b: u32| b.saturating_add(reach).saturating_add(1) as f32;
        let hi =
            Vec3::new(far(block.0), far(block.1), far(block.2)) * BLOCK as f32 - Vec3::splat(shift);
        (lo, hi)
    }

    /// The range of the block holding `site` (unknown outside the slab's columns).
    #[inline]
    pub fn at(&self, site: &Site) -> Range {
        // The cell (cell model) or node (voxel model) the point reads, then its block; a node
        // on a block's upper face belongs to both blocks, and both include it.
        self.range(self.block_of(site))
    }

    /// The range of block `(bx, by, bz)` (global block coordinates; unknown outside).
    #[inline]
    pub fn range(&self, block: (u32, u32, u32)) -> Range {
        self.index(block)
            .and_then(|i| self.data.get(i).copied())
            .unwrap_or(Range::UNKNOWN)
    }

    /// Where block `(bx, by, bz)` sits in the storage order (X columns slowest, then Z, then
    /// Y), or `None` outside the slab's columns.
    #[inline]
    fn index(&self, (bx, by, bz): (u32, u32, u32)) -> Option<usize> {
        if bx < self.x0 || bx >= self.x1 {
            return None;
        }
        Some(
            ((bx - self.x0) as usize * self.nz as usize + bz as usize) * self.ny as usize
                + by as usize,
        )
    }

    /// Every block's range, in storage order.
    pub fn ranges(&self) -> &'a [Range] {
        self.data
    }

    /// Blocks along X (the slab's columns), Y and Z.
    pub fn shape(&self) -> (u32, u32, u32) {
        (self.x1 - self.x0, self.ny, self.nz)
    }

    /// The same blocks, leaping by the distances in `leaps` ([`crate::leaps::build`] for the
    /// view being traced: a map built for another view may skip samples that show).
    pub fn with_leaps(self, leaps: &'a [u8]) -> Result<Blocks<'a>, BlocksError> {
        if leaps.len() != self.data.len() {
            return Err(BlocksError {
                needed: self.data.len(),
                given: leaps.len(),
            });
        }
        Ok(Blocks {
            leaps: Some(leaps),
            ..self
        })
    }

    /// Block `(bx, by, bz)`'s chessboard distance to the nearest block the view cannot skip
    /// (0 outside the slab's columns), or `None` without a leap map.
    #[inline]
    pub fn leap(&self, block: (u32, u32, u32)) -> Option<u8> {
        let leaps = self.leaps?;
        Some(
            self.index(block)
                .and_then(|i| leaps.get(i).copied())
                .unwrap_or(0),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::counters::Counters;
    use crate::field;
    use crate::grid::Grid;

    #[test]
    fn every_field_value_lies_in_its_block() {
        let grid = Grid::new([9, 7, 6], Vec3::ONE).unwrap();
        let data: [u8; 9 * 7 * 6] = core::array::from_fn(|i| (i * 37 % 251) as u8);
        let slab = Slab::whole(grid, &data).unwrap();
        let mut storage = [Range::UNKNOWN; 2 * 2 * 2];
        Blocks::build(&slab, &mut storage).unwrap();
        let blocks = Blocks::new(&slab, &storage).unwrap();
        let mut c = Counters::default();
        for i in 0..400 {
            let p = Vec3::new(
                (i % 17) as f32 * 0.5,
                (i % 13) as f32 * 0.47,
                (i % 11) as f32 * 0.46,
            );
            for model in [Model::Cell, Model::Voxel] {
                let v = field::value(&slab, model, p, &mut c);
                let r = blocks.at(&field::locate(&grid, model, p));
                assert!(r.min <= v && v <= r.max, "{p} {model:?}: {v} outside {r:?}");
            }
        }
    }

    #[test]
    fn blocks_beyond_the_stored_planes_are_unknown() {
        let grid = Grid::new([13, 2, 2], Vec3::ONE).unwrap();
        let data = [5u8; 4 * 4];
        // Owns planes 4..6 with one ghost plane: stores 3..7, so block 1 (planes 4..=8) is unknown.
        let slab = Slab::new(grid, 4..6, 1, &data).unwrap();
        let (x0, x1, n) = extent(&slab);
        assert_eq!((x0, x1), (0, 2));
        let mut storage = [Range::UNKNOWN; 2];
        assert_eq!(n, 2);
        Blocks::build(&slab, &mut storage).unwrap();
        let blocks = Blocks::new(&slab, &storage).unwrap();
        assert_eq!(
            blocks.at(&field::locate(&grid, Model::Cell, Vec3::new(5.0, 0.0, 0.0))),
            Range::UNKNOWN
        );
        assert!(Blocks::build(&slab, &mut [Range::UNKNOWN; 3]).is_err());
    }
}

//! Cell ranges: for every min/max block of a slab, the least and greatest of each of its 4³
//! cells' eight nodes, as stored. They depend on the slab's samples alone, so a host builds
//! them once per volume and slab, and a view's cell masks are a classification of them
//! ([`crate::skip::cells::classify_columns`]) rather than another pass over the volume.
//!
//! Invariants: a present cell's range holds every value of the trilinear field inside it
//! (each lies between the least and greatest of its corners; an axis of one node pads its
//! far corner with its near one, as [`crate::volume::field::locate`] does); a cell with a
//! corner on a plane the slab does not store, and every cell of a block a stored row of which
//! is missing, is `unknown`: no range is claimed for it. Cells past the grid's last node
//! (in a block at its end) are not present; no sample lies in them. A build split by block
//! columns gives the same bits as a whole one.

use crate::skip::blocks::{Blocks, BlocksError, CellMask, ALL, BLOCK, PER_BLOCK};
use crate::volume::sample::Sample;
use crate::volume::slab::Slab;

const EDGE: usize = BLOCK as usize;
/// Nodes per block edge: the cells' corners.
const NODES: usize = EDGE + 1;
/// The bits of a block's cells at X offset 0, every Y and Z: every fourth bit.
const FIRST_X: CellMask = 0x1111_1111_1111_1111;

/// One block's cells: their ranges, by cell bit (`x + 4·(y + 4·z)` within the block, as
/// [`crate::skip::cells::bit`]), and which of them the ranges speak for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BlockCells<T> {
    /// Each cell's least node.
    pub lo: [T; PER_BLOCK],
    /// Each cell's greatest node.
    pub hi: [T; PER_BLOCK],
    /// Cells inside the grid.
    pub present: CellMask,
    /// Cells whose range is not known: a verdict on them must keep them.
    pub unknown: CellMask,
}

impl<T: Sample> Default for BlockCells<T> {
    /// A block of which nothing is known.
    fn default() -> Self {
        BlockCells {
            lo: [T::default(); PER_BLOCK],
            hi: [T::default(); PER_BLOCK],
            present: ALL,
            unknown: ALL,
        }
    }
}

/// Fill `out` with the cells of `slab`'s block columns `columns` (counted from its first;
/// `blocks` built from `slab`, one entry per block in its order).
pub fn build_columns<T: Sample>(
    slab: &Slab<'_, T>,
    blocks: &Blocks<'_>,
    columns: core::ops::Range<u32>,
    out: &mut [BlockCells<T>],
) -> Result<(), BlocksError> {
    let ranges = blocks.columns(columns.clone())?;
    BlocksError::check_storage(ranges.len(), out.len())?;
    let (_, ny, nz) = blocks.shape();
    let x0 = blocks.first_column() + columns.start;
    // A grid has a block along every axis; `max` keeps a chunk size of zero from panicking.
    let mut out = out.chunks_mut((ny as usize).max(1));
    for bx in x0..x0 + columns.len() as u32 {
        for bz in 0..nz {
            let Some(column) = out.next() else {
                return Ok(());
            };
            if !of_column(slab, bx, bz, column) {
                for (by, cells) in (0..).zip(column.iter_mut()) {
                    *cells = of_block(slab, [bx, by, bz]).unwrap_or_default();
                }
            }
        }
    }
    Ok(())
}

/// Blocks along Y that [`of_column`] takes at a time: the nodes it keeps on the stack.
const CHUNK_BLOCKS: usize = 16;
/// Nodes along Y of a chunk of blocks: their cells' corners.
const CHUNK_NODES: usize = CHUNK_BLOCKS * EDGE + 1;

/// The cells of the column of blocks `(bx, bz)` into `out` (its blocks in Y order), in the
/// same bits as [`of_block`] gives each: the same corners, picked in the same order (along
/// X, then Z, then Y). A line of cells along Y at a time, so that the picks run over long
/// rows of nodes. `false`, with `out` untouched, where a plane of the column's nodes is not
/// stored or a row of them is not whole: [`of_block`] tells those cells apart.
fn of_column<T: Sample>(slab: &Slab<'_, T>, bx: u32, bz: u32, out: &mut [BlockCells<T>]) -> bool {
    let dims = slab.grid().dims();
    let ny = dims[1] as usize;
    // The column's first node along X and Z and how many (at most five), as `Blocks` counts
    // them; none for a block past the grid, which `Blocks` never holds.
    let span = |b: u32, n: u32| {
        let nodes = crate::skip::blocks::nodes(b, n);
        (nodes.start, nodes.len() as u32)
    };
    let ((x0, nx), (z0, nz)) = (span(bx, dims[0]), span(bz, dims[2]));
    let stored = slab.stored();
    if nx == 0 || nz == 0 || !(stored.contains(&x0) && stored.contains(&(x0 + nx - 1))) {
        return false;
    }
    // Each row of the column's nodes, clamped to its last as `of_block` pads an axis.
    let mut rows: [[&[T]; NODES]; NODES] = [[&[]; NODES]; NODES];
    for (x, plane) in rows.iter_mut().enumerate() {
        for (z, row) in plane.iter_mut().enumerate() {
            let at = (x0 + (x as u32).min(nx - 1), z0 + (z as u32).min(nz - 1));
            match slab.row(at.0, at.1) {
                Some(whole) if whole.len() == ny => *row = whole,
                _ => return false,
            }
        }
    }
    let cells = [nx, nz].map(|n| (n.saturating_sub(1).max(1)) as usize);
    for (by, block) in (0u32..).zip(out.iter_mut()) {
        let (_, n) = span(by, dims[1]);
        let cells_y = (n.saturating_sub(1).max(1)) as usize;
        let present = match cells == [EDGE; 2] && cells_y == EDGE {
            true => ALL,
            false => {
                let mut present: CellMask = 0;
                for x in 0..cells[0] {
                    for z in 0..cells[1] {
                        for y in 0..cells_y {
                            present |= 1 << (x + EDGE * (y + EDGE * z));
                        }
                    }
                }
                present
            }
        };
        *block = BlockCells {
            present,
            unknown: 0,
            ..BlockCells::default()
        };
    }
    for x in 0..cells[0] {
        for z in 0..cells[1] {
            let corners = [
                rows[x][z],
                rows[x + 1][z],
                rows[x][z + 1],
                rows[x + 1][z + 1],
            ];
            for (chunk, blocks) in out.chunks_mut(CHUNK_BLOCKS).enumerate() {
                let y0 = chunk * CHUNK_BLOCKS * EDGE;
                line(&corners, y0, blocks, x + EDGE * EDGE * z, dims[1]);
            }
        }
    }
    true
}

/// The cells at X and Z offset `at` (`x + 16·z`) of `blocks` (their first node along Y is
/// `y0`, of a grid `ny` nodes long), from the four rows of their corners along X and Z.
#[inline(always)]
fn line<T: Sample>(rows: &[&[T]; 4], y0: usize, blocks: &mut [BlockCells<T>], at: usize, ny: u32) {
    let ny = ny as usize;
    // The nodes this chunk's cells read: through its last block's last node, or the grid's.
    let end = (y0 + blocks.len() * EDGE + 1).min(ny);
    let mut lo = [T::default(); CHUNK_NODES];
    let mut hi = [T::default(); CHUNK_NODES];
    let [a, b, c, d] = rows.map(|r| r.get(y0..end).unwrap_or_default());
    let nodes = lo.iter_mut().zip(hi.iter_mut());
    for ((l, h), (((&a, &b), &c), &d)) in nodes.zip(a.iter().zip(b).zip(c).zip(d)) {
        *l = a.lesser(b).lesser(c.lesser(d));
        *h = a.greater(b).greater(c.greater(d));
    }
    // At least one node: a chunk's first lies in the grid (`saturating` where it would not).
    let last = end.saturating_sub(y0 + 1);
    for (k, block) in blocks.iter_mut().enumerate() {
        // A block whose five nodes along Y the chunk holds (all but a grid's last, short
        // one): its cells' corners without a clamp.
        if let (Some(lo), Some(hi)) = (
            lo.get(k * EDGE..=k * EDGE + EDGE),
            hi.get(k * EDGE..=k * EDGE + EDGE),
        ) {
            if k * EDGE + EDGE <= last && block.present == ALL {
                for y in 0..EDGE {
                    block.lo[at + EDGE * y] = lo[y].lesser(lo[y + 1]);
                    block.hi[at + EDGE * y] = hi[y].greater(hi[y + 1]);
                }
                continue;
            }
        }
        for y in 0..EDGE {
            if block.present >> (at + EDGE * y) & 1 == 0 {
                continue;
            }
            // A cell's two corner nodes along Y, the grid's last padding a short block.
            let (p, q) = ((k * EDGE + y).min(last), (k * EDGE + y + 1).min(last));
            block.lo[at + EDGE * y] = lo[p].lesser(lo[q]);
            block.hi[at + EDGE * y] = hi[p].greater(hi[q]);
        }
    }
}

/// The cells of block `b`; `None` when a row of its nodes on a stored plane is not there.
pub(crate) fn of_block<T: Sample>(slab: &Slab<'_, T>, b: [u32; 3]) -> Option<BlockCells<T>> {
    let dims = slab.grid().dims();
    // The block's nodes along each axis, as `Blocks` counts them: its cells' corners.
    let first = b.map(|b| b * BLOCK);
    let len: [usize; 3] = core::array::from_fn(|a| {
        (((b[a] + 1) * BLOCK).min(dims[a].saturating_sub(1)) + 1 - first[a]) as usize
    });
    // The block's nodes once (at most 5³), an axis of fewer nodes padded with its last. Kept
    // as stored: their order is their values' (`Sample::lesser`).
    let mut nodes = [[[T::default(); NODES]; NODES]; NODES];
    let stored = slab.stored();
    let mut unknown: CellMask = 0;
    for (x, plane) in nodes.iter_mut().enumerate() {
        let at = first[0] + x.min(len[0] - 1) as u32;
        if !stored.contains(&at) {
            // The cells on either side of this plane of nodes, every Y and Z.
            for cell in [x.checked_sub(1), Some(x)].into_iter().flatten() {
                unknown |= FIRST_X << cell.min(EDGE - 1);
            }
            continue;
        }
        for (z, line) in plane.iter_mut().enumerate() {
            let (x, z) = (x.min(len[0] - 1) as u32, z.min(len[2] - 1) as u32);
            let row = slab.row(first[0] + x, first[2] + z)?;
            let start = first[1] as usize;
            let values = row.get(start..start + len[1])?;
            match <&[T; NODES]>::try_from(values) {
                // A whole row of the block's nodes: one copy.
                Ok(whole) => *line = *whole,
                Err(_) => {
                    for (y, node) in line.iter_mut().enumerate() {
                        *node = values.get(y.min(len[1] - 1)).copied().unwrap_or_default();
                    }
                }
            }
        }
    }
    // Each cell's extremes in three passes over pairs of neighbours (along x, z, then y)
    // instead of fourteen comparisons a cell.
    let hi = corner_extremes(&nodes, T::greater);
    let lo = corner_extremes(&nodes, T::lesser);
    let cells = len.map(|n| n.saturating_sub(1).max(1));
    let mut block = BlockCells {
        present: 0,
        unknown,
        ..BlockCells::default()
    };
    if cells == [EDGE; 3] {
        // Every cell present (nearly every block of a large volume): bounds the compiler
        // knows, and no mask built bit by bit.
        block.present = ALL;
        for x in 0..EDGE {
            for z in 0..EDGE {
                for y in 0..EDGE {
                    let i = x + EDGE * (y + EDGE * z);
                    block.lo[i] = lo[x][z][y].lesser(lo[x][z][y + 1]);
                    block.hi[i] = hi[x][z][y].greater(hi[x][z][y + 1]);
                }
            }
        }
        return Some(block);
    }
    for x in 0..cells[0] {
        for z in 0..cells[2] {
            for y in 0..cells[1] {
                let i = x + EDGE * (y + EDGE * z);
                block.lo[i] = lo[x][z][y].lesser(lo[x][z][y + 1]);
                block.hi[i] = hi[x][z][y].greater(hi[x][z][y + 1]);
                block.present |= 1 << i;
            }
        }
    }
    Some(block)
}

/// The nodes of a block, each replaced (over the first `EDGE` along x and z) by `pick` of it
/// and its neighbours one over along x and then z: what is left for the y pass of a cell.
#[inline(always)]
fn corner_extremes<T: Sample>(
    nodes: &[[[T; NODES]; NODES]; NODES],
    pick: fn(T, T) -> T,
) -> [[[T; NODES]; NODES]; NODES] {
    let mut out = *nodes;
    for x in 0..EDGE {
        for z in 0..NODES {
            for y in 0..NODES {
                out[x][z][y] = pick(out[x][z][y], nodes[x + 1][z][y]);
            }
        }
    }
    for plane in out.iter_mut().take(EDGE) {
        for z in 0..EDGE {
            // Row z from row z + 1, which this pass has not changed yet.
            let (near, far) = plane.split_at_mut(z + 1);
            for (node, next) in near[z].iter_mut().zip(&far[0]) {
                *node = pick(*node, *next);
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::grid::Grid;
    use glam::Vec3;

    /// The build by columns of blocks gives each block what [`of_block`] gives it, in every
    /// bit: whole slabs and partial ones (whose columns at the slab's ends touch planes not
    /// stored, which [`of_block`] takes), grids whose blocks end short along each axis, one
    /// node thick along Y, and longer than a chunk of blocks along Y; bytes and floats
    /// (signed zeros and NaN among them, where the order of the picks shows).
    #[test]
    fn the_build_by_columns_gives_each_block_what_of_block_gives_it() {
        use crate::skip::blocks::{Blocks, Range};
        fn check<T: Sample>(dims: [u32; 3], data: &[T], owned: core::ops::Range<u32>, ghost: u32) {
            let grid = Grid::new(dims, Vec3::ONE).unwrap();
            let stored = crate::volume::slab::stored_planes(&grid, owned.clone(), ghost);
            let plane = (dims[1] * dims[2]) as usize;
            let held = &data[stored.start as usize * plane..stored.end as usize * plane];
            let slab = Slab::new(grid, owned, ghost, held).unwrap();
            let (_, _, len) = crate::skip::minmax::extent(&slab);
            let mut ranges = [Range::UNKNOWN; 64];
            crate::skip::minmax::build(&slab, &mut ranges[..len]).unwrap();
            let blocks = Blocks::new(slab.grid(), slab.stored(), &ranges[..len]).unwrap();
            let (cols, ny, nz) = blocks.shape();
            let mut built = [BlockCells::<T>::default(); 64];
            build_columns(&slab, &blocks, 0..cols, &mut built[..len]).unwrap();
            let mut i = 0;
            let x0 = blocks.first_column();
            for bx in x0..x0 + cols {
                for bz in 0..nz {
                    for by in 0..ny {
                        let want = of_block(&slab, [bx, by, bz]).unwrap_or_default();
                        let bits = |c: &BlockCells<T>| {
                            let f = |v: &[T; PER_BLOCK]| v.map(|t| t.to_f32().to_bits());
                            (f(&c.lo), f(&c.hi), c.present, c.unknown)
                        };
                        assert_eq!(
                            bits(&built[i]),
                            bits(&want),
                            "{dims:?} block {bx} {by} {bz}"
                        );
                        i += 1;
                    }
                }
            }
        }
        let mut next = crate::testing::xorshift(0xc01_0b10c);
        for dims in [
            [9u32, 10, 11],
            [13, 1, 6],
            [6, 70, 5],
            [17, 17, 17],
            [5, 2, 9],
        ] {
            let n = dims.iter().product::<u32>() as usize;
            let (mut bytes, mut floats) = ([0u8; 17 * 17 * 17], [0f32; 17 * 17 * 17]);
            let specials = [0.0, -0.0, f32::NAN, 1.5, -2.0];
            for (b, f) in bytes.iter_mut().zip(floats.iter_mut()) {
                *b = next() as u8;
                *f = specials[next() as usize % specials.len()];
            }
            for (owned, ghost) in [(0..dims[0], 0), (2..5, 1), (0..3, 1), (3..dims[0], 0)] {
                check(dims, &bytes[..n], owned.clone(), ghost);
                check(dims, &floats[..n], owned, ghost);
            }
        }
    }

    /// Each block's cells against their eight corners read one by one: present exactly where
    /// the cell lies in the grid, its range the least and greatest corner, the rest as a
    /// block of which nothing is known says. Uneven dimensions, so that blocks at the grid's
    /// end are partial along each axis in turn, and a grid of whole blocks.
    #[test]
    fn every_cell_s_range_is_the_least_and_greatest_of_its_corners() {
        let mut next = crate::testing::xorshift(0x5eed_ce11);
        for dims in [[9u32, 10, 11], [13, 8, 6], [17, 17, 17], [5, 2, 9]] {
            let n = dims.iter().product::<u32>() as usize;
            let mut all = [0u8; 17 * 17 * 17];
            all.iter_mut().for_each(|v| *v = next() as u8);
            let data = &all[..n];
            let grid = Grid::new(dims, Vec3::ONE).unwrap();
            let slab = Slab::whole(grid, data).unwrap();
            let node = |x: u32, y: u32, z: u32| {
                let [x, y, z] = [x, y, z].map(|v| v as usize);
                data[(x * dims[2] as usize + z) * dims[1] as usize + y]
            };
            let blocks = dims.map(|d| d.saturating_sub(1).max(1).div_ceil(BLOCK));
            for bx in 0..blocks[0] {
                for by in 0..blocks[1] {
                    for bz in 0..blocks[2] {
                        let got = of_block(&slab, [bx, by, bz]).unwrap();
                        assert_eq!(got.unknown, 0);
                        for i in 0..PER_BLOCK as u32 {
                            let c = [i % BLOCK, i / BLOCK % BLOCK, i / (BLOCK * BLOCK)];
                            let lo = [bx, by, bz].map(|b| b * BLOCK);
                            let at: [u32; 3] = core::array::from_fn(|a| lo[a] + c[a]);
                            let inside = (0..3).all(|a| at[a] < dims[a].saturating_sub(1).max(1));
                            assert_eq!(got.present >> i & 1 == 1, inside, "{dims:?} {at:?}");
                            let (mut want_lo, mut want_hi) = (u8::MAX, u8::MIN);
                            for d in 0..8u32 {
                                let p: [u32; 3] = core::array::from_fn(|a| {
                                    (at[a] + (d >> a & 1)).min(dims[a] - 1)
                                });
                                want_lo = want_lo.min(node(p[0], p[1], p[2]));
                                want_hi = want_hi.max(node(p[0], p[1], p[2]));
                            }
                            if !inside {
                                (want_lo, want_hi) = (0, 0);
                            }
                            let i = i as usize;
                            assert_eq!(
                                (got.lo[i], got.hi[i]),
                                (want_lo, want_hi),
                                "{dims:?} {at:?}"
                            );
                        }
                    }
                }
            }
        }
    }
}

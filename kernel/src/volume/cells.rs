//! Whole cells of plane-major storage (a slab's samples, or its node field's lanes) as the
//! interior runs of a composited ray read them: a cell's eight items at one offset and three
//! strides fixed for the storage, under one range check.
//!
//! Invariant: a box of cells is held ([`Cells::holding`]) only where each of its cells has
//! `lo + 1` inside the grid on every axis and both X planes in the storage; there
//! [`HeldCells::at`] gives exactly the items [`crate::volume::slab::Slab::cell`] (or
//! [`crate::volume::lanes::Nodes::cell`]) gives for the cell from `lo` to `lo + 1` (tested).
//! Nothing it is asked panics.

use core::ops::Range;

/// Plane-major storage of some of a grid's X planes, rows along Z, nodes along Y.
#[derive(Clone, Copy, Debug)]
pub struct Cells<'a, U> {
    data: &'a [U],
    first: u32,
    end: u32,
    /// Items from one row (Z) to the next, and from one plane (X) to the next.
    row: usize,
    plane: usize,
    /// Whole cells along Y and Z: one fewer than the nodes.
    rows_of_cells: u32,
    layers_of_cells: u32,
}

impl<'a, U: Copy> Cells<'a, U> {
    /// The planes `planes` of a grid of `ny × nz` nodes a plane, stored in `data` (plane-major,
    /// as a slab stores them); the caller has checked `data` holds them all.
    pub(crate) fn new(data: &'a [U], planes: Range<u32>, ny: u32, nz: u32) -> Self {
        let row = ny as usize;
        // A grid one node thin along Y or Z has no whole cell.
        let end = if ny < 2 || nz < 2 {
            planes.start
        } else {
            planes.end
        };
        Cells {
            data,
            first: planes.start,
            end,
            row,
            plane: row * nz as usize,
            rows_of_cells: ny.saturating_sub(1),
            layers_of_cells: nz.saturating_sub(1),
        }
    }

    /// Bytes of the storage.
    pub fn bytes(&self) -> usize {
        size_of_val(self.data)
    }

    /// A hint that the cell from `lo` is read soon (`prefetch_rows` at its place).
    #[inline(always)]
    pub fn prefetch(&self, [x, y, z]: [u32; 3]) {
        let base = (x.wrapping_sub(self.first) as usize)
            .wrapping_mul(self.plane)
            .wrapping_add((z as usize).wrapping_mul(self.row))
            .wrapping_add(y as usize);
        prefetch_rows(self.data, base, self.row, self.plane);
    }

    /// The low X planes of the whole cells stored: both their planes are.
    pub fn cell_planes(&self) -> Range<u32> {
        self.first..self.end.saturating_sub(1).max(self.first)
    }

    /// The cells as [`HeldCells`] for the cells whose low corner has X in `x`, Y below
    /// `y_end` and Z below `z_end`, where every one of them is stored whole; `None` where
    /// some is not.
    pub fn holding(&self, x: Range<u32>, y_end: u32, z_end: u32) -> Option<HeldCells<'a, U>> {
        let held = x.start >= self.first
            && x.end <= self.cell_planes().end
            && y_end <= self.rows_of_cells
            && z_end <= self.layers_of_cells
            && self.end > self.first;
        // Strides of 32 bits: their sums cannot overflow, so the compiler sees every corner's
        // offset bounded by the far corner's and checks that one alone.
        let (row, plane) = (
            u32::try_from(self.row).ok()?,
            u32::try_from(self.plane).ok()?,
        );
        held.then_some(HeldCells {
            cells: *self,
            row,
            plane,
        })
    }
}

/// Storage known to hold every cell of a box whole: a cell read there with none of the
/// per-axis tests a loop through the box would repeat on every sample.
#[derive(Clone, Copy, Debug)]
pub struct HeldCells<'a, U> {
    cells: Cells<'a, U>,
    /// The storage's strides, known to fit 32 bits.
    row: u32,
    plane: u32,
}

impl<U: Copy> HeldCells<'_, U> {
    /// The eight items of the cell of the box ([`Cells::holding`]) whose low corner is `lo`,
    /// ordered by corner bits `z y x` from 000 to 111. A cell outside the box gives some
    /// cell's items or `None`, never a panic: the box is the caller's to keep.
    #[inline(always)]
    pub fn at(&self, lo: [u32; 3]) -> Option<[U; 8]> {
        self.at_index(self.index(lo))
    }

    /// Where the node `lo` is in the storage: what [`HeldCells::at_index`] reads the cell
    /// whose low corner it is from, and what a structure laid out as the storage (as
    /// [`crate::skip::node_leaps::NodeLeaps`]) reads the cell's entry at, one offset away.
    #[inline(always)]
    pub fn index(&self, [x, y, z]: [u32; 3]) -> usize {
        (x.wrapping_sub(self.cells.first) as usize)
            .wrapping_mul(self.plane as usize)
            .wrapping_add((z as usize).wrapping_mul(self.row as usize))
            .wrapping_add(y as usize)
    }

    /// How far apart in the storage two nodes `[dx, dy, dz]` apart are (wrapping: added to a
    /// place, a negative offset moves back).
    #[inline]
    pub fn offset(&self, [dx, dy, dz]: [i64; 3]) -> usize {
        let (row, plane) = (i64::from(self.row), i64::from(self.plane));
        dx.wrapping_mul(plane)
            .wrapping_add(dz.wrapping_mul(row))
            .wrapping_add(dy) as usize
    }

    /// A hint that the cell whose low corner is at `base` ([`HeldCells::index`], any place)
    /// is read soon (`prefetch_rows`), by the strides this view holds (the run's loop
    /// keeps them in registers).
    #[inline(always)]
    pub fn prefetch(&self, base: usize) {
        prefetch_rows(
            self.cells.data,
            base,
            self.row as usize,
            self.plane as usize,
        );
    }

    /// The storage's first X plane, and the items from one plane to the next.
    pub fn planes(&self) -> (u32, usize) {
        (self.cells.first, self.plane as usize)
    }

    /// [`HeldCells::at`] of the cell whose low corner is at `base` ([`HeldCells::index`]).
    #[inline(always)]
    pub fn at_index(&self, base: usize) -> Option<[U; 8]> {
        let c = &self.cells;
        let (row, plane) = (self.row as usize, self.plane as usize);
        let far = plane + row + 1;
        let cell = c.data.get(base..)?.get(..=far)?;
        Some([
            cell[0],
            cell[plane],
            cell[1],
            cell[plane + 1],
            cell[row],
            cell[plane + row],
            cell[row + 1],
            cell[far],
        ])
    }
}

/// A hint that the cell whose low corner is at place `base` of plane-major storage `data`
/// (strides `row` and `plane`) is read soon: the four rows of its eight items, from where
/// the cell starts in each (a row's two items are mostly in one cache line). `base` may be
/// any place, in the storage or not; no value changes ([`voxcube_simd::prefetch`]).
#[inline(always)]
fn prefetch_rows<U>(data: &[U], base: usize, row: usize, plane: usize) {
    for offset in [0, row, plane, plane + row] {
        voxcube_simd::prefetch(data, base.wrapping_add(offset));
    }
}

/// The eight items of a cell in plane-major storage `data`, its low corner at `base` and its
/// high corner `steps` items further along X, Y and Z (each zero or one node's stride),
/// ordered by corner bits `z y x` from 000 to 111; `None` where any lies past `data`.
#[inline(always)]
pub(crate) fn corners<U: Copy>(
    data: &[U],
    base: usize,
    [sx, sy, sz]: [usize; 3],
) -> Option<[U; 8]> {
    // One range check for the cell: the far corner's offset, summed without overflow, bounds
    // every other corner's, which the compiler then sees need no check of their own.
    let far = sx.checked_add(sy)?.checked_add(sz)?;
    let cell = data.get(base..)?.get(..=far)?;
    Some([
        cell[0],
        cell[sx],
        cell[sy],
        cell[sx + sy],
        cell[sz],
        cell[sx + sz],
        cell[sy + sz],
        cell[far],
    ])
}

#[cfg(test)]
mod tests {
    use crate::volume::grid::Grid;
    use crate::volume::lanes::{Lanes, Nodes};
    use crate::volume::slab::Slab;
    use glam::Vec3;

    #[test]
    fn a_held_cell_reads_what_the_slab_and_the_node_field_read() {
        let grid = Grid::new([7, 5, 4], Vec3::ONE).unwrap();
        let data: [u8; 5 * 20] = core::array::from_fn(|i| (i * 37 % 251) as u8);
        // Planes 2..5 owned, 1..6 stored.
        let slab = Slab::new(grid, 2..5, 1, &data).unwrap();
        let lanes: [[i16; 4]; 3 * 20] = core::array::from_fn(|i| [i as i16, -(i as i16), 3, 4]);
        let nodes = Nodes::new(&grid, 2..5, &lanes).unwrap();
        let (cells, node_cells) = (slab.cells(), nodes.cells());
        assert_eq!(cells.cell_planes(), 1..5);
        assert_eq!(node_cells.cell_planes(), 2..4);
        let held = cells.holding(1..5, 4, 3).unwrap();
        let held_nodes = node_cells.holding(2..4, 4, 3).unwrap();
        let up = |c: u32| (c, c + 1);
        let mut read = 0;
        for x in 1..5 {
            for y in 0..4 {
                for z in 0..3 {
                    let expected = slab.cell(up(x), up(y), up(z));
                    assert!(expected.is_some());
                    assert_eq!(held.at([x, y, z]), expected, "{x} {y} {z}");
                    read += 1;
                    if (2..4).contains(&x) {
                        let expected = nodes.cell([x, y, z], [x + 1, y + 1, z + 1]);
                        let lanes = held_nodes.at([x, y, z]).map(|c| c.map(Lanes::unpack));
                        assert!(expected.is_some());
                        assert_eq!(lanes, expected, "nodes {x} {y} {z}");
                    }
                }
            }
        }
        assert_eq!(read, 4 * 4 * 3);
        // Far outside the box, never a panic.
        for lo in [[u32::MAX; 3], [u32::MAX, 0, 0], [0, u32::MAX, 0], [6, 4, 3]] {
            let _ = held.at(lo);
        }
    }

    #[test]
    fn an_offset_between_nodes_is_the_difference_of_their_places() {
        let grid = Grid::new([9, 7, 6], Vec3::ONE).unwrap();
        let data = [0u8; 7 * 42];
        let slab = Slab::new(grid, 2..7, 1, &data).unwrap();
        let held = slab.cells().holding(1..7, 6, 5).unwrap();
        let mut compared = 0;
        for lo in [[1, 0, 0], [3, 2, 1], [6, 5, 4], [4, 6, 0]] {
            for d in [
                [0, 0, 0],
                [1, 0, 0],
                [0, 1, 0],
                [0, 0, 1],
                [-1, 2, -1],
                [2, -3, 3],
            ] {
                let to = [0, 1, 2].map(|a| i64::from(lo[a]) + d[a]);
                if to.iter().any(|&c| c < 0) {
                    continue;
                }
                let to = to.map(|c| c as u32);
                let moved = held.index(lo).wrapping_add(held.offset(d));
                assert_eq!(moved, held.index(to), "{lo:?} + {d:?}");
                compared += 1;
            }
        }
        assert!(compared >= 18, "{compared} offsets compared");
    }

    #[test]
    fn a_box_with_a_cell_not_stored_whole_is_not_held() {
        let grid = Grid::new([7, 5, 4], Vec3::ONE).unwrap();
        let data = [0u8; 5 * 20];
        let cells = Slab::new(grid, 2..5, 1, &data).unwrap().cells();
        assert!(cells.holding(1..5, 4, 3).is_some());
        // One plane further, one row or one layer more: a corner past the storage or the grid.
        assert!(cells.holding(0..5, 4, 3).is_none());
        assert!(cells.holding(1..6, 4, 3).is_none());
        assert!(cells.holding(1..5, 5, 3).is_none());
        assert!(cells.holding(1..5, 4, 4).is_none());
        // A grid one node thin holds no cell.
        let thin = Grid::new([7, 1, 4], Vec3::ONE).unwrap();
        let data = [0u8; 5 * 4];
        let cells = Slab::new(thin, 2..5, 1, &data).unwrap().cells();
        assert!(cells.holding(1..5, 0, 3).is_none());
    }
}

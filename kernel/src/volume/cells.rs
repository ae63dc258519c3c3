//! Whole cells of plane-major storage (a slab's samples, or its node field's lanes) as the
//! interior runs of a composited ray read them: a cell's eight items at one offset and three
//! strides fixed for the storage, under one range check.
//!
//! Invariant: for a cell whose low corner `lo` has `lo + 1` inside the grid on every axis and
//! both X planes in the storage, [`Cells::at`] gives exactly the items
//! [`crate::volume::slab::Slab::cell`] (or [`crate::volume::lanes::Nodes::cell`]) gives for
//! the cell from `lo` to `lo + 1` (tested); any other `lo` gives `None`, never a panic.

use crate::volume::lanes::corners;
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
    /// The greatest low corner along Y and Z of a whole cell.
    last_y: u32,
    last_z: u32,
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
            last_y: ny.saturating_sub(2),
            last_z: nz.saturating_sub(2),
        }
    }

    /// The low X planes of the whole cells stored: both their planes are.
    pub fn cell_planes(&self) -> Range<u32> {
        self.first..self.end.saturating_sub(1).max(self.first)
    }

    /// The eight items of the cell whose low corner is `lo`, ordered by corner bits `z y x`
    /// from 000 to 111; `None` unless the whole cell is stored.
    #[inline(always)]
    pub fn at(&self, [x, y, z]: [u32; 3]) -> Option<[U; 8]> {
        // A cell past the grid's last along Y or Z would read the next row's; past the last
        // stored plane, the slice check refuses its far corner.
        if y > self.last_y || z > self.last_z || x >= self.end {
            return None;
        }
        let x = x.checked_sub(self.first)?;
        let base = x as usize * self.plane + z as usize * self.row + y as usize;
        corners(self.data, base, [self.plane, 1, self.row])
    }
}

#[cfg(test)]
mod tests {
    use crate::volume::grid::Grid;
    use crate::volume::lanes::{Lanes, Nodes};
    use crate::volume::slab::Slab;
    use glam::Vec3;

    #[test]
    fn a_whole_cell_reads_what_the_slab_and_the_node_field_read_and_no_other_does() {
        let grid = Grid::new([7, 5, 4], Vec3::ONE).unwrap();
        let data: [u8; 5 * 20] = core::array::from_fn(|i| (i * 37 % 251) as u8);
        // Planes 2..5 owned, 1..6 stored.
        let slab = Slab::new(grid, 2..5, 1, &data).unwrap();
        let lanes: [[i16; 4]; 3 * 20] = core::array::from_fn(|i| [i as i16, -(i as i16), 3, 4]);
        let nodes = Nodes::new(&grid, 2..5, &lanes).unwrap();
        let (cells, node_cells) = (slab.cells(), nodes.cells());
        assert_eq!(cells.cell_planes(), 1..5);
        assert_eq!(node_cells.cell_planes(), 2..4);
        let mut whole = 0;
        for x in 0..9 {
            for y in 0..7 {
                for z in 0..6 {
                    let up = |c: u32| (c, c + 1);
                    let fits = y + 1 < 5 && z + 1 < 4;
                    let expected = slab.cell(up(x), up(y), up(z)).filter(|_| fits);
                    assert_eq!(cells.at([x, y, z]), expected, "{x} {y} {z}");
                    whole += usize::from(expected.is_some());
                    let expected = nodes
                        .cell([x, y, z], [x + 1, y + 1, z + 1])
                        .filter(|_| fits);
                    let read = node_cells.at([x, y, z]).map(|c| c.map(Lanes::unpack));
                    assert_eq!(read, expected, "nodes {x} {y} {z}");
                }
            }
        }
        assert_eq!(whole, 4 * 4 * 3);
        // Far past the grid, never a panic.
        assert_eq!(cells.at([u32::MAX, u32::MAX, u32::MAX]), None);
        assert_eq!(cells.at([u32::MAX, 0, 0]), None);
    }
}

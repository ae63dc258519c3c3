//! How the fast tier's node field is stored: each grid node's four lanes (its value and its
//! central differences along X, Y and Z, [`crate::volume::nodes`]) in a type that holds them
//! exactly for its sample kind, and a field's planes as a slab reads them.
//!
//! Invariant: [`Lanes::unpack`] gives back in every bit the lanes [`Lanes::pack`] took, for
//! every node of the sample kind that stores them so; a field is read only inside its planes.

use crate::volume::cells::{corners, Cells};
use crate::volume::grid::Grid;
use core::fmt;
use core::ops::Range;
use glam::Vec4;

/// How a node's four lanes (value, then the differences along X, Y, Z) are stored: plain
/// bytes (`Pod`), so that a host may hold a field in whatever memory serves it best.
pub trait Lanes: Copy + Default + fmt::Debug + Send + Sync + bytemuck::Pod + 'static {
    /// The lanes stored: exact for every node of the sample kind that stores them this way.
    fn pack(lanes: Vec4) -> Self;
    /// The lanes as [`Lanes::pack`] took them.
    fn unpack(self) -> Vec4;
}

impl Lanes for [i16; 4] {
    #[inline(always)]
    fn pack(lanes: Vec4) -> Self {
        // A byte node's lanes are whole numbers in [-255, 255]: added to 1.5·2^23 each is
        // exact, and the sum's low mantissa bits hold it in two's complement. `as` would
        // check every lane for NaN and overflow, which none needs.
        const SHIFT: f32 = 12_582_912.0;
        let sums = (lanes + Vec4::splat(SHIFT)).to_array();
        sums.map(|sum| sum.to_bits().wrapping_sub(SHIFT.to_bits()) as i16)
    }
    #[inline(always)]
    fn unpack(self) -> Vec4 {
        let [v, dx, dy, dz] = self;
        Vec4::new(f32::from(v), f32::from(dx), f32::from(dy), f32::from(dz))
    }
}

impl Lanes for [f32; 4] {
    #[inline(always)]
    fn pack(lanes: Vec4) -> Self {
        lanes.to_array()
    }
    #[inline(always)]
    fn unpack(self) -> Vec4 {
        Vec4::from_array(self)
    }
}

/// Why a node field cannot be attached to a slab or built into storage.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum NodesError {
    /// The storage does not hold exactly the field's planes.
    StorageLength {
        /// Nodes the planes need.
        expected: usize,
        /// Nodes given.
        actual: usize,
    },
    /// The slab does not store every plane the field's nodes read.
    NotStored {
        /// The planes the nodes read.
        read: Range<u32>,
        /// The planes the slab stores.
        stored: Range<u32>,
    },
}

impl fmt::Display for NodesError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            NodesError::StorageLength { expected, actual } => write!(
                f,
                "node field storage holds {actual} nodes, its planes need {expected}"
            ),
            NodesError::NotStored {
                ref read,
                ref stored,
            } => write!(
                f,
                "a node field's nodes read planes [{}, {}), the slab stores [{}, {})",
                read.start, read.end, stored.start, stored.end
            ),
        }
    }
}

impl core::error::Error for NodesError {}

/// A node field over some of a slab's planes, as `volume::nodes::fill` writes it.
#[derive(Clone, Copy, Debug)]
pub struct Nodes<'a, N> {
    data: &'a [N],
    first: u32,
    end: u32,
    ny: usize,
    nz: usize,
}

impl<'a, N: Lanes> Nodes<'a, N> {
    /// The field of planes `planes` of `grid` in `data`.
    pub fn new(grid: &Grid, planes: Range<u32>, data: &'a [N]) -> Result<Self, NodesError> {
        let expected = planes.len() * grid.plane_len();
        if data.len() != expected {
            return Err(NodesError::StorageLength {
                expected,
                actual: data.len(),
            });
        }
        let [_, ny, nz] = grid.dims();
        Ok(Nodes {
            data,
            first: planes.start,
            end: planes.end,
            ny: ny as usize,
            nz: nz as usize,
        })
    }

    /// The planes it holds.
    pub fn planes(&self) -> Range<u32> {
        self.first..self.end
    }

    /// Its planes as whole cells: what a run through a slab's interior reads.
    #[inline]
    pub fn cells(&self) -> Cells<'a, N> {
        Cells::new(self.data, self.planes(), self.ny as u32, self.nz as u32)
    }

    /// The lanes of the eight nodes of the cell from node `lo` to node `hi` (equal or
    /// adjacent on each axis, as a cell-model site's corners are), ordered by corner bits
    /// `z y x` as a slab's cells are; `None` where any lies outside the field.
    #[inline(always)]
    pub fn cell(&self, [x0, y0, z0]: [u32; 3], [x1, y1, z1]: [u32; 3]) -> Option<[Vec4; 8]> {
        // A site's high corner is its low one or the next, inside the grid.
        if x0 < self.first || x1 >= self.end {
            return None;
        }
        let (ny, nz) = (self.ny, self.nz);
        let base = ((x0 - self.first) as usize * nz + z0 as usize) * ny + y0 as usize;
        let steps = [
            (x1 - x0) as usize * nz * ny,
            (y1 - y0) as usize,
            (z1 - z0) as usize * ny,
        ];
        corners(self.data, base, steps).map(|c| c.map(N::unpack))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn byte_lanes_keep_every_value_a_byte_node_takes() {
        for v in -255..=255 {
            let lanes = Vec4::new(v as f32, -v as f32, 255.0, -255.0);
            assert_eq!(<[i16; 4]>::pack(lanes).unpack(), lanes);
        }
    }
}

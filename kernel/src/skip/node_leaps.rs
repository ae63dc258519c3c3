//! A cell leap map laid out as a slab stores its nodes, for reading: what the run through a
//! slab's interior asks of a sample's cell ([`crate::skip::cell_leaps::fill_node_layout`]
//! builds it from a map of the cell leaps' own layout).
//!
//! Invariant: the distance read at a cell's low node's place is the cell leap map's for
//! that cell; every other place, and every place past the map, reads 0 (no leap).

use crate::skip::octant::Octant;

/// One octant's cell leap map laid out as a slab stores its nodes (plane-major, rows along Z,
/// nodes along Y, the grid's strides), over some X planes: a cell's distance at its low
/// node's place. A sample loop that reads a cell of such storage has that place in hand, so
/// the distance costs it one load instead of an index of its own. Places that are no cell's
/// low node (a row's last node, a plane's last row) and places past the map read 0: no leap.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NodeLeaps<'a> {
    map: &'a [u8],
    first: u32,
    octant: Octant,
}

impl<'a> NodeLeaps<'a> {
    /// The map of `octant`'s rays in `map`, laid out over planes from `first` on of a grid
    /// ([`crate::skip::cell_leaps::fill_node_layout`]).
    pub fn new(map: &'a [u8], first: u32, octant: Octant) -> NodeLeaps<'a> {
        NodeLeaps { map, first, octant }
    }

    /// The octant whose rays it serves.
    pub fn octant(&self) -> Octant {
        self.octant
    }

    /// The first X plane it holds.
    pub fn first(&self) -> u32 {
        self.first
    }

    /// A hint that place `i` is read soon; `i` may be any place, in the map or not
    /// ([`voxcube_simd::prefetch`]).
    #[inline(always)]
    pub fn prefetch(&self, i: usize) {
        voxcube_simd::prefetch(self.map, i);
    }

    /// The distance at place `i` (0 past the map).
    #[inline(always)]
    pub fn at(&self, i: usize) -> u8 {
        self.map.get(i).copied().unwrap_or(0)
    }
}

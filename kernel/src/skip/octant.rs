//! Octants of ray directions: which way along each axis a ray moves, the key of every map
//! that looks ahead of a ray (leap maps, cell leap maps).
//!
//! Invariant: a direction component of zero, of either sign, counts as up; such a ray keeps
//! its coordinate, as a ray moving up never lowers it, so "ahead" covers it either way.

use glam::Vec3;

/// Octants of ray directions.
pub const OCTANTS: usize = 8;

/// An octant of ray directions: bit `a` set when the ray moves down along axis `a` (its
/// direction's component is below zero; zero, of either sign, counts as up: such a ray keeps
/// its coordinate, as a ray moving up never lowers it).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Octant(u8);

impl Octant {
    /// The octant of index-space direction `dir`.
    #[inline]
    pub fn of(dir: Vec3) -> Octant {
        Octant(dir.cmplt(Vec3::ZERO).bitmask() as u8)
    }

    /// The octant numbered `i` (its bits; `i` below [`OCTANTS`]).
    pub fn from_index(i: usize) -> Octant {
        Octant((i % OCTANTS) as u8)
    }

    /// Its number, below [`OCTANTS`].
    #[inline]
    pub fn index(self) -> usize {
        usize::from(self.0)
    }

    /// Whether rays of this octant move down along `axis`.
    #[inline]
    pub fn down(self, axis: usize) -> bool {
        self.0 >> axis & 1 == 1
    }

    /// The first and last coordinate along `axis` of the cells or blocks at most `reach`
    /// steps ahead of `at` for rays of this octant, and nowhere behind (saturating at the
    /// ends of `u32`).
    #[inline]
    pub fn span(self, axis: usize, at: u32, reach: u32) -> (u32, u32) {
        match self.down(axis) {
            true => (at.saturating_sub(reach), at),
            false => (at, at.saturating_add(reach)),
        }
    }
}

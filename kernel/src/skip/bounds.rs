//! One view's depth bounds over a slab, for reading: what the marcher asks of a primary ray
//! before its first sample ([`crate::skip::depths`] builds them).
//!
//! Invariant: a bound is never above the parameter of the ray's first sample that may show,
//! and a pixel outside the rows held reads minus infinity (nothing to pass over).

use crate::node::topology::Rows;

/// One view's depth bounds over a slab, for reading: a bound per pixel of the rows it holds,
/// row-major.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Depths<'a> {
    map: &'a [f32],
    width: u32,
    rows: Rows,
}

impl<'a> Depths<'a> {
    /// The bounds [`crate::skip::depths::build`] wrote into `map` for the rows `rows` of an image `width` pixels
    /// wide.
    pub fn new(map: &'a [f32], width: u32, rows: Rows) -> Depths<'a> {
        Depths { map, width, rows }
    }

    /// Pixel `pixel`'s bound: no sample of its primary ray at a parameter below it lies in an
    /// obstacle. Minus infinity (nothing to pass over) for a pixel outside the rows held.
    #[inline]
    pub fn bound(&self, pixel: u32) -> f32 {
        let width = self.width.max(1);
        let Some(row) = self.rows.index(pixel / width) else {
            return f32::NEG_INFINITY;
        };
        let at = row as usize * width as usize + (pixel % width) as usize;
        self.map.get(at).copied().unwrap_or(f32::NEG_INFINITY)
    }
}

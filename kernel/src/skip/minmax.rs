//! Building min/max blocks from a slab's samples: each block's least and greatest value over
//! the nodes it stores, in storage order, whole or a part of the block columns at a time.
//!
//! Invariant: a block takes the range of every node a sample it holds may read, and a block
//! without a stored plane is unknown, so a range never claims a value impossible; a build
//! split by columns gives the same bits as a whole one.

use crate::skip::blocks::{
    check_columns, column_len, count, extent_for, nodes, BlocksError, BLOCK, GATHER,
};
use crate::volume::sample::{Range, Sample};
use crate::volume::slab::Slab;

/// The global block columns a slab's stored planes touch, and the storage they need.
pub fn extent<T: Sample>(slab: &Slab<'_, T>) -> (u32, u32, usize) {
    extent_for(slab.grid(), slab.stored())
}

/// Fill `out` (exactly [`extent`]'s length) with `slab`'s blocks.
pub fn build<T: Sample>(slab: &Slab<'_, T>, out: &mut [Range]) -> Result<(), BlocksError> {
    let (x0, x1, _) = extent(slab);
    build_columns(slab, 0..x1 - x0, out)
}

/// Fill `out` with the blocks of `slab`'s block columns `columns` (counted from its first;
/// [`column_len`] blocks each, the storage order's slowest axis), as [`build`]
/// fills their part of its storage: a build split by columns gives the same bits.
pub fn build_columns<T: Sample>(
    slab: &Slab<'_, T>,
    columns: core::ops::Range<u32>,
    out: &mut [Range],
) -> Result<(), BlocksError> {
    let (x0, x1, _) = extent(slab);
    check_columns(&columns, x1 - x0)?;
    BlocksError::check_storage(columns.len() * column_len(slab.grid()), out.len())?;
    let x0 = x0 + columns.start;
    let [nx, ny, nz] = slab.grid().dims();
    let bz = count(nz) as usize;
    // The blocks of one line along Y (one block in X and in Z, every Y) lie side by side in
    // `out`, and the line's nodes on one Y row side by side in storage. So the line's
    // least and greatest value at each Y node are gathered over its rows first, in
    // straight passes along the rows that the compiler vectorises, and then each block
    // takes those of its own Y nodes, rather than gathering block by block, a few values of
    // a row at a time, which the compiler cannot vectorise. The passes compare samples as
    // stored, many to a vector register for bytes, and convert only each block's two
    // extremes: `to_f32` keeps the samples' order.
    let stored = slab.stored();
    for (k, line) in out.chunks_exact_mut(count(ny) as usize).enumerate() {
        // A block at the slab's end takes the range of the nodes it stores: every sample
        // the slab owns reads stored nodes only, and no other sample asks its blocks.
        let xs = nodes(x0 + (k / bz) as u32, nx);
        let xs = xs.start.max(stored.start)..xs.end.min(stored.end);
        let zs = nodes((k % bz) as u32, nz);
        for (c, blocks) in line.chunks_mut(GATHER / BLOCK as usize).enumerate() {
            // Nodes y0..y1: these blocks' own, and the plane they share with the next.
            let y0 = c * GATHER;
            let y1 = (y0 + GATHER + 1).min(ny as usize);
            // The first row's values start both, so no sample type needs extremes of
            // its own.
            let (mut lo, mut hi) = ([T::default(); GATHER + 1], [T::default(); GATHER + 1]);
            let mut first = true;
            // A block without a stored plane is unknown.
            let mut complete = !xs.is_empty();
            for x in xs.clone() {
                for z in zs.clone() {
                    let Some(values) = slab.row(x, z).and_then(|row| row.get(y0..y1)) else {
                        complete = false;
                        continue;
                    };
                    for ((l, h), &v) in lo.iter_mut().zip(&mut hi).zip(values) {
                        (*l, *h) = match first {
                            true => (v, v),
                            false => (l.lesser(v), h.greater(v)),
                        };
                    }
                    first = false;
                }
            }
            // Only nodes y0..y1 were read.
            let read = ..y1 - y0;
            let (lo, hi) = (lo.get(read).unwrap_or(&[]), hi.get(read).unwrap_or(&[]));
            for (by, r) in (c * GATHER / BLOCK as usize..).zip(blocks.iter_mut()) {
                let ys = nodes(by as u32, ny);
                let ys = ys.start as usize - y0..ys.end as usize - y0;
                *r = match (complete, lo.get(ys.clone()), hi.get(ys)) {
                    (true, Some(lo), Some(hi)) => Range {
                        min: lo.iter().map(|v| v.to_f32()).fold(f32::INFINITY, f32::min),
                        max: hi
                            .iter()
                            .map(|v| v.to_f32())
                            .fold(f32::NEG_INFINITY, f32::max),
                    },
                    _ => Range::UNKNOWN,
                };
            }
        }
    }
    Ok(())
}

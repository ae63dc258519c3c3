//! Chessboard-distance space leaping: for each min/max block of a slab, how many blocks away
//! (Chebyshev distance, over the slab's block columns) the nearest block lies that a view
//! cannot skip. A ray in a block at distance `d ≥ 1` may jump over every sample whose block
//! lies within `d − 1` of it at once, instead of leaving one block per jump.
//!
//! Invariants: distances are exact (a two-pass chamfer over the 26 neighbours, which is exact
//! for the chessboard metric; tested against brute force) and saturate at [`u8::MAX`], which
//! only shortens leaps. A block the view cannot skip, including one whose range is unknown, is
//! at distance 0. Blocks outside the slab's columns or the grid are not obstacles: the marcher
//! checks that every landing is owned and lies in a block the map calls empty (so in the
//! slab's columns), and the samples between lie in the same box of blocks. A leap map belongs to one view's emptiness test: it must be rebuilt for another
//! view, as the block ranges need not be.

use crate::blocks::{Blocks, BlocksError};
use crate::view::View;

/// Fill `out` (one entry per block of `blocks`, in the blocks' order) with each block's
/// chessboard distance to the nearest block `view` cannot skip.
pub fn build(blocks: &Blocks<'_>, view: &View, out: &mut [u8]) -> Result<(), BlocksError> {
    let ranges = blocks.ranges();
    if out.len() != ranges.len() {
        return Err(BlocksError::Storage {
            needed: ranges.len(),
            given: out.len(),
        });
    }
    for (d, r) in out.iter_mut().zip(ranges) {
        *d = if view.empty(*r) { u8::MAX } else { 0 };
    }
    let (cols, ny, nz) = blocks.shape();
    chamfer(out, [cols, nz, ny]);
    Ok(())
}

/// The chessboard distance transform in place, `d` laid out with axis 0 slowest and axis 2
/// fastest over `dims`: a forward pass takes each entry's 13 neighbours before it in that
/// order, a backward pass the 13 after it.
fn chamfer(d: &mut [u8], dims: [u32; 3]) {
    let [a, b, c] = dims.map(|n| n as usize);
    let at = |i: usize, j: usize, k: usize| (i * b + j) * c + k;
    // Offsets that come earlier in the layout's order: (-1, *, *), (0, -1, *), (0, 0, -1).
    let mut earlier = [(0isize, 0isize, 0isize); 13];
    let mut n = 0;
    for di in -1isize..=1 {
        for dj in -1isize..=1 {
            for dk in -1isize..=1 {
                if (di, dj, dk) < (0, 0, 0) {
                    earlier[n] = (di, dj, dk);
                    n += 1;
                }
            }
        }
    }
    let step = |d: &mut [u8], (i, j, k): (usize, usize, usize), sign: isize| {
        let here = at(i, j, k);
        if d[here] == 0 {
            return;
        }
        let mut best = d[here];
        for &(di, dj, dk) in &earlier {
            let (ni, nj, nk) = (
                i as isize + sign * di,
                j as isize + sign * dj,
                k as isize + sign * dk,
            );
            let inside = (0..a as isize).contains(&ni)
                && (0..b as isize).contains(&nj)
                && (0..c as isize).contains(&nk);
            if inside {
                best = best.min(d[at(ni as usize, nj as usize, nk as usize)].saturating_add(1));
            }
        }
        d[here] = best;
    };
    for i in 0..a {
        for j in 0..b {
            for k in 0..c {
                step(d, (i, j, k), 1);
            }
        }
    }
    for i in (0..a).rev() {
        for j in (0..b).rev() {
            for k in (0..c).rev() {
                step(d, (i, j, k), -1);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brute force: the least chessboard distance to a zero entry, saturating at 255.
    fn brute(seed: &[u8], dims: [u32; 3]) -> [u8; 216] {
        let [a, b, c] = dims.map(|n| n as i32);
        let mut out = [0u8; 216];
        for i in 0..a {
            for j in 0..b {
                for k in 0..c {
                    let mut best = i32::from(u8::MAX);
                    for ii in 0..a {
                        for jj in 0..b {
                            for kk in 0..c {
                                if seed[((ii * b + jj) * c + kk) as usize] == 0 {
                                    let dist =
                                        (i - ii).abs().max((j - jj).abs()).max((k - kk).abs());
                                    best = best.min(dist);
                                }
                            }
                        }
                    }
                    out[((i * b + j) * c + k) as usize] = best as u8;
                }
            }
        }
        out
    }

    #[test]
    fn the_two_passes_give_exact_chessboard_distances() {
        let mut next = crate::testing::xorshift(0x2545_f491);
        for round in 0..300 {
            let dims = [1 + next() % 6, 1 + next() % 6, 1 + next() % 6];
            let len = dims.iter().product::<u32>() as usize;
            // From nearly empty to nearly full of obstacles; sometimes none at all.
            let density = round % 10;
            let mut d = [u8::MAX; 216];
            for v in d.iter_mut().take(len) {
                if next() % 10 < density {
                    *v = 0;
                }
            }
            let expected = brute(&d, dims);
            chamfer(&mut d[..len], dims);
            assert_eq!(&d[..len], &expected[..len], "{dims:?} density {density}");
        }
    }
}

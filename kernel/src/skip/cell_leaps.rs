//! Cell leap maps: for every cell of a slab's blocks and one octant of ray directions, the
//! chessboard distance in cells, over the cells a ray moving into that octant can reach, to
//! the nearest cell a view cannot skip. A ray in a cell at distance `d ≥ 1` may jump over
//! every sample in the cube of cells reaching `d − 1` ahead of it along each axis: on a noisy
//! volume most empty space lies in small gaps between cells that show, where a leap map of
//! whole blocks says nothing and a ray would otherwise look at its samples one by one.
//!
//! Invariants: a map is built from one view's cell masks ([`crate::skip::cells`]), so a cell is an
//! obstacle (distance 0) exactly where its mask bit is set: the same proof, cell by cell.
//! Distances are exact up to [`MAX_DISTANCE`] (the seven neighbours ahead, as in
//! [`crate::skip::leaps`], a row at a time; tested against brute force) and capped there, which
//! only shortens leaps; so a distance depends on no cell further away, and a map built in
//! parts of planes, each with that many planes ahead of it, is the same map. Cells outside
//! the slab's block columns or past the grid are not obstacles: the marcher checks that every
//! landing is in an owned plane (so in the map) and in the cube, and the samples between lie
//! in the same cube, since a ray's cells move monotonically, each axis the way its octant
//! says. The map is laid out row by row, X fastest, over the cells of the blocks' columns:
//! a byte per cell, 64 per block.

use crate::skip::blocks::{Blocks, BlocksError, CellMask, BLOCK};
use crate::skip::octant::Octant;

/// Bytes of one octant's map per block: a byte per cell.
pub use crate::skip::blocks::PER_BLOCK;

/// The greatest distance a map holds: a cell further from every obstacle holds this. Each
/// doubling of it costs the build another pass over every cell, and a leap of 32 cells
/// already holds 45 samples at the paper's step, 160 at Δt = ⅕.
pub const MAX_DISTANCE: u8 = 32;

/// One octant's cell leap map over a slab's blocks, for reading.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CellLeaps<'a> {
    map: &'a [u8],
    /// The octant whose rays it serves.
    octant: Octant,
    /// The global X of the map's first cell.
    x0: u32,
    /// Cells along X and Y.
    width: u32,
    height: u32,
}

impl<'a> CellLeaps<'a> {
    /// The map `blocks` carry for their octant's rays, when they carry one.
    #[inline]
    pub fn of(blocks: &Blocks<'a>) -> Option<CellLeaps<'a>> {
        CellLeaps::new(blocks, blocks.cell_leap_map()?).ok()
    }

    /// The map of `blocks` in `map` (one octant's part of [`build`]'s storage), for the rays
    /// of the octant `blocks` serve.
    pub fn new(blocks: &Blocks<'_>, map: &'a [u8]) -> Result<CellLeaps<'a>, BlocksError> {
        let (cols, ny, nz) = blocks.shape();
        let len = cols as usize * ny as usize * nz as usize;
        BlocksError::check_storage(len * PER_BLOCK, map.len())?;
        Ok(CellLeaps {
            map,
            octant: blocks.octant(),
            x0: blocks.first_column() * BLOCK,
            width: cols * BLOCK,
            height: ny * BLOCK,
        })
    }

    /// The distances of the cells of row `(y, z)` (X from the map's first), as
    /// [`CellLeaps::distance`] reads them: empty outside the map.
    fn row(&self, y: u32, z: u32) -> &'a [u8] {
        if y >= self.height {
            return &[];
        }
        let start = (z as usize * self.height as usize + y as usize) * self.width as usize;
        let end = start
            .saturating_add(self.width as usize)
            .min(self.map.len());
        self.map.get(start..end).unwrap_or(&[])
    }

    /// The octant whose rays read this map (the blocks' [`Blocks::toward`] when it was found).
    pub fn octant(&self) -> Octant {
        self.octant
    }

    /// The distance of the cell whose low corner is `lo` ([`crate::volume::field::Site::lo`] of a
    /// cell-model sample): 0, nothing may be skipped, outside the map.
    #[inline]
    pub fn distance(&self, lo: [u32; 3]) -> u8 {
        let [x, y, z] = lo;
        let x = x.wrapping_sub(self.x0);
        if x >= self.width || y >= self.height {
            return 0;
        }
        let i = (z as usize * self.height as usize + y as usize) * self.width as usize + x as usize;
        self.map.get(i).copied().unwrap_or(0)
    }
}

/// A cell leap map known to hold every cell of a box: read there without the per-axis tests
/// of [`CellLeaps::distance`], which a loop through the box would repeat on every sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeldLeaps<'a> {
    leaps: CellLeaps<'a>,
}

impl<'a> HeldLeaps<'a> {
    /// [`CellLeaps::distance`] of a cell of the box it was found for
    /// ([`CellLeaps::holding`]). A cell outside the box reads some cell's distance or 0, never
    /// a panic: the box is the caller's to keep.
    #[inline(always)]
    pub fn distance(&self, [x, y, z]: [u32; 3]) -> u8 {
        let m = &self.leaps;
        let i = (z as usize * m.height as usize + y as usize) * m.width as usize
            + x.wrapping_sub(m.x0) as usize;
        m.map.get(i).copied().unwrap_or(0)
    }
}

impl<'a> CellLeaps<'a> {
    /// The map as [`HeldLeaps`] for the cells whose low corner has X in `x`, Y below `y_end`
    /// and Z below `z_end`, where it holds them all; `None` where it does not.
    pub fn holding(
        &self,
        x: core::ops::Range<u32>,
        y_end: u32,
        z_end: u32,
    ) -> Option<HeldLeaps<'a>> {
        let row = self.width as usize * self.height as usize;
        let depth = self.map.len().checked_div(row)?;
        let held = x.start >= self.x0
            && x.end.saturating_sub(self.x0) <= self.width
            && y_end <= self.height
            && z_end as usize <= depth;
        held.then_some(HeldLeaps { leaps: *self })
    }
}

/// Fill `out` (`planes.len()` planes of `grid`'s nodes) with `leaps`' distances laid out as
/// [`crate::skip::node_leaps::NodeLeaps`] reads them: each cell's at its low node's place, 0
/// elsewhere.
///
/// A transpose (the map runs X fastest, the nodes Y fastest), taken a square of [`TILE`]
/// cells of X by [`TILE`] of Y at a time through a buffer on the stack: each side is read and
/// written a run of [`TILE`] bytes at a time. Cell by cell, one side misses the cache on
/// every cell of a volume that leaves the caches, and a plane's power-of-two length sends a
/// whole column of writes to one cache set.
pub fn fill_node_layout(
    leaps: &CellLeaps<'_>,
    grid: &crate::volume::grid::Grid,
    planes: core::ops::Range<u32>,
    out: &mut [u8],
) -> Result<(), BlocksError> {
    fill_node_tiles(leaps, grid, planes, out, TILE)
}

/// Cells along X and along Y that [`fill_node_layout`] moves at a time: 4 KiB of stack.
pub const TILE: usize = 64;

/// [`fill_node_layout`] in squares of `tile` (at most [`TILE`]) cells a side.
fn fill_node_tiles(
    leaps: &CellLeaps<'_>,
    grid: &crate::volume::grid::Grid,
    planes: core::ops::Range<u32>,
    out: &mut [u8],
    tile: usize,
) -> Result<(), BlocksError> {
    let [_, ny, nz] = grid.dims();
    let plane = grid.plane_len();
    BlocksError::check_storage(planes.len() * plane, out.len())?;
    let tile = tile.clamp(1, TILE);
    let mut square = [[0u8; TILE]; TILE];
    for z in 0..nz {
        for x0 in planes.clone().step_by(tile) {
            let xs = x0..planes.end.min(x0.saturating_add(tile as u32));
            for y0 in (0..ny).step_by(tile) {
                let ys = y0..ny.min(y0.saturating_add(tile as u32));
                for (y, line) in ys.clone().zip(square.iter_mut()) {
                    let row = match y + 1 < ny && z + 1 < nz {
                        true => leaps.row(y, z),
                        false => &[],
                    };
                    for (x, d) in xs.clone().zip(line.iter_mut()) {
                        *d = row
                            .get(x.wrapping_sub(leaps.x0) as usize)
                            .copied()
                            .unwrap_or(0);
                    }
                }
                for (i, x) in xs.clone().enumerate() {
                    let row = z as usize * ny as usize + y0 as usize;
                    let at = (x - planes.start) as usize * plane + row;
                    let Some(run) = out.get_mut(at..at + ys.len()) else {
                        continue;
                    };
                    for (o, line) in run.iter_mut().zip(&square) {
                        *o = line[i];
                    }
                }
            }
        }
    }
    Ok(())
}

/// Fill `out` (a byte per cell of `blocks`' columns, [`PER_BLOCK`] per block) with each
/// cell's chessboard distance, for rays of `octant`, to the nearest cell ahead that the
/// blocks' cell masks say may show. Blocks without masks show everywhere: every distance is 0.
pub fn build(blocks: &Blocks<'_>, octant: Octant, out: &mut [u8]) -> Result<(), BlocksError> {
    build_planes(blocks, octant, 0..planes(blocks), out)
}

/// Planes of cells (along Z) of a map of `blocks`.
pub fn planes(blocks: &Blocks<'_>) -> usize {
    (blocks.shape().2 * BLOCK) as usize
}

/// Bytes of one plane of cells of a map of `blocks`.
pub fn plane_len(blocks: &Blocks<'_>) -> usize {
    let (cols, ny, _) = blocks.shape();
    (cols * BLOCK) as usize * (ny * BLOCK) as usize
}

/// The planes to build with [`build_planes`] for the exact distances of planes `part` of a map
/// of `planes` planes, for rays of `octant`: the part and [`MAX_DISTANCE`] planes ahead of it.
pub fn with_planes_ahead(
    part: core::ops::Range<usize>,
    planes: usize,
    octant: Octant,
) -> core::ops::Range<usize> {
    let more = usize::from(MAX_DISTANCE);
    match octant.down(2) {
        true => part.start.saturating_sub(more)..part.end.min(planes),
        false => part.start.min(planes)..part.end.saturating_add(more).min(planes),
    }
}

/// Part `i` of `n` of a map of `planes` planes for rays of `octant`, for `n` builders that
/// each build their part with the planes ahead of it ([`with_planes_ahead`]): the parts tile
/// the planes in order, and the regions they build are as even as whole planes allow. A part
/// with planes ahead of it builds up to [`MAX_DISTANCE`] of them besides its own, and the one
/// at the far end none, so parts of equal length would leave one builder waiting for
/// another (two halves of a volume deeper than the distance build unequal numbers of
/// planes). Parts at the near end may be empty where `n` is large for `planes`.
pub fn part(i: usize, n: usize, planes: usize, octant: Octant) -> core::ops::Range<usize> {
    let n = n.max(1);
    // For rays moving up in Z, numbered from the far end: part `j` ends where part `j - 1`
    // starts, and starts as far back as a region of `region` planes, its own and those ahead
    // of it up to the last, allows.
    let from_far = |region: usize, j: usize| -> core::ops::Range<usize> {
        let mut end = planes;
        let mut start = planes;
        for _ in 0..=j {
            end = start;
            let reach = end.saturating_add(usize::from(MAX_DISTANCE)).min(planes);
            start = reach.saturating_sub(region).min(end);
        }
        start..end
    };
    // The least region whose parts reach the first plane: a region of every plane does.
    let (mut lo, mut hi) = (planes.div_ceil(n), planes);
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        match from_far(mid, n - 1).start == 0 {
            true => hi = mid,
            false => lo = mid + 1,
        }
    }
    // Rays moving down in Z: the same parts mirrored, the far end at the first plane.
    let i = i.min(n - 1);
    match octant.down(2) {
        false => from_far(lo, n - 1 - i),
        true => {
            let mirrored = from_far(lo, i);
            planes - mirrored.end..planes - mirrored.start
        }
    }
}

/// Masks of a row of blocks the build gathers on the stack: 2 KiB, a row of 1,024 cells.
const GATHERED: usize = 256;

/// [`build`]'s planes `planes` alone (`out` holds them, one after the other), as if no cell
/// lay beyond them: each distance is [`build`]'s where at least [`MAX_DISTANCE`] planes lie
/// between its cell and the last of `planes` ahead (a distance depends on no cell further
/// away), and may be larger elsewhere. So a build split into parts of planes, each built with
/// that many planes more ahead of it, gives the same bits.
pub fn build_planes(
    blocks: &Blocks<'_>,
    octant: Octant,
    planes: core::ops::Range<usize>,
    out: &mut [u8],
) -> Result<(), BlocksError> {
    let (cols, ny, nz) = blocks.shape();
    let (b, ny, nz) = (BLOCK as usize, ny as usize, nz as usize);
    let plane_len = cols as usize * b * ny * b;
    let last = planes.end.min(nz * b);
    let planes = planes.start.min(last)..last;
    BlocksError::check_storage(planes.len() * plane_len, out.len())?;
    let Some(masks) = blocks.masks() else {
        out.fill(0);
        return Ok(());
    };
    BlocksError::check_storage(cols as usize * ny * nz, masks.len())?;
    let dims = [cols as usize * b, ny * b, planes.len()];
    // The blocks are stored X columns slowest, then Z, then Y: a row's blocks are `ny · nz`
    // apart, and its cells in each are one row of four bits of the block's mask. The four
    // rows of cells through a row of blocks come one after the other, so the row's masks are
    // gathered once for them (up to [`GATHERED`] a row; past that, read in place): read in
    // place, each is a cache miss on a volume that leaves the caches.
    let mut gathered = [0 as CellMask; GATHERED];
    let mut gathered_row = None;
    let obstacles = |row: &mut [u8], y: usize, z: usize| {
        let z = planes.start + z;
        let first = (z / b) * ny + y / b;
        let shift = b * (y % b + b * (z % b));
        let in_place = masks.iter().skip(first).step_by(ny * nz);
        if gathered_row != Some(first) {
            for (g, &mask) in gathered.iter_mut().zip(in_place.clone()) {
                *g = mask;
            }
            gathered_row = Some(first);
        }
        let row_masks = gathered.iter().chain(in_place.skip(GATHERED));
        for (cells, mask) in row.chunks_mut(b).zip(row_masks) {
            let bits = mask >> shift;
            if bits & 0xf == 0 {
                continue;
            }
            for (i, cell) in cells.iter_mut().enumerate() {
                if bits >> i & 1 == 1 {
                    *cell = 0;
                }
            }
        }
    };
    ahead(out, dims, octant, obstacles);
    Ok(())
}

/// The chessboard distance transform restricted to an octant, into `d` (X fastest over
/// `dims`, then Y, then Z); `obstacles(row, y, z)` sets row `(y, z)`'s obstacles to 0 and
/// leaves its other cells. Planes and rows are taken from the far end, so the rows ahead of a
/// row are final when it is reached. First the row holds one more than the least of the
/// three rows ahead of it (one over in Y, in Z, in both; a loop the compiler vectorizes);
/// then [`along`] finishes it with the cells ahead in the row itself.
fn ahead(
    d: &mut [u8],
    dims: [usize; 3],
    octant: Octant,
    mut obstacles: impl FnMut(&mut [u8], usize, usize),
) {
    let [w, h, depth] = dims;
    let order = |n: usize, down: bool| (0..n).map(move |i| if down { i } else { n - 1 - i });
    let next = |i: usize, n: usize, down: bool| match down {
        true => i.checked_sub(1),
        false => Some(i + 1).filter(|&j| j < n),
    };
    let row_of = |y: usize, z: usize| (z * h + y) * w;
    const NONE: [u8; 0] = [];
    for z in order(depth, octant.down(2)) {
        let nz = next(z, depth, octant.down(2));
        for y in order(h, octant.down(1)) {
            let ny = next(y, h, octant.down(1));
            let at = row_of(y, z);
            let (before, rest) = d.split_at_mut(at);
            let (row, after) = rest.split_at_mut(w);
            // A row ahead: before this one in storage, or after it.
            let ahead_row = |start: usize| -> &[u8] {
                match start < at {
                    true => &before[start..start + w],
                    false => &after[start - at - w..start - at],
                }
            };
            let [a, b, c] = [
                ny.map(|y| ahead_row(row_of(y, z))),
                nz.map(|z| ahead_row(row_of(y, z))),
                ny.zip(nz).map(|(y, z)| ahead_row(row_of(y, z))),
            ];
            match (a, b, c) {
                (Some(a), Some(b), Some(c)) => {
                    for (((cell, &a), &b), &c) in row.iter_mut().zip(a).zip(b).zip(c) {
                        *cell = a.min(b).min(c).saturating_add(1);
                    }
                }
                (a, b, _) => {
                    // At the far face of Y or Z (or both): the rows that exist.
                    let (a, b) = (a.unwrap_or(&NONE), b.unwrap_or(&NONE));
                    for (x, cell) in row.iter_mut().enumerate() {
                        let least = a.get(x).copied().unwrap_or(u8::MAX);
                        *cell = least
                            .min(b.get(x).copied().unwrap_or(u8::MAX))
                            .saturating_add(1);
                    }
                }
            }
            along(row, octant.down(0), |row| obstacles(row, y, z));
        }
    }
}

/// One row's distances, from one more than the least of the rows ahead of each cell (`row`,
/// at least 1 everywhere) and `obstacles`, for rays moving down X when `down`: each cell
/// first takes the least of its own and the next cell's ahead (the three rows ahead at the X
/// ahead), its obstacles then 0; then, from the far end, each takes the least of its own and
/// one more than the cell ahead of it, so the least over the cells `j` ahead of their value
/// plus their distance from it, and at most [`MAX_DISTANCE`]: any cell further on is at
/// least that far. That pass carries one value from cell to cell, which doubling steps over
/// the row in vector lanes, or a scan within chunks of lanes, did not beat
/// (docs/speed-log.md).
fn along(row: &mut [u8], down: bool, obstacles: impl FnOnce(&mut [u8])) {
    least_with_next(row, down);
    obstacles(row);
    // The value carried on from the cell ahead; none lies past the row's far end. Capping it
    // caps every cell: one more than a capped value is at most one over the cap, which the
    // cell's own cap takes back.
    let mut ahead = MAX_DISTANCE;
    let mut take = |cell: &mut u8| {
        ahead = (*cell).min(ahead.saturating_add(1)).min(MAX_DISTANCE);
        *cell = ahead;
    };
    match down {
        true => row.iter_mut().for_each(&mut take),
        false => row.iter_mut().rev().for_each(&mut take),
    }
}

/// Lanes of [`least_with_next`]: one SSE2 register of bytes.
const LANES: usize = 16;

/// `row[x] = min(row[x], row[x ± 1])` for every cell with a cell ahead (`+` up, `−` down
/// when `down`), each reading the value from before the call. The row is taken in chunks from
/// the near end, each chunk's cells ahead read before it is written (no earlier chunk wrote
/// them); the cells left over at the far end are the last chunk's worth of the row, read
/// before any chunk is written and written last, the cells they share with the chunk before
/// taking the same values again.
fn least_with_next(row: &mut [u8], down: bool) {
    let len = row.len();
    let least = |cells: &[u8], ahead: &[u8], out: &mut [u8]| {
        for ((o, &c), &a) in out.iter_mut().zip(cells).zip(ahead) {
            *o = c.min(a);
        }
    };
    if len <= LANES {
        // One cell after another, each reading its cell ahead before that one is written.
        match down {
            true => (1..len).rev().for_each(|x| row[x] = row[x].min(row[x - 1])),
            false => (0..len.saturating_sub(1)).for_each(|x| row[x] = row[x].min(row[x + 1])),
        }
        return;
    }
    // The far end's chunk and the cell ahead of each of its cells, as they are now.
    let mut far = [0u8; LANES + 1];
    let far_at = match down {
        true => 0,
        false => len - LANES - 1,
    };
    far.copy_from_slice(&row[far_at..far_at + LANES + 1]);
    let mut out = [0u8; LANES];
    let chunks = (len - 1) / LANES;
    for i in 0..chunks {
        let (at, from) = match down {
            true => (len - (i + 1) * LANES, len - (i + 1) * LANES - 1),
            false => (i * LANES, i * LANES + 1),
        };
        let mut ahead = [0u8; LANES];
        ahead.copy_from_slice(&row[from..from + LANES]);
        least(&row[at..at + LANES], &ahead, &mut out);
        row[at..at + LANES].copy_from_slice(&out);
    }
    match down {
        true => {
            least(&far[1..], &far[..LANES], &mut out);
            row[1..=LANES].copy_from_slice(&out);
        }
        false => {
            least(&far[..LANES], &far[1..], &mut out);
            row[far_at..far_at + LANES].copy_from_slice(&out);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parts_tile_the_planes_and_even_out_what_each_builds() {
        let built =
            |part: core::ops::Range<usize>, planes: usize, octant: Octant| match part.is_empty() {
                true => 0,
                false => with_planes_ahead(part, planes, octant).len(),
            };
        for octant in [Octant::from_index(0), Octant::from_index(4)] {
            for planes in [0, 1, 5, 31, 32, 33, 64, 116, 117, 300, 1000] {
                for n in 1..=17 {
                    let parts = (0..n).map(|i| part(i, n, planes, octant));
                    let mut at = 0;
                    for p in parts.clone() {
                        assert_eq!(p.start, at, "{planes} planes, part {p:?} of {n}");
                        at = p.end;
                    }
                    assert_eq!(at, planes, "{planes} planes in {n}");
                    let most = parts.map(|p| built(p, planes, octant)).max();
                    let even = (0..n)
                        .map(|i| built(i * planes / n..(i + 1) * planes / n, planes, octant))
                        .max();
                    assert!(most <= even, "{planes} planes in {n}: {most:?} > {even:?}");
                }
            }
            let sod = [part(0, 2, 116, octant), part(1, 2, 116, octant)];
            let regions = sod.clone().map(|p| with_planes_ahead(p, 116, octant).len());
            assert_eq!(regions, [74, 74], "{sod:?}");
        }
    }

    /// Brute force: the least chessboard distance to an obstacle ahead (each axis up, or down
    /// where the octant says), at most [`MAX_DISTANCE`].
    fn brute(obstacle: &[bool], dims: [usize; 3], octant: Octant) -> [u8; 512] {
        let [w, h, depth] = dims.map(|n| n as i32);
        let ahead = |from: i32, to: i32, a: usize| match octant.down(a) {
            true => to <= from,
            false => to >= from,
        };
        let at = |x: i32, y: i32, z: i32| ((z * h + y) * w + x) as usize;
        let mut out = [0u8; 512];
        for z in 0..depth {
            for y in 0..h {
                for x in 0..w {
                    let mut best = i32::from(MAX_DISTANCE);
                    for zz in 0..depth {
                        for yy in 0..h {
                            for xx in 0..w {
                                let forward = ahead(x, xx, 0) && ahead(y, yy, 1) && ahead(z, zz, 2);
                                if forward && obstacle[at(xx, yy, zz)] {
                                    best = best.min(
                                        (x - xx).abs().max((y - yy).abs()).max((z - zz).abs()),
                                    );
                                }
                            }
                        }
                    }
                    out[at(x, y, z)] = best as u8;
                }
            }
        }
        out
    }

    #[test]
    fn row_passes_give_exact_chessboard_distances_ahead_in_every_octant() {
        let mut next = crate::testing::xorshift(0x9e37_79b9);
        for round in 0..300 {
            // Half the rounds cubes, half long rows (past a chunk of lanes, and past two).
            let dims = match round % 2 {
                0 => [1 + next() % 8, 1 + next() % 8, 1 + next() % 8],
                _ => [1 + next() % 42, 1 + next() % 4, 1 + next() % 3],
            }
            .map(|n| n as usize);
            let len = dims.iter().product::<usize>();
            // From no obstacle at all to nearly all obstacles.
            let density = round % 10;
            let mut obstacle = [false; 512];
            for o in obstacle.iter_mut().take(len) {
                *o = next() % 20 < density;
            }
            for octant in 0..8 {
                let octant = Octant::from_index(octant);
                let mut d = [7u8; 512];
                let [w, h, _] = dims;
                ahead(&mut d[..len], dims, octant, |row, y, z| {
                    for (x, cell) in row.iter_mut().enumerate() {
                        if obstacle[(z * h + y) * w + x] {
                            *cell = 0;
                        }
                    }
                });
                let expected = brute(&obstacle, dims, octant);
                assert_eq!(
                    &d[..len],
                    &expected[..len],
                    "{dims:?} {octant:?} density {density}"
                );
            }
        }
    }

    #[test]
    fn a_map_reads_each_cell_s_own_mask_bit_in_rows_wider_than_the_gathered_masks() {
        // 258 block columns: a row of blocks longer than the masks gathered on the stack.
        const COLS: usize = GATHERED + 2;
        const BLOCKS: usize = COLS * 2 * 2;
        let grid = crate::volume::grid::Grid::new([4 * COLS as u32 + 1, 9, 9], glam::Vec3::ONE)
            .unwrap_or_else(|e| panic!("{e}"));
        let ranges = [crate::skip::blocks::Range::UNKNOWN; BLOCKS];
        let mut next = crate::testing::xorshift(0x5eed);
        let mut word = || u64::from(next()) << 32 | u64::from(next());
        // Sparse obstacles (a quarter of the cells), so that distances vary.
        let masks: [CellMask; BLOCKS] = core::array::from_fn(|_| word() & word());
        let plain =
            Blocks::new(&grid, 0..grid.dims()[0], &ranges).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(plain.shape(), (COLS as u32, 2, 2));
        let blocks = plain.with_cells(&masks).unwrap_or_else(|e| panic!("{e}"));
        let dims = [COLS * 4, 8, 8];
        let bit = |x: usize, y: usize, z: usize| {
            let block = ((x / 4) * 2 + z / 4) * 2 + y / 4;
            masks[block] >> (x % 4 + 4 * (y % 4 + 4 * (z % 4))) & 1 == 1
        };
        for octant in [0, 3, 5, 6] {
            let octant = Octant::from_index(octant);
            let mut built = [0u8; BLOCKS * PER_BLOCK];
            build(&blocks, octant, &mut built).unwrap_or_else(|e| panic!("{e}"));
            let mut expected = [0u8; BLOCKS * PER_BLOCK];
            ahead(&mut expected, dims, octant, |row, y, z| {
                for (x, cell) in row.iter_mut().enumerate() {
                    if bit(x, y, z) {
                        *cell = 0;
                    }
                }
            });
            assert_eq!(built, expected, "{octant:?}");
            // Obstacles past the gathered masks count.
            let far = (4 * GATHERED..dims[0]).any(|x| built[(7 * 8 + 7) * dims[0] + x] == 0);
            assert!(far || (4 * GATHERED..dims[0]).all(|x| !bit(x, 7, 7)));
        }
    }

    #[test]
    fn far_from_every_obstacle_the_distance_is_capped() {
        let dims = [300, 1, 1];
        let mut d = [0u8; 300];
        ahead(&mut d, dims, Octant::from_index(0), |row, _, _| {
            row[299] = 0
        });
        assert_eq!(d[299], 0);
        assert_eq!(d[298], 1);
        assert_eq!(d[299 - 31], 31);
        assert_eq!(d[299 - 32], 32);
        assert_eq!(d[299 - 33], 32);
        assert_eq!(d[0], 32);
        // Down X: the obstacle at the low end.
        ahead(&mut d, dims, Octant::from_index(1), |row, _, _| row[0] = 0);
        assert_eq!(&d[..4], &[0, 1, 2, 3]);
        assert_eq!(d[40], 32);
    }
}

#[cfg(test)]
mod held_tests {
    use super::*;
    use crate::skip::blocks::Range;
    use crate::volume::grid::Grid;
    use glam::Vec3;

    #[test]
    fn a_held_map_and_one_laid_out_as_the_nodes_read_the_distances_of_their_cells() {
        // Planes 3..14 stored: four block columns of two by three blocks.
        const BLOCKS: usize = 4 * 2 * 3;
        let grid = Grid::new([14, 9, 10], Vec3::ONE).unwrap();
        let blocks = Blocks::new(&grid, 3..14, &[Range::UNKNOWN; BLOCKS]).unwrap();
        let bytes: [u8; BLOCKS * PER_BLOCK] = core::array::from_fn(|i| (i % 7) as u8);
        let map = CellLeaps::new(&blocks, &bytes).unwrap();
        let x0 = blocks.first_column() * BLOCK;
        let (cols, ny, nz) = blocks.shape();
        let (x1, y_end, z_end) = (x0 + cols * BLOCK, ny * BLOCK, nz * BLOCK);
        let held = map.holding(x0..x1, y_end, z_end).unwrap();
        let mut nonzero = 0;
        for x in x0..x1 {
            for y in 0..y_end {
                for z in 0..z_end {
                    let d = held.distance([x, y, z]);
                    assert_eq!(d, map.distance([x, y, z]), "{x} {y} {z}");
                    nonzero += usize::from(d != 0);
                }
            }
        }
        assert!(nonzero > 0);
        assert!(map.holding(x0 + 1..x1 + 1, y_end, z_end).is_none());
        assert!(map.holding(x0..x1 + 1, y_end, z_end).is_none());
        assert!(map.holding(x0..x1, y_end + 1, z_end).is_none());
        assert!(map.holding(x0..x1, y_end, z_end + 1).is_none());
        // Outside the box, never a panic.
        let _ = held.distance([u32::MAX; 3]);
        // Laid out as the nodes: each cell's distance at its low node's place.
        let [_, ny, nz] = grid.dims();
        let planes = 3..14;
        let mut out = [0xffu8; 11 * 9 * 10];
        fill_node_layout(&map, &grid, planes.clone(), &mut out).unwrap();
        assert!(fill_node_layout(&map, &grid, planes.clone(), &mut out[1..]).is_err());
        // Whatever the tiles, the same layout.
        for tile in [1, 3, 5] {
            let mut tiled = [0x5au8; 11 * 9 * 10];
            fill_node_tiles(&map, &grid, planes.clone(), &mut tiled, tile).unwrap();
            assert_eq!(tiled, out, "tiles of {tile}");
        }
        // Read as a slab's storage of planes 2.. reads it: one offset away.
        let storage = crate::volume::cells::Cells::new(&[0u8; 12 * 9 * 10], 2..14, ny, nz);
        let cells = storage.holding(3..13, ny - 1, nz - 1).unwrap();
        let (first, plane) = cells.planes();
        let node = crate::skip::node_leaps::NodeLeaps::new(&out, planes.start, Octant::default());
        let offset = (first as usize)
            .wrapping_sub(planes.start as usize)
            .wrapping_mul(plane);
        let mut nonzero = 0;
        for x in planes.clone() {
            for z in 0..nz {
                for y in 0..ny {
                    let at = node.at(cells.index([x, y, z]).wrapping_add(offset));
                    let cell = y + 1 < ny && z + 1 < nz;
                    let expected = if cell { map.distance([x, y, z]) } else { 0 };
                    assert_eq!(at, expected, "{x} {y} {z}");
                    nonzero += usize::from(at != 0);
                }
            }
        }
        assert!(nonzero > 100, "{nonzero}");
        // The negative control: one plane off, the distances read are another cell's.
        let wrong = offset.wrapping_add(plane);
        let differs = (3..12).any(|x| {
            node.at(cells.index([x, 1, 1]).wrapping_add(wrong)) != map.distance([x, 1, 1])
        });
        assert!(differs);
        // Past the map, no leap and no panic.
        assert_eq!(node.at(usize::MAX), 0);
    }
}

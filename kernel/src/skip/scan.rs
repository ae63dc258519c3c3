//! Scanning a ray's next samples against a view's cell masks, four lattice samples a step: how
//! many in a row lie in cells the view calls empty, each found by its own exact position.
//!
//! Invariants: a lane holds one lattice sample, `t` and position from the same operations as
//! [`crate::trace::lattice::Lattice::t`] and [`crate::trace::ray::Ray::at4`], and its cell from the same
//! clamp as [`crate::volume::field::corner4`] under the cell model, followed by a floor that is exact
//! on the clamped range; so a scanned sample's cell and mask bit are the ones the marcher
//! would read for it, bit for bit. A run ends at the first sample past the lattice, outside
//! the slab's owned planes (whose blocks lie in its block columns), or in a cell whose bit is
//! set: it never claims a sample the marcher would not skip. Block and bit indices are whole numbers in
//! `f32`, exact because [`Masks::of`] refuses masks of 2^23 cells or more.
//!
//! Why scan at all: on a noisy volume the empty cells between the cells a ray must read come
//! a few at a time, and a jump over a box of them costs a turn of the marcher's loop and
//! more than scanning the same few samples here does (docs/speed-log.md). Where a ray takes
//! many samples per
//! cell, a box holds many more samples than a scan step, and jumping wins: [`pays`] tells
//! the two apart.

use crate::skip::blocks::{Blocks, BLOCK};
use crate::skip::cells::CellMask;
use crate::trace::lattice::Lattice;
use crate::trace::ray::Ray;
use crate::volume::field::{whole_lanes4, MAGIC};
use crate::volume::grid::Grid;
use core::ops::Range;
use glam::Vec4;

/// Scan steps of four samples a call at most: the run then goes back to the marcher's loop,
/// which may find a block to leap over (a scan pays per sample, a leap per box of blocks).
pub const STEPS: u32 = 8;

/// The least distance in cells that a ray's step moves along its fastest axis for a scan to
/// pay: below it a cell holds more than five samples of the ray, and jumping over a box of
/// empty cells ([`crate::skip::cells::empty_box`]) is cheaper. Counted in instructions on
/// SOD's paper view over a sweep of Δt (docs/speed-log.md), scanning and jumping cross over
/// near 0.23 cells a step for surfaces and near 0.16 for compositing; the threshold lies
/// between.
pub const MIN_STEP: f32 = 0.2;

/// Cells per block edge, as the lanes count them.
const EDGE: f32 = BLOCK as f32;

/// Whether scanning pays for `ray` sampled on `lattice`: see [`MIN_STEP`].
#[inline]
pub fn pays(ray: &Ray, lattice: &Lattice) -> bool {
    lattice.dt * ray.dir.abs().max_element() >= MIN_STEP
}

/// A slab's cell masks as a scan reads them: their storage, and what locating a cell's bit
/// in it takes, as whole numbers in `f32`.
#[derive(Clone, Copy, Debug)]
pub struct Masks<'a> {
    cells: &'a [CellMask],
    /// Blocks along Y, and in a column of blocks (along Y and Z).
    ny: f32,
    column: f32,
    /// The slab's first block column.
    first: f32,
    /// The owned planes: the first, and one past the last.
    owned: (f32, f32),
    /// The grid's last cell along each axis.
    last_cell: Vec4,
}

impl<'a> Masks<'a> {
    /// The masks `blocks` carry, for a slab owning planes `owned` of `grid`; `None` without
    /// masks, or for masks of `2^23` cells or more (a cell's index, as `f32`, would not
    /// convert exactly).
    pub fn of(blocks: &Blocks<'a>, grid: &Grid, owned: Range<u32>) -> Option<Masks<'a>> {
        let cells = blocks.masks()?;
        if cells.len() >= 1 << 17 {
            return None;
        }
        let (_, ny, nz) = blocks.shape();
        let (_, last_cell) = grid.last_indices();
        Some(Masks {
            cells,
            ny: ny as f32,
            column: (ny * nz) as f32,
            first: blocks.first_column() as f32,
            owned: (owned.start as f32, owned.end as f32),
            last_cell,
        })
    }
}

/// `floor(v)` in every lane of `v` in `[0, 2^23)`: `v + 2^23` rounds it to the nearest whole
/// number, exactly, and that is one too many where it rounded up. Equal to
/// [`Vec4::floor`] there (tested), without the call or the emulation that `floor` becomes
/// on a target without a rounding instruction.
#[inline(always)]
fn floor_small(v: Vec4) -> Vec4 {
    let nearest = (v + Vec4::splat(MAGIC)) - Vec4::splat(MAGIC);
    nearest - Vec4::select(nearest.cmpgt(v), Vec4::ONE, Vec4::ZERO)
}

/// `floor(c / 4)` in every lane of `c`, a whole number in `[0, 2^23)`: `c / 4` is exact and
/// lies on a whole number `n` or a quarter, a half or three quarters past it, so `c / 4 + 5/8`
/// is nearest to `n + 1`, and adding `2^23` rounds to that exactly (the sum lies where `f32`
/// holds the whole numbers and no more).
#[inline(always)]
fn quarter_floor(c: Vec4) -> Vec4 {
    (c * (1.0 / EDGE) + Vec4::splat(0.625) + Vec4::splat(MAGIC)) - Vec4::splat(MAGIC + 1.0)
}

/// How many of the samples after sample `k` of `ray` on `lattice` lie, one after the other, in
/// cells `masks` call empty, in the slab's owned planes and on the lattice: at most
/// `4 · STEPS`. Out of line: inlined into the marcher it leaves the loop fewer registers.
#[inline(never)]
pub fn empty_run(ray: &Ray, lattice: &Lattice, k: u32, masks: &Masks<'_>) -> u32 {
    let o = ray.origin;
    let d = ray.dir;
    let (t0, dt) = (Vec4::splat(lattice.t_entry), Vec4::splat(lattice.dt));
    let [lx, ly, lz, _] = masks.last_cell.to_array().map(Vec4::splat);
    let (own0, own1) = (Vec4::splat(masks.owned.0), Vec4::splat(masks.owned.1));
    // Samples after `k` that exist.
    let room = lattice.last.saturating_sub(k);
    // `k + 1 ..= k + 4`, whole numbers in `f32`, exact while they are at most `last ≤ 2^24`
    // (lanes past it are never read: `room` stops the run first).
    let mut index = Vec4::splat(k as f32) + Vec4::new(1.0, 2.0, 3.0, 4.0);
    let mut run = 0;
    for _ in 0..STEPS {
        let t = t0 + index * dt;
        // The clamp of `field::corner4`: `max` with zero is its `select(q > 0, q, 0)` (NaN
        // and -0 land on +0), and the last cell is below the last node.
        let cell = |o: f32, d: f32, last: Vec4| {
            floor_small(
                (Vec4::splat(o) + Vec4::splat(d) * t)
                    .max(Vec4::ZERO)
                    .min(last),
            )
        };
        let (cx, cy, cz) = (cell(o.x, d.x, lx), cell(o.y, d.y, ly), cell(o.z, d.z, lz));
        let (bx, by, bz) = (quarter_floor(cx), quarter_floor(cy), quarter_floor(cz));
        // `Blocks::index` and `cells::bit` in one number, the bit's index in the storage's
        // bits; for an owned sample every term is a whole number below that, so exact. A
        // cell-model corner's block is inside the counts along Y and Z, so
        // `Blocks::block_of`'s clamp there changes nothing; along X an owned plane's block
        // is inside the slab's columns, which cover its stored planes. (Another lane's number
        // may be anything: its bit is not used.)
        let block = (bx - Vec4::splat(masks.first)) * masks.column + bz * masks.ny + by;
        let bit = (cx - bx * EDGE) + (cy - by * EDGE) * EDGE + (cz - bz * EDGE) * (EDGE * EDGE);
        let cells = whole_lanes4(block * 64.0 + bit);
        let owned = (cx.cmpge(own0) & cx.cmplt(own1)).bitmask();
        for (lane, &cell) in cells.iter().enumerate() {
            let empty = masks
                .cells
                .get((cell / 64) as usize)
                .is_some_and(|mask| mask >> (cell % 64) & 1 == 0);
            if run == room || owned >> lane & 1 == 0 || !empty {
                return run;
            }
            run += 1;
        }
        index += Vec4::splat(4.0);
    }
    run
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::skip::blocks::Range as BlockRange;
    use crate::volume::field;
    use crate::volume::grid::Model;
    use crate::volume::slab::Slab;
    use glam::Vec3;

    /// What the marcher reads for sample `k`, one sample at a time: whether it exists, is
    /// owned, and lies in a cell whose mask bit is clear.
    fn skippable(ray: &Ray, lattice: &Lattice, k: u32, slab: &Slab<'_, f32>) -> bool {
        let Some(blocks) = slab.blocks() else {
            return false;
        };
        if k > lattice.last {
            return false;
        }
        let corner = field::corner4(slab.grid(), Model::Cell, ray.at4(lattice.t(k)));
        slab.owns(corner.plane())
            && blocks.cells(blocks.block_of(corner.lo)) & crate::skip::cells::bit(corner.lo) == 0
    }

    /// Random rays through random slabs of a 13×10×9 grid with random masks (a tenth of the
    /// bits set): `scan` must give, for every call, the run the samples give one by one.
    /// Returns how many calls were compared, how many of them ran at least one sample, and how
    /// many ran as far as a call goes.
    fn compare(
        scan: impl Fn(&Ray, &Lattice, u32, &Masks<'_>) -> u32,
    ) -> Result<(u32, u32, u32), u32> {
        const DIMS: [u32; 3] = [13, 10, 9];
        let mut next = crate::testing::xorshift(0x5ca1_0001);
        let mut unit = move || (next() >> 8) as f32 / (1u32 << 24) as f32;
        let grid = Grid::new(DIMS, Vec3::ONE).expect("a valid grid");
        let data = [0.0f32; 13 * 10 * 9];
        let (mut calls, mut ran, mut whole) = (0, 0, 0);
        for case in 0..400u32 {
            // A slab of some of the planes (ghosts as far as the grid goes).
            let start = case % 6;
            let owned = start..(start + 1 + case % 7).min(DIMS[0]);
            let stored = crate::volume::slab::stored_planes(&grid, owned.clone(), 1);
            let len = (stored.end - stored.start) as usize * grid.plane_len();
            let slab = Slab::new(grid, owned.clone(), 1, &data[..len]).expect("a valid slab");
            let (_, _, blocks_len) = crate::skip::minmax::extent(&slab);
            let mut ranges = [BlockRange::UNKNOWN; 64];
            let mut masks = [0u64; 64];
            for m in masks.iter_mut() {
                // A tenth of the bits set: runs of empty cells, short and long, as in noise.
                *m = (0..64).fold(0, |m, b| m | u64::from(unit() < 0.1) << b);
            }
            crate::skip::minmax::build(&slab, &mut ranges[..blocks_len])
                .expect("storage of the extent");
            let blocks = Blocks::new(slab.grid(), slab.stored(), &ranges[..blocks_len])
                .and_then(|b| b.with_cells(&masks[..blocks_len]))
                .expect("blocks of the slab");
            let slab = slab.with_blocks(blocks);
            let index = Masks::of(&blocks, &grid, owned).expect("masks");
            // Origins in and about the grid, directions of every octant, axis-aligned ones
            // among them.
            let mut axis = |scale: f32| (unit() - 0.2) * scale;
            let origin = Vec3::new(axis(15.0), axis(12.0), axis(11.0));
            let mut dir = Vec3::new(axis(1.0) - 0.3, axis(1.0) - 0.3, axis(1.0) - 0.3);
            if case % 5 == 0 {
                dir = Vec3::new(dir.x, 0.0, 0.0);
            }
            let ray = Ray {
                origin,
                dir,
                dir_world: dir,
            };
            let dt = [0.5, 0.2, 0.37, 1.0][case as usize % 4];
            let Some(lattice) = Lattice::new(0.0, 40.0, dt) else {
                continue;
            };
            for k in 0..=lattice.last {
                let by_one = (1..=4 * STEPS)
                    .take_while(|&j| skippable(&ray, &lattice, k + j, &slab))
                    .count() as u32;
                if scan(&ray, &lattice, k, &index) != by_one {
                    return Err(case);
                }
                calls += 1;
                ran += u32::from(by_one > 0);
                whole += u32::from(by_one == 4 * STEPS);
            }
        }
        Ok((calls, ran, whole))
    }

    #[test]
    fn a_run_is_the_samples_the_marcher_would_skip() {
        let (calls, ran, whole) = compare(empty_run).unwrap_or_else(|case| panic!("case {case}"));
        // The comparison saw runs, not only samples that stop at once, and runs as long as a
        // call goes.
        assert!(
            ran > calls / 8 && whole > calls / 100,
            "{ran} of {calls} calls ran, {whole} all the way"
        );
    }

    #[test]
    fn a_scan_that_rounds_instead_of_flooring_is_caught() {
        // Negative control: the same scan with each cell rounded to the nearest whole number
        // (the first half of `floor_small`) misplaces samples, and the comparison says so.
        fn rounding(ray: &Ray, lattice: &Lattice, k: u32, masks: &Masks<'_>) -> u32 {
            let mut shifted = *ray;
            shifted.origin += Vec3::splat(0.5);
            empty_run(&shifted, lattice, k, masks)
        }
        assert!(compare(rounding).is_err());
    }

    #[test]
    fn a_scan_past_the_owned_planes_is_caught() {
        // Negative control: the same scan told that the slab owns every plane.
        fn unowned(ray: &Ray, lattice: &Lattice, k: u32, masks: &Masks<'_>) -> u32 {
            let every = Masks {
                owned: (0.0, f32::MAX),
                ..*masks
            };
            empty_run(ray, lattice, k, &every)
        }
        assert!(compare(unowned).is_err());
    }

    #[test]
    fn a_quarter_floor_is_the_block_of_a_cell() {
        let top = (1u32 << 23) - 1;
        for c in (0..1 << 16).chain(top - (1 << 16)..=top) {
            let lanes = Vec4::splat(c as f32);
            assert_eq!(quarter_floor(lanes), Vec4::splat((c / BLOCK) as f32), "{c}");
        }
    }

    #[test]
    fn the_floor_is_the_floor_on_its_range() {
        let mut next = crate::testing::xorshift(0x0f10_0123);
        for _ in 0..20_000 {
            let r = next();
            let v = match r % 4 {
                0 => (r >> 9) as f32,
                1 => f32::from_bits(next()).abs().min(8_388_607.5),
                _ => (r >> 8) as f32 / 256.0,
            };
            let v = Vec4::new(v, v * 0.25, v + 0.5, (v - 1.0).max(0.0));
            assert_eq!(floor_small(v), v.floor(), "{v}");
        }
    }
}

//! Depth bounds: for every pixel of a parallel projection, a ray parameter before which its
//! primary ray meets no cell of a slab that the view cannot skip, so that the ray passes over
//! every sample before it in one step instead of leaping through empty cells turn by turn
//! (on the paper's view most of those turns came before a ray's first evaluated sample).
//!
//! The bound of a pixel is the least, over the cells whose mask bit is set ([`crate::skip::cells`]:
//! the obstacles) that its ray may pass through once widened by [`WIDEN`] on every side, of
//! the least parameter at which any of the view's rays meets that widened cell. Which rays
//! pass through a cell, and at which parameters, are linear in the point for a parallel
//! projection: with the image's per-pixel steps `U`, `V`
//! and the rays' direction `D` (index space, as the rays hold them), a point `q` lies on the
//! ray of image coordinates `(a, b)` at parameter `t` exactly when `q = O + a·U + b·V + t·D`,
//! so `(a, b, t)` is one 3×3 inverse applied to `q − O`, and its range over a box is found
//! from the box's corners per axis. A cell is left out when each cell in front of it (one
//! cell back along each axis the rays move along) is an obstacle too: a line entering the
//! widened cell does so through a face toward the eye, and that face lies in the widened
//! cell in front, which the line reaches no later; following such cells forward ends at a
//! cell that is kept, so no pixel's bound rises. Blocks are taken nearest the eye first, and a
//! block whose every pixel already holds a bound no later than the block's nearest point is
//! passed over whole: it could lower none (on a big volume most blocks lie behind others).
//!
//! Invariants: a sample before its pixel's bound lies in no obstacle, so skipping it is what
//! the marcher would do turn by turn with the same masks: [`crate::trace::march`] skips through the
//! bound only while [`crate::trace::view::View::may_skip`] holds and only over owned planes, and the
//! image and every count are those of a render without bounds. The rays the kernel computes
//! differ from the exact lines `O + a·U + b·V + t·D` by rounding, and a sample's position
//! from its exact point on its line likewise; [`build`] refuses a view whose coordinates
//! could make either reach [`WIDEN`] / 4 (magnitudes over [`MAX_REACH`] index units), so a
//! sample whose computed cell is an obstacle lies on its pixel's exact line inside that
//! obstacle widened. A bound is rounded down to `f32`; a pixel no obstacle covers holds
//! infinity. Perspective views get no bounds.

use crate::node::topology::Rows;
use crate::skip::blocks::{Blocks, BLOCK};
pub use crate::skip::bounds::Depths;
use crate::skip::cells::{CellMask, ALL};
use crate::trace::camera::Projection;
use crate::trace::view::View;
use glam::{BVec3, DMat3, DVec3, Vec3};

/// How far each obstacle is widened on every side, in cells: the room left for rounding.
pub const WIDEN: f64 = 1.0 / 16.0;

/// How much wider than its cells' a block's image span and earlier than their parameters its
/// least parameter is taken, in pixels and index units: far more than the few units in the
/// last place by which the block's arithmetic and a cell's can round apart at coordinates up
/// to [`MAX_REACH`], far less than anything a bound or a pixel is decided by.
const BLOCK_SLACK: f64 = 1e-6;

/// The largest coordinate magnitude, in index units, for which the rounding of a ray's
/// origin, direction and samples stays under [`WIDEN`] / 4: each is a few `f32` operations
/// on numbers this large, each erring by at most 2⁻²⁴ of them, and 2¹⁴ · 2⁻²⁰ = 2⁻⁶.
pub const MAX_REACH: f64 = 16384.0;

/// Why [`build`] made no bounds.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DepthsError {
    /// The view is a perspective one: its rays are not parallel.
    Perspective,
    /// The blocks carry no cell masks to bound.
    NoMasks,
    /// Storage of `given` bounds for an image of `needed` pixels.
    Storage {
        /// Pixels of the image.
        needed: usize,
        /// Bounds given.
        given: usize,
    },
    /// The view's coordinates reach too far for the rounding allowance ([`MAX_REACH`]), or
    /// its geometry is degenerate.
    Reach,
}

impl core::fmt::Display for DepthsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            DepthsError::Perspective => write!(f, "a perspective view has no depth bounds"),
            DepthsError::NoMasks => write!(
                f,
                "depth bounds are built from cell masks, and there are none"
            ),
            DepthsError::Storage { needed, given } => {
                write!(f, "depth bounds for {needed} pixels, storage for {given}")
            }
            DepthsError::Reach => write!(
                f,
                "the view's coordinates exceed {MAX_REACH} index units, or its rays are degenerate"
            ),
        }
    }
}

impl core::error::Error for DepthsError {}

/// The linear map from index space to a view's image coordinates and ray parameter.
#[derive(Clone, Copy, Debug)]
struct Frame {
    /// Rows of the inverse of `[U V D]`: a point's image `a`, image `b` and parameter `t`,
    /// each from `q − origin`.
    rows: [DVec3; 3],
    origin: DVec3,
    /// Image size, pixels.
    width: u32,
    height: u32,
    /// The axes the rays move along, and each one's sign.
    moving: [bool; 3],
    rising: [bool; 3],
}

impl Frame {
    /// The frame of `view`'s parallel rays: `O`, `U` and `V` from its camera, `D` as its
    /// rays hold it.
    fn of(view: &View, box_hi: Vec3) -> Result<Frame, DepthsError> {
        let spec = view.spec();
        let camera = spec.camera;
        let Projection::Orthographic { width: world_w } = camera.projection() else {
            return Err(DepthsError::Perspective);
        };
        let (w, h) = (spec.width.max(1), spec.height.max(1));
        let world_w = f64::from(world_w);
        let world_h = world_w * f64::from(h) / f64::from(w);
        let inv = view.inv_spacing().as_dvec3();
        let (right, up) = camera.image_axes();
        let (r, u, e) = (
            right.as_dvec3() * inv,
            up.as_dvec3() * inv,
            camera.eye().as_dvec3() * inv,
        );
        let (pw, ph) = (world_w / f64::from(w), world_h / f64::from(h));
        // Pixel (a, b)'s ray starts at eye + right·((a + ½)·pw − W/2) + up·(H/2 − (b + ½)·ph).
        let (step_u, step_v) = (r * pw, u * -ph);
        let origin = e + r * (0.5 * pw - 0.5 * world_w) + u * (0.5 * world_h - 0.5 * ph);
        let d = view.primary_line(0).dir.as_dvec3();
        let columns = DMat3::from_cols(step_u, step_v, d);
        let det = columns.determinant();
        if !(det.is_finite() && det != 0.0) {
            return Err(DepthsError::Reach);
        }
        let inverse = columns.inverse();
        let rows = [0, 1, 2].map(|i| inverse.row(i));
        // The greatest magnitude the rays' arithmetic meets: origins across the image, and
        // the direction times the largest parameter a sample in the dataset's box can have.
        let t_far = (0..8)
            .map(|i| {
                let corner = DVec3::select(
                    BVec3::new(i & 1 != 0, i & 2 != 0, i & 4 != 0),
                    box_hi.as_dvec3(),
                    DVec3::ZERO,
                );
                rows[2].dot(corner - origin)
            })
            .fold(0.0f64, f64::max);
        let reach =
            (e.abs() + r.abs() * world_w + u.abs() * world_h + d.abs() * t_far).max_element();
        if !(reach <= MAX_REACH) {
            return Err(DepthsError::Reach);
        }
        Ok(Frame {
            rows,
            origin,
            width: w,
            height: h,
            moving: d.cmpne(DVec3::ZERO).into(),
            rising: d.cmpgt(DVec3::ZERO).into(),
        })
    }

    /// The pixel indices along one image axis whose coordinates lie in `[least, most]`
    /// (widened by a millionth of a pixel for the rounding of this arithmetic), within
    /// `0..n`.
    fn pixels(least: f64, most: f64, n: u32) -> core::ops::Range<u32> {
        let slack = 1e-6;
        // Kept within [-1, n] first, where truncating to an integer is exact; a NaN (which no
        // frame `Frame::of` accepts can give) widens to the whole axis, as `max` and `min`
        // return the other operand. Truncation, then a step where it went the wrong way,
        // rather than `libm`'s ceil and floor, which are calls on the build's inner loop.
        let n_f = f64::from(n);
        let lo = (least - slack).max(-1.0).min(n_f);
        let hi = (most + slack).min(n_f).max(-1.0);
        let (l, h) = (lo as i64, hi as i64);
        let first = (l + i64::from((l as f64) < lo)).max(0);
        let last = (h - i64::from((h as f64) > hi)).min(i64::from(n) - 1);
        match first <= last {
            true => first as u32..last as u32 + 1,
            false => 0..0,
        }
    }
}

/// Fill `out` (a bound per pixel of `view`'s rows `rows`, row-major) with the depth bounds of
/// the cells `blocks`' masks keep for `view` (see the module's text). The bounds of a row do
/// not depend on which other rows are built.
pub fn build(
    blocks: &Blocks<'_>,
    view: &View,
    rows: Rows,
    out: &mut [f32],
) -> Result<(), DepthsError> {
    let places = 0..rows.count(view.spec().height);
    build_places(blocks, view, rows, places, out)
}

/// [`build`]'s bounds of the rows at `places` among `rows` only, into `out` (those rows,
/// row-major): the same bits as [`build`] gives them, since a row's bounds do not depend on
/// the others. Parts of the rows can be built apart, on threads, into their own pieces of
/// one map. A part passes over a block none of whose rows it builds at the cost of placing
/// the block on the image's rows, and over a cell of other rows at the cost of placing the
/// cell on them, before anything else is found of it.
pub fn build_places(
    blocks: &Blocks<'_>,
    view: &View,
    rows: Rows,
    places: core::ops::Range<u32>,
    out: &mut [f32],
) -> Result<(), DepthsError> {
    place(blocks, view, rows, places, out, true).map(|_| ())
}

/// [`build_places`], passing over hidden blocks (see the loop) when `cull` holds; the blocks
/// passed over so.
fn place(
    blocks: &Blocks<'_>,
    view: &View,
    rows: Rows,
    places: core::ops::Range<u32>,
    out: &mut [f32],
    cull: bool,
) -> Result<u32, DepthsError> {
    blocks.masks().ok_or(DepthsError::NoMasks)?;
    let held = rows.count(view.spec().height);
    let places = places.start.min(held)..places.end.min(held);
    let pixels = places.len() * view.spec().width as usize;
    if out.len() != pixels {
        return Err(DepthsError::Storage {
            needed: pixels,
            given: out.len(),
        });
    }
    let (cols, ny, nz) = blocks.shape();
    let x0 = blocks.first_column() * BLOCK;
    let extent = [cols * BLOCK, ny * BLOCK, nz * BLOCK];
    let box_hi = Vec3::new((x0 + extent[0]) as f32, extent[1] as f32, extent[2] as f32);
    let frame = Frame::of(view, box_hi)?;
    out.fill(f32::INFINITY);
    // Each image coordinate and the parameter are linear in a cell's low corner `c`: over the
    // widened cell, `row·(c − O)` plus the least (or greatest) of `row·(−WIDEN)` and
    // `row·(1 + WIDEN)` per axis.
    let over_cell = |row: usize| {
        let r = frame.rows[row];
        let (near, far) = (r * -WIDEN, r * (1.0 + WIDEN));
        let at_origin = r.dot(frame.origin);
        (
            near.min(far).element_sum() - at_origin,
            near.max(far).element_sum() - at_origin,
        )
    };
    let (a_span, b_span, t_least) = (over_cell(0), over_cell(1), over_cell(2).0);
    // The same over a whole block widened alike, `BLOCK_SLACK` wider still, so that what
    // this arithmetic finds of a block holds what the arithmetic above finds of any of its
    // cells. Only filters: the cells are placed exactly below.
    let over_block = |row: usize| {
        let r = frame.rows[row];
        let (near, far) = (r * -WIDEN, r * (f64::from(BLOCK) + WIDEN));
        let at_origin = r.dot(frame.origin);
        (
            near.min(far).element_sum() - at_origin - BLOCK_SLACK,
            near.max(far).element_sum() - at_origin + BLOCK_SLACK,
        )
    };
    let (block_a, block_b, block_t) = (over_block(0), over_block(1), over_block(2).0);
    // A block none of whose rows is among `places` holds no cell that is, so a part passes
    // over it whole: its rows half a pixel wider still.
    let block_rows = (block_b.0 - 0.5, block_b.1 + 0.5);
    // The places among `places` of the rows whose image coordinates lie in `[lo, hi]`.
    let placed = |lo: f64, hi: f64| {
        let within = rows.within(Frame::pixels(lo, hi, frame.height));
        within.start.max(places.start)..within.end.min(places.end)
    };
    // A part that builds every row has no block to pass over.
    let every_row = places == (0..held);
    let w = frame.width as usize;
    let (bx0, bx1) = (blocks.first_column(), blocks.first_column() + cols);
    // The block in front of block `b` along `axis` (none past the blocks: no obstacle).
    let ahead = |b: u32, axis: usize| -> Option<u32> {
        let bounds = [(bx0, bx1), (0, ny), (0, nz)][axis];
        match frame.rising[axis] {
            true => b.checked_sub(1).filter(|&n| n >= bounds.0),
            false => Some(b + 1).filter(|&n| n < bounds.1),
        }
    };
    // Blocks nearer the eye first along every axis the rays move along, so that the bounds
    // of the blocks in front are in place when a block behind them comes.
    let toward = |axis: usize, n: u32, i: u32| match frame.rising[axis] {
        true => i,
        false => n - 1 - i,
    };
    let mut passed_over = 0;
    let (moving, rising) = (frame.moving, frame.rising);
    for ix in 0..cols {
        let bx = bx0 + toward(0, cols, ix);
        for iz in 0..nz {
            let bz = toward(2, nz, iz);
            // This column's masks and those of the columns in front along X and Z, read as
            // slices: a block's neighbours in front are then at its own index, or one over.
            let column = |x: Option<u32>, z: Option<u32>| match (x, z) {
                (Some(x), Some(z)) => blocks.column_masks(x, z),
                _ => &[],
            };
            let (front_x, own, front_z) = (
                column(ahead(bx, 0), Some(bz)),
                blocks.column_masks(bx, bz),
                column(Some(bx), ahead(bz, 2)),
            );
            // The mask at `i` of `masks`; none past the blocks: no obstacle.
            let mask_at = |masks: &[CellMask], i: Option<u32>| -> CellMask {
                i.and_then(|i| masks.get(i as usize)).copied().unwrap_or(0)
            };
            // Most blocks of a big volume keep no cell: passed over a word of them at a time.
            for (by, mask) in blocks.kept_in_column(bx, bz, rising[1]) {
                let corner = DVec3::new(
                    f64::from(bx * BLOCK),
                    f64::from(by * BLOCK),
                    f64::from(bz * BLOCK),
                );
                let at = |row: usize| frame.rows[row].dot(corner);
                if !every_row && placed(at(1) + block_rows.0, at(1) + block_rows.1).is_empty() {
                    continue;
                }
                // The cells whose front neighbour is an obstacle, along every moving axis:
                // along X and Z the block at this one's index in the columns in front, along
                // Y the one next toward the eye in its own column. Each axis's shifts are
                // constants: this runs for every block that keeps a cell.
                let mut hidden = ALL;
                if moving[0] {
                    hidden &= in_front::<0>(mask, mask_at(front_x, Some(by)), rising[0]);
                }
                if moving[1] {
                    hidden &= in_front::<1>(mask, mask_at(own, ahead(by, 1)), rising[1]);
                }
                if moving[2] {
                    hidden &= in_front::<2>(mask, mask_at(front_z, Some(by)), rising[2]);
                }
                let mut visible = mask & !hidden;
                if visible == 0 {
                    continue;
                }
                // A block whose every pixel already holds a bound no greater than any of its
                // cells could give is hidden behind blocks placed before it: placing its
                // cells would lower nothing. `round_down` keeps order, so a bound at most
                // the block's rounded least parameter is at most each cell's.
                if cull {
                    let least = round_down(at(2) + block_t);
                    let mut ys = placed(at(1) + block_b.0, at(1) + block_b.1);
                    let a = at(0);
                    let columns = Frame::pixels(a + block_a.0, a + block_a.1, frame.width);
                    let hidden_behind = ys.all(|place| {
                        let row = (place - places.start) as usize * w;
                        let span = row + columns.start as usize..row + columns.end as usize;
                        out.get(span)
                            .is_some_and(|slots| slots.iter().all(|&slot| slot <= least))
                    });
                    if hidden_behind {
                        passed_over += 1;
                        continue;
                    }
                }
                while visible != 0 {
                    let i = visible.trailing_zeros();
                    visible &= visible - 1;
                    let c = DVec3::new(
                        f64::from(bx * BLOCK + i % BLOCK),
                        f64::from(by * BLOCK + i / BLOCK % BLOCK),
                        f64::from(bz * BLOCK + i / (BLOCK * BLOCK)),
                    );
                    let at = |row: usize| frame.rows[row].dot(c);
                    let b = at(1);
                    let ys = placed(b + b_span.0, b + b_span.1);
                    if ys.is_empty() {
                        continue;
                    }
                    let a = at(0);
                    let t = round_down(at(2) + t_least);
                    let columns = Frame::pixels(a + a_span.0, a + a_span.1, frame.width);
                    for place in ys {
                        let row = (place - places.start) as usize * w;
                        let span = row + columns.start as usize..row + columns.end as usize;
                        if let Some(slots) = out.get_mut(span) {
                            for slot in slots {
                                *slot = slot.min(t);
                            }
                        }
                    }
                }
            }
        }
    }
    Ok(passed_over)
}

/// The cells of a block (mask `mask`) whose neighbour one cell back along axis `AXIS` (down
/// when the rays rise along it, up when they fall) is an obstacle, given the mask `beyond` of
/// the block that neighbour lies in at the block's face.
#[inline(always)]
fn in_front<const AXIS: usize>(mask: CellMask, beyond: CellMask, rising: bool) -> CellMask {
    // Bit `x + 4y + 16z`: one cell along `AXIS` is `stride` bits; `face` holds the cells at
    // offset 0 along it, `far` those at offset 3.
    let stride = [1, 4, 16][AXIS];
    let face = [0x1111_1111_1111_1111u64, 0x000F_000F_000F_000F, 0xFFFF][AXIS];
    let far = face << (3 * stride);
    match rising {
        // The neighbour below: inside the block one stride down; at offset 0, the block
        // below's cell at offset 3.
        true => ((mask << stride) & !face) | ((beyond & far) >> (3 * stride)),
        false => ((mask >> stride) & !far) | ((beyond & face) << (3 * stride)),
    }
}

/// The greatest `f32` not above `x` (the crate's MSRV predates `f32::next_down`).
fn round_down(x: f64) -> f32 {
    let f = x as f32;
    if f64::from(f) <= x {
        return f;
    }
    // `f` rounded up: the next `f32` toward minus infinity, one unit in the last place.
    if f > 0.0 {
        f32::from_bits(f.to_bits() - 1)
    } else if f == 0.0 {
        -f32::from_bits(1)
    } else {
        f32::from_bits(f.to_bits() + 1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optics::surface::IsoSurface;
    use crate::skip::blocks::Range;
    use crate::trace::camera::Camera;
    use crate::trace::view::{Mode, ViewSpec};
    use crate::volume::field;
    use crate::volume::grid::{Grid, Model};
    use crate::volume::slab::Slab;

    /// The cells of a block whose neighbour one cell back along an axis is an obstacle, one
    /// cell at a time.
    #[test]
    fn cells_in_front_are_found_across_the_block_face() {
        let mut next = crate::testing::xorshift(0x0dd_f00d);
        let bits = |n: &mut dyn FnMut() -> u32| u64::from(n()) << 32 | u64::from(n());
        for _ in 0..2000 {
            let (mask, beyond) = (bits(&mut next), bits(&mut next));
            for axis in 0..3 {
                for rising in [true, false] {
                    let found = match axis {
                        0 => in_front::<0>(mask, beyond, rising),
                        1 => in_front::<1>(mask, beyond, rising),
                        _ => in_front::<2>(mask, beyond, rising),
                    };
                    for i in 0..64u32 {
                        let mut at = [i % 4, i / 4 % 4, i / 16];
                        let stride = [1u32, 4, 16][axis];
                        // Inside the block unless the cell is on the face the rays enter by.
                        let inside = at[axis] != if rising { 0 } else { 3 };
                        let neighbour = match (inside, rising) {
                            (true, true) => mask >> (i - stride) & 1,
                            (true, false) => mask >> (i + stride) & 1,
                            (false, true) => {
                                at[axis] = 3;
                                beyond >> (at[0] + 4 * at[1] + 16 * at[2]) & 1
                            }
                            (false, false) => {
                                at[axis] = 0;
                                beyond >> (at[0] + 4 * at[1] + 16 * at[2]) & 1
                            }
                        };
                        assert_eq!(
                            found >> i & 1,
                            neighbour,
                            "axis {axis} rising {rising} cell {i}"
                        );
                    }
                }
            }
        }
    }

    /// For each pixel, the samples of its primary ray below its bound that lie in the blocks'
    /// columns, as `(in an obstacle, not)`, each sample placed as the marcher places it.
    fn below_bounds(blocks: &Blocks<'_>, view: &View, bounds: &[f32], grid: &Grid) -> (u32, u32) {
        let (mut bad, mut good) = (0, 0);
        let columns =
            blocks.first_column() * BLOCK..(blocks.first_column() + blocks.shape().0) * BLOCK;
        for pixel in 0..view.pixel_count() as u32 {
            let Some(ray) = view.primary_ray(pixel) else {
                continue;
            };
            for k in 0..=ray.lattice.last {
                let t = ray.lattice.t(k);
                if !(t < bounds[pixel as usize]) {
                    break;
                }
                let lo = field::corner4(grid, Model::Cell, ray.ray.at4(t)).lo;
                if !columns.contains(&lo[0]) {
                    continue;
                }
                match blocks.cells(blocks.block_of(lo)) & crate::skip::cells::bit(lo) {
                    0 => good += 1,
                    _ => bad += 1,
                }
            }
        }
        (bad, good)
    }

    /// No sample of a pixel's ray below its bound lies in a cell whose mask bit is set: random
    /// masks from empty to nearly full, anisotropic grids, whole volumes and slabs' columns,
    /// parallel views from every side, along an axis (rays parallel to faces), from outside,
    /// from inside and from far away (the view refused where too far), steps from 1/64 to 2;
    /// each cluster's rows built alone, and rows built in parts, are the same bounds. And the
    /// bounds pass over samples: the check is not vacuous. A bound raised by one step is
    /// caught (the negative control).
    #[test]
    fn no_sample_below_a_bound_lies_in_a_cell_that_shows() {
        let mut next = crate::testing::xorshift(0x5eed_d3b7);
        let (mut passed, mut raised_caught, mut far_rounds) = (0u32, 0u32, 0u32);
        let mut part_missed = 0u32;
        let data = [0u8; 16 * 16 * 16];
        for round in 0..400 {
            let dims = [2 + next() % 15, 2 + next() % 15, 2 + next() % 15];
            let spacing = [0, 1, 2].map(|_| [1.0, 0.5, 2.0, 0.3][(next() % 4) as usize]);
            let grid = Grid::new(dims, Vec3::from_array(spacing)).unwrap();
            let n = grid.plane_len() * dims[0] as usize;
            // The whole volume, or a slab of a few planes (its blocks' columns).
            let slab = match round % 2 {
                0 => Slab::whole(grid, &data[..n]).unwrap(),
                _ => {
                    let start = next() % dims[0];
                    let owned = start..(start + 1 + next() % 5).min(dims[0]);
                    let stored = crate::volume::slab::stored_planes(&grid, owned.clone(), 1);
                    let len = (stored.end - stored.start) as usize * grid.plane_len();
                    Slab::new(grid, owned, 1, &data[..len]).unwrap()
                }
            };
            let ranges = [Range::UNKNOWN; 4 * 4 * 4];
            let (_, _, len) = crate::skip::minmax::extent(&slab);
            let blocks = Blocks::new(slab.grid(), slab.stored(), &ranges[..len]).unwrap();
            let density = next() % 64;
            let mut masks = [0u64; 4 * 4 * 4];
            for m in masks.iter_mut().take(len) {
                for bit in 0..64 {
                    if next() % 64 < density / 4 {
                        *m |= 1 << bit;
                    }
                }
            }
            let blocks = blocks.with_cells(&masks[..len]).unwrap();
            let centre = Vec3::from_array(dims.map(|d| d as f32 / 2.0)) * Vec3::from_array(spacing);
            let mut eye = Vec3::new(
                (next() % 80) as f32 - 40.0,
                (next() % 80) as f32 - 40.0,
                (next() % 80) as f32 - 40.0,
            );
            if round % 4 == 0 {
                eye = centre;
                eye[(next() % 3) as usize] += [30.0, -30.0][(next() % 2) as usize];
            }
            if round % 7 == 0 {
                eye = centre * 0.9;
            }
            // Far away, where the rays' rounding is largest: thousands of index units.
            let far = round % 5 == 1;
            if far {
                eye = centre + (eye - centre).normalize_or_zero() * 4000.0;
            }
            let up = match (centre - eye).normalize_or_zero().cross(Vec3::Y).length() > 1e-3 {
                true => Vec3::Y,
                false => Vec3::Z,
            };
            let Ok(camera) = Camera::look_at(
                eye,
                centre,
                up,
                Projection::Orthographic {
                    width: 4.0 + (next() % 30) as f32,
                },
            ) else {
                continue;
            };
            let mut surfaces = heapless::Vec::new();
            let _ = surfaces.push(IsoSurface {
                iso: 100.0,
                color: Vec3::ONE,
                transparency: 0.0,
            });
            let view = View::new(
                ViewSpec {
                    width: 3 + next() % 20,
                    height: 3 + next() % 20,
                    dt: [1.0 / 64.0, 0.2, 0.5, 1.0, 2.0][(next() % 5) as usize],
                    ..crate::testing::spec(camera, Mode::Surfaces(surfaces))
                },
                &grid,
            )
            .unwrap();
            let mut bounds = [0.0f32; 22 * 22];
            let pixels = view.pixel_count() as usize;
            match build(&blocks, &view, Rows::ALL, &mut bounds[..pixels]) {
                // Too far for the allowance on a fine anisotropic grid: refused, never wrong.
                Err(DepthsError::Reach) if far => continue,
                built => built.unwrap(),
            }
            far_rounds += u32::from(far);
            // A cluster's rows alone: the same bounds there, read by pixel.
            let (width, height) = (view.spec().width, view.spec().height);
            let clusters = 1 + (next() % 4) as u16;
            for cluster in 0..clusters {
                let rows = Rows::of_cluster(cluster, clusters).unwrap();
                let held = (rows.count(height) * width) as usize;
                let mut part = [0.0f32; 22 * 22];
                build(&blocks, &view, rows, &mut part[..held]).unwrap();
                let read = Depths::new(&part[..held], width, rows);
                for pixel in 0..pixels as u32 {
                    let (row, theirs) = (pixel / width, read.bound(pixel));
                    match row % u32::from(clusters) == u32::from(cluster) {
                        true => assert_eq!(theirs, bounds[pixel as usize], "round {round}"),
                        false => assert_eq!(theirs, f32::NEG_INFINITY, "round {round}"),
                    }
                }
            }
            // Rows built in two parts, each into its piece of one map: the same bounds. The
            // control: the second part left unbuilt is missed somewhere.
            let cut = next() % (height + 1);
            let (mut parts, mut first_only) = ([0.0f32; 22 * 22], [f32::INFINITY; 22 * 22]);
            let at = cut as usize * width as usize;
            let (low, high) = parts[..pixels].split_at_mut(at);
            build_places(&blocks, &view, Rows::ALL, 0..cut, low).unwrap();
            build_places(&blocks, &view, Rows::ALL, cut..height, high).unwrap();
            build_places(&blocks, &view, Rows::ALL, 0..cut, &mut first_only[..at]).unwrap();
            let same = |a: &[f32]| {
                let pairs = a.iter().zip(&bounds[..pixels]);
                pairs.into_iter().all(|(a, b)| a.to_bits() == b.to_bits())
            };
            assert!(same(&parts[..pixels]), "round {round}: rows cut at {cut}");
            part_missed += u32::from(!same(&first_only[..pixels]));
            let (bad, good) = below_bounds(&blocks, &view, &bounds[..pixels], &grid);
            assert_eq!(
                bad, 0,
                "round {round}: {bad} samples below a bound in a cell that shows"
            );
            passed += good;
            // The negative control: a step more, and some sample in a cell that shows is
            // passed over (where any lies behind a bound at all).
            let raised = bounds.map(|b| b + view.spec().dt * 1.01);
            raised_caught +=
                u32::from(below_bounds(&blocks, &view, &raised[..pixels], &grid).0 > 0);
        }
        assert!(passed > 10_000, "only {passed} samples passed over");
        assert!(far_rounds > 20, "only {far_rounds} rounds from far away");
        assert!(
            raised_caught > 100,
            "raised bounds caught in only {raised_caught} rounds"
        );
        assert!(
            part_missed > 100,
            "a part left unbuilt changed the bounds in only {part_missed} rounds"
        );
    }

    /// Passing over the blocks hidden behind others gives the bounds that placing every
    /// cell gives, bit for bit: volumes of a few blocks to a side, masks from sparse to
    /// nearly full (dense masks hide blocks), whole images and parts of rows, views from
    /// every side. And blocks are passed over: the comparison is not vacuous.
    #[test]
    fn hidden_blocks_passed_over_change_no_bound() {
        let mut next = crate::testing::xorshift(0x0b10_c4ed);
        let data = [0u8; 28 * 28 * 28];
        let mut passed_over = 0u32;
        for round in 0..800 {
            let dims = [8 + next() % 21, 8 + next() % 21, 8 + next() % 21];
            let spacing = [0, 1, 2].map(|_| [1.0, 0.5, 2.0][(next() % 3) as usize]);
            let grid = Grid::new(dims, Vec3::from_array(spacing)).unwrap();
            let n = grid.plane_len() * dims[0] as usize;
            let slab = Slab::whole(grid, &data[..n]).unwrap();
            let ranges = [Range::UNKNOWN; 7 * 7 * 7];
            let (_, _, len) = crate::skip::minmax::extent(&slab);
            let blocks = Blocks::new(slab.grid(), slab.stored(), &ranges[..len]).unwrap();
            let density = next() % 65;
            let mut masks = [0u64; 7 * 7 * 7];
            for m in masks.iter_mut().take(len) {
                for bit in 0..64 {
                    if next() % 64 < density {
                        *m |= 1 << bit;
                    }
                }
            }
            let blocks = blocks.with_cells(&masks[..len]).unwrap();
            let centre = Vec3::from_array(dims.map(|d| d as f32 / 2.0)) * Vec3::from_array(spacing);
            let eye = centre
                + Vec3::new(
                    (next() % 80) as f32 - 40.0,
                    (next() % 80) as f32 - 40.0,
                    (next() % 80) as f32 - 40.0,
                );
            let up = match (centre - eye).normalize_or_zero().cross(Vec3::Y).length() > 1e-3 {
                true => Vec3::Y,
                false => Vec3::Z,
            };
            let projection = Projection::Orthographic {
                width: 10.0 + (next() % 40) as f32,
            };
            let Ok(camera) = Camera::look_at(eye, centre, up, projection) else {
                continue;
            };
            let mut surfaces = heapless::Vec::new();
            let _ = surfaces.push(IsoSurface {
                iso: 100.0,
                color: Vec3::ONE,
                transparency: 0.0,
            });
            let spec = ViewSpec {
                width: 5 + next() % 40,
                height: 5 + next() % 40,
                ..crate::testing::spec(camera, Mode::Surfaces(surfaces))
            };
            let view = View::new(spec, &grid).unwrap();
            let height = view.spec().height;
            let start = next() % height;
            let places = start..start + 1 + next() % (height - start);
            let pixels = places.len() * view.spec().width as usize;
            let (mut culled, mut every) = ([0.0f32; 45 * 45], [0.0f32; 45 * 45]);
            let rows = Rows::ALL;
            let found = place(
                &blocks,
                &view,
                rows,
                places.clone(),
                &mut culled[..pixels],
                true,
            );
            place(&blocks, &view, rows, places, &mut every[..pixels], false).unwrap();
            passed_over += found.unwrap();
            let same = culled
                .iter()
                .zip(&every)
                .all(|(a, b)| a.to_bits() == b.to_bits());
            assert!(
                same,
                "round {round}: a hidden block passed over changed a bound"
            );
        }
        assert!(passed_over > 1000, "only {passed_over} blocks passed over");
    }

    #[test]
    fn pixel_ranges_are_the_whole_indices_within_the_span() {
        let reference = |least: f64, most: f64, n: u32| {
            let first = libm::ceil(least - 1e-6).max(0.0);
            let last = libm::floor(most + 1e-6).min(f64::from(n) - 1.0);
            match first <= last {
                true => first as u32..last as u32 + 1,
                false => 0..0,
            }
        };
        let values = [
            -1e9,
            -3.5,
            -1.0,
            -0.5,
            -1e-7,
            0.0,
            1e-7,
            0.3,
            1.0,
            2.0,
            2.5,
            9.0,
            9.999_999_5,
            10.0,
            11.5,
            1e9,
        ];
        for &least in &values {
            for &most in &values {
                for n in [1, 10, 12] {
                    assert_eq!(
                        Frame::pixels(least, most, n),
                        reference(least, most, n),
                        "{least} {most} {n}"
                    );
                }
            }
        }
        assert_eq!(Frame::pixels(f64::NAN, f64::NAN, 7), 0..7);
    }

    #[test]
    fn bounds_round_down_to_f32() {
        for x in [
            0.1f64, -0.1, 1e-45, -1e-45, 3.0, -3.0, 1e39, -1e39, 0.0, 16777217.0,
        ] {
            let f = round_down(x);
            assert!(f64::from(f) <= x, "{x}: {f}");
            let up = match f {
                f if f >= 0.0 => f32::from_bits(f.to_bits() + 1),
                f => f32::from_bits(f.to_bits() - 1),
            };
            assert!(
                f64::from(up) > x || f == f32::MAX,
                "{x}: {f} is not the greatest"
            );
        }
    }

    #[test]
    fn views_without_parallel_near_rays_get_no_bounds() {
        let grid = Grid::new([9, 9, 9], Vec3::ONE).unwrap();
        let data = [0u8; 729];
        let slab = Slab::whole(grid, &data).unwrap();
        let ranges = [Range::UNKNOWN; 8];
        let masks = [u64::MAX; 8];
        let blocks = Blocks::new(slab.grid(), slab.stored(), &ranges).unwrap();
        let with_masks = blocks.with_cells(&masks).unwrap();
        let view = |eye: Vec3, projection| {
            let camera = Camera::look_at(eye, Vec3::splat(4.0), Vec3::Y, projection).unwrap();
            let mut surfaces = heapless::Vec::new();
            let _ = surfaces.push(IsoSurface {
                iso: 100.0,
                color: Vec3::ONE,
                transparency: 0.0,
            });
            View::new(
                crate::testing::spec(camera, Mode::Surfaces(surfaces)),
                &grid,
            )
            .unwrap()
        };
        let parallel = view(
            Vec3::new(2.0, 2.0, 20.0),
            Projection::Orthographic { width: 6.0 },
        );
        let mut out = [0.0f32; 16];
        assert_eq!(
            build(&blocks, &parallel, Rows::ALL, &mut out),
            Err(DepthsError::NoMasks)
        );
        assert_eq!(
            build(&with_masks, &parallel, Rows::ALL, &mut out[..15]),
            Err(DepthsError::Storage {
                needed: 16,
                given: 15
            })
        );
        assert_eq!(build(&with_masks, &parallel, Rows::ALL, &mut out), Ok(()));
        let persp = view(
            Vec3::new(2.0, 2.0, 20.0),
            Projection::Perspective { fov_y: 0.5 },
        );
        assert_eq!(
            build(&with_masks, &persp, Rows::ALL, &mut out),
            Err(DepthsError::Perspective)
        );
        let far = view(
            Vec3::new(2.0, 2.0, 1e5),
            Projection::Orthographic { width: 6.0 },
        );
        assert_eq!(
            build(&with_masks, &far, Rows::ALL, &mut out),
            Err(DepthsError::Reach)
        );
    }
}

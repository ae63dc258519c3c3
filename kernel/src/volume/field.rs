//! The continuous field a slab defines under a model: nearest (voxel) or trilinear (cell)
//! reads at index-space points, and the object-space gradient by central differences.
//!
//! Invariants: positions are clamped into the grid before any read, so no position reads
//! outside the grid: infinities clamp to the nearer edge and NaN to the low edge, and still
//! yield a finite value. Each read is counted.

use crate::counters::Counters;
use crate::volume::grid::{Grid, Model};
use crate::volume::sample::Sample;
use crate::volume::slab::Slab;
use glam::{Vec3, Vec3A, Vec4};
use voxcube_simd as whole;

/// Node `(x, y, z)`'s value, or zero where `slab` does not store it (counted).
#[inline]
pub(crate) fn read<T: Sample>(
    slab: &Slab<'_, T>,
    x: u32,
    y: u32,
    z: u32,
    counters: &mut Counters,
) -> f32 {
    match slab.get(x, y, z) {
        Some(v) => v.to_f32(),
        None => {
            counters.slab_misses += 1;
            0.0
        }
    }
}

/// Where a point reads the grid under a model: the nodes and fractions that the ownership
/// rule, the block lookup and the interpolation all need, found once per sample (each would
/// otherwise clamp and floor the same coordinates again).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Site {
    /// The cell's low corner (cell model) or the nearest node (voxel model).
    pub lo: [u32; 3],
    /// The cell's high corner, `lo + 1` clamped into the grid (voxel model: `lo`).
    pub hi: [u32; 3],
    /// The position inside the cell, each coordinate in `[0, 1]` (voxel model: zero).
    pub frac: Vec3,
}

impl Site {
    /// The X plane that owns a sample here: equal to [`Grid::owner_plane`] of the point's
    /// `x` under the same model, for every `f32` (tested), so either may decide ownership.
    #[inline]
    pub fn plane(&self) -> u32 {
        self.lo[0]
    }
}

/// The [`Site`] of index-space point `p` in `grid` under `model`.
#[inline]
pub fn locate(grid: &Grid, model: Model, p: Vec3) -> Site {
    locate4(grid, model, p.extend(0.0))
}

/// [`locate`] of the point in the first three lanes of `q`: the sample loop computes its
/// positions in four lanes and passes them on as they are.
#[inline]
pub fn locate4(grid: &Grid, model: Model, q: Vec4) -> Site {
    corner4(grid, model, q).site(grid)
}

/// The first step of [`locate4`]: the corner a point reads, with what finishing its
/// [`Site`] needs. The sample loop decides from the corner alone whether a sample is read
/// (its owner plane, block and cell), and finds the far corner and the fractions only for
/// the samples it reads.
#[derive(Clone, Copy, Debug)]
pub struct Corner {
    /// [`Site::lo`].
    pub lo: [u32; 3],
    /// The position clamped into the grid, and the corner as floats; `None`: voxel model.
    cell: Option<(Vec4, Vec4)>,
}

impl Corner {
    /// The cell-model corner as whole floats, [`cell4`] of the same point; `None` under the
    /// voxel model.
    #[inline]
    pub fn cell(&self) -> Option<Vec4> {
        self.cell.map(|(_, corner)| corner)
    }

    /// [`Site::plane`].
    #[inline]
    pub fn plane(&self) -> u32 {
        self.lo[0]
    }

    /// The whole [`Site`], in every bit the one [`locate4`] gives.
    #[inline]
    pub fn site(&self, grid: &Grid) -> Site {
        match self.cell {
            None => Site {
                lo: self.lo,
                hi: self.lo,
                frac: Vec3::ZERO,
            },
            Some((v, corner)) => {
                let dims = grid.dims();
                let lo = self.lo;
                Site {
                    lo,
                    hi: core::array::from_fn(|a| (lo[a] + 1).min(dims[a] - 1)),
                    frac: (v - corner).truncate(),
                }
            }
        }
    }
}

/// The [`Corner`] of the point in the first three lanes of `q`.
#[inline]
pub fn corner4(grid: &Grid, model: Model, q: Vec4) -> Corner {
    // The three axes in the lanes of one vector, for every sample and every read: clamped
    // into [0, n - 1] (`q > 0` is false for NaN and -0.0, which land on +0.0), where
    // truncation is the floor and exact (n ≤ 2^23, `Grid::new` checks). Equal to the
    // per-axis definition in the tests for every kind of f32.
    let (last_node, last_cell) = grid.last_indices();
    let v = clamped(q, last_node);
    match model {
        // The nearest node, halves rounding up: `v + 0.5` truncated, kept in the grid.
        Model::Voxel => Corner {
            lo: whole_lanes(whole::trunc((v + Vec4::splat(0.5)).min(last_node))),
            cell: None,
        },
        Model::Cell => {
            let corner = cell_of(v, last_cell);
            Corner {
                lo: whole_lanes(corner),
                cell: Some((v, corner)),
            }
        }
    }
}

/// The cell-model [`Corner::lo`] of the point in the first three lanes of `q`, as whole
/// floats in those lanes (the `w` lane is some whole number too): in every bit the corner
/// [`corner4`] finds, for walks that compare cells with faces in vector lanes and need the
/// integers only where they read a map.
#[inline(always)]
pub fn cell4(grid: &Grid, q: Vec4) -> Vec4 {
    let (last_node, last_cell) = grid.last_indices();
    cell_of(clamped(q, last_node), last_cell)
}

/// The cell-model corner of a point `v` clamped into the grid: its floor, kept off the last
/// node (truncation is the floor there).
#[inline(always)]
fn cell_of(v: Vec4, last_cell: Vec4) -> Vec4 {
    whole::trunc(v.min(last_cell))
}

/// `q` clamped into `[0, last_node]`: `q > 0` is false for NaN and -0.0, which land on +0.0.
#[inline(always)]
fn clamped(q: Vec4, last_node: Vec4) -> Vec4 {
    Vec4::select(q.cmpgt(Vec4::ZERO), q, Vec4::ZERO).min(last_node)
}

/// `2^23`: the least `f32` from which on every representable number is whole, so adding it
/// to a number in `[0, 2^23]` rounds that number to a whole one and leaves it in the
/// mantissa's low bits.
pub(crate) const MAGIC: f32 = (1u32 << 23) as f32;

/// The first three lanes of `v` as integers, each lane a whole number in `[0, 2^23]` (as
/// [`locate`] clamps them, `n ≤ MAX_DIM`): exact. `as` would check every lane for NaN and
/// overflow, one lane at a time, which no lane here needs, on every sample.
#[inline(always)]
pub(crate) fn whole_lanes(v: Vec4) -> [u32; 3] {
    let [x, y, z, _] = whole_lanes4(v);
    [x, y, z]
}

/// Every lane of `v` as an integer, exactly for a whole number in `[0, 2^23]`
/// ([`whole::lanes`]); any other lane gives some integer, never a panic.
#[inline(always)]
pub(crate) fn whole_lanes4(v: Vec4) -> [u32; 4] {
    whole::lanes(v)
}

/// The field value at index-space point `p` under `model`.
#[inline]
pub fn value<T: Sample>(slab: &Slab<'_, T>, model: Model, p: Vec3, counters: &mut Counters) -> f32 {
    value_at(slab, model, &locate(slab.grid(), model, p), counters)
}

/// The field value at `site` (found under `model`).
#[inline(always)]
pub fn value_at<T: Sample>(
    slab: &Slab<'_, T>,
    model: Model,
    site: &Site,
    counters: &mut Counters,
) -> f32 {
    match model {
        Model::Voxel => {
            counters.lookups += 1;
            let [x, y, z] = site.lo;
            read(slab, x, y, z, counters)
        }
        Model::Cell => interpolate(slab, site, counters),
    }
}

/// The value of the grid node nearest to `p` (halves round up, as [`Grid::owner_plane`]).
pub fn nearest<T: Sample>(slab: &Slab<'_, T>, p: Vec3, counters: &mut Counters) -> f32 {
    value_at(
        slab,
        Model::Voxel,
        &locate(slab.grid(), Model::Voxel, p),
        counters,
    )
}

/// The trilinear interpolation of the eight nodes of the cell around `p`.
#[inline]
pub fn trilinear<T: Sample>(slab: &Slab<'_, T>, p: Vec3, counters: &mut Counters) -> f32 {
    interpolate(slab, &locate(slab.grid(), Model::Cell, p), counters)
}

/// The trilinear interpolation of the eight nodes of the cell at `site` (cell model).
#[inline(always)]
fn interpolate<T: Sample>(slab: &Slab<'_, T>, site: &Site, counters: &mut Counters) -> f32 {
    counters.interpolations += 1;
    let ([x0, y0, z0], [x1, y1, z1]) = (site.lo, site.hi);
    let (low, high) = match slab.cell((x0, x1), (y0, y1), (z0, z1)) {
        Some(cell) => x_lanes(cell),
        None => cell_missing(slab, (x0, x1), (y0, y1), (z0, z1), counters),
    };
    lerp_x_lanes(low, high, site.frac)
}

/// The trilinear interpolation of a cell's eight nodes (corner bits `z y x` from 000 to 111)
/// at fractions `frac`: in every bit the value [`trilinear`] finds for a point there.
#[inline(always)]
pub(crate) fn lerp_cell<T: Sample>(cell: [T; 8], frac: Vec3) -> f32 {
    let (low, high) = x_lanes(cell);
    lerp_x_lanes(low, high, frac)
}

/// A cell's low-x and high-x nodes as the four lerps along X take them. The lanes are built
/// from the loaded values directly: going through an array on the stack costs a
/// store-forwarding stall.
#[inline(always)]
fn x_lanes<T: Sample>(cell: [T; 8]) -> (Vec4, Vec4) {
    let [c000, c100, c010, c110, c001, c101, c011, c111] = cell;
    (
        Vec4::new(c000.to_f32(), c010.to_f32(), c001.to_f32(), c011.to_f32()),
        Vec4::new(c100.to_f32(), c110.to_f32(), c101.to_f32(), c111.to_f32()),
    )
}

/// The four lerps along X, one per lane, then Y and Z. Each lane rounds exactly as the
/// scalar `lerp` (glam never fuses), and all four lanes hold data: left to itself the compiler
/// packs two lanes and leaves stale values in the others, which can be subnormal and stall
/// every multiply that follows.
#[inline(always)]
fn lerp_x_lanes(low: Vec4, high: Vec4, frac: Vec3) -> f32 {
    let Vec3 {
        x: fx,
        y: fy,
        z: fz,
    } = frac;
    let [c00, c10, c01, c11] = (low + Vec4::splat(fx) * (high - low)).to_array();
    lerp(lerp(c00, c10, fy), lerp(c01, c11, fy), fz)
}

/// The cell-model corner of a point `q` in the grid's interior (every axis strictly between
/// 0 and the last node, where [`corner4`]'s clamp changes nothing): `trunc(q)` as whole
/// floats and as integers, in every bit the corner [`corner4`] and [`cell4`] find there.
#[inline(always)]
pub(crate) fn interior_corner(q: Vec4) -> (Vec4, [u32; 3]) {
    whole::trunc_lanes(q)
}

/// The trilinear value at four points at once, the four rays of a packet in the four SIMD
/// lanes: equal in every bit to [`trilinear`] at each point (every lane does the same
/// operations in the same order). Locating and gathering stay per point; the seven lerps run
/// once for all four. `voxcube bench` measures whether tracing rays in packets would pay.
pub fn trilinear4<T: Sample>(
    slab: &Slab<'_, T>,
    p: [Vec3; 4],
    counters: &mut Counters,
) -> [f32; 4] {
    counters.interpolations += 4;
    let sites = p.map(|q| locate(slab.grid(), Model::Cell, q));
    // corners[c][lane], corner bits z y x as in `Slab::cell`.
    let mut corners = [[0.0f32; 4]; 8];
    for (lane, site) in sites.iter().enumerate() {
        let ([x0, y0, z0], [x1, y1, z1]) = (site.lo, site.hi);
        let values = match slab.cell((x0, x1), (y0, y1), (z0, z1)) {
            Some(c) => c.map(Sample::to_f32),
            None => {
                let (low, high) = cell_missing(slab, (x0, x1), (y0, y1), (z0, z1), counters);
                let ([l0, l1, l2, l3], [h0, h1, h2, h3]) = (low.to_array(), high.to_array());
                [l0, h0, l1, h1, l2, h2, l3, h3]
            }
        };
        for (corner, v) in values.into_iter().enumerate() {
            corners[corner][lane] = v;
        }
    }
    let frac = |axis: usize| Vec4::from_array(sites.map(|s| s.frac[axis]));
    lerp_corners(corners.map(Vec4::from_array), [frac(0), frac(1), frac(2)]).to_array()
}

/// The trilinear interpolation of eight corners (corner bits `z y x` from 000 to 111) in four
/// lanes at once, with fractions `f` along X, Y and Z: along X first, then Y, then Z, each
/// lane rounding as the scalar [`lerp`] does, so every lane is [`trilinear`]'s value for its
/// own corners. Four points' values, or one point's value and gradient lanes.
#[inline(always)]
pub(crate) fn lerp_corners(corners: [Vec4; 8], [fx, fy, fz]: [Vec4; 3]) -> Vec4 {
    let [c000, c100, c010, c110, c001, c101, c011, c111] = corners;
    let lerp4 = |a: Vec4, b: Vec4, t: Vec4| a + t * (b - a);
    let (c00, c10) = (lerp4(c000, c100, fx), lerp4(c010, c110, fx));
    let (c01, c11) = (lerp4(c001, c101, fx), lerp4(c011, c111, fx));
    lerp4(lerp4(c00, c10, fy), lerp4(c01, c11, fy), fz)
}

/// A cell some of whose nodes lie outside the stored planes: each node read alone, the misses
/// counted, the low-x and high-x nodes laid out as [`trilinear`] lanes them. Never taken when
/// the ghost planes are wide enough; kept out of line so that the sample loop stays small.
#[cold]
#[inline(never)]
fn cell_missing<T: Sample>(
    slab: &Slab<'_, T>,
    (x0, x1): (u32, u32),
    (y0, y1): (u32, u32),
    (z0, z1): (u32, u32),
    counters: &mut Counters,
) -> (Vec4, Vec4) {
    (
        Vec4::new(
            read(slab, x0, y0, z0, counters),
            read(slab, x0, y1, z0, counters),
            read(slab, x0, y0, z1, counters),
            read(slab, x0, y1, z1, counters),
        ),
        Vec4::new(
            read(slab, x1, y0, z0, counters),
            read(slab, x1, y1, z0, counters),
            read(slab, x1, y0, z1, counters),
            read(slab, x1, y1, z1, counters),
        ),
    )
}

#[inline]
fn lerp(a: f32, b: f32, t: f32) -> f32 {
    // `a + t·(b - a)` is exact at t = 0 and stays within [a, b] for t in [0, 1] up to rounding.
    a + t * (b - a)
}

/// The object-space gradient at `p` by central differences at distance `d` (in cells) along
/// each axis, in field units per world unit. Points near the border are clamped into the
/// grid, so there the difference is one-sided (and smaller): a documented approximation.
pub fn gradient<T: Sample>(
    slab: &Slab<'_, T>,
    model: Model,
    p: Vec3,
    d: f32,
    counters: &mut Counters,
) -> Vec3 {
    counters.gradients += 1;
    let shared = match model {
        Model::Cell if d == 1.0 => unit_differences(slab, p),
        _ => None,
    };
    let pairs = match shared {
        Some(pairs) => {
            counters.interpolations += 6;
            pairs
        }
        None => core::array::from_fn(|axis| {
            let mut offset = Vec3::ZERO;
            offset[axis] = d;
            (
                value(slab, model, p + offset, counters),
                value(slab, model, p - offset, counters),
            )
        }),
    };
    let g = pairs.map(|(ahead, behind)| (ahead - behind) / (2.0 * d));
    Vec3::from_array(g) * slab.grid().inv_spacing()
}

/// The six trilinear reads of a central difference at a distance of one cell, `(ahead,
/// behind)` per axis, each equal in every bit to [`value`] at `p ± e_axis`; `None` where that
/// cannot be shown cheaply (the caller then reads them one by one).
///
/// Where no read is clamped and `x ± 1` lands exactly one cell over with the same fraction
/// (true unless the sum rounds, as it can where the exponent changes), the six cells are
/// neighbours of `p`'s own with `p`'s fractions: they span 32 distinct nodes, not 48, and
/// the lerps along x of the four cells that share planes `i` and `i + 1` overlap. Every lerp
/// is the one [`interpolate`] performs, on the same operands in the same order, in lanes that
/// all hold data.
fn unit_differences<T: Sample>(slab: &Slab<'_, T>, p: Vec3) -> Option<[(f32, f32); 3]> {
    let site = locate(slab.grid(), Model::Cell, p);
    let [i, j, k] = site.lo;
    // Planes i - 1 ..= i + 2, rows k - 1 ..= k + 2, nodes j - 1 ..= j + 2: every node the six
    // cells span, stored and checked at once; a row's offsets are from (i - 1, j - 1, k - 1).
    // So cells i - 1 and i + 1 lie inside the grid on every axis: `p[a]` is in [1, n - 2), no
    // read clamps, and the unchanged coordinates (at least 1, never -0.0) add 0.0 exactly.
    let corner = [i.checked_sub(1)?, j.checked_sub(1)?, k.checked_sub(1)?];
    let window = slab.window(corner, 4)?;
    if !unit_steps_exact(p) {
        return None;
    }
    // Rows by plane x and row z, nodes j - 1 ..= j + 2 in the lanes. Every row is read whole,
    // even where only nodes j and j + 1 (lanes y and z) are used: four nodes convert in a few
    // vector instructions, two one by one took more, and picking lanes is one shuffle.
    let row = |dx: usize, dz: usize| window.nodes::<4>(dx, dz, 0).map(|n| n.map(T::to_f32));
    let (a0, a1) = (row(1, 1)?, row(2, 1)?);
    let (b0, b1) = (row(1, 2)?, row(2, 2)?);
    let (c0, c1) = (Vec4::from(row(1, 0)?), Vec4::from(row(2, 0)?));
    let (d0, d1) = (Vec4::from(row(1, 3)?), Vec4::from(row(2, 3)?));
    let (behind_x, ahead_x) = (
        (Vec4::from(row(0, 1)?), Vec4::from(row(0, 2)?)),
        (Vec4::from(row(3, 1)?), Vec4::from(row(3, 2)?)),
    );
    let Vec3 {
        x: fx,
        y: fy,
        z: fz,
    } = site.frac;
    let lerp4 = |a: Vec4, b: Vec4, t: f32| a + Vec4::splat(t) * (b - a);
    // Along x between planes i and i + 1: rows z = k and z = k + 1 over y = j - 1 ..= j + 2,
    // then (y, z) = (j, k - 1), (j + 1, k - 1), (j, k + 2), (j + 1, k + 2).
    let [xa0, xa1, xa2, xa3] = lerp4(Vec4::from(a0), Vec4::from(a1), fx).to_array();
    let [xb0, xb1, xb2, xb3] = lerp4(Vec4::from(b0), Vec4::from(b1), fx).to_array();
    let [xc0, xc1, xd0, xd1] = lerp4(
        Vec4::new(c0.y, c0.z, d0.y, d0.z),
        Vec4::new(c1.y, c1.z, d1.y, d1.z),
        fx,
    )
    .to_array();
    // The cells one over along x: their four lerps in `interpolate`'s lane order
    // (y0 z0, y1 z0, y0 z1, y1 z1), between planes i - 1 and i, and i + 1 and i + 2.
    let corners = |(z0, z1): (Vec4, Vec4)| Vec4::new(z0.y, z0.z, z1.y, z1.z);
    let at_i = Vec4::new(a0[1], a0[2], b0[1], b0[2]);
    let at_i1 = Vec4::new(a1[1], a1[2], b1[1], b1[2]);
    let [xp0, xp1, xp2, xp3] = lerp4(at_i1, corners(ahead_x), fx).to_array();
    let [xm0, xm1, xm2, xm3] = lerp4(corners(behind_x), at_i, fx).to_array();
    // Along y, two per cell (`p` the cell ahead, `m` the one behind): at z0, then at z1.
    let [xp_z0, xp_z1, xm_z0, xm_z1] = lerp4(
        Vec4::new(xp0, xp2, xm0, xm2),
        Vec4::new(xp1, xp3, xm1, xm3),
        fy,
    )
    .to_array();
    let [yp_z0, yp_z1, ym_z0, ym_z1] = lerp4(
        Vec4::new(xa2, xb2, xa0, xb0),
        Vec4::new(xa3, xb3, xa1, xb1),
        fy,
    )
    .to_array();
    let [zp_z0, zp_z1, zm_z0, zm_z1] = lerp4(
        Vec4::new(xb1, xd0, xc0, xa1),
        Vec4::new(xb2, xd1, xc1, xa2),
        fy,
    )
    .to_array();
    // Along z, one per cell.
    let [x_ahead, x_behind, y_ahead, y_behind] = lerp4(
        Vec4::new(xp_z0, xm_z0, yp_z0, ym_z0),
        Vec4::new(xp_z1, xm_z1, yp_z1, ym_z1),
        fz,
    )
    .to_array();
    let [z_ahead, z_behind, _, _] = lerp4(
        Vec4::new(zp_z0, zm_z0, zp_z0, zm_z0),
        Vec4::new(zp_z1, zm_z1, zp_z1, zm_z1),
        fz,
    )
    .to_array();
    Some([
        (x_ahead, x_behind),
        (y_ahead, y_behind),
        (z_ahead, z_behind),
    ])
}

/// Whether `p ± 1` is exact on every axis, for `p` with every coordinate in `[1, 2^23]`: then
/// each neighbour `p ± e_a` is one cell over with `p`'s own fraction, which is what
/// [`unit_differences`] needs (its fraction is `p ± 1 - (i ± 1)`, exact, and so `p - i`).
///
/// For such a coordinate `fl(p + 1)` lies in `[p, 2p]`, so `fl(p + 1) - p` is exact (Sterbenz)
/// and equals 1 just when the sum did not round; `p - 1` likewise. Two operations a lane
/// instead of a floor and a fraction compared per axis (tested equal to that definition).
#[inline(always)]
fn unit_steps_exact(p: Vec3) -> bool {
    let p = Vec3A::from(p);
    let (ahead, behind) = (p + Vec3A::ONE, p - Vec3A::ONE);
    ((ahead - p).cmpeq(Vec3A::ONE) & (p - behind).cmpeq(Vec3A::ONE)).all()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::grid::{floor_index, Grid, MAX_DIM};
    use heapless::Vec;

    /// Clamp `v` into `[0, n - 1]`; NaN becomes 0 (`max` returns the other operand).
    fn clamp_axis(v: f32, n: u32) -> f32 {
        v.max(0.0).min((n - 1) as f32)
    }

    /// The definition of a cell-model site, one axis at a time: cell index `i ∈ [0, n - 2]`
    /// (0 when `n = 1`), the next node, and the fraction `f ∈ [0, 1]`.
    fn cell_axis(v: f32, n: u32) -> (u32, u32, f32) {
        let v = clamp_axis(v, n);
        let i = floor_index(v).min(n.saturating_sub(2));
        let f = v - i as f32;
        (i, (i + 1).min(n - 1), f)
    }

    /// The definition of a voxel-model site's node along one axis: nearest, halves up.
    fn voxel_axis(v: f32, n: u32) -> u32 {
        floor_index(clamp_axis(v, n) + 0.5).min(n - 1)
    }

    #[test]
    fn a_site_is_the_per_axis_definition_for_every_kind_of_coordinate() {
        let mut next = crate::testing::xorshift(0x9e37_79b9);
        for dims in [
            [1, 1, 1],
            [2, 3, 1],
            [5, 4, 3],
            [97, 97, 116],
            [MAX_DIM, 2, 3],
        ] {
            let grid = Grid::new(dims, Vec3::ONE).unwrap();
            let mut xs = Vec::<f32, 4096>::new();
            for n in dims.map(|n| n as f32) {
                for edge in [0.0, 0.5, 1.0, n - 2.0, n - 1.5, n - 1.0, n - 0.5, n] {
                    for ulps in -2i32..=2 {
                        let bits = f32::to_bits(edge).wrapping_add_signed(ulps);
                        xs.extend([edge, f32::from_bits(bits), -f32::from_bits(bits)]);
                    }
                }
            }
            let special = [
                f32::NAN,
                f32::INFINITY,
                f32::NEG_INFINITY,
                -0.0,
                1e-45,
                1e30,
                -1e30,
            ];
            xs.extend(special);
            while !xs.is_full() {
                // Any bit pattern, and any position in or near the grid.
                let r = next();
                let _ = xs.push(f32::from_bits(r));
                let _ = xs.push((r >> 8) as f32 / (1 << 24) as f32 * (dims[0] as f32 + 4.0) - 2.0);
            }
            for (n, &x) in xs.iter().enumerate() {
                // Each value on each axis, beside others.
                let p = Vec3::new(x, xs[(n * 7 + 1) % xs.len()], xs[(n * 13 + 2) % xs.len()]);
                let cell = locate(&grid, Model::Cell, p);
                let voxel = locate(&grid, Model::Voxel, p);
                // The corner as whole floats, for walks in lanes: the same cell.
                let floats = cell4(&grid, p.extend(0.0)).truncate();
                let found = corner4(&grid, Model::Cell, p.extend(0.0)).cell();
                assert_eq!(found.map(Vec4::truncate), Some(floats), "{p}");
                assert_eq!(floats, Vec3::from_array(cell.lo.map(|c| c as f32)), "{p}");
                for a in 0..3 {
                    let (lo, hi, f) = cell_axis(p[a], dims[a]);
                    // Equal as numbers: the definition's `max(-0.0, 0.0)` may keep either zero.
                    assert_eq!(
                        (cell.lo[a], cell.hi[a], cell.frac[a]),
                        (lo, hi, f),
                        "{p} {dims:?}"
                    );
                    let node = voxel_axis(p[a], dims[a]);
                    assert_eq!((voxel.lo[a], voxel.hi[a], voxel.frac[a]), (node, node, 0.0));
                }
            }
        }
    }

    #[test]
    fn whole_lanes_are_the_lanes_as_integers() {
        let mut next = crate::testing::xorshift(0x51f1_5eed);
        let check = |n: u32| {
            let lanes = [n, n / 2, n / 3];
            let v = Vec4::new(lanes[0] as f32, lanes[1] as f32, lanes[2] as f32, f32::NAN);
            assert_eq!(whole_lanes(v), lanes, "{v}");
        };
        for n in [0, 1, 2, 3, MAX_DIM - 2, MAX_DIM - 1, MAX_DIM] {
            check(n);
        }
        for _ in 0..100_000 {
            check(next() % (MAX_DIM + 1));
        }
    }

    fn ramp() -> ([f32; 27], Grid) {
        // f(x, y, z) = x + 10y + 100z, plane-major (x slowest, then z, then y).
        let mut data = [0.0f32; 27];
        for x in 0..3 {
            for z in 0..3 {
                for y in 0..3 {
                    data[(x * 3 + z) * 3 + y] = x as f32 + 10.0 * y as f32 + 100.0 * z as f32;
                }
            }
        }
        (
            data,
            Grid::new([3, 3, 3], Vec3::new(1.0, 2.0, 4.0)).unwrap(),
        )
    }

    #[test]
    fn trilinear_reproduces_a_linear_field_and_nearest_rounds() {
        let (data, grid) = ramp();
        let slab = Slab::whole(grid, &data).unwrap();
        let mut c = Counters::default();
        let v = trilinear(&slab, Vec3::new(0.25, 1.5, 1.75), &mut c);
        assert!((v - (0.25 + 15.0 + 175.0)).abs() < 1e-4);
        assert_eq!(trilinear(&slab, Vec3::new(2.0, 2.0, 2.0), &mut c), 222.0);
        assert_eq!(
            nearest(&slab, Vec3::new(0.5, 1.49, 2.2), &mut c),
            1.0 + 10.0 + 200.0
        );
        assert_eq!(c.slab_misses, 0);
        // Outside and non-finite points clamp into the grid.
        assert_eq!(
            trilinear(&slab, Vec3::new(-5.0, 9.0, f32::NAN), &mut c),
            20.0
        );
        assert_eq!(nearest(&slab, Vec3::splat(f32::INFINITY), &mut c), 222.0);
    }

    #[test]
    fn a_site_names_the_owner_plane_for_every_kind_of_coordinate() {
        for dims in [[1, 2, 3], [2, 1, 1], [5, 4, 3], [97, 97, 116]] {
            let grid = Grid::new(dims, Vec3::ONE).unwrap();
            let n = dims[0] as f32;
            let special = [
                f32::NAN,
                f32::INFINITY,
                f32::NEG_INFINITY,
                -0.0,
                0.0,
                -0.5,
                0.5,
                n - 1.0,
                n - 1.5,
                n - 0.5,
                n,
                1e30,
                -1e30,
            ];
            let sweep = (0..2000).map(|i| i as f32 * (n + 2.0) / 1999.0 - 1.0);
            let near_half = (0..200).map(|i| f32::from_bits(0x3f00_0000 + i * 40_000));
            let xs = || {
                special
                    .into_iter()
                    .chain(sweep.clone())
                    .chain(near_half.clone())
            };
            for model in [Model::Cell, Model::Voxel] {
                for x in xs() {
                    let site = locate(&grid, model, Vec3::new(x, 0.3, 0.7));
                    assert_eq!(site.plane(), grid.owner_plane(x, model), "{x} {model:?}");
                }
            }
        }
    }

    #[test]
    fn four_lanes_equal_four_scalar_reads_in_every_bit() {
        let (data, grid) = ramp();
        let slab = Slab::whole(grid, &data).unwrap();
        let mut c = Counters::default();
        for i in 0..500 {
            let at = |j: u32| {
                let k = (i * 4 + j) as f32;
                Vec3::new(
                    (k * 0.137) % 2.6 - 0.2,
                    (k * 0.291) % 2.4,
                    (k * 0.173) % 2.9 - 0.3,
                )
            };
            let p = [at(0), at(1), at(2), at(3)];
            let four = trilinear4(&slab, p, &mut c);
            for lane in 0..4 {
                let one = trilinear(&slab, p[lane], &mut c);
                assert_eq!(four[lane].to_bits(), one.to_bits(), "{}", p[lane]);
            }
        }
        // Lanes outside the stored planes read zeros and count the misses, as the scalar does.
        let part = Slab::new(grid, 1..2, 0, &data[9..18]).unwrap();
        let p = [
            Vec3::splat(0.5),
            Vec3::ONE,
            Vec3::new(1.2, 0.5, 2.0),
            Vec3::ONE,
        ];
        let (mut c, mut d) = (Counters::default(), Counters::default());
        let four = trilinear4(&part, p, &mut c);
        for lane in 0..4 {
            assert_eq!(
                four[lane].to_bits(),
                trilinear(&part, p[lane], &mut d).to_bits()
            );
        }
        assert!(d.slab_misses > 0);
        assert_eq!(c.slab_misses, d.slab_misses);
    }

    #[test]
    fn gradient_is_in_world_units() {
        let (data, grid) = ramp();
        let slab = Slab::whole(grid, &data).unwrap();
        let mut c = Counters::default();
        let g = gradient(&slab, Model::Cell, Vec3::splat(1.0), 0.5, &mut c);
        assert!((g - Vec3::new(1.0, 5.0, 25.0)).length() < 1e-4, "{g}");
    }

    /// The gradient as defined: six reads, one by one.
    fn reference<T: Sample>(slab: &Slab<'_, T>, p: Vec3, d: f32, c: &mut Counters) -> Vec3 {
        let g: [f32; 3] = core::array::from_fn(|axis| {
            let mut offset = Vec3::ZERO;
            offset[axis] = d;
            let ahead = value(slab, Model::Cell, p + offset, c);
            let behind = value(slab, Model::Cell, p - offset, c);
            (ahead - behind) / (2.0 * d)
        });
        Vec3::from_array(g) * slab.grid().inv_spacing()
    }

    #[test]
    fn shared_gradient_reads_equal_six_reads_in_every_bit() {
        // A field with no structure to hide behind: every node a different hash.
        const DIMS: [u32; 3] = crate::testing::HASHED_DIMS;
        let (data, grid) = crate::testing::hashed_field();
        let whole = Slab::whole(grid, &data).unwrap();
        // Planes 3 and 4 owned, 2 to 5 stored: neighbours past those are not stored.
        let part = Slab::new(grid, 3..5, 1, &data[2 * 56..6 * 56]).unwrap();
        let (mut shared, mut fallback) = (0, 0);
        let mut next = crate::testing::xorshift(0x2545_f491);
        let whole_number = |r: u32, n: u32| (1 + r % (n - 1)) as f32;
        for n in 0..20_000 {
            let mut p = Vec3::ZERO;
            for a in 0..3 {
                let r = next();
                let extent = DIMS[a] as f32;
                p[a] = match n % 4 {
                    // Anywhere, out of the grid included.
                    0 => (r >> 8) as f32 / (1 << 24) as f32 * (extent + 2.0) - 1.0,
                    // Where all six neighbours' cells lie in the grid.
                    1 => (r >> 8) as f32 / (1 << 24) as f32 * (extent - 3.0) + 1.0,
                    // Just above a whole number, where `x + 1` may round.
                    2 => f32::from_bits(whole_number(r, DIMS[a]).to_bits() + r % 5),
                    // Just below one.
                    _ => f32::from_bits(whole_number(r, DIMS[a]).to_bits() - r % 5),
                };
            }
            for slab in [&whole, &part] {
                let (mut c, mut d) = (Counters::default(), Counters::default());
                let bits = |g: Vec3| g.to_array().map(f32::to_bits);
                let g = gradient(slab, Model::Cell, p, 1.0, &mut c);
                assert_eq!(bits(g), bits(reference(slab, p, 1.0, &mut d)), "{p}");
                // The same reads counted, misses of neighbours past the stored planes too.
                d.gradients = 1;
                assert_eq!(c, d, "{p}");
                match unit_differences(slab, p) {
                    Some(_) => shared += 1,
                    None => fallback += 1,
                }
            }
        }
        // Both ways were taken, each many times.
        assert!(
            shared > 5_000 && fallback > 5_000,
            "{shared} shared, {fallback} not"
        );
        // Where `x + 1` rounds the reads are not shared: 1 + 2^-23 + 1 is 2, not 2 + 2^-23.
        let p = Vec3::new(1.0 + f32::EPSILON, 3.5, 3.5);
        assert_eq!(unit_differences(&whole, p), None);
        assert!(unit_differences(&whole, Vec3::new(1.5, 3.5, 3.5)).is_some());
        // Other distances and the voxel model read one by one.
        let (mut c, mut d) = (Counters::default(), Counters::default());
        let g = gradient(&whole, Model::Cell, Vec3::splat(3.3), 0.5, &mut c);
        assert_eq!(g, reference(&whole, Vec3::splat(3.3), 0.5, &mut d));
    }

    #[test]
    fn unit_steps_are_exact_where_each_neighbour_lands_one_cell_over_with_the_same_fraction() {
        // The definition, per axis: `p ± 1` floors to the next cell and leaves the same
        // fraction.
        let lands = |v: f32, cell: u32, frac: f32| {
            v >= 0.0 && floor_index(v) == cell && (v - cell as f32).to_bits() == frac.to_bits()
        };
        let defined = |x: f32| {
            let i = floor_index(x);
            let frac = x - i as f32;
            lands(x + 1.0, i + 1, frac) && lands(x - 1.0, i - 1, frac)
        };
        let mut next = crate::testing::xorshift(0x9e37_79b9);
        let (mut exact, mut rounded) = (0, 0);
        for n in 0..200_000u32 {
            let r = next();
            // Near every power of two up to 2^23, where `x + 1` may round, and anywhere.
            let x = match n % 2 {
                0 => {
                    let power = (1u32 << (r % 24)) as f32;
                    f32::from_bits((power.to_bits() as i32 + (r >> 8) as i32 % 9 - 4) as u32)
                }
                _ => 1.0 + (r >> 8) as f32 / (1 << 24) as f32 * ((1 << 23) as f32 - 1.0),
            };
            if !(1.0..=(1u32 << 23) as f32).contains(&x) {
                continue;
            }
            // Each axis alone, the others at a coordinate where both steps are exact.
            for axis in 0..3 {
                let mut p = Vec3::splat(1.5);
                p[axis] = x;
                assert_eq!(unit_steps_exact(p), defined(x), "{x:e} on axis {axis}");
            }
            if defined(x) {
                exact += 1;
            } else {
                rounded += 1;
            }
        }
        assert!(
            exact > 10_000 && rounded > 10_000,
            "{exact} exact, {rounded} not"
        );
    }

    #[test]
    fn a_single_sample_grid_reads_its_one_value() {
        let grid = Grid::new([1, 1, 1], Vec3::ONE).unwrap();
        let slab = Slab::whole(grid, &[7u8]).unwrap();
        let mut c = Counters::default();
        assert_eq!(trilinear(&slab, Vec3::new(0.3, -1.0, 2.0), &mut c), 7.0);
        assert_eq!(
            gradient(&slab, Model::Cell, Vec3::ZERO, 1.0, &mut c),
            Vec3::ZERO
        );
    }
}

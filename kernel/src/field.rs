//! The continuous field a slab defines under a model: nearest (voxel) or trilinear (cell)
//! reads at index-space points, and the object-space gradient by central differences.
//!
//! Invariants: positions are clamped into the grid before any read, so a finite position
//! never reads outside the grid; a non-finite coordinate is clamped to the grid's low edge
//! (`f32::max`/`min` discard NaN) and still yields a finite value. Each read is counted.

use crate::counters::Counters;
use crate::grid::{floor_index, Grid, Model};
use crate::sample::Sample;
use crate::slab::Slab;
use glam::{Vec3, Vec4};

/// Clamp `v` into `[0, n - 1]`; NaN becomes 0.
#[inline]
fn clamp_axis(v: f32, n: u32) -> f32 {
    // `max` returns the other operand for NaN, so NaN lands on 0.
    v.max(0.0).min((n - 1) as f32)
}

#[inline]
fn read<T: Sample>(slab: &Slab<'_, T>, x: u32, y: u32, z: u32, counters: &mut Counters) -> f32 {
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
    let dims = grid.dims();
    let p = p.to_array();
    match model {
        Model::Voxel => {
            let lo: [u32; 3] = core::array::from_fn(|a| {
                floor_index(clamp_axis(p[a], dims[a]) + 0.5).min(dims[a] - 1)
            });
            Site {
                lo,
                hi: lo,
                frac: Vec3::ZERO,
            }
        }
        Model::Cell => {
            let [(x0, x1, fx), (y0, y1, fy), (z0, z1, fz)] =
                core::array::from_fn(|a| cell_axis(p[a], dims[a]));
            Site {
                lo: [x0, y0, z0],
                hi: [x1, y1, z1],
                frac: Vec3::new(fx, fy, fz),
            }
        }
    }
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

/// Cell index and fraction along one axis: `i ∈ [0, n - 2]` (0 when `n = 1`), `f ∈ [0, 1]`.
#[inline]
fn cell_axis(v: f32, n: u32) -> (u32, u32, f32) {
    let v = clamp_axis(v, n);
    let i = floor_index(v).min(n.saturating_sub(2));
    let f = v - i as f32;
    (i, (i + 1).min(n - 1), f)
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
    let Vec3 {
        x: fx,
        y: fy,
        z: fz,
    } = site.frac;
    // The four lerps along x, one per lane: each lane rounds exactly as the scalar `lerp`
    // (glam never fuses), and all four lanes hold data. Left to itself the compiler packs two
    // lanes and leaves stale values in the others, which can be subnormal and stall the
    // multiply (a measured 40% of the whole render). The lanes are built from the loaded
    // values directly: going through an array on the stack costs a store-forwarding stall.
    let (low, high) = match slab.cell((x0, x1), (y0, y1), (z0, z1)) {
        Some([c000, c100, c010, c110, c001, c101, c011, c111]) => (
            Vec4::new(c000.to_f32(), c010.to_f32(), c001.to_f32(), c011.to_f32()),
            Vec4::new(c100.to_f32(), c110.to_f32(), c101.to_f32(), c111.to_f32()),
        ),
        None => cell_missing(slab, (x0, x1), (y0, y1), (z0, z1), counters),
    };
    let [c00, c10, c01, c11] = (low + Vec4::splat(fx) * (high - low)).to_array();
    lerp(lerp(c00, c10, fy), lerp(c01, c11, fy), fz)
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
    let [c000, c100, c010, c110, c001, c101, c011, c111] = corners.map(Vec4::from_array);
    let frac = |axis: usize| Vec4::from_array(sites.map(|s| s.frac[axis]));
    let (fx, fy, fz) = (frac(0), frac(1), frac(2));
    let lerp4 = |a: Vec4, b: Vec4, t: Vec4| a + t * (b - a);
    let (c00, c10) = (lerp4(c000, c100, fx), lerp4(c010, c110, fx));
    let (c01, c11) = (lerp4(c001, c101, fx), lerp4(c011, c111, fx));
    lerp4(lerp4(c00, c10, fy), lerp4(c01, c11, fy), fz).to_array()
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
    let mut g = [0.0f32; 3];
    for (axis, slot) in g.iter_mut().enumerate() {
        let mut offset = Vec3::ZERO;
        offset[axis] = d;
        let ahead = value(slab, model, p + offset, counters);
        let behind = value(slab, model, p - offset, counters);
        *slot = (ahead - behind) / (2.0 * d);
    }
    Vec3::from_array(g) * slab.grid().inv_spacing()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::grid::Grid;

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

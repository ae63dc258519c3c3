//! The continuous field a slab defines under a model: nearest (voxel) or trilinear (cell)
//! reads at index-space points, and the object-space gradient by central differences.
//!
//! Invariants: positions are clamped into the grid before any read, so a finite position
//! never reads outside the grid; a non-finite coordinate is clamped to the grid's low edge
//! (`f32::max`/`min` discard NaN) and still yields a finite value. Each read is counted.

use crate::counters::Counters;
use crate::grid::{floor_index, Model};
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

/// The field value at index-space point `p` under `model`.
#[inline]
pub fn value<T: Sample>(slab: &Slab<'_, T>, model: Model, p: Vec3, counters: &mut Counters) -> f32 {
    match model {
        Model::Voxel => nearest(slab, p, counters),
        Model::Cell => trilinear(slab, p, counters),
    }
}

/// The value of the grid node nearest to `p` (halves round up, as [`crate::grid::Grid::owner_plane`]).
pub fn nearest<T: Sample>(slab: &Slab<'_, T>, p: Vec3, counters: &mut Counters) -> f32 {
    counters.lookups += 1;
    let [nx, ny, nz] = slab.grid().dims();
    let x = floor_index(clamp_axis(p.x, nx) + 0.5);
    let y = floor_index(clamp_axis(p.y, ny) + 0.5);
    let z = floor_index(clamp_axis(p.z, nz) + 0.5);
    read(slab, x.min(nx - 1), y.min(ny - 1), z.min(nz - 1), counters)
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
#[inline(always)]
pub fn trilinear<T: Sample>(slab: &Slab<'_, T>, p: Vec3, counters: &mut Counters) -> f32 {
    counters.interpolations += 1;
    let [nx, ny, nz] = slab.grid().dims();
    let (x0, x1, fx) = cell_axis(p.x, nx);
    let (y0, y1, fy) = cell_axis(p.y, ny);
    let (z0, z1, fz) = cell_axis(p.z, nz);
    // The four lerps along x, one per lane: each lane rounds exactly as the scalar `lerp`
    // (glam never fuses), and all four lanes hold data. Left to itself the compiler packs two
    // lanes and leaves stale values in the others, which can be subnormal and stall the
    // multiply (a measured 40% of the whole render).
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

/// A cell some of whose nodes lie outside the stored planes: each node read alone, the misses
/// counted; the low-x and high-x nodes as [`trilinear`] lays them out. Never taken when the ghost planes are wide enough; kept out of line so that the
/// sample loop stays small.
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

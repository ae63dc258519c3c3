//! The fast tier's node field: every node's value and its central differences along X, Y and
//! Z in four lanes, so that one trilinear interpolation of lanes gives a point's value and
//! its gradient ([`value_and_gradient`]) where the exact tier reads six more cells.
//!
//! Invariants: a stored node is [`node`] of its slab in every bit (a byte volume's nodes are
//! integers in `[-255, 255]`, exact in `i16`; other kinds keep the `f32` lanes as computed).
//! Where a slab holds no field, or a cell's nodes lie outside it, the same lanes are computed
//! on the fly from the slab, so holding the field changes no pixel, only the time. A field
//! that does not match its slab is refused when attached, never read past.

use crate::counters::Counters;
use crate::volume::field::{self, Site};
use crate::volume::grid::Grid;
use crate::volume::lanes::NodesError;
use crate::volume::sample::Sample;
use crate::volume::slab::{Slab, Window};
use core::ops::Range;
use glam::{Vec3, Vec4};

/// Node `(x, y, z)`'s lanes: its value, and along each axis the value of the next node minus
/// that of the previous, each index clamped into the grid (so the difference is one-sided at
/// the grid's faces, and zero on an axis one node long). Reads `slab`; a node it does not
/// store reads zero and is counted, as every read is.
pub fn node<T: Sample>(slab: &Slab<'_, T>, [x, y, z]: [u32; 3], counters: &mut Counters) -> Vec4 {
    let dims = slab.grid().dims();
    let mut at = |x, y, z| field::read(slab, x, y, z, counters);
    let ahead = |i: u32, a: usize| (i + 1).min(dims[a] - 1);
    let behind = |i: u32| i.saturating_sub(1);
    let v = at(x, y, z);
    let dx = at(ahead(x, 0), y, z) - at(behind(x), y, z);
    let dy = at(x, ahead(y, 1), z) - at(x, behind(y), z);
    let dz = at(x, y, ahead(z, 2)) - at(x, y, behind(z));
    Vec4::new(v, dx, dy, dz)
}

/// Whether index-space point `p` lies in `grid` (every coordinate in `[0, n − 1]`; never for
/// NaN): there the central difference of the trilinear field at one cell is, in exact
/// arithmetic, the interpolation of the nodes' differences at `p`'s fractions, axis by axis.
/// Away from the faces each `f(p ± e)` interpolates the neighbouring cell at the same
/// fractions; where `p ± e` leaves the grid its read is clamped onto the face node, which is
/// the node a face's one-sided difference reads. Outside the grid the point itself is
/// clamped and the two differ.
#[inline]
pub fn in_grid(grid: &Grid, p: Vec3) -> bool {
    let (last_node, _) = grid.last_indices();
    let p = p.extend(0.0);
    (p.cmpge(Vec4::ZERO) & p.cmple(last_node)).bitmask() & 0b111 == 0b111
}

/// The planes whose nodes the field of a slab owning `owned` holds: those of its own samples'
/// cells (the cell model's high corners lie one plane past the owned ones), and the plane
/// before them, where a surface found between a predecessor's sample and the slab's first
/// lies. Depends on the owned planes alone, so one field serves every view of a volume.
pub fn planes_for(grid: &Grid, owned: Range<u32>) -> Range<u32> {
    one_more_each_side(grid, owned)
}

/// `planes` and the plane each side of them, inside the grid.
fn one_more_each_side(grid: &Grid, planes: Range<u32>) -> Range<u32> {
    planes.start.saturating_sub(1)..planes.end.saturating_add(1).min(grid.dims()[0])
}

/// Nodes the field of a slab owning `owned` holds.
pub fn len_for(grid: &Grid, owned: Range<u32>) -> usize {
    planes_for(grid, owned).len() * grid.plane_len()
}

/// Write the lanes of every node of planes `planes` into `out` (plane-major, as a slab stores
/// them), each equal in every bit to [`node`] of `slab`; `out` must hold exactly those
/// planes' nodes, and `slab` must store the planes they read (one more each side, inside the
/// grid). A part of a field: callers may fill the planes of [`planes_for`] in pieces, on as
/// many threads as they like.
pub fn fill<T: Sample>(
    slab: &Slab<'_, T>,
    planes: Range<u32>,
    out: &mut [T::Node],
) -> Result<(), NodesError> {
    let grid = slab.grid();
    let [nx, ny, nz] = grid.dims();
    let expected = planes.len() * grid.plane_len();
    if out.len() != expected {
        return Err(NodesError::StorageLength {
            expected,
            actual: out.len(),
        });
    }
    let read = one_more_each_side(grid, planes.clone());
    let stored = slab.stored();
    let holds = stored.start <= read.start && read.end <= stored.end;
    if !(planes.is_empty() || holds) {
        return Err(NodesError::NotStored { read, stored });
    }
    let rows = out.chunks_exact_mut(ny as usize);
    let places = planes.flat_map(|x| (0..nz).map(move |z| (x, z)));
    for ((x, z), out) in places.zip(rows) {
        // A row at a time from the five rows its nodes read, as `node` clamps them: the
        // same values subtracted in the same order.
        let row = |x: u32, z: u32| slab.row(x, z);
        let stencil = (
            row(x, z),
            row((x + 1).min(nx - 1), z),
            row(x.saturating_sub(1), z),
            row(x, (z + 1).min(nz - 1)),
            row(x, z.saturating_sub(1)),
        );
        let (Some(here), Some(ahead), Some(behind), Some(above), Some(below)) = stencil else {
            // Not taken: every row read is stored (checked above).
            return Err(NodesError::NotStored { read, stored });
        };
        let n = ny as usize;
        let (Some(here), Some(ahead), Some(behind), Some(above), Some(below)) = (
            here.get(..n),
            ahead.get(..n),
            behind.get(..n),
            above.get(..n),
            below.get(..n),
        ) else {
            return Err(NodesError::NotStored { read, stored });
        };
        fill_row(out, here, (ahead, behind), (above, below));
    }
    Ok(())
}

/// One row of lanes from its row of nodes `here` and the rows beside it along X and along Z
/// (all as long as `out`), a neighbour past the row's end clamped to its end node as [`node`]
/// clamps it. The nodes inside the row take their Y neighbours from a window of three, with
/// no clamp and no bounds check: the same values, subtracted in the same order.
#[inline]
fn fill_row<T: Sample>(
    out: &mut [T::Node],
    here: &[T],
    (ahead, behind): (&[T], &[T]),
    (above, below): (&[T], &[T]),
) {
    let f = |row: &[T], y: usize| row.get(y).copied().unwrap_or_default();
    let Some(last) = out.len().checked_sub(1) else {
        return;
    };
    // The row's two ends, whose Y neighbour is clamped.
    for y in [0, last] {
        let lanes = T::node_lanes(
            f(here, y),
            [f(ahead, y), f(behind, y)],
            [f(here, (y + 1).min(last)), f(here, y.saturating_sub(1))],
            [f(above, y), f(below, y)],
        );
        if let Some(slot) = out.get_mut(y) {
            *slot = lanes;
        }
    }
    let inside = out.get_mut(1..last).unwrap_or_default();
    fn beside<T>(row: &[T]) -> &[T] {
        row.get(1..).unwrap_or_default()
    }
    let rows = here
        .windows(3)
        .zip(beside(ahead).iter().zip(beside(behind)))
        .zip(beside(above).iter().zip(beside(below)));
    for (slot, ((h, (&a, &b)), (&u, &d))) in inside.iter_mut().zip(rows) {
        *slot = T::node_lanes(h[1], [a, b], [h[2], h[0]], [u, d]);
    }
}

/// The value and gradient at `site` (cell model) by the node field: one trilinear
/// interpolation of the cell's node lanes. The value lane is the trilinear value in every
/// bit ([`field::trilinear`]: the same lerps, in the same order); the gradient is the
/// interpolated differences, halved, in field units per world unit. Where the slab holds no
/// field for the cell, its nodes' lanes come from [`node`], the same bits. Counts one
/// interpolation and one gradient either way.
#[inline(always)]
pub fn value_and_gradient<T: Sample>(
    slab: &Slab<'_, T>,
    site: &Site,
    counters: &mut Counters,
) -> (f32, Vec3) {
    counters.interpolations += 1;
    counters.gradients += 1;
    lanes_at(slab, site, counters)
}

/// [`value_and_gradient`] without counting the interpolation and the gradient (only reads
/// that miss): for a caller that counts them as the reads it stands for, so that the counters
/// do not depend on whether a node holds the field.
#[inline(always)]
pub fn lanes_at<T: Sample>(
    slab: &Slab<'_, T>,
    site: &Site,
    counters: &mut Counters,
) -> (f32, Vec3) {
    let corners = match slab.nodes().and_then(|nodes| nodes.cell(site.lo, site.hi)) {
        Some(corners) => corners,
        None => on_the_fly(slab, site, counters),
    };
    lerp_lanes(corners, site.frac, slab.grid().inv_spacing())
}

/// A cell's eight nodes' lanes interpolated at fractions `frac`: the value, and the gradient
/// (the differences halved, per world unit along each axis).
#[inline(always)]
pub(crate) fn lerp_lanes(corners: [Vec4; 8], frac: Vec3, inv_spacing: Vec3) -> (f32, Vec3) {
    let [v, dx, dy, dz] = field::lerp_corners(corners, frac.to_array().map(Vec4::splat)).to_array();
    (v, Vec3::new(dx, dy, dz) * 0.5 * inv_spacing)
}

/// The lanes of a cell's eight nodes from the slab itself, where no field is held: from the
/// 4×4×4 window of nodes around the cell where it lies in the grid and the slab (the
/// neighbours `node` reads are then in it, unclamped, so the lanes are the same
/// subtractions), else node by node.
#[inline]
fn on_the_fly<T: Sample>(slab: &Slab<'_, T>, site: &Site, counters: &mut Counters) -> [Vec4; 8] {
    let ([x0, y0, z0], [x1, y1, z1]) = (site.lo, site.hi);
    let whole = x1 == x0 + 1 && y1 == y0 + 1 && z1 == z0 + 1;
    let first = [x0.checked_sub(1), y0.checked_sub(1), z0.checked_sub(1)];
    let window = match (whole, first) {
        (true, [Some(x), Some(y), Some(z)]) => slab.window([x, y, z], 4),
        _ => None,
    };
    match window.and_then(|w| in_window(&w)) {
        Some(lanes) => lanes,
        None => node_by_node(slab, site, counters),
    }
}

/// The eight inner nodes' lanes of a 4×4×4 window, corner bits `z y x` from 000 to 111.
#[inline(always)]
fn in_window<T: Sample>(w: &Window<'_, T>) -> Option<[Vec4; 8]> {
    // Row `dz` of plane `dx`, its four nodes along Y as f32: the twelve rows the inner
    // nodes and their neighbours lie on, each read once.
    let row = |dx: usize, dz: usize| w.nodes::<4>(dx, dz, 0).map(|r| r.map(T::to_f32));
    // By [x][z] bit: the inner rows, and the rows one plane out along X (by z) and one row
    // out along Z (by x).
    let inner = [[row(1, 1)?, row(1, 2)?], [row(2, 1)?, row(2, 2)?]];
    let (below_x, above_x) = ([row(0, 1)?, row(0, 2)?], [row(3, 1)?, row(3, 2)?]);
    let (below_z, above_z) = ([row(1, 0)?, row(2, 0)?], [row(1, 3)?, row(2, 3)?]);
    Some(core::array::from_fn(|c| {
        let (bx, by, bz) = (c & 1, (c >> 1) & 1, (c >> 2) & 1);
        let y = 1 + by;
        let here = inner[bx][bz];
        let (ahead_x, behind_x) = match bx {
            0 => (inner[1][bz], below_x[bz]),
            _ => (above_x[bz], inner[0][bz]),
        };
        let (ahead_z, behind_z) = match bz {
            0 => (inner[bx][1], below_z[bx]),
            _ => (above_z[bx], inner[bx][0]),
        };
        Vec4::new(
            here[y],
            ahead_x[y] - behind_x[y],
            here[y + 1] - here[y - 1],
            ahead_z[y] - behind_z[y],
        )
    }))
}

/// The lanes of a cell's eight nodes, each by [`node`]: at the grid's faces, and next to
/// planes the slab does not store. Out of line, so that the sample loop stays small.
#[cold]
#[inline(never)]
fn node_by_node<T: Sample>(slab: &Slab<'_, T>, site: &Site, counters: &mut Counters) -> [Vec4; 8] {
    let ([x0, y0, z0], [x1, y1, z1]) = (site.lo, site.hi);
    let corner = |c: usize| {
        let pick = |bit: usize, lo: u32, hi: u32| if c & bit == 0 { lo } else { hi };
        [pick(1, x0, x1), pick(2, y0, y1), pick(4, z0, z1)]
    };
    core::array::from_fn(|c| node(slab, corner(c), counters))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::field::locate;
    use crate::volume::grid::Model;
    use crate::volume::lanes::{Lanes, Nodes};

    fn bits(v: Vec4) -> [u32; 4] {
        v.to_array().map(f32::to_bits)
    }

    /// The exact tier's rule ([`in_grid`]): at a point in the grid, the nodes' differences
    /// interpolated are the central difference of the trilinear field up to rounding, near
    /// the faces too; at a point outside, a different quantity, far beyond rounding (the
    /// rule's negative control).
    #[test]
    fn in_the_grid_the_nodes_differences_are_the_exact_gradient_up_to_rounding() {
        let (data, grid) = crate::testing::hashed_field();
        let slab = Slab::whole(grid, &data).unwrap();
        // The field's values reach 2^25 · 10⁻³: a few units in the last place of that, per
        // world unit (spacing down to ½).
        let tolerance = 64.0 * f32::EPSILON * 33_554.0 * 2.0;
        let dims = grid.dims();
        let mut next = crate::testing::xorshift(0x9e3d_c311);
        let (mut inside, mut outside, mut far_apart) = (0, 0, 0);
        for n in 0..40_000 {
            // Half the points in the grid, a tenth of those on a face; half up to a cell out.
            let mut p = Vec3::ZERO;
            for a in 0..3 {
                let last = (dims[a] - 1) as f32;
                let unit = (next() >> 8) as f32 / (1 << 24) as f32;
                p[a] = match (n % 2, next() % 10) {
                    (0, 0) => [0.0, last][(next() % 2) as usize],
                    (0, _) => unit * last,
                    _ => unit * (last + 2.0) - 1.0,
                };
            }
            let mut c = Counters::default();
            let site = locate(&grid, Model::Cell, p);
            let exact = field::gradient(&slab, Model::Cell, p, 1.0, &mut c);
            let (_, lanes) = value_and_gradient(&slab, &site, &mut c);
            let apart = (lanes - exact).abs().max_element();
            if in_grid(&grid, p) {
                inside += 1;
                assert!(apart <= tolerance, "{p}: {lanes} against {exact}");
            } else {
                outside += 1;
                far_apart += usize::from(apart > 1_000.0 * tolerance);
            }
        }
        assert!(inside > 20_000 && outside > 5_000, "{inside} {outside}");
        assert!(far_apart > outside / 2, "{far_apart} of {outside}");
        assert!(in_grid(&grid, Vec3::ZERO) && in_grid(&grid, Vec3::new(8.0, 6.0, 7.0)));
        assert!(!in_grid(&grid, Vec3::new(-0.001, 1.0, 1.0)));
        assert!(!in_grid(&grid, Vec3::new(1.0, 6.001, 1.0)));
        assert!(!in_grid(&grid, Vec3::new(1.0, 1.0, f32::NAN)));
    }

    /// A byte field with no structure: every node a different hash.
    fn hashed_bytes() -> ([u8; 9 * 7 * 8], Grid) {
        let (values, grid) = crate::testing::hashed_field();
        (values.map(|v| (v.to_bits() >> 7) as u8), grid)
    }

    fn whole_field<T: Sample>(slab: &Slab<'_, T>) -> ([T::Node; 9 * 7 * 8], Range<u32>) {
        let planes = planes_for(slab.grid(), slab.owned());
        let mut out = [T::Node::default(); 9 * 7 * 8];
        let len = len_for(slab.grid(), slab.owned());
        fill(slab, planes.clone(), &mut out[..len]).unwrap();
        (out, planes)
    }

    #[test]
    fn a_node_is_its_value_and_the_differences_of_its_neighbours_one_sided_at_the_faces() {
        let (data, grid) = hashed_bytes();
        let slab = Slab::whole(grid, &data).unwrap();
        let f = |x: u32, y: u32, z: u32| f32::from(slab.get(x, y, z).unwrap());
        let mut c = Counters::default();
        assert_eq!(
            node(&slab, [3, 2, 4], &mut c),
            Vec4::new(
                f(3, 2, 4),
                f(4, 2, 4) - f(2, 2, 4),
                f(3, 3, 4) - f(3, 1, 4),
                f(3, 2, 5) - f(3, 2, 3)
            )
        );
        // At the grid's faces the difference takes the node itself on the missing side.
        assert_eq!(
            node(&slab, [0, 6, 7], &mut c),
            Vec4::new(
                f(0, 6, 7),
                f(1, 6, 7) - f(0, 6, 7),
                f(0, 6, 7) - f(0, 5, 7),
                f(0, 6, 7) - f(0, 6, 6)
            )
        );
        assert_eq!(c.slab_misses, 0);
    }

    #[test]
    fn a_linear_field_has_its_exact_gradient_inside_the_grid() {
        // f = 3x + 5y - 7z on spacing (1, ½, 2): gradient (3, 10, -3.5) per world unit.
        let grid = Grid::new([6, 5, 4], Vec3::new(1.0, 0.5, 2.0)).unwrap();
        let mut data = [0.0f32; 6 * 5 * 4];
        for x in 0..6 {
            for z in 0..4 {
                for y in 0..5 {
                    data[(x * 4 + z) * 5 + y] = 3.0 * x as f32 + 5.0 * y as f32 - 7.0 * z as f32;
                }
            }
        }
        let slab = Slab::whole(grid, &data).unwrap();
        let mut c = Counters::default();
        for p in [
            Vec3::new(1.25, 1.5, 1.75),
            Vec3::new(3.9, 2.01, 1.0),
            Vec3::splat(2.0),
        ] {
            let site = locate(&grid, Model::Cell, p);
            let (v, g) = value_and_gradient(&slab, &site, &mut c);
            assert!(
                (v - (3.0 * p.x + 5.0 * p.y - 7.0 * p.z)).abs() < 1e-4,
                "{p}"
            );
            assert_eq!(g, Vec3::new(3.0, 10.0, -3.5), "{p}");
        }
    }

    #[test]
    fn the_value_lane_is_the_trilinear_value_and_the_field_the_nodes_in_every_bit() {
        let (bytes, grid) = hashed_bytes();
        let (floats, _) = crate::testing::hashed_field();
        check(&Slab::whole(grid, &bytes).unwrap());
        check(&Slab::whole(grid, &floats).unwrap());
        // A cut slab: planes 3 and 4 owned, 1 to 6 stored, the field over 2 to 5.
        let plane = grid.plane_len();
        let part = Slab::new(grid, 3..5, 2, &bytes[plane..7 * plane]).unwrap();
        assert_eq!(planes_for(&grid, part.owned()), 2..6);
        check(&part);
    }

    #[test]
    fn rows_of_one_two_and_three_nodes_clamp_their_ends_as_a_node_does() {
        let (bytes, _) = hashed_bytes();
        for ny in [1u32, 2, 3] {
            let grid = Grid::new([4, ny, 3], Vec3::ONE).unwrap();
            let data = &bytes[..grid.plane_len() * 4];
            let slab = Slab::whole(grid, data).unwrap();
            let (storage, planes) = whole_field(&slab);
            let mut c = Counters::default();
            let mut i = 0;
            for x in planes {
                for z in 0..3 {
                    for y in 0..ny {
                        let want = node(&slab, [x, y, z], &mut c);
                        assert_eq!(bits(storage[i].unpack()), bits(want), "{ny}: {x} {y} {z}");
                        i += 1;
                    }
                }
            }
            assert_eq!(i, grid.plane_len() * 4);
        }
    }

    fn check<T: Sample>(slab: &Slab<'_, T>) {
        let grid = *slab.grid();
        let (storage, planes) = whole_field(slab);
        let len = len_for(&grid, slab.owned());
        let nodes = Nodes::new(&grid, planes.clone(), &storage[..len]).unwrap();
        let held = slab.with_nodes(nodes);
        // Each stored node is `node` of the slab.
        let mut c = Counters::default();
        for x in planes.clone() {
            for z in 0..grid.dims()[2] {
                for y in 0..grid.dims()[1] {
                    let i = ((x - planes.start) as usize * grid.dims()[2] as usize + z as usize)
                        * grid.dims()[1] as usize
                        + y as usize;
                    assert_eq!(
                        bits(storage[i].unpack()),
                        bits(node(slab, [x, y, z], &mut c))
                    );
                }
            }
        }
        let mut next = crate::testing::xorshift(0x7f4a_7c15);
        let extent = grid.dims().map(|n| n as f32);
        for _ in 0..5_000 {
            let mut p = Vec3::ZERO;
            for a in 0..3 {
                p[a] = (next() >> 8) as f32 / (1 << 24) as f32 * (extent[a] + 1.0) - 0.5;
            }
            // In the cells whose nodes the field holds (at the grid's faces, out of it too).
            let (lo, hi) = (planes.start as f32, planes.end as f32 - 1.0);
            if slab.stored() != (0..grid.dims()[0]) {
                p.x = p.x.clamp(lo, hi - 1e-3);
            }
            let site = locate(&grid, Model::Cell, p);
            let (mut c, mut d) = (Counters::default(), Counters::default());
            let with = value_and_gradient(&held, &site, &mut c);
            let without = value_and_gradient(slab, &site, &mut d);
            // The value is the trilinear one, and the field the slab's own nodes.
            let trilinear = field::trilinear(slab, p, &mut Counters::default());
            assert_eq!(with.0.to_bits(), trilinear.to_bits(), "{p}");
            assert_eq!(
                bits(with.1.extend(with.0)),
                bits(without.1.extend(without.0))
            );
            assert_eq!((c.slab_misses, d.slab_misses), (0, 0), "{p}");
            assert_eq!(
                (c.gradients, c.interpolations),
                (d.gradients, d.interpolations)
            );
        }
    }

    #[test]
    fn a_field_that_does_not_match_its_planes_is_refused() {
        let (data, grid) = hashed_bytes();
        let slab = Slab::whole(grid, &data).unwrap();
        let storage = [[0i16; 4]; 10];
        assert_eq!(
            Nodes::new(&grid, 0..9, &storage[..]).map(|_| ()),
            Err(NodesError::StorageLength {
                expected: 9 * 56,
                actual: 10
            })
        );
        let mut out = [[0i16; 4]; 56];
        assert!(fill(&slab, 0..2, &mut out).is_err());
        assert!(fill(&slab, 3..4, &mut out).is_ok());
        // A slab with one ghost plane stores planes 2 to 5 for planes 3 and 4: their field's
        // planes 2 to 5 read 1 to 6, which it does not store. Refused, not filled with zeros.
        let plane = grid.plane_len();
        let thin = Slab::new(grid, 3..5, 1, &data[2 * plane..6 * plane]).unwrap();
        let planes = planes_for(&grid, thin.owned());
        let mut out = [[0i16; 4]; 4 * 56];
        assert_eq!(
            fill(&thin, planes, &mut out),
            Err(NodesError::NotStored {
                read: 1..7,
                stored: 2..6
            })
        );
    }
}

//! The interior of a slab for a ray: the samples whose whole cell (cell model)
//! lies inside the grid, in the slab's owned planes and in the storage the loop reads, where
//! the clamp of [`crate::volume::field::corner4`] changes nothing, every sample is the slab's
//! own, and a cell is read whole under one range check. The composited loop and the surface
//! search run through them without the general step's questions ([`crate::trace::runway`]).
//!
//! Invariants: a sample at index-space point `q` is inside exactly when, on each of the three
//! axes, `q > 0`, `q ≥ floor` and `q < ceiling` ([`Interior::holds`]); there its cell is
//! `trunc(q)` and its fractions `q − trunc(q)`, bit for bit what the general step finds
//! ([`crate::volume::field::interior_corner`]). Positions are monotone in the lattice index
//! along each axis (one multiply and one add from `t_k`, itself monotone, each rounding
//! monotone), so a ray's inside samples are one run of indices, and a run whose two ends are
//! inside lies inside throughout.

use crate::trace::state::RayState;
use crate::volume::grid::Grid;
use core::ops::Range;
use glam::Vec4;

/// The box of index space whose points are inside.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Interior {
    /// On X the first plane of the cells inside; zero on Y and Z.
    floor: Vec4,
    /// On X the plane past the last cell inside; the last node on Y and Z.
    ceiling: Vec4,
    /// The same bounds as integers, for [`Interior::cells`].
    cells: (Range<u32>, u32, u32),
}

impl Interior {
    /// The interior of `grid` for the cells whose low X plane is in `planes` (those a slab
    /// owns and holds whole); `None` where no cell is inside.
    pub(crate) fn new(grid: &Grid, planes: Range<u32>) -> Option<Interior> {
        let [nx, ny, nz] = grid.dims();
        // A cell's high corner is inside the grid: its low one short of the last node.
        let end = planes.end.min(nx.saturating_sub(1));
        if planes.start >= end || ny < 2 || nz < 2 {
            return None;
        }
        Some(Interior {
            floor: Vec4::new(planes.start as f32, 0.0, 0.0, 0.0),
            ceiling: Vec4::new(end as f32, (ny - 1) as f32, (nz - 1) as f32, 0.0),
            cells: (planes.start..end, ny - 1, nz - 1),
        })
    }

    /// The cells inside: their low corners' X planes, and the Y and Z past the last.
    pub(crate) fn cells(&self) -> (Range<u32>, u32, u32) {
        self.cells.clone()
    }

    /// Whether the index-space point in the first three lanes of `q` is inside (never for a
    /// NaN lane).
    #[inline(always)]
    pub(crate) fn holds(&self, q: Vec4) -> bool {
        let inside = q.cmpgt(Vec4::ZERO) & q.cmpge(self.floor) & q.cmplt(self.ceiling);
        inside.bitmask() & 0b111 == 0b111
    }

    /// The last sample of `ray` from sample `k` on (inside, at most the lattice's last) that
    /// is inside. Where the ray leaves is estimated from the faces it moves toward, then
    /// checked with the samples' own arithmetic, so the estimate decides how long the run
    /// is found, never whether a sample outside is in it.
    pub(crate) fn last(&self, ray: &RayState, k: u32) -> u32 {
        let (lattice, r) = (&ray.lattice, &ray.ray);
        let inside = |k: u32| self.holds(r.at4(lattice.t(k)));
        let left = lattice.last.saturating_sub(k);
        // Each axis's face ahead, the three divisions in lanes; an axis the ray does not move
        // along (the fourth lane among them) never ends it.
        let (o, d) = (r.origin.extend(0.0), r.dir.extend(0.0));
        let face = Vec4::select(d.cmpgt(Vec4::ZERO), self.ceiling, self.floor);
        let t_out = Vec4::select(d.cmpne(Vec4::ZERO), (face - o) / d, Vec4::INFINITY);
        let t_out = t_out.min_element();
        let ahead = (t_out - lattice.t(k)) / lattice.dt;
        let mut n = if ahead.is_finite() {
            (ahead.max(0.0) as u32).min(left)
        } else {
            left
        };
        // The estimate errs by a step or two where it is finite: back a step at a time,
        // then by halves.
        let mut misses = 0;
        while n > 0 && !inside(k + n) {
            n = if misses < 3 { n - 1 } else { n / 2 };
            misses += 1;
        }
        // And on, where it fell short.
        for _ in 0..2 {
            if n < left && inside(k + n + 1) {
                n += 1;
            } else {
                break;
            }
        }
        k + n
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trace::lattice::Lattice;
    use crate::trace::ray::{Entry, Ray};
    use crate::trace::state::RayKind;
    use crate::volume::field;
    use crate::volume::grid::Model;
    use glam::Vec3;

    fn grid() -> Grid {
        Grid::new([12, 9, 10], Vec3::new(1.0, 0.5, 2.0)).unwrap()
    }

    /// A point near the grid, with lanes on and around every face and cell boundary.
    fn point(next: &mut impl FnMut() -> u32, dims: [u32; 3]) -> Vec4 {
        let mut q = Vec4::ZERO;
        for a in 0..3 {
            let n = dims[a] as f32;
            q[a] = match next() % 6 {
                // Whole numbers, on a face or a cell boundary.
                0 => (next() % (dims[a] + 2)) as f32 - 1.0,
                // Just below and above one.
                1 => f32::from_bits(((next() % (dims[a] + 1)) as f32).to_bits().wrapping_sub(1)),
                2 => f32::from_bits(((next() % (dims[a] + 1)) as f32).to_bits() + 1),
                3 => -0.0,
                _ => (next() >> 8) as f32 / (1 << 24) as f32 * (n + 2.0) - 1.0,
            };
        }
        q
    }

    #[test]
    fn inside_the_corner_and_fractions_are_the_general_steps_bit_for_bit() {
        let grid = grid();
        let interior = Interior::new(&grid, 2..9).unwrap();
        let mut next = crate::testing::xorshift(0x1a7e_510f);
        let (mut inside, mut outside) = (0, 0);
        for _ in 0..200_000 {
            let q = point(&mut next, grid.dims());
            let corner = field::corner4(&grid, Model::Cell, q);
            let site = corner.site(&grid);
            if interior.holds(q) {
                inside += 1;
                let (cell, lo) = field::interior_corner(q);
                assert_eq!(lo, site.lo, "{q}");
                assert_eq!(
                    corner.cell().map(|c| c.to_array().map(f32::to_bits)),
                    Some(cell.to_array().map(f32::to_bits)),
                    "{q}"
                );
                let frac = (q - cell).truncate();
                assert_eq!(
                    frac.to_array().map(f32::to_bits),
                    site.frac.to_array().map(f32::to_bits),
                    "{q}"
                );
                assert_eq!(site.hi, lo.map(|c| c + 1), "{q}");
                assert!((2..9).contains(&site.plane()), "{q}");
            } else {
                outside += 1;
            }
        }
        assert!(inside > 20_000 && outside > 20_000, "{inside} {outside}");
    }

    #[test]
    fn a_box_one_node_wider_would_let_the_identity_break() {
        // The negative control of the test above: the box's ceiling is tight. Past the last
        // node the clamp moves the point, so a run that took such a sample as inside would
        // read another cell with other fractions.
        let grid = grid();
        let q = Vec4::new(5.5, 8.25, 3.5, 0.0);
        let interior = Interior::new(&grid, 2..9).unwrap();
        let wider = Interior {
            ceiling: interior.ceiling + Vec4::new(0.0, 1.0, 0.0, 0.0),
            ..interior.clone()
        };
        assert!(!interior.holds(q) && wider.holds(q));
        let site = field::locate4(&grid, Model::Cell, q);
        let (cell, lo) = field::interior_corner(q);
        assert!(lo != site.lo || (q - cell).truncate() != site.frac);
    }

    #[test]
    fn a_rays_inside_samples_are_one_run_and_last_finds_its_end() {
        let grid = grid();
        let interior = Interior::new(&grid, 3..8).unwrap();
        let mut next = crate::testing::xorshift(0x7e57_1a57);
        let unit = |n: u32| (n >> 8) as f32 / (1 << 24) as f32;
        let mut runs = 0;
        for _ in 0..6_000 {
            let origin = Vec3::new(unit(next()) * 14.0 - 1.0, unit(next()) * 11.0 - 1.0, -2.0);
            let mut dir = Vec3::new(unit(next()) - 0.5, unit(next()) - 0.5, unit(next()) + 0.05);
            // Along an axis now and then.
            if next() % 5 == 0 {
                dir.x = 0.0;
            }
            let dir = dir.normalize();
            let dt = 0.05 + unit(next());
            let Some(lattice) = Lattice::new(0.0, 20.0, dt) else {
                continue;
            };
            let ray = Ray {
                origin,
                dir,
                dir_world: dir,
            };
            let state = RayState::new(RayKind::Primary, 0, ray, lattice, Entry::Inside, 0);
            let inside = |k: u32| interior.holds(ray.at4(lattice.t(k)));
            let Some(first) = (0..=lattice.last).find(|&k| inside(k)) else {
                continue;
            };
            runs += 1;
            let end = (first..=lattice.last)
                .take_while(|&k| inside(k))
                .last()
                .unwrap_or(first);
            assert!(!(end + 1..=lattice.last).any(inside), "two runs: {state:?}");
            // From the first sample inside, and from every later one.
            for k in first..=end {
                assert_eq!(interior.last(&state, k), end, "{state:?} from {k}");
            }
        }
        assert!(runs > 1_500, "{runs}");
    }
}

//! Row leaps of distributed generation: bounds on how a primary ray's first sample, and its
//! miss of the dataset's box, change from pixel to pixel along an image row, so that a ring
//! position passes over pixels without setting up their rays.
//!
//! Under distributed generation every ring position walks every pixel of its cluster and
//! starts the rays whose first sample it owns; setting up a ray to learn that costs as much
//! as the ray's start, so without a bound a ring of `n` set up every ray `n` times.
//!
//! The bounds, for a parallel projection (perspective views get none, and every pixel is set
//! up as before). Along a row the ray origin moves by a constant `U` per pixel and the
//! direction `D` is fixed (both in index units). A ray's first sample is its entry into the
//! dataset's box, at `t_near = max(0, t_x, t_y, t_z)` with `t_a` linear in the pixel, so the
//! entry's x is continuous and piecewise linear along the part of the row that hits the box
//! (one interval: the box is convex). Its slope on the piece where axis `a` sets `t_near` is
//! `U.x − U.a·D.x/D.a` (zero for `a = x`), and `U.x` where the eye is inside the box.
//! [`RowLeaps::slope`] is the largest of them, widened by 1%. A ray that misses does so by a
//! distance off a slab of faces it runs parallel to, or by a gap between leaving one slab
//! and entering another; [`RowLeaps::misses_after`] bounds how fast either closes.
//!
//! Invariants: [`passable`] never passes over a pixel whose first sample the position owns,
//! nor, at the position that sends the background of misses, over a pixel that misses; and
//! [`RowLeaps::misses_after`] never counts a pixel that hits. They leave a margin of
//! [`MARGIN_PLANES`] planes beyond the x range the owned planes can claim, and 2⁻¹² of the
//! coordinates' magnitude for rounding (f32 arithmetic of a few operations errs by about
//! 2⁻²²). A pixel close to an edge of a bound is always set up and judged by the exact rule,
//! so the bounds change which rays are set up, never which node starts them or what any
//! pixel shows.

use crate::trace::camera::Projection;
use crate::trace::lattice::Lattice;
use crate::volume::grid::{Grid, Model};
use core::ops::Range;
use glam::Vec3;

/// Planes of slack between the x range owned planes can claim and a pixel passed over.
pub const MARGIN_PLANES: f32 = 1.0;

/// The per-pixel bound of one view; see the module's text.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RowLeaps {
    /// Index units along x that the first sample moves at most per pixel of a row.
    slope: f32,
    /// `U`: how far the ray origin moves per pixel of a row (index units).
    step: Vec3,
    /// `D`: the rays' direction (index units per world unit of `t`).
    dir: Vec3,
    /// How fast a missing ray's gap between leaving one pair of faces and entering another
    /// can close, per pixel: twice the largest `|U.a / D.a|`, widened by 1%.
    gap_slope: f32,
    /// The dataset's box (index space).
    lo: Vec3,
    hi: Vec3,
}

impl RowLeaps {
    /// The bound for `projection` with image axes `right`, view direction `forward` (world,
    /// unit), `width` pixels across, `inv_spacing` index units per world unit and the
    /// dataset's box `[lo, hi]` (index space); `None` for a perspective projection or a bound
    /// that is not finite.
    pub fn new(
        projection: Projection,
        right: Vec3,
        forward: Vec3,
        width: u32,
        inv_spacing: Vec3,
        (lo, hi): (Vec3, Vec3),
    ) -> Option<RowLeaps> {
        let Projection::Orthographic { width: world_width } = projection else {
            return None;
        };
        let to_f64 = |v: Vec3| [f64::from(v.x), f64::from(v.y), f64::from(v.z)];
        let step = f64::from(world_width) / f64::from(width.max(1));
        let s = to_f64(inv_spacing);
        let (r, f) = (to_f64(right), to_f64(forward));
        let u: [f64; 3] = core::array::from_fn(|a| r[a] * step * s[a]);
        let d: [f64; 3] = core::array::from_fn(|a| f[a] * s[a]);
        // The eye inside the box (t_near = 0): the entry is the origin itself.
        let mut slope = u[0].abs();
        for a in 1..3 {
            if d[a] != 0.0 {
                slope = slope.max((u[0] - u[a] * d[0] / d[a]).abs());
            }
        }
        let slope = (slope * 1.01) as f32;
        let gap = (0..3)
            .filter(|&a| d[a] != 0.0)
            .map(|a| (u[a] / d[a]).abs())
            .fold(0.0, f64::max);
        let gap_slope = (2.0 * gap * 1.01) as f32;
        let to_f32 = |v: [f64; 3]| Vec3::new(v[0] as f32, v[1] as f32, v[2] as f32);
        let leaps = RowLeaps {
            slope,
            step: to_f32(u),
            dir: to_f32(d),
            gap_slope,
            lo,
            hi,
        };
        let finite = slope.is_finite()
            && gap_slope.is_finite()
            && leaps.step.is_finite()
            && leaps.dir.is_finite();
        finite.then_some(leaps)
    }

    /// Index units along x that a row's first samples move at most per pixel.
    pub fn slope(&self) -> f32 {
        self.slope
    }

    /// How many pixels after one whose primary ray's first sample lies at index-space `x`
    /// (at world parameter `t`), along the same row, certainly do not start in a slab that
    /// claims `claim`. Saturates at `u32::MAX` where the row's first samples cannot move
    /// along x at all; the caller stops at the row's end.
    pub fn not_started(&self, x: f32, t: f32, claim: Claim) -> u32 {
        let margin = MARGIN_PLANES + (x.abs() + (t * self.dir.x).abs()) * (1.0 / 4096.0);
        let distance = (claim.lo - x).max(x - claim.hi) - margin;
        if !(distance > 0.0) {
            return 0;
        }
        if self.slope == 0.0 {
            return u32::MAX;
        }
        // Saturating: a distance of more pixels than u32 holds passes over the whole row.
        libm::floorf(distance / self.slope) as u32
    }

    /// How many pixels after one whose primary ray (from index-space `origin`) misses the
    /// box, along the same row, certainly miss it too; saturating at `u32::MAX` (the caller
    /// stops at the row's end).
    ///
    /// Either certificate of a miss will do. Along an axis the rays run parallel to, the
    /// origin lies outside the box's slab by some distance, which the origin closes by at
    /// most `|U.a|` a pixel. Otherwise the ray leaves one pair of faces before it enters
    /// another (or before `t = 0`): the gap `t_near − t_far` closes by at most
    /// twice the largest `|U.a / D.a|` a pixel, as each end moves by at most that.
    /// Each leaves a margin of 2⁻¹² of the magnitudes involved for rounding.
    pub fn misses_after(&self, origin: Vec3) -> u32 {
        let pixels = |excess: f32, margin: f32, per_pixel: f32| -> u32 {
            let excess = excess - margin;
            if !(excess > 0.0) {
                0
            } else if per_pixel == 0.0 {
                u32::MAX
            } else {
                libm::floorf(excess / per_pixel) as u32
            }
        };
        let (mut t_near, mut t_far, mut size) = (0.0f32, f32::INFINITY, 0.0f32);
        let mut best = 0;
        for a in 0..3 {
            let (o, d, lo, hi) = (origin[a], self.dir[a], self.lo[a], self.hi[a]);
            let scale = o.abs() + lo.abs() + hi.abs() + 1.0;
            if d == 0.0 {
                let outside = (lo - o).max(o - hi);
                best = best.max(pixels(outside, scale / 4096.0, self.step[a].abs()));
            } else {
                let (t0, t1) = ((lo - o) / d, (hi - o) / d);
                t_near = t_near.max(t0.min(t1));
                t_far = t_far.min(t0.max(t1));
                size = size.max(scale / d.abs());
            }
        }
        if t_far.is_finite() {
            let margin = (t_near.abs() + t_far.abs() + size) / 4096.0;
            best = best.max(pixels(t_near - t_far, margin, self.gap_slope));
        }
        best
    }
}

/// A ring position's row leap: given one pixel's primary ray (first sample at index-space
/// `x`, over `lattice`) that this position does not start, how many of the next `left`
/// pixels of the row it may pass over without setting up their rays.
///
/// A position that sends the background of pixels that miss (`sends_misses`, ring position
/// 0) may pass over a pixel only if it certainly hits. It asks `ahead(n)` for the lattice of
/// the ray `n` pixels on, where the bound ends, and passes over the pixels between only if
/// both rays cross the box by a robust margin ([`crosses_robustly`]): along parallel rays the
/// length of a convex box's chord is a concave function of the pixel, so every pixel between
/// crosses at least as far, and hits. The position then lands on pixel `n` itself, which it
/// sets up again and judges by the exact rule.
pub fn passable(
    leaps: RowLeaps,
    x: f32,
    lattice: &Lattice,
    claim: Claim,
    left: u32,
    sends_misses: bool,
    ahead: impl FnOnce(u32) -> Option<Lattice>,
) -> u32 {
    let n = leaps.not_started(x, lattice.t_entry, claim).min(left);
    if !sends_misses {
        return n;
    }
    if n < 2 || !crosses_robustly(lattice) {
        return 0;
    }
    match ahead(n) {
        Some(far) if crosses_robustly(&far) => n - 1,
        _ => 0,
    }
}

/// Whether a ray's chord through the box is longer than 2⁻¹² of its ends' magnitude: far
/// beyond the rounding of the few operations that found it, so a ray whose exact chord is at
/// least this long is found to hit.
pub fn crosses_robustly(lattice: &Lattice) -> bool {
    let (a, b) = (lattice.t_entry, lattice.t_exit);
    b - a > (a.abs() + b.abs()) * (1.0 / 4096.0) + f32::MIN_POSITIVE
}

/// The x range in which a slab's owned planes can claim a first sample, widened by one plane
/// each way: [`Grid::owner_plane`] takes `⌊x⌋` (cell model) or `⌊x + ½⌋` (voxel model)
/// clamped into the grid, so the first and last slabs also own everything beyond the grid's
/// ends.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Claim {
    lo: f32,
    hi: f32,
}

impl Claim {
    /// The range the `owned` planes of `grid` claim under `model`.
    pub fn of(owned: Range<u32>, grid: &Grid, model: Model) -> Claim {
        let lo = if owned.start == 0 {
            f32::NEG_INFINITY
        } else {
            owned.start as f32 - 1.0
        };
        let hi = if owned.end > grid.last_owner_plane(model) {
            f32::INFINITY
        } else {
            owned.end as f32 + 1.0
        };
        Claim { lo, hi }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::node::partition::Partition;
    use crate::optics::surface::IsoSurface;
    use crate::testing::xorshift;
    use crate::trace::camera::Camera;
    use crate::trace::march::RayState;
    use crate::trace::view::{Mode, View, ViewSpec};

    /// A parallel view of `grid` from direction `from` at `distance` diagonals from its
    /// centre (inside the box when small), `across` diagonals wide, on a `width × height` image.
    fn view(
        grid: &Grid,
        model: Model,
        from: Vec3,
        distance: f32,
        across: f32,
        size: [u32; 2],
    ) -> View {
        let (lo, hi) = grid.world_box(model);
        let (centre, diagonal) = ((lo + hi) * 0.5, (hi - lo).length());
        let up = if from.normalize().y.abs() > 0.9 {
            Vec3::Z
        } else {
            Vec3::Y
        };
        let camera = Camera::look_at(
            centre + from.normalize() * distance * diagonal,
            centre,
            up,
            Projection::Orthographic {
                width: across * diagonal,
            },
        )
        .unwrap();
        let mut surfaces = heapless::Vec::new();
        let _ = surfaces.push(IsoSurface {
            iso: 1.0,
            color: Vec3::ONE,
            transparency: 0.0,
        });
        let spec = ViewSpec {
            width: size[0],
            height: size[1],
            model,
            max_depth: 0,
            ..crate::testing::spec(camera, Mode::Surfaces(surfaces))
        };
        View::new(spec, grid).unwrap()
    }

    /// Every ring position's row leaps over every row of `view`, as a worker takes them (ring
    /// position 0 sends the background of pixels that miss, unless `zero_sends_misses` is
    /// off). Returns the pixels passed over that the position starts after all, the pixels
    /// position 0 passed over that miss (no one would send their background), the pixels
    /// passed over after a miss as certain misses that hit, and the pixels passed over.
    fn check(
        view: &View,
        grid: &Grid,
        partition: &Partition,
        leaps: RowLeaps,
        zero_sends_misses: bool,
    ) -> (u32, u32, u32, u64) {
        let (w, h) = (view.spec().width, view.spec().height);
        let model = view.spec().model;
        let (mut started, mut missed, mut hit, mut passed) = (0, 0, 0, 0);
        for row in 0..h {
            let rays: heapless::Vec<Option<RayState>, 128> =
                (0..w).map(|px| view.primary_ray(row * w + px)).collect();
            let first = |ray: &RayState| ray.ray.at(ray.lattice.t(0)).x;
            let owner =
                |q: usize| rays[q].map(|r| partition.owner(grid.owner_plane(first(&r), model)));
            for (p, ray) in rays.iter().enumerate() {
                let Some(ray) = ray else {
                    let line = view.primary_line(row * w + p as u32);
                    let n = leaps.misses_after(line.origin).min(w - 1 - p as u32) as usize;
                    passed += n as u64;
                    hit += rays[p + 1..=p + n].iter().filter(|q| q.is_some()).count() as u32;
                    continue;
                };
                for j in 0..partition.slabs() {
                    let n = passable(
                        leaps,
                        first(ray),
                        &ray.lattice,
                        Claim::of(partition.planes(j), grid, model),
                        w - 1 - p as u32,
                        j == 0 && zero_sends_misses,
                        |k| rays[p + k as usize].map(|far| far.lattice),
                    ) as usize;
                    passed += n as u64;
                    started += u32::from(n > 0 && owner(p) == Some(j));
                    for q in p + 1..=p + n {
                        started += u32::from(owner(q) == Some(j));
                        missed += u32::from(j == 0 && rays[q].is_none());
                    }
                }
            }
        }
        (started, missed, hit, passed)
    }

    /// Random grids (anisotropic spacing, both models), directions (some along axes or
    /// diagonals), eyes inside and outside the box, image widths and slab counts.
    fn cases(mut each: impl FnMut(&View, &Grid, &Partition)) {
        let mut next = xorshift(0x5eed_1992);
        let mut unit = move || (next() >> 8) as f32 / (1u32 << 24) as f32;
        let special = [
            Vec3::X,
            -Vec3::Z,
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(-1.0, 1.0, 1.0),
        ];
        for case in 0..300 {
            let dims = [
                4 + (unit() * 36.0) as u32,
                4 + (unit() * 20.0) as u32,
                4 + (unit() * 20.0) as u32,
            ];
            let spacing = Vec3::new(0.5 + unit() * 1.5, 0.5 + unit() * 1.5, 0.5 + unit() * 1.5);
            let grid = Grid::new(dims, spacing).unwrap();
            let model = if unit() < 0.5 {
                Model::Cell
            } else {
                Model::Voxel
            };
            let from = match special.get(case % 12) {
                Some(&d) => d,
                None => Vec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5) + Vec3::splat(1e-3),
            };
            let distance = if case % 7 == 0 {
                0.1 * unit()
            } else {
                0.6 + 3.0 * unit()
            };
            let size = [8 + (unit() * 120.0) as u32, 1 + (unit() * 6.0) as u32];
            let view = view(&grid, model, from, distance, 0.5 + unit() * 1.5, size);
            let slabs = [2, 3, 4, 8][(unit() * 4.0) as usize % 4];
            let partition = Partition::uniform(dims[0], slabs.min(dims[0] as usize - 1)).unwrap();
            each(&view, &grid, &partition);
        }
    }

    #[test]
    fn no_pixel_passed_over_is_started_by_the_slab_that_passed_it() {
        let (mut total, mut parallel) = (0, 0);
        cases(|view, grid, partition| {
            let leaps = view.row_leaps().expect("a parallel view has a bound");
            let (started, missed, hit, passed) = check(view, grid, partition, leaps, true);
            assert_eq!(
                (started, missed, hit),
                (0, 0, 0),
                "{:?} {:?}",
                view.spec().camera,
                grid.dims()
            );
            total += passed;
            parallel += 1;
        });
        // The bound is not vacuous: it passes over a good share of the pixels checked.
        assert!(
            total > 100_000 && parallel == 300,
            "{total} pixels passed over"
        );
    }

    /// In how many of the cases a bound made tighter by `tighten` shows in `count` (a
    /// negative control: the checks can fail).
    fn caught(
        tighten: impl Fn(RowLeaps) -> RowLeaps,
        count: impl Fn((u32, u32, u32, u64)) -> u32,
    ) -> u32 {
        let mut caught = 0;
        cases(|view, grid, partition| {
            let leaps = tighten(view.row_leaps().expect("parallel"));
            caught += u32::from(count(check(view, grid, partition, leaps, true)) > 0);
        });
        caught
    }

    #[test]
    fn a_bound_a_quarter_too_tight_is_caught() {
        let slope = |l: RowLeaps| RowLeaps {
            slope: l.slope * 0.25,
            ..l
        };
        let n = caught(slope, |(started, ..)| started);
        assert!(n > 10, "only {n} cases caught a slope four times too small");
        let misses = |l: RowLeaps| RowLeaps {
            gap_slope: l.gap_slope * 0.25,
            step: l.step * 0.25,
            ..l
        };
        let n = caught(misses, |(_, _, hit, _)| hit);
        assert!(
            n > 10,
            "only {n} cases caught a miss bound four times too tight"
        );
    }

    #[test]
    fn position_zero_passing_over_without_its_far_check_skips_misses_and_is_caught() {
        let (mut caught, mut passed_with_check) = (0, 0);
        cases(|view, grid, partition| {
            let leaps = view.row_leaps().expect("parallel");
            caught += u32::from(check(view, grid, partition, leaps, false).1 > 0);
            passed_with_check += check(view, grid, partition, leaps, true).3;
        });
        assert!(
            caught > 10,
            "only {caught} cases caught position 0 skipping misses"
        );
        assert!(passed_with_check > 0);
    }

    #[test]
    fn perspective_views_have_no_bound_and_far_pixels_are_passed_over() {
        let grid = Grid::new([40, 8, 8], Vec3::ONE).unwrap();
        let camera = Camera::look_at(
            Vec3::new(20.0, 4.0, 60.0),
            Vec3::new(20.0, 4.0, 4.0),
            Vec3::Y,
            Projection::Perspective { fov_y: 0.5 },
        )
        .unwrap();
        let mut v = view(&grid, Model::Cell, Vec3::Z, 2.0, 1.0, [8, 8]);
        let mut spec = v.spec().clone();
        spec.camera = camera;
        v = View::new(spec, &grid).unwrap();
        assert_eq!(v.row_leaps(), None);
        let leaps = RowLeaps::new(
            Projection::Orthographic { width: 10.0 },
            Vec3::X,
            -Vec3::Z,
            10,
            Vec3::ONE,
            grid.index_box(Model::Cell),
        )
        .unwrap();
        // Rays along -z, one index unit apart along x. From x = -20, twenty units short of the
        // box, the next 19 pixels (a margin of 2^-12 of the coordinates) certainly miss; from
        // y = 20, above the box, the whole row does; from inside the box's x and y, none.
        assert_eq!(leaps.misses_after(Vec3::new(-20.0, 4.0, 50.0)), 19);
        assert_eq!(leaps.misses_after(Vec3::new(10.0, 20.0, 50.0)), u32::MAX);
        assert_eq!(leaps.misses_after(Vec3::new(10.0, 4.0, 50.0)), 0);
        // One index unit per pixel along x; slab 20..30 claims [19, 31], and the margin is a
        // plane and a bit: from x = 5 about 12 pixels are surely not its own.
        assert!((leaps.slope() - 1.01).abs() < 1e-6);
        let n = leaps.not_started(5.0, 50.0, Claim::of(20..30, &grid, Model::Cell));
        assert!((11..=13).contains(&n), "{n}");
        assert_eq!(
            leaps.not_started(25.0, 50.0, Claim::of(20..30, &grid, Model::Cell)),
            0
        );
        assert_eq!(
            leaps.not_started(f32::NAN, 50.0, Claim::of(20..30, &grid, Model::Cell)),
            0
        );
        // The last slab also owns everything past the grid's end.
        assert_eq!(
            leaps.not_started(500.0, 50.0, Claim::of(30..39, &grid, Model::Cell)),
            0
        );
    }
}

//! Octant space leaping: for each min/max block of a slab and each octant of ray directions a
//! view uses, how many blocks ahead the nearest block lies that the view cannot skip, in the
//! chessboard metric over the blocks a ray moving into that octant can reach. A ray in a
//! block at distance `d ≥ 1` may jump over every sample whose block lies in the box reaching
//! `d − 1` blocks ahead along each axis, instead of leaving one block per jump. Obstacles
//! behind a ray or beside and behind it do not shorten its leaps, as they do in a cube
//! around the block.
//!
//! Invariants: distances are exact (one pass over the seven neighbours ahead, which is exact
//! for the chessboard metric restricted to an octant; tested against brute force) and
//! saturate at [`u8::MAX`], which only shortens leaps. A block the view cannot skip,
//! including one whose range is unknown, is at distance 0. Blocks outside the slab's columns
//! or the grid are not obstacles: the marcher checks that every landing is owned and lies in
//! a block the map calls empty (so in the slab's columns), and the samples between lie in
//! the same box of blocks, since a ray's block coordinates move monotonically, each the way
//! its octant says. A leap map belongs to one view's emptiness test and one octant: a ray
//! reads the map of its own direction's octant, and leaps by no map when the view has none
//! for it.

use crate::optics::shade::LightKind;
use crate::skip::blocks::{Blocks, BlocksError};
use crate::skip::octant::{Octant, OCTANTS};
use crate::trace::view::View;
use glam::Vec3;

/// The octants `view`'s rays take, one bit per octant ([`Octant::index`]): its primary and
/// transparency rays ([`primary_octants`]), and the shadow rays of its lights that cast
/// shadows. An octant left out only costs speed (its rays leap by no map), so near an axis
/// both sides are taken where directions vary or are computed apart from the rays'.
pub fn octants(view: &View) -> u8 {
    let spec = view.spec();
    let inv = view.inv_spacing();
    let mut mask = primary_octants(view);
    for light in spec.lights.iter().filter(|l| l.shadows) {
        mask |= match light.kind {
            LightKind::Directional { direction } => spread(-direction * inv, -direction * inv),
            LightKind::Point { .. } => u8::MAX,
        };
    }
    mask
}

/// The least and greatest of `view`'s primary directions in index space, per axis: one for
/// a parallel projection; the image's corners bound them for a perspective one (each
/// component is monotone across the image).
fn primary_bounds(view: &View) -> (Vec3, Vec3) {
    let spec = view.spec();
    let (w, h) = (spec.width, spec.height);
    let (x, y) = (w.saturating_sub(1), h.saturating_sub(1));
    let corners = [(0, 0), (x, 0), (0, y), (x, y)]
        .map(|(x, y)| spec.camera.primary(x, y, w, h).1 * view.inv_spacing());
    corners
        .iter()
        .fold((corners[0], corners[0]), |(lo, hi), &d| {
            (lo.min(d), hi.max(d))
        })
}

/// The octants `view`'s primary rays take, one bit per octant: the one of their direction for
/// a parallel projection (every pixel's is the same, from the same expression as here, and so
/// its sign bits: a view at zero elevation takes one map, not two), else every octant between
/// the image corners' directions and within a rounding of them. Transparency rays go on the
/// same way.
pub fn primary_octants(view: &View) -> u8 {
    let (lo, hi) = primary_bounds(view);
    match view.spec().camera.projection() {
        crate::trace::camera::Projection::Orthographic { .. } => 1 << Octant::of(lo).index(),
        crate::trace::camera::Projection::Perspective { .. } => spread(lo, hi),
    }
}

/// The octants of every direction between `lo` and `hi` (per axis), and of those within a
/// rounding of them.
fn spread(lo: Vec3, hi: Vec3) -> u8 {
    let slack = lo.abs().max(hi.abs()).max_element() * 1e-5;
    // Per axis: which of up (bit 0) and down (bit 1) occur.
    let sides: [u8; 3] =
        core::array::from_fn(|a| u8::from(!(hi[a] < -slack)) | u8::from(lo[a] < slack) << 1);
    (0..OCTANTS)
        .filter(|&o| (0..3).all(|a| sides[a] >> (o >> a & 1) & 1 == 1))
        .fold(0, |mask, o| mask | 1 << o)
}

/// Fill `out` (one entry per block of `blocks`, in the blocks' order) with each block's
/// chessboard distance, for rays of `octant`, to the nearest block ahead that `view` cannot
/// skip.
pub fn build(
    blocks: &Blocks<'_>,
    view: &View,
    octant: Octant,
    out: &mut [u8],
) -> Result<(), BlocksError> {
    let ranges = blocks.ranges();
    BlocksError::check_storage(ranges.len(), out.len())?;
    for (d, r) in out.iter_mut().zip(ranges) {
        *d = if view.empty(*r) { u8::MAX } else { 0 };
    }
    let (cols, ny, nz) = blocks.shape();
    // The storage order: X columns slowest, then Z, then Y.
    ahead(
        out,
        [cols, nz, ny],
        [octant.down(0), octant.down(2), octant.down(1)],
    );
    Ok(())
}

/// The chessboard distance transform restricted to an octant, in place: `d` laid out with
/// axis 0 slowest and axis 2 fastest over `dims`, each axis ahead upwards unless `down`
/// says so. One pass from the far corner: each entry takes its seven neighbours ahead, whose
/// distances are final by then (a nearest obstacle ahead of a block is one step nearer to its
/// neighbour on the way).
fn ahead(d: &mut [u8], dims: [u32; 3], down: [bool; 3]) {
    let [a, b, c] = dims.map(|n| n as usize);
    let at = |i: usize, j: usize, k: usize| (i * b + j) * c + k;
    // The far end first along each axis, and the step towards the neighbours ahead.
    let order = |n: usize, down: bool| (0..n).map(move |i| if down { i } else { n - 1 - i });
    let next = |i: usize, n: usize, down: bool| {
        if down {
            i.checked_sub(1)
        } else {
            Some(i + 1).filter(|&j| j < n)
        }
    };
    for i in order(a, down[0]) {
        for j in order(b, down[1]) {
            for k in order(c, down[2]) {
                let here = at(i, j, k);
                if d[here] == 0 {
                    continue;
                }
                let (ni, nj, nk) = (
                    next(i, a, down[0]),
                    next(j, b, down[1]),
                    next(k, c, down[2]),
                );
                let mut best = u8::MAX;
                for step in 1..8u8 {
                    let pick = |bit: u8, now: usize, ahead: Option<usize>| match step >> bit & 1 {
                        0 => Some(now),
                        _ => ahead,
                    };
                    if let (Some(x), Some(y), Some(z)) =
                        (pick(0, i, ni), pick(1, j, nj), pick(2, k, nk))
                    {
                        best = best.min(d[at(x, y, z)].saturating_add(1));
                    }
                }
                d[here] = best;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brute force: the least chessboard distance to a zero entry ahead (each axis up, or
    /// down where `down` says), saturating at 255.
    fn brute(seed: &[u8], dims: [u32; 3], down: [bool; 3]) -> [u8; 216] {
        let [a, b, c] = dims.map(|n| n as i32);
        let ahead = |from: i32, to: i32, down: bool| if down { to <= from } else { to >= from };
        let mut out = [0u8; 216];
        for i in 0..a {
            for j in 0..b {
                for k in 0..c {
                    let mut best = i32::from(u8::MAX);
                    for ii in 0..a {
                        for jj in 0..b {
                            for kk in 0..c {
                                let forward = ahead(i, ii, down[0])
                                    && ahead(j, jj, down[1])
                                    && ahead(k, kk, down[2]);
                                if forward && seed[((ii * b + jj) * c + kk) as usize] == 0 {
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
    fn one_pass_gives_exact_chessboard_distances_ahead_in_every_octant() {
        let mut next = crate::testing::xorshift(0x2545_f491);
        for round in 0..300 {
            let dims = [1 + next() % 6, 1 + next() % 6, 1 + next() % 6];
            let len = dims.iter().product::<u32>() as usize;
            // From nearly empty to nearly full of obstacles; sometimes none at all.
            let density = round % 10;
            let mut seed = [u8::MAX; 216];
            for v in seed.iter_mut().take(len) {
                if next() % 10 < density {
                    *v = 0;
                }
            }
            for octant in 0..8 {
                let down = [octant & 1 == 1, octant & 2 == 2, octant & 4 == 4];
                let mut d = seed;
                ahead(&mut d[..len], dims, down);
                let expected = brute(&seed, dims, down);
                assert_eq!(
                    &d[..len],
                    &expected[..len],
                    "{dims:?} {down:?} density {density}"
                );
            }
        }
    }

    #[test]
    fn an_octant_is_the_signs_of_a_direction() {
        assert_eq!(Octant::of(Vec3::new(1.0, 2.0, 3.0)).index(), 0);
        assert_eq!(Octant::of(Vec3::new(-1.0, 2.0, -3.0)).index(), 0b101);
        // Zero of either sign moves no way: up.
        assert_eq!(Octant::of(Vec3::new(-0.0, 0.0, -1e-30)).index(), 0b100);
        let o = Octant::of(Vec3::new(0.5, -0.5, 0.0));
        assert!(!o.down(0) && o.down(1) && !o.down(2));
        assert_eq!(Octant::from_index(o.index()), o);
    }

    /// A parallel view's rays all have the direction its primary octants are found from, in
    /// every bit, so a view at zero elevation (no motion along Y) takes one map: its rays'.
    /// A perspective view's rays there go up and down, and it takes both sides.
    #[test]
    fn a_parallel_view_takes_its_rays_octant_only() {
        use crate::trace::camera::{Camera, Projection};
        use crate::trace::view::{Mode, ViewSpec};
        let grid = crate::volume::grid::Grid::new([8, 8, 8], Vec3::new(1.0, 0.5, 2.0)).unwrap();
        let centre = Vec3::new(3.5, 1.75, 7.0);
        for (eye, perspective) in [
            (Vec3::new(30.0, 1.75, 40.0), false),
            (Vec3::new(-20.0, 1.75, -9.0), false),
            (Vec3::new(30.0, 1.75, 40.0), true),
        ] {
            let projection = match perspective {
                false => Projection::Orthographic { width: 12.0 },
                true => Projection::Perspective { fov_y: 0.6 },
            };
            let camera = Camera::look_at(eye, centre, Vec3::Y, projection).unwrap();
            let mut surfaces = heapless::Vec::new();
            let _ = surfaces.push(crate::optics::surface::IsoSurface {
                iso: 0.5,
                color: Vec3::ONE,
                transparency: 0.0,
            });
            let spec = ViewSpec {
                width: 9,
                height: 7,
                ..crate::testing::spec(camera, Mode::Surfaces(surfaces))
            };
            let view = View::new(spec, &grid).unwrap();
            let taken = octants(&view);
            match perspective {
                false => {
                    let dir = view.primary_line(0).dir;
                    assert_eq!(dir.y, 0.0, "{eye}: the rays do not move along Y");
                    assert_eq!(taken, 1 << Octant::of(dir).index(), "{eye}");
                }
                // Rays above and below the image's middle row.
                true => assert_eq!(taken.count_ones(), 2, "{eye}: {taken:08b}"),
            }
        }
    }

    #[test]
    fn spread_takes_every_octant_between_and_both_sides_near_an_axis() {
        let one = Vec3::new(1.0, -2.0, 0.5);
        assert_eq!(spread(one, one), 1 << 0b010);
        // Y across zero: both halves in Y.
        assert_eq!(
            spread(Vec3::new(1.0, -2.0, 0.5), Vec3::new(1.0, 2.0, 0.5)),
            1 << 0b000 | 1 << 0b010
        );
        // A component that is zero, or a rounding from it, takes both sides.
        let flat = Vec3::new(1.0, 1e-9, -0.5);
        assert_eq!(spread(flat, flat), 1 << 0b100 | 1 << 0b110);
    }
}

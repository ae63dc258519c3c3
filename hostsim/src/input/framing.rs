//! What part of a volume a view can show, for framing its default camera and for warning
//! when it can show nothing.
//!
//! A cell can show when its value range (its eight corners for the cell model, its one
//! sample for the voxel model) is not [`View::empty`]: the same test empty-space skipping
//! uses, so a cell outside the frame is one every ray passes over. The frame is the box of
//! those cells oriented along the camera's axes (so a round object fills the image, not its
//! axis-aligned box seen corner-on), in world units.

use crate::input::dataset::{Volume, VolumeData};
use voxcube_kernel::trace::camera::Projection;
use voxcube_kernel::trace::view::View;
use voxcube_kernel::volume::grid::{Grid, Model};
use voxcube_kernel::volume::sample::Range;
use voxcube_kernel::Vec3;

/// A box for a camera to frame: its corners and its centre, in world units.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// The eight corners.
    pub corners: [Vec3; 8],
    /// The centre.
    pub centre: Vec3,
}

impl Frame {
    /// An axis-aligned box.
    pub fn of_box(b: (Vec3, Vec3)) -> Frame {
        Frame {
            corners: corners(b),
            centre: (b.0 + b.1) * 0.5,
        }
    }

    /// The box spanning `along[a]` on each of the orthonormal `axes`.
    pub fn oriented(axes: [Vec3; 3], along: [(f32, f32); 3]) -> Frame {
        let point = |t: [f32; 3]| axes[0] * t[0] + axes[1] * t[1] + axes[2] * t[2];
        let mid = along.map(|(a, b)| (a + b) * 0.5);
        Frame {
            corners: core::array::from_fn(|c| {
                point(core::array::from_fn(|a| {
                    if c >> a & 1 == 0 {
                        along[a].0
                    } else {
                        along[a].1
                    }
                }))
            }),
            centre: point(mid),
        }
    }
}

/// The cells of a volume that one view can show, summarised for framing: for every row of
/// cells along Y (one X and one Z index), the least and greatest Y of a cell in it that can
/// show. Which cells show depends on the view's transfer function or iso values and its
/// model, never on its camera, so one summary frames every camera of an orbit, and a frame
/// costs a pass over the rows, not over the volume.
///
/// Invariant: the frame from the summary is the frame from every cell that shows, bit for
/// bit. A corner's position along an axis is computed in `f32` from its coordinates by
/// products with fixed factors and sums, each monotone under rounding, so along a row (X and
/// Z fixed) it is monotone in Y, and its least and greatest over the row's cells lie on the
/// row's first and last cell that shows.
#[derive(Clone, Debug, PartialEq)]
pub struct Showing {
    model: Model,
    /// Cells along Z: a row's index is `x · cells_z + z`.
    cells_z: usize,
    /// Each row's least and greatest Y that shows; `None` where no cell of the row shows.
    rows: Vec<Option<(u32, u32)>>,
}

impl Showing {
    /// The cells of `volume` that `view` can show: one pass over the samples.
    pub fn of(volume: &Volume, view: &View) -> Showing {
        match &volume.data {
            VolumeData::U8(v) => Showing::of_samples(v, volume, view),
            VolumeData::U16(v) => Showing::of_samples(v, volume, view),
            VolumeData::I16(v) => Showing::of_samples(v, volume, view),
            VolumeData::F32(v) => Showing::of_samples(v, volume, view),
        }
    }

    fn of_samples<T: Copy + Into<f32>>(data: &[T], volume: &Volume, view: &View) -> Showing {
        let [nx, ny, nz] = volume.grid.dims().map(|d| d as usize);
        let model = view.spec().model;
        // Cells per axis, and the offset of a cell's far corners: corners i..=i+1 for the cell
        // model (one cell, read twice, on an axis of one sample), the sample itself for the
        // voxel model.
        let span = |n: usize| match model {
            Model::Cell => (n.saturating_sub(1).max(1), usize::from(n > 1)),
            Model::Voxel => (n, 0),
        };
        let ((cx, ox), (cy, oy), (cz, oz)) = (span(nx), span(ny), span(nz));
        // Plane-major: x slowest, then z, then y.
        let row = |x: usize, z: usize| &data[(x * nz + z) * ny..][..ny];
        let mut lo = vec![f32::INFINITY; ny];
        let mut hi = vec![f32::NEG_INFINITY; ny];
        let mut rows = Vec::with_capacity(cx * cz);
        for x in 0..cx {
            for z in 0..cz {
                // The least and greatest of the row's node rows at each Y, then of each cell's
                // two Y: the least and greatest of its corners, as `Range`s are taken.
                lo.fill(f32::INFINITY);
                hi.fill(f32::NEG_INFINITY);
                for (dx, dz) in [(0, 0), (0, oz), (ox, 0), (ox, oz)] {
                    for ((l, h), &v) in lo.iter_mut().zip(&mut hi).zip(row(x + dx, z + dz)) {
                        let v: f32 = v.into();
                        (*l, *h) = (l.min(v), h.max(v));
                    }
                }
                let cell = |y: usize| Range {
                    min: lo[y].min(lo[y + oy]),
                    max: hi[y].max(hi[y + oy]),
                };
                let whole = Range {
                    min: lo.iter().fold(f32::INFINITY, |a, &b| a.min(b)),
                    max: hi.iter().fold(f32::NEG_INFINITY, |a, &b| a.max(b)),
                };
                let shows = |y: &usize| !view.empty(cell(*y));
                rows.push(match view.empty(whole) {
                    true => None,
                    false => (0..cy)
                        .find(shows)
                        .zip((0..cy).rev().find(shows))
                        .map(|(a, b)| (a as u32, b as u32)),
                });
            }
        }
        Showing {
            model,
            cells_z: cz,
            rows,
        }
    }

    /// Every row's first and last cell that shows, by index.
    fn ends(&self) -> impl Iterator<Item = [usize; 3]> + '_ {
        let cz = self.cells_z.max(1);
        self.rows.iter().enumerate().flat_map(move |(r, ys)| {
            let (x, z) = (r / cz, r % cz);
            let ends = ys.map(|(a, b)| [[x, a as usize, z], [x, b as usize, z]]);
            ends.into_iter().flatten()
        })
    }

    /// The frame of the cells that show, along `view`'s camera axes (right, up, forward).
    pub fn frame(&self, volume: &Volume, view: &View) -> Option<Frame> {
        let camera = &view.spec().camera;
        let (right, up) = camera.image_axes();
        let axes = [right, up, camera.forward()];
        let mut along: Option<[(f32, f32); 3]> = None;
        for i in self.ends() {
            let lo = cell_lo(volume, self.model, i);
            let hi = cell_lo(volume, self.model, i.map(|k| k + 1));
            let e = along.get_or_insert([(f32::INFINITY, f32::NEG_INFINITY); 3]);
            for p in corners((lo, hi)) {
                for a in 0..3 {
                    let t = p.dot(axes[a]);
                    e[a] = (e[a].0.min(t), e[a].1.max(t));
                }
            }
        }
        along.map(|along| Frame::oriented(axes, along))
    }

    /// The world box of the cells that show.
    pub fn world_box(&self, volume: &Volume) -> Option<(Vec3, Vec3)> {
        let mut b: Option<([usize; 3], [usize; 3])> = None;
        for i in self.ends() {
            let (lo, hi) = b.get_or_insert((i, i));
            for a in 0..3 {
                lo[a] = lo[a].min(i[a]);
                hi[a] = hi[a].max(i[a]);
            }
        }
        let (lo, hi) = b?;
        Some((
            cell_lo(volume, self.model, lo),
            cell_lo(volume, self.model, hi.map(|i| i + 1)),
        ))
    }
}

/// The world position of cell index `i`'s low corner (clamped into the volume's box).
fn cell_lo(volume: &Volume, model: Model, i: [usize; 3]) -> Vec3 {
    let shift = match model {
        Model::Cell => 0.0,
        Model::Voxel => -0.5,
    };
    let (lo, hi) = volume.grid.world_box(model);
    (Vec3::new(i[0] as f32, i[1] as f32, i[2] as f32) + Vec3::splat(shift))
        .clamp(lo / volume.grid.spacing(), hi / volume.grid.spacing())
        * volume.grid.spacing()
}

/// The eight corners of a box.
pub fn corners((lo, hi): (Vec3, Vec3)) -> [Vec3; 8] {
    core::array::from_fn(|c| {
        Vec3::new(
            if c & 1 == 0 { lo.x } else { hi.x },
            if c & 2 == 0 { lo.y } else { hi.y },
            if c & 4 == 0 { lo.z } else { hi.z },
        )
    })
}

/// Why `view` of a volume can draw nothing (or a surface of it nothing), if a reason shows
/// before rendering: iso values outside the data's range, a transfer function transparent
/// over it, a camera facing away, or a volume outside the image.
///
/// `range` is the least and greatest value of the volume on `grid` (`None`: it has none): a
/// host that holds the samples takes [`Volume::held_range`], one that does not (MPI ranks
/// hold their own) what its nodes report.
pub fn blank_reasons(range: Option<(f64, f64)>, grid: &Grid, view: &View) -> Vec<String> {
    use voxcube_kernel::trace::view::Mode;
    let (min, max) = range.map_or((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi)| {
        (lo as f32, hi as f32)
    });
    let mut out = Vec::new();
    match &view.spec().mode {
        Mode::Surfaces(surfaces) => {
            for (i, s) in surfaces.iter().enumerate() {
                if !(s.iso > min && s.iso <= max) {
                    out.push(format!(
                        "surfaces[{i}].iso = {} lies outside the data's range ({min} to {max}): that surface draws nothing",
                        s.iso
                    ));
                }
            }
        }
        Mode::Composite(_) => {
            if view.empty(Range { min, max }) {
                out.push(format!(
                    "the transfer function is transparent over the data's range ({min} to {max}): the view draws nothing"
                ));
            }
        }
    }
    let camera = &view.spec().camera;
    let (lo, hi) = grid.world_box(view.spec().model);
    let depth = |p: Vec3| (p - camera.eye()).dot(camera.forward());
    let box_corners = corners((lo, hi));
    if box_corners.iter().all(|&p| depth(p) <= 0.0) {
        out.push("the camera faces away from the volume: it lies behind the eye".into());
    } else if box_corners.iter().all(|&p| depth(p) > 0.0) {
        let (right, up) = camera.image_axes();
        let spec = view.spec();
        let aspect = spec.width as f32 / spec.height as f32;
        // Image-plane position of a point, in half-widths and half-heights of the image.
        let project = |p: Vec3| -> (f32, f32) {
            let d = p - camera.eye();
            match camera.projection() {
                Projection::Orthographic { width } => {
                    (d.dot(right) * 2.0 / width, d.dot(up) * 2.0 * aspect / width)
                }
                Projection::Perspective { fov_y } => {
                    let t = libm::tanf(fov_y * 0.5) * d.dot(camera.forward());
                    (d.dot(right) / (t * aspect), d.dot(up) / t)
                }
            }
        };
        let (mut x0, mut x1, mut y0, mut y1) = (f32::MAX, f32::MIN, f32::MAX, f32::MIN);
        for p in box_corners {
            let (x, y) = project(p);
            (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
        }
        if x1 < -1.0 || x0 > 1.0 || y1 < -1.0 || y0 > 1.0 {
            out.push(
                "no primary ray meets the volume: it lies outside the image (see camera look_at, width or fov)"
                    .into(),
            );
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::dataset::plane_major_from_fn;
    use crate::input::scene::Scene;
    use voxcube_kernel::volume::grid::Grid;

    fn view_of(text: &str) -> View {
        let jobs = Scene::parse(text, "t.toml", std::path::Path::new("."))
            .and_then(Scene::load)
            .unwrap_or_else(|e| panic!("{e}"));
        jobs.into_iter()
            .next()
            .and_then(|d| d.views.into_iter().next())
            .map(|v| v.view)
            .unwrap_or_else(|| panic!("a view"))
    }

    /// Every cell's index that `view` can show, one by one: the reference the rows summarise.
    fn each_showing<T: Copy + Into<f32>>(
        data: &[T],
        volume: &Volume,
        view: &View,
    ) -> Vec<[usize; 3]> {
        let [nx, ny, nz] = volume.grid.dims().map(|d| d as usize);
        let model = view.spec().model;
        let at = |x: usize, y: usize, z: usize| -> f32 { data[(x * nz + z) * ny + y].into() };
        let span = |n: usize| match model {
            Model::Cell => (n.saturating_sub(1).max(1), usize::from(n > 1)),
            Model::Voxel => (n, 0),
        };
        let ((cx, ox), (cy, oy), (cz, oz)) = (span(nx), span(ny), span(nz));
        let mut out = Vec::new();
        for x in 0..cx {
            for z in 0..cz {
                for y in 0..cy {
                    let mut r = Range {
                        min: f32::INFINITY,
                        max: f32::NEG_INFINITY,
                    };
                    for dx in 0..=ox {
                        for dz in 0..=oz {
                            for dy in 0..=oy {
                                let v = at(x + dx, y + dy, z + dz);
                                r.min = r.min.min(v);
                                r.max = r.max.max(v);
                            }
                        }
                    }
                    if !view.empty(r) {
                        out.push([x, y, z]);
                    }
                }
            }
        }
        out
    }

    /// The frame and box of every cell that shows, each cell's corners taken one by one.
    fn brute_force(volume: &Volume, view: &View) -> (Option<Frame>, Option<(Vec3, Vec3)>) {
        let VolumeData::U8(data) = &volume.data else {
            unreachable!("the tests' volumes are bytes")
        };
        let cells = each_showing(data, volume, view);
        let model = view.spec().model;
        let camera = &view.spec().camera;
        let (right, up) = camera.image_axes();
        let axes = [right, up, camera.forward()];
        let mut along: Option<[(f32, f32); 3]> = None;
        let mut b: Option<([usize; 3], [usize; 3])> = None;
        for &i in &cells {
            let (lo, hi) = (
                cell_lo(volume, model, i),
                cell_lo(volume, model, i.map(|k| k + 1)),
            );
            let e = along.get_or_insert([(f32::INFINITY, f32::NEG_INFINITY); 3]);
            for p in corners((lo, hi)) {
                for a in 0..3 {
                    let t = p.dot(axes[a]);
                    e[a] = (e[a].0.min(t), e[a].1.max(t));
                }
            }
            let (l, h) = b.get_or_insert((i, i));
            for a in 0..3 {
                (l[a], h[a]) = (l[a].min(i[a]), h[a].max(i[a]));
            }
        }
        let frame = along.map(|along| Frame::oriented(axes, along));
        let world = b.map(|(l, h)| {
            (
                cell_lo(volume, model, l),
                cell_lo(volume, model, h.map(|i| i + 1)),
            )
        });
        (frame, world)
    }

    #[test]
    fn the_rows_frame_what_every_cell_frames_bit_for_bit() {
        let mut rng = crate::rng::SplitMix(0xF4A3);
        let mut checked = 0;
        for dims in [[9, 7, 11], [1, 6, 5], [6, 1, 7], [5, 8, 1], [13, 13, 13]] {
            // Sparse blobs in noise, so that rows end on many different cells.
            let data = plane_major_from_fn(dims, |_, _, _| {
                let u = rng.next_u64();
                if u.is_multiple_of(7) {
                    (u >> 8) as u8
                } else {
                    (u >> 8) as u8 % 40
                }
            });
            let volume = Volume::new(
                Grid::new(dims, Vec3::new(1.0, 0.7, 1.3)).unwrap_or_else(|e| panic!("{e}")),
                VolumeData::U8(data),
            );
            for model in ["cell", "voxel"] {
                for (az, el) in [(45.0, 0.0), (-130.0, 35.0), (10.0, -80.0), (200.0, 12.5)] {
                    for what in ["[[datasets.views.surfaces]]\niso = 120.0", "[[datasets.views.surfaces]]\niso = 250.0", "mode = \"composite\"\n[[datasets.views.transfer]]\nvalue = 100.0\ncolor = [1.0, 1.0, 1.0]\nopacity = 0.0\n[[datasets.views.transfer]]\nvalue = 200.0\ncolor = [1.0, 1.0, 1.0]\nopacity = 0.5"] {
                        let (head, tail) = what.split_at(what.find('[').unwrap_or(0));
                        let text = format!("[[datasets]]\nname = \"m\"\nbuiltin = \"sphere\"\n[[datasets.views]]\nmodel = \"{model}\"\n{head}\n[datasets.views.camera]\nazimuth = {az:?}\nelevation = {el:?}\n{tail}\n");
                        let view = view_of(&text);
                        let summary = Showing::of(&volume, &view);
                        let (frame, world) = brute_force(&volume, &view);
                        assert_eq!(summary.frame(&volume, &view), frame, "{dims:?} {model} {az} {el}: {what}");
                        assert_eq!(summary.world_box(&volume), world, "{dims:?} {model}: {what}");
                        checked += usize::from(frame.is_some());
                    }
                }
            }
        }
        // Most cases frame something: the comparison is not between two Nones.
        assert!(checked >= 60, "{checked}");
    }

    #[test]
    fn a_summary_that_drops_a_row_s_end_frames_otherwise() {
        // The negative control: the ends carry the frame, so rows that forget their last cell
        // that shows change the frame and the box.
        let data = plane_major_from_fn([6, 6, 6], |x, y, z| {
            u8::from(x == 2 && z == 3 && (1..5).contains(&y)) * 200
        });
        let volume = Volume::new(
            Grid::new([6, 6, 6], Vec3::ONE).unwrap_or_else(|e| panic!("{e}")),
            VolumeData::U8(data),
        );
        let view = view_of("[[datasets]]\nname = \"m\"\nbuiltin = \"sphere\"\n[[datasets.views]]\n[[datasets.views.surfaces]]\niso = 100.0\n");
        let mut summary = Showing::of(&volume, &view);
        let (whole, frame) = (summary.world_box(&volume), summary.frame(&volume, &view));
        assert!(whole.is_some());
        for row in summary.rows.iter_mut().flatten() {
            row.1 = row.0;
        }
        assert_ne!(summary.world_box(&volume), whole);
        assert_ne!(summary.frame(&volume, &view), frame);
    }

    #[test]
    fn the_box_holds_the_cells_that_can_show_and_nothing_more() {
        // A 10³ volume, zero but for a 2×3×1 block of 100 at x 4..6, y 2..5, z 7.
        let data = plane_major_from_fn([10, 10, 10], |x, y, z| {
            u8::from((4..6).contains(&x) && (2..5).contains(&y) && z == 7) * 100
        });
        let volume = Volume::new(
            Grid::new([10, 10, 10], Vec3::ONE).unwrap_or_else(|e| panic!("{e}")),
            VolumeData::U8(data),
        );
        let view = view_of("[[datasets]]\nname = \"m\"\nbuiltin = \"sphere\"\n[[datasets.views]]\n[[datasets.views.surfaces]]\niso = 50.0\n");
        // Cells touching a 100 corner: x 3..=5, y 1..=4, z 6..=7 (cell model).
        assert_eq!(
            Showing::of(&volume, &view).world_box(&volume),
            Some((Vec3::new(3.0, 1.0, 6.0), Vec3::new(6.0, 5.0, 8.0)))
        );
        let above = view_of("[[datasets]]\nname = \"m\"\nbuiltin = \"sphere\"\n[[datasets.views]]\n[[datasets.views.surfaces]]\niso = 150.0\n");
        assert_eq!(Showing::of(&volume, &above).world_box(&volume), None);
        let voxel = view_of("[[datasets]]\nname = \"m\"\nbuiltin = \"sphere\"\n[[datasets.views]]\nmodel = \"voxel\"\n[[datasets.views.surfaces]]\niso = 50.0\n");
        assert_eq!(
            Showing::of(&volume, &voxel).world_box(&volume),
            Some((Vec3::new(3.5, 1.5, 6.5), Vec3::new(5.5, 4.5, 7.5)))
        );
    }
}

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
use voxcube_kernel::volume::grid::Model;
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

/// The frame of the cells of `volume` that `view` can show, along its camera's axes (right,
/// up, forward), or `None` when no cell can show.
pub fn showing(volume: &Volume, view: &View) -> Option<Frame> {
    let camera = &view.spec().camera;
    let (right, up) = camera.image_axes();
    let axes = [right, up, camera.forward()];
    let cells = match &volume.data {
        VolumeData::U8(v) => extent_along(v, volume, view, axes),
        VolumeData::U16(v) => extent_along(v, volume, view, axes),
        VolumeData::F32(v) => extent_along(v, volume, view, axes),
    };
    cells.map(|along| Frame::oriented(axes, along))
}

/// The world box of the cells of `volume` that `view` can show, or `None` when none can.
pub fn showing_box(volume: &Volume, view: &View) -> Option<(Vec3, Vec3)> {
    let mut b: Option<([usize; 3], [usize; 3])> = None;
    let mut note = |i: [usize; 3]| {
        let (lo, hi) = b.get_or_insert((i, i));
        for a in 0..3 {
            lo[a] = lo[a].min(i[a]);
            hi[a] = hi[a].max(i[a]);
        }
    };
    match &volume.data {
        VolumeData::U8(v) => each_showing(v, volume, view, &mut note),
        VolumeData::U16(v) => each_showing(v, volume, view, &mut note),
        VolumeData::F32(v) => each_showing(v, volume, view, &mut note),
    }
    let (lo, hi) = b?;
    let model = view.spec().model;
    Some((
        cell_lo(volume, model, lo),
        cell_lo(volume, model, hi.map(|i| i + 1)),
    ))
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

fn extent_along<T: Copy + Into<f32>>(
    data: &[T],
    volume: &Volume,
    view: &View,
    axes: [Vec3; 3],
) -> Option<[(f32, f32); 3]> {
    let model = view.spec().model;
    let mut along: Option<[(f32, f32); 3]> = None;
    each_showing(data, volume, view, &mut |i| {
        let lo = cell_lo(volume, model, i);
        let hi = cell_lo(volume, model, i.map(|k| k + 1));
        let e = along.get_or_insert([(f32::INFINITY, f32::NEG_INFINITY); 3]);
        for p in corners((lo, hi)) {
            for a in 0..3 {
                let t = p.dot(axes[a]);
                e[a] = (e[a].0.min(t), e[a].1.max(t));
            }
        }
    });
    along
}

/// Call `f` with the index of every cell `view` can show.
fn each_showing<T: Copy + Into<f32>>(
    data: &[T],
    volume: &Volume,
    view: &View,
    f: &mut dyn FnMut([usize; 3]),
) {
    let [nx, ny, nz] = volume.grid.dims().map(|d| d as usize);
    let model = view.spec().model;
    // Plane-major: x slowest, then z, then y.
    let at = |x: usize, y: usize, z: usize| -> f32 { data[(x * nz + z) * ny + y].into() };
    // Cells per axis: corners i..=i+1 for the cell model (one cell on a 1-sample axis), the
    // sample itself for the voxel model.
    let span = |n: usize| match model {
        Model::Cell => (n.saturating_sub(1).max(1), usize::from(n > 1)),
        Model::Voxel => (n, 0),
    };
    let ((cx, ox), (cy, oy), (cz, oz)) = (span(nx), span(ny), span(nz));
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
                    f([x, y, z]);
                }
            }
        }
    }
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

/// Why `view` of `volume` can draw nothing (or a surface of it nothing), if a reason shows
/// before rendering: iso values outside the data's range, a transfer function transparent
/// over it, a camera facing away, or a volume outside the image.
pub fn blank_reasons(volume: &Volume, view: &View) -> Vec<String> {
    use voxcube_kernel::trace::view::Mode;
    let stats = volume.stats();
    let (min, max) = (stats.min as f32, stats.max as f32);
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
    let (lo, hi) = volume.grid.world_box(view.spec().model);
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
            showing_box(&volume, &view),
            Some((Vec3::new(3.0, 1.0, 6.0), Vec3::new(6.0, 5.0, 8.0)))
        );
        let above = view_of("[[datasets]]\nname = \"m\"\nbuiltin = \"sphere\"\n[[datasets.views]]\n[[datasets.views.surfaces]]\niso = 150.0\n");
        assert_eq!(showing_box(&volume, &above), None);
        let voxel = view_of("[[datasets]]\nname = \"m\"\nbuiltin = \"sphere\"\n[[datasets.views]]\nmodel = \"voxel\"\n[[datasets.views.surfaces]]\niso = 50.0\n");
        assert_eq!(
            showing_box(&volume, &voxel),
            Some((Vec3::new(3.5, 1.5, 6.5), Vec3::new(5.5, 4.5, 7.5)))
        );
    }
}

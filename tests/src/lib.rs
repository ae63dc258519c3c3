//! Helpers shared by voxcube's integration tests: small volumes built from functions, views
//! built without a scene file, and whole-image traces that keep the unquantised colours.

use voxcube::input::dataset::{plane_major_from_fn, Volume, VolumeData};
use voxcube_kernel::counters::Counters;
use voxcube_kernel::heapless;
use voxcube_kernel::optics::shade::{Light, Shading};
use voxcube_kernel::optics::surface::IsoSurface;
use voxcube_kernel::optics::transfer::{ControlPoint, TransferFunction};
use voxcube_kernel::trace::camera::{Camera, Projection};
use voxcube_kernel::trace::tracer::trace_pixel;
use voxcube_kernel::trace::view::{Mode, View, ViewSpec};
use voxcube_kernel::volume::grid::{Grid, Model};
use voxcube_kernel::volume::sample::Sample;
use voxcube_kernel::volume::slab::Slab;
use voxcube_kernel::Vec3;

/// The shared data folder beside the repository (`../shared/data`).
pub fn shared_data() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/data")
}

/// The jobs of `scenes/sod.toml` (the paper's dataset), or `None` where the shared data is
/// not beside the repository (an error on CI, which always has it).
pub fn sod_jobs() -> Option<Vec<voxcube::input::scene::DatasetJob>> {
    let dir = shared_data();
    if !dir.is_dir() {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI is set but {} is missing",
            dir.display()
        );
        eprintln!("skipping: {} not found", dir.display());
        return None;
    }
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/sod.toml");
    let jobs =
        voxcube::input::scene::Scene::from_file(&path).and_then(voxcube::input::scene::Scene::load);
    Some(jobs.unwrap_or_else(|e| panic!("{e}")))
}

/// A u8 volume with `f(x, y, z)` at each node.
pub fn volume_u8(dims: [u32; 3], spacing: Vec3, f: impl Fn(u32, u32, u32) -> u8) -> Volume {
    Volume::new(
        Grid::new(dims, spacing).expect("test grid"),
        VolumeData::U8(plane_major_from_fn(dims, f)),
    )
}

/// An f32 volume with `f(x, y, z)` at each node.
pub fn volume_f32(dims: [u32; 3], spacing: Vec3, f: impl Fn(u32, u32, u32) -> f32) -> Volume {
    Volume::new(
        Grid::new(dims, spacing).expect("test grid"),
        VolumeData::F32(plane_major_from_fn(dims, f)),
    )
}

/// Opaque (or not) iso-surfaces.
pub fn surfaces(list: &[(f32, f32)]) -> Mode {
    let mut v = heapless::Vec::new();
    for &(iso, transparency) in list {
        v.push(IsoSurface {
            iso,
            color: Vec3::new(0.9, 0.8, 0.6),
            transparency,
        })
        .expect("few surfaces");
    }
    Mode::Surfaces(v)
}

/// A one-colour transfer function: white with `opacity` per cell edge everywhere.
pub fn constant_transfer(opacity: f32) -> Mode {
    Mode::Composite(
        TransferFunction::new(&[ControlPoint {
            value: 0.0,
            color: Vec3::ONE,
            opacity,
        }])
        .expect("valid transfer function"),
    )
}

/// A view spec with the defaults tests start from: unlit, black background, no lights.
pub fn spec(
    camera: Camera,
    width: u32,
    height: u32,
    model: Model,
    dt: f32,
    mode: Mode,
) -> ViewSpec {
    ViewSpec {
        width,
        height,
        camera,
        model,
        dt,
        gradient_distance: 1.0,
        mode,
        shading: None,
        lights: heapless::Vec::new(),
        background: Vec3::ZERO,
        cutoff: 0.0,
        max_depth: 8,
        refine_steps: 2,
        accuracy: voxcube_kernel::trace::view::Accuracy::Exact,
        compositing: voxcube_kernel::trace::view::Compositing::Sampled,
    }
}

/// The same spec, shaded with these lights.
pub fn lit(mut s: ViewSpec, lights: &[Light]) -> ViewSpec {
    s.shading = Some(Shading::default());
    for l in lights {
        s.lights.push(*l).expect("few lights");
    }
    s
}

/// An orthographic camera.
pub fn ortho(eye: Vec3, target: Vec3, up: Vec3, width: f32) -> Camera {
    Camera::look_at(eye, target, up, Projection::Orthographic { width }).expect("valid camera")
}

/// A perspective camera.
pub fn perspective(eye: Vec3, target: Vec3, up: Vec3, fov_degrees: f32) -> Camera {
    Camera::look_at(
        eye,
        target,
        up,
        Projection::Perspective {
            fov_y: fov_degrees.to_radians(),
        },
    )
    .expect("valid camera")
}

/// Every pixel's unquantised colour, and the counters.
pub fn trace_all(volume: &Volume, view: &View) -> (Vec<Vec3>, Counters) {
    fn go<T: Sample>(grid: Grid, data: &[T], view: &View) -> (Vec<Vec3>, Counters) {
        // A pre-integrated view's table, as every host lends it.
        let table = voxcube::memory::segments::SegmentTable::of(view);
        let slab = table.apply(Slab::whole(grid, data).expect("whole slab"));
        let mut c = Counters::default();
        let colors = (0..view.pixel_count() as u32)
            .map(|p| trace_pixel(view, &slab, p, &mut c))
            .collect();
        (colors, c)
    }
    match &volume.data {
        VolumeData::U8(d) => go(volume.grid, d, view),
        VolumeData::U16(d) => go(volume.grid, d, view),
        VolumeData::I16(d) => go(volume.grid, d, view),
        VolumeData::F32(d) => go(volume.grid, d, view),
    }
}

/// Every pixel's unquantised colour of `view` traced on `slab` alone, as bits (for tests
/// that compare two ways of computing it), and the counters.
pub fn colour_bits<T: Sample>(view: &View, slab: &Slab<'_, T>) -> (Vec<[u32; 3]>, Counters) {
    let mut c = Counters::default();
    let colours = (0..view.pixel_count() as u32)
        .map(|p| {
            trace_pixel(view, slab, p, &mut c)
                .to_array()
                .map(f32::to_bits)
        })
        .collect();
    (colours, c)
}

/// `view` of `volume` in tier `tier`, all else as it is.
pub fn in_tier(view: &View, volume: &Volume, tier: voxcube_kernel::trace::view::Accuracy) -> View {
    let spec = ViewSpec {
        accuracy: tier,
        ..view.spec().clone()
    };
    View::new(spec, &volume.grid).expect("the view, in another tier")
}

/// Build a view, panicking with the reason if the spec is invalid (tests build valid ones).
pub fn view(spec: ViewSpec, volume: &Volume) -> View {
    View::new(spec, &volume.grid).expect("valid view")
}

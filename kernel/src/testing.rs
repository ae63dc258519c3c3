//! What the kernel's unit tests share: a seeded pseudo-random sequence, so that a failing
//! case comes back on every run without a random-number crate in a `no_std` kernel, the
//! parameters of a small view, and a small field of hashed values.

/// Marsaglia's xorshift32 from `seed` (non-zero): the same numbers on every run.
pub fn xorshift(seed: u32) -> impl FnMut() -> u32 {
    let mut state = seed;
    move || {
        state ^= state << 13;
        state ^= state >> 17;
        state ^= state << 5;
        state
    }
}

/// A small view's parameters for `camera` and `mode`: 4×4 pixels, the cell model, Δt = ½,
/// unlit and without lights. A test states what it is about over these with `..`.
pub fn spec(
    camera: crate::trace::camera::Camera,
    mode: crate::trace::view::Mode,
) -> crate::trace::view::ViewSpec {
    crate::trace::view::ViewSpec {
        width: 4,
        height: 4,
        camera,
        model: crate::volume::grid::Model::Cell,
        dt: 0.5,
        gradient_distance: 1.0,
        mode,
        shading: None,
        lights: heapless::Vec::new(),
        background: glam::Vec3::ZERO,
        cutoff: 1.0 / 512.0,
        max_depth: 2,
        refine_steps: 2,
        accuracy: crate::trace::view::Accuracy::Exact,
        compositing: crate::trace::view::Compositing::Sampled,
    }
}

/// A composited view of `grid` seen obliquely with parallel rays, one control point of
/// opacity ½, under `shading` and `lights`: where shading tests look at a point's light.
pub fn composited_view(
    grid: &crate::volume::grid::Grid,
    shading: Option<crate::optics::shade::Shading>,
    lights: &[crate::optics::shade::Light],
) -> crate::trace::view::View {
    use crate::optics::transfer::{ControlPoint, TransferFunction};
    use crate::trace::camera::{Camera, Projection};
    use glam::Vec3;
    let camera = Camera::look_at(
        Vec3::new(30.0, 9.0, 14.0),
        Vec3::splat(4.0),
        Vec3::Y,
        Projection::Orthographic { width: 20.0 },
    );
    let tf = TransferFunction::new(&[ControlPoint {
        value: 1.0,
        color: Vec3::ONE,
        opacity: 0.5,
    }]);
    let (Ok(camera), Ok(tf), Ok(lights)) = (camera, tf, heapless::Vec::from_slice(lights)) else {
        panic!("the composited view's camera, transfer function or lights");
    };
    let spec = crate::trace::view::ViewSpec {
        shading,
        lights,
        ..spec(camera, crate::trace::view::Mode::Composite(tf))
    };
    match crate::trace::view::View::new(spec, grid) {
        Ok(view) => view,
        Err(e) => panic!("the composited view: {e}"),
    }
}

/// The dimensions of [`hashed_field`].
pub const HASHED_DIMS: [u32; 3] = [9, 7, 8];

/// A small anisotropic field with no structure for a shortcut to hide behind: every node a
/// different hash, plane-major, on a grid of spacing (1, ½, 2).
pub fn hashed_field() -> ([f32; 9 * 7 * 8], crate::volume::grid::Grid) {
    let hash = |i: usize| ((i as u32).wrapping_mul(2_654_435_761) >> 7) as f32 * 1e-3;
    let grid = crate::volume::grid::Grid::new(HASHED_DIMS, glam::Vec3::new(1.0, 0.5, 2.0));
    match grid {
        Ok(grid) => (core::array::from_fn(hash), grid),
        Err(e) => panic!("the hashed field's grid: {e}"),
    }
}

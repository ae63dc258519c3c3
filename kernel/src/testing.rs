//! What the kernel's unit tests share: a seeded pseudo-random sequence, so that a failing
//! case comes back on every run without a random-number crate in a `no_std` kernel, and the
//! parameters of a small view.

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
pub fn spec(camera: crate::camera::Camera, mode: crate::view::Mode) -> crate::view::ViewSpec {
    crate::view::ViewSpec {
        width: 4,
        height: 4,
        camera,
        model: crate::grid::Model::Cell,
        dt: 0.5,
        gradient_distance: 1.0,
        mode,
        shading: None,
        lights: heapless::Vec::new(),
        background: glam::Vec3::ZERO,
        cutoff: 1.0 / 512.0,
        max_depth: 2,
        refine_steps: 2,
    }
}

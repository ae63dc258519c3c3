//! The lighting of one point before shadowing: its ambient term, each light's direct term, and
//! which lights need a shadow ray. A surface hit's [`Lighting`] is what a distributed trace
//! sends to the pixel's home; the home multiplies in the visibilities that come back and
//! combines them by [`crate::tree::surface_color`], exactly as the in-process tracer does.
//!
//! Invariant: `direct[l]` is zero for every light `l ≥ lights`; a light needs a shadow ray only
//! if it casts shadows and lights the point (`direct[l] ≠ 0`).

use crate::counters::Counters;
use crate::field;
use crate::sample::Sample;
use crate::shade::{self, MAX_LIGHTS};
use crate::slab::Slab;
use crate::tree;
use crate::view::View;
use glam::Vec3;

/// A point's light, before shadowing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lighting {
    /// Ambient term (the unlit colour when the view has no shading).
    pub ambient: Vec3,
    /// Each light's Lambert + Phong term.
    pub direct: [Vec3; MAX_LIGHTS],
    /// World direction toward each light and its distance (for shadow rays).
    pub to_light: [(Vec3, f32); MAX_LIGHTS],
    /// Lights that contribute (the view's lights, or 0 without shading).
    pub lights: u8,
    /// Bit `l` set: light `l` needs a shadow ray.
    pub shadow_mask: u8,
}

impl Lighting {
    /// The point's colour given each light's visibility (1 where no shadow ray was traced).
    pub fn color(&self, visibility: &[f32; MAX_LIGHTS]) -> Vec3 {
        let n = usize::from(self.lights).min(MAX_LIGHTS);
        tree::surface_color(self.ambient, &self.direct[..n], &visibility[..n])
    }
}

/// The lighting of a point of colour `base` at index-space `p`, seen along `view_dir`. Uses the
/// cut-face normal when given, else the gradient's.
pub fn lighting<T: Sample>(
    view: &View,
    slab: &Slab<'_, T>,
    base: Vec3,
    p: Vec3,
    cap_normal: Option<Vec3>,
    view_dir: Vec3,
    counters: &mut Counters,
) -> Lighting {
    let spec = view.spec();
    let mut out = Lighting {
        ambient: base,
        direct: [Vec3::ZERO; MAX_LIGHTS],
        to_light: [(Vec3::ZERO, 0.0); MAX_LIGHTS],
        lights: 0,
        shadow_mask: 0,
    };
    let Some(shading) = &spec.shading else {
        return out;
    };
    counters.shadings += 1;
    let n = match cap_normal {
        Some(n) => shade::face_viewer(n, view_dir),
        None => {
            let g = field::gradient(slab, spec.model, p, spec.gradient_distance, counters);
            let (n, fallback) = shade::normal(g, view_dir);
            counters.normal_fallbacks += u64::from(fallback);
            n
        }
    };
    let world = view.to_world(p);
    out.ambient = base * shading.ambient;
    out.lights = spec.lights.len() as u8;
    for (l, light) in spec.lights.iter().enumerate() {
        let Some(toward) = light.toward(world) else {
            continue;
        };
        out.to_light[l] = toward;
        out.direct[l] = shade::direct(shading, base, n, view_dir, toward.0, light.color);
        if light.shadows && out.direct[l] != Vec3::ZERO {
            out.shadow_mask |= 1 << l;
        }
    }
    out
}

//! A whole pixel traced on one node that holds the whole volume: the primary ray, its chain of
//! transparency rays and every shadow ray, combined by [`crate::trace::tree`].
//!
//! Invariants: no allocation (the chain of hits lives in a fixed stack of [`MAX_DEPTH`] + 1
//! frames, which the view's depth limit never exceeds); the result is finite for every input.
//! Given a slab that does not own every plane, a ray that would leave it is treated as having
//! left the volume and counted in `slab_misses`: in-process tracing is for whole volumes, the
//! worker of a cluster forwards such rays instead.

use crate::counters::Counters;
use crate::optics::shade::MAX_LIGHTS;
use crate::trace::lighting::lighting;
use crate::trace::march::{march, RayKind, RayState, Stop};
use crate::trace::tree;
use crate::trace::view::{Mode, View, MAX_DEPTH};
use crate::volume::sample::Sample;
use crate::volume::slab::Slab;
use glam::Vec3;
use heapless::Vec;

/// The colour of pixel `pixel` (row-major) of `view`.
pub fn trace_pixel<T: Sample>(
    view: &View,
    slab: &Slab<'_, T>,
    pixel: u32,
    counters: &mut Counters,
) -> Vec3 {
    counters.rays_set_up += 1;
    match view.primary_ray(pixel) {
        Some(ray) => trace_primary(view, slab, ray, counters),
        None => view.spec().background,
    }
}

/// The colour a primary ray of `view` sees.
pub fn trace_primary<T: Sample>(
    view: &View,
    slab: &Slab<'_, T>,
    mut ray: RayState,
    counters: &mut Counters,
) -> Vec3 {
    let background = view.spec().background;
    counters.primary_rays += 1;
    match &view.spec().mode {
        Mode::Composite(_) => {
            let stop = march(view, slab, &mut ray, counters);
            note_leave(stop, counters);
            ray.color + background * ray.weight
        }
        Mode::Surfaces(surfaces) => {
            // (opacity, colour) of each surface hit, front to back.
            let mut hits: Vec<(f32, Vec3), { MAX_DEPTH as usize + 1 }> = Vec::new();
            loop {
                let stop = march(view, slab, &mut ray, counters);
                note_leave(stop, counters);
                let Stop::Hit(hit) = stop else { break };
                let Some(surface) = surfaces.get(usize::from(hit.surface)) else {
                    break;
                };
                let dir = ray.ray.dir_world;
                let light = lighting(
                    view,
                    slab,
                    surface.color,
                    hit.point,
                    hit.cap_normal,
                    dir,
                    counters,
                );
                let mut visibility = [1.0f32; MAX_LIGHTS];
                for (l, v) in visibility.iter_mut().enumerate() {
                    if light.shadow_mask & (1 << l) != 0 {
                        let (to_light, distance) = light.to_light[l];
                        *v = shadow_visibility(
                            view, slab, ray.pixel, hit.point, to_light, distance, counters,
                        );
                    }
                }
                let color = light.color(&visibility);
                let alpha = surface.opacity();
                if hits.push((alpha, color)).is_err() {
                    break;
                }
                match view.continuation(&ray, alpha) {
                    Some(next) => {
                        counters.transparency_rays += 1;
                        ray = next;
                    }
                    None => {
                        counters.early_terminations += u64::from(alpha < 1.0);
                        break;
                    }
                }
            }
            let mut seen = background;
            while let Some((alpha, color)) = hits.pop() {
                seen = tree::through(alpha, color, seen);
            }
            seen
        }
    }
}

/// Transmittance of the shadow ray from `from` toward a light (1 when no sample lies between).
pub fn shadow_visibility<T: Sample>(
    view: &View,
    slab: &Slab<'_, T>,
    pixel: u32,
    from: Vec3,
    to_light: Vec3,
    distance: f32,
    counters: &mut Counters,
) -> f32 {
    let Some(mut ray) = view.shadow_ray(pixel, from, to_light, distance) else {
        return 1.0;
    };
    debug_assert_eq!(ray.kind, RayKind::Shadow);
    counters.shadow_rays += 1;
    let stop = march(view, slab, &mut ray, counters);
    note_leave(stop, counters);
    ray.weight
}

fn note_leave(stop: Stop, counters: &mut Counters) {
    if let Stop::Leave { .. } = stop {
        counters.slab_misses += 1;
    }
}

/// A view's image of a whole volume into `out` (RGBA8, row-major), one pixel after another.
/// `out` shorter than the image is filled as far as it goes.
pub fn render_into<T: Sample>(
    view: &View,
    slab: &Slab<'_, T>,
    out: &mut [[u8; 4]],
    counters: &mut Counters,
) {
    for (slot, color) in out.iter_mut().zip(Pixels::new(view, slab, counters)) {
        *slot = crate::trace::pixel::rgba8(color);
    }
}

/// The colours of a view's pixels in row-major order, traced one after another on one node.
/// A pixel after a miss that certainly misses too ([`View::misses_after`]) is the
/// background without its ray being set up; every other pixel is [`trace_pixel`]'s colour.
#[derive(Debug)]
pub struct Pixels<'a, 'd, T: Sample> {
    view: &'a View,
    slab: &'a Slab<'d, T>,
    counters: &'a mut Counters,
    /// The next pixel.
    next: u32,
    /// Pixels before this one certainly miss.
    misses_until: u32,
}

impl<'a, 'd, T: Sample> Pixels<'a, 'd, T> {
    /// The pixels of `view` of `slab`, counting the work in `counters`.
    pub fn new(view: &'a View, slab: &'a Slab<'d, T>, counters: &'a mut Counters) -> Self {
        Pixels {
            view,
            slab,
            counters,
            next: 0,
            misses_until: 0,
        }
    }
}

impl<T: Sample> Iterator for Pixels<'_, '_, T> {
    type Item = Vec3;

    fn next(&mut self) -> Option<Vec3> {
        let pixel = self.next;
        if u64::from(pixel) >= self.view.pixel_count() {
            return None;
        }
        self.next += 1;
        let background = self.view.spec().background;
        if pixel < self.misses_until {
            return Some(background);
        }
        self.counters.rays_set_up += 1;
        Some(match self.view.primary_ray(pixel) {
            Some(ray) => trace_primary(self.view, self.slab, ray, self.counters),
            None => {
                self.misses_until = pixel + 1 + self.view.misses_after(pixel);
                background
            }
        })
    }
}

//! The composited sample loop: front-to-back emission and absorption over a ray's lattice
//! samples in one slab, in a single loop that reads a sample, classifies it and, where it
//! shows, shades and composites it. What may be passed over is asked of
//! [`crate::trace::skipping`]; what a sample reads and how it is classified are set once per
//! call, for the view's tier.
//!
//! Invariants: the colour and transmittance follow `C += w·α·c`, `w *= 1 − α` in sample
//! order, the same operations on every node, so a ray's result does not depend on where its
//! segments ran; a sample that does not show (α = 0) changes neither, so skipping changes no
//! pixel; the ray stops once `w` is at or below the view's cutoff (or NaN).

use crate::counters::Counters;
use crate::optics::transfer::{corrected_opacity, TransferFunction};
use crate::trace::lighting::Unshadowed;
use crate::trace::skipping::{skip_to, Probe, Skipper};
use crate::trace::state::{RayState, Stop};
use crate::trace::view::View;
use crate::volume::field;
use crate::volume::nodes;
use crate::volume::sample::Sample;
use crate::volume::slab::Slab;
use glam::Vec3;

/// Advance `ray` of composited `view` (transfer function `tf`) through the samples `slab`
/// owns.
pub(crate) fn composite<T: Sample>(
    view: &View,
    slab: &Slab<'_, T>,
    tf: &TransferFunction,
    ray: &mut RayState,
    counters: &mut Counters,
) -> Stop {
    let spec = view.spec();
    let grid = slab.grid();
    let mut skipper = Skipper::new(view, slab, ray);
    if let Some(last) = skipper.depth_run(slab, ray, true) {
        skip_to(view, ray, last, counters);
    }
    // Which samples stand for a whole Δt segment, asked once for the call, and only where the
    // fast tier's table reads it.
    let full_below = view.classified().map_or(0, |_| ray.lattice.full_below());
    // Where the node field is held and the view shades by it, each sample reads its value and
    // gradient in one interpolation of the field's lanes.
    let lanes = view.node_gradients() && slab.nodes().is_some();
    let light = Unshadowed::new(view);
    // The colour and transmittance stay in registers for the call.
    let (mut color, mut weight) = (ray.color, ray.weight);
    let stop = loop {
        if ray.k > ray.lattice.last {
            break Stop::Exit;
        }
        let probe = Probe::of(ray, grid, spec.model, ray.k);
        let plane = probe.corner.plane();
        if !slab.owns(plane) {
            break Stop::Leave { plane };
        }
        if let Some(last) = skipper.empty_run(view, slab, ray, &probe, true) {
            skip_to(view, ray, last, counters);
            continue;
        }
        counters.samples += 1;
        let site = probe.corner.site(grid);
        let (v, gradient) = match lanes {
            true => {
                // Counted as the value's read; the gradient where the shading takes it.
                counters.interpolations += 1;
                let (v, g) = nodes::lanes_at(slab, &site, counters);
                (v, Some(g))
            }
            false => (field::value_at(slab, spec.model, &site, counters), None),
        };
        // Most samples of a composited view are transparent: their colour is not looked at.
        let (alpha, base) = match view.classified() {
            // The fast tier: a whole segment's entry, or the entry's opacity corrected for
            // the last, shorter one.
            Some(table) if ray.k < full_below => {
                let (color, alpha) = table.full(v);
                (alpha, color)
            }
            Some(table) => {
                let (color, opacity) = table.per_edge(v);
                let len = ray.lattice.segment(ray.k) / view.cell_edge();
                (corrected_opacity(opacity, len), color)
            }
            None => {
                let span = tf.span(v);
                let alpha = corrected_opacity(
                    tf.opacity_at(span),
                    ray.lattice.segment(ray.k) / view.cell_edge(),
                );
                // Looked up only where it shows.
                let color = if alpha > 0.0 {
                    tf.color_at(span)
                } else {
                    Vec3::ZERO
                };
                (alpha, color)
            }
        };
        // The state a ray keeps of its last sample read (`done_here` stays clear: only a
        // surface view reports crossings).
        ray.prev = v;
        ray.primed = true;
        ray.k += 1;
        if alpha > 0.0 {
            // Compositing casts no shadows: every light is fully visible.
            let lit = light.color(
                slab,
                base,
                (probe.p4.truncate(), &site, gradient),
                ray.ray.dir_world,
                counters,
            );
            color += lit * (weight * alpha);
            weight *= 1.0 - alpha;
            if !(weight > spec.cutoff) {
                counters.early_terminations += 1;
                break Stop::Terminated;
            }
        }
    };
    ray.color = color;
    ray.weight = weight;
    stop
}

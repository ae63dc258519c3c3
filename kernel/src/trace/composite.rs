//! The composited sample loop: front-to-back emission and absorption over a ray's lattice
//! samples in one slab, in a single loop that reads a sample, classifies it and, where it
//! shows, shades and composites it. What may be passed over is asked of
//! [`crate::trace::skipping`]. How a sample is read (the node field's lanes, or the slab's
//! value) and classified (the fast tier's table, or the transfer function) are chosen once
//! per call: the loop is compiled once per choice, so that each holds only its own work.
//!
//! Invariants: the colour and transmittance follow `C += w·α·c`, `w *= 1 − α` in sample
//! order, the same operations on every node, so a ray's result does not depend on where its
//! segments ran; a sample that does not show (α = 0) changes neither, so skipping changes no
//! pixel; the ray stops once `w` is at or below the view's cutoff (or NaN).

use crate::counters::Counters;
use crate::optics::classify::Classified;
use crate::optics::transfer::{corrected_opacity, TransferFunction};
use crate::trace::lattice::Lattice;
use crate::trace::lighting::Unshadowed;
use crate::trace::skipping::{skip_to, Probe, Skipper};
use crate::trace::state::{RayState, Stop};
use crate::trace::view::View;
use crate::volume::field::{self, Site};
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
    // Where the node field is held and the view shades by it, each sample reads its value and
    // gradient in one interpolation of the field's lanes.
    let lanes = view.node_gradients() && slab.nodes().is_some();
    match (view.classified(), lanes) {
        (Some(table), true) => samples(view, slab, &Tabled::of(table, ray), Lanes, ray, counters),
        (Some(table), false) => samples(view, slab, &Tabled::of(table, ray), Value, ray, counters),
        (None, true) => samples(view, slab, &ByFunction(tf), Lanes, ray, counters),
        (None, false) => samples(view, slab, &ByFunction(tf), Value, ray, counters),
    }
}

/// How a sample's value becomes its opacity and colour.
trait Classify {
    /// Sample `k`'s opacity over its segment of `lattice`, and its colour (`Vec3::ZERO` where
    /// the opacity is zero: most samples of a composited view are transparent, and their
    /// colour is not looked at).
    fn classify(&self, view: &View, lattice: &Lattice, k: u32, v: f32) -> (f32, Vec3);
}

/// The fast tier: the pre-classified table's entry for a whole Δt segment, or its opacity
/// corrected for the last, shorter one.
struct Tabled<'a> {
    table: &'a Classified,
    /// Samples below this one stand for a whole segment, asked once for the call.
    full_below: u32,
}

impl<'a> Tabled<'a> {
    fn of(table: &'a Classified, ray: &RayState) -> Self {
        Tabled {
            table,
            full_below: ray.lattice.full_below(),
        }
    }
}

impl Classify for Tabled<'_> {
    #[inline(always)]
    fn classify(&self, view: &View, lattice: &Lattice, k: u32, v: f32) -> (f32, Vec3) {
        if k < self.full_below {
            let (color, alpha) = self.table.full(v);
            (alpha, color)
        } else {
            let (color, opacity) = self.table.per_edge(v);
            let len = lattice.segment(k) / view.cell_edge();
            (corrected_opacity(opacity, len), color)
        }
    }
}

/// The exact tier: the transfer function itself, its opacity corrected for the segment.
struct ByFunction<'a>(&'a TransferFunction);

impl Classify for ByFunction<'_> {
    #[inline(always)]
    fn classify(&self, view: &View, lattice: &Lattice, k: u32, v: f32) -> (f32, Vec3) {
        let span = self.0.span(v);
        let alpha = corrected_opacity(
            self.0.opacity_at(span),
            lattice.segment(k) / view.cell_edge(),
        );
        // Looked up only where it shows.
        let color = if alpha > 0.0 {
            self.0.color_at(span)
        } else {
            Vec3::ZERO
        };
        (alpha, color)
    }
}

/// How a sample is read: its value, and the gradient where the read gives it.
trait Reading: Copy {
    fn read<T: Sample>(
        self,
        view: &View,
        slab: &Slab<'_, T>,
        site: &Site,
        counters: &mut Counters,
    ) -> (f32, Option<Vec3>);
}

/// The node field's lanes: value and gradient in one interpolation.
#[derive(Clone, Copy)]
struct Lanes;

impl Reading for Lanes {
    #[inline(always)]
    fn read<T: Sample>(
        self,
        _: &View,
        slab: &Slab<'_, T>,
        site: &Site,
        counters: &mut Counters,
    ) -> (f32, Option<Vec3>) {
        // Counted as the value's read; the gradient where the shading takes it.
        counters.interpolations += 1;
        let (v, g) = nodes::lanes_at(slab, site, counters);
        (v, Some(g))
    }
}

/// The slab's value; the shading computes a gradient where it needs one.
#[derive(Clone, Copy)]
struct Value;

impl Reading for Value {
    #[inline(always)]
    fn read<T: Sample>(
        self,
        view: &View,
        slab: &Slab<'_, T>,
        site: &Site,
        counters: &mut Counters,
    ) -> (f32, Option<Vec3>) {
        (
            field::value_at(slab, view.spec().model, site, counters),
            None,
        )
    }
}

/// The loop itself, for one way of reading and one of classifying.
#[inline(always)]
fn samples<T: Sample, C: Classify, R: Reading>(
    view: &View,
    slab: &Slab<'_, T>,
    classify: &C,
    read: R,
    ray: &mut RayState,
    counters: &mut Counters,
) -> Stop {
    let spec = view.spec();
    let grid = slab.grid();
    let mut skipper = Skipper::new(view, slab, ray);
    skipper.pass_depth_bound(view, slab, ray, true, counters);
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
        let (v, gradient) = read.read(view, slab, &site, counters);
        let (alpha, base) = classify.classify(view, &ray.lattice, ray.k, v);
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

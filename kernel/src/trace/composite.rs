//! The composited sample loop: front-to-back emission and absorption over a ray's lattice
//! samples in one slab, in a single loop that reads a sample, classifies it and, where it
//! shows, shades and composites it (in the slab's interior, the fast tier's samples that show
//! wait in a short batch for their light: `crate::trace::deferred`). What may be passed over
//! is asked of `crate::trace::skipping`. How a sample is read (`crate::trace::reading`: the
//! node field's lanes, or the slab's value) and classified (the fast tier's table, or the
//! transfer function) are chosen once per call: the loop is compiled once per choice, so that
//! each holds only its own work.
//! A view that composites pre-integrated takes its own loop, `crate::trace::preintegrated`:
//! its samples close segments rather than stand for them.
//!
//! Invariants: the colour and transmittance follow `C += w·α·c`, `w *= 1 − α` in sample
//! order, the same operations on every node, so a ray's result does not depend on where its
//! segments ran; a sample that does not show (α = 0) changes neither, so skipping changes no
//! pixel; the ray stops once `w` is at or below the view's cutoff (or NaN).

use crate::counters::Counters;
use crate::optics::classify::Classified;
use crate::optics::transfer::{corrected_opacity, TransferFunction};
use crate::trace::deferred::Deferred;
use crate::trace::lattice::Lattice;
use crate::trace::lighting::Unshadowed;
use crate::trace::preintegrated;
use crate::trace::ray::Ray;
use crate::trace::reading::{GridLanes, Lanes, Reading, Value};
use crate::trace::runway::{self, CellTest, Inside, Next, Read, Run, Runway};
use crate::trace::skipping::Skipper;
use crate::trace::state::{RayState, Stop};
use crate::trace::view::View;
use crate::volume::cells::Cells;
use crate::volume::field::{self, Site};
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
    // The exact tier reads them so wherever that is its own gradient.
    let central = view.exact_node_gradients() && slab.nodes().is_some();
    if let Some(layout) = view.segments() {
        return preintegrated::composite(view, slab, layout, lanes, ray, counters);
    }
    match (view.classified(), lanes, central) {
        (Some(table), true, _) => {
            prefetching(view, slab, &Tabled::of(table, ray), Lanes, ray, counters)
        }
        (Some(table), false, _) => {
            prefetching(view, slab, &Tabled::of(table, ray), Value, ray, counters)
        }
        (None, _, true) => prefetching(view, slab, &ByFunction(tf), GridLanes, ray, counters),
        (None, true, false) => prefetching(view, slab, &ByFunction(tf), Lanes, ray, counters),
        (None, false, false) => prefetching(view, slab, &ByFunction(tf), Value, ray, counters),
    }
}

/// [`samples`], asking for cells ahead of the samples where the slab holds a node field
/// larger than the caches ([`Slab::prefetched_field`]): then memory's latency passes while
/// the loop works on the samples before. A run through the interior asks, as it looks at each
/// sample, for the cell and map byte some samples on ([`Inside::step`]); the general step,
/// for the cell of the sample four on from each it evaluates. Both tiers read the field
/// where it is held (the fast tier its values and gradients, the exact tier its gradients),
/// and it is eight times the slab's bytes, so its misses are the ones that count.
#[inline(always)]
fn prefetching<T: Sample, C: Classify, R: Reading<T>>(
    view: &View,
    slab: &Slab<'_, T>,
    classify: &C,
    read: R,
    ray: &mut RayState,
    counters: &mut Counters,
) -> Stop {
    match slab.prefetched_field() {
        Some(cells) => samples(view, slab, classify, read, Asking(cells), ray, counters),
        None => samples(view, slab, classify, read, NotAhead, ray, counters),
    }
}

/// Whether a loop asks for cells ahead of its samples: a type, so that a loop that does not
/// carries no test for it.
trait Ahead: Copy {
    /// Ask for the cell of sample `k + PREFETCH_AHEAD` of `ray` on `lattice`, at its lattice
    /// position (computed, not stepped); outside the grid some cell, which a prefetch
    /// passes over or asks for harmlessly. The general step's samples.
    fn ask(self, ray: &Ray, lattice: &Lattice, k: u32);

    /// In a run through the interior, the storage offset of the cell to ask for ahead of
    /// each sample looked at (`offset` finds it, [`Inside::hint_offset`]), or none.
    fn hint(self, offset: impl FnOnce() -> usize) -> Option<usize>;
}

/// Samples read from storage that stays in the caches: nothing asked.
#[derive(Clone, Copy)]
struct NotAhead;

impl Ahead for NotAhead {
    #[inline(always)]
    fn ask(self, _: &Ray, _: &Lattice, _: u32) {}

    #[inline(always)]
    fn hint(self, _: impl FnOnce() -> usize) -> Option<usize> {
        None
    }
}

/// Samples read from `Cells` larger than the caches.
#[derive(Clone, Copy)]
struct Asking<'a, U>(Cells<'a, U>);

/// How many samples ahead of an evaluated one a loop that prefetches asks for a cell: the
/// requests in flight must cover memory's latency, and at 512³ two, four and eight ahead
/// timed alike (docs/speed-log.md).
const PREFETCH_AHEAD: u32 = 4;

impl<U: Copy> Ahead for Asking<'_, U> {
    #[inline(always)]
    fn ask(self, ray: &Ray, lattice: &Lattice, k: u32) {
        let q = ray.at4(lattice.t(k.saturating_add(PREFETCH_AHEAD)));
        self.0.prefetch(field::interior_corner(q).1);
    }

    #[inline(always)]
    fn hint(self, offset: impl FnOnce() -> usize) -> Option<usize> {
        Some(offset())
    }
}

/// How a sample's value becomes its opacity and colour.
trait Classify {
    /// Whether the samples that show may wait in a batch for the shading table's light
    /// ([`Deferred`]): the fast tier's, whose table is what the batch lights by.
    const TABLED: bool;

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
    const TABLED: bool = true;

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
    const TABLED: bool = false;

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

/// The loop itself, for one way of reading and one of classifying: each sample through the
/// general step (where it lies, whose it is, what the skipping says of it), except in the
/// slab's interior, where [`run`] takes them.
#[inline(always)]
fn samples<T: Sample, C: Classify, R: Reading<T>, A: Ahead>(
    view: &View,
    slab: &Slab<'_, T>,
    classify: &C,
    read: R,
    ahead: A,
    ray: &mut RayState,
    counters: &mut Counters,
) -> Stop {
    let spec = view.spec();
    let grid = slab.grid();
    let mut turned = None;
    let mut skipper = Skipper::new(view, slab, ray, &mut turned);
    skipper.pass_depth_bound(view, slab, ray, true, counters);
    let light = Unshadowed::new(view, ray.ray.dir_world);
    // Where the interior's samples need no more of the skipping than their cell's leap
    // distance, and the storage holds whole cells there.
    let inner = Runway::of(view, slab, &skipper, R::cells(slab));
    // The interior's last sample, once a sample inside is found: its samples are one run.
    let mut inside_to: Option<u32> = None;
    let stepped = runway::stepped_distances(spec.dt);
    // The colour and transmittance stay in registers for the call.
    let (mut color, mut weight) = (ray.color, ray.weight);
    let stop = loop {
        if ray.k > ray.lattice.last {
            break Stop::Exit;
        }
        if let (Some(end), Some(runway)) = (inside_to, &inner) {
            if ray.k <= end {
                let ran = runway::through!(runway, end, stepped, |inside| {
                    run(
                        view,
                        slab,
                        classify,
                        (read, ahead),
                        inside,
                        ray,
                        (&light, &mut color, &mut weight),
                        &mut skipper,
                        counters,
                    )
                });
                match ran {
                    Run::Done => continue,
                    Run::Terminated => break Stop::Terminated,
                    // The general step reads it.
                    Run::Unread => {}
                }
            }
        }
        let at = (inner.as_ref(), &mut inside_to);
        // Compositing may always skip a sample that shows nothing.
        let may_skip = |_: &View, _: &RayState| true;
        let probe = match runway::before_read(view, slab, ray, at, &mut skipper, may_skip, counters)
        {
            Next::Leave(plane) => break Stop::Leave { plane },
            Next::Again => continue,
            Next::Read(probe) => probe,
        };
        counters.samples += 1;
        ahead.ask(&ray.ray, &ray.lattice, ray.k);
        let site = probe.corner.site(grid);
        let (v, gradient) = read.read(view, slab, (probe.p4.truncate(), &site), counters);
        let (alpha, base) = classify.classify(view, &ray.lattice, ray.k, v);
        // The state a ray keeps of its last sample read (`done_here` stays clear: only a
        // surface view reports crossings).
        ray.prev = v;
        ray.primed = true;
        ray.k += 1;
        if alpha > 0.0 {
            // Compositing casts no shadows: every light is fully visible.
            let lit = light.color(slab, base, (probe.p4.truncate(), &site, gradient), counters);
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

/// The samples from `ray.k` through `inside.end`, all in the interior: no clamp, no owner, no
/// range check per corner, and of the skipping only the cell's leap distance, stepping over
/// or leaping from a cell the map calls empty (the same samples the general step passes).
/// The same operations as the general step on each sample (its corner, fractions, read,
/// classification, shading and compositing), so the same bits and the same counts.
#[allow(
    clippy::too_many_arguments,
    reason = "inlined into one caller; the arguments are the loop's state"
)]
#[inline(always)]
fn run<T: Sample, C: Classify, R: Reading<T>, A: Ahead, E: CellTest>(
    view: &View,
    slab: &Slab<'_, T>,
    classify: &C,
    (read, ahead): (R, A),
    inside: &Inside<'_, '_, R::Node, E>,
    ray: &mut RayState,
    (light, color, weight): (&Unshadowed<'_>, &mut Vec3, &mut f32),
    skipper: &mut Skipper<'_>,
    totals: &mut Counters,
) -> Run {
    let (lattice, r, cutoff) = (ray.lattice, ray.ray, view.spec().cutoff);
    // Counted here and added once at the end: the loop's counts then stay in registers
    // rather than in memory behind a pointer the compiler must assume others read.
    let mut local = Counters::default();
    let counters = &mut local;
    let mut k = ray.k;
    let mut looked = inside.look(lattice, r, k);
    let hint = ahead.hint(|| inside.hint_offset(&r, lattice.dt));
    let mut last_read = None;
    // Where the fast tier's table shades them, shaded samples whose gradient came with the
    // read wait for their light in a batch (the exact tier's lights, `powf` and all, gained
    // nothing from the wait: docs/speed-log.md).
    let mut waiting = Deferred::new();
    let tabled = C::TABLED && light.table().is_some();
    let end = loop {
        if k > inside.end {
            break Run::Done;
        }
        let Some(Read { q, cell, lo, index }) = inside.step(
            slab,
            (ray, lattice, r),
            skipper,
            (&mut k, &mut looked),
            hint,
        ) else {
            continue;
        };
        let Some(nodes) = inside.cells.at_index(index) else {
            break Run::Unread;
        };
        let frac = (q - cell).truncate();
        counters.samples += 1;
        let (v, gradient) = read.read_cell(slab, nodes, frac, counters);
        let (alpha, base) = classify.classify(view, &lattice, k, v);
        last_read = Some(v);
        k += 1;
        if alpha > 0.0 {
            if let (true, Some(g)) = (tabled, gradient) {
                waiting.push((g, base, *weight * alpha), light, color, counters);
                *weight *= 1.0 - alpha;
                if !(*weight > cutoff) {
                    counters.early_terminations += 1;
                    break Run::Terminated;
                }
                continue;
            }
            if tabled {
                // What waits comes first: the colour adds in sample order.
                waiting.light(light, color, counters);
            }
            let site = Site {
                lo,
                hi: lo.map(|c| c + 1),
                frac,
            };
            let lit = light.color(slab, base, (q.truncate(), &site, gradient), counters);
            *color += lit * (*weight * alpha);
            *weight *= 1.0 - alpha;
            if !(*weight > cutoff) {
                counters.early_terminations += 1;
                break Run::Terminated;
            }
        }
    };
    if tabled {
        waiting.light(light, color, counters);
    }
    local.skipped += runway::passed_over(ray.k, k, local.samples);
    ray.k = k;
    if let Some(v) = last_read {
        ray.prev = v;
        ray.primed = true;
    }
    totals.add(&local);
    end
}

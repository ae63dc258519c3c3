//! The pre-integrated composited loop (fast tier, `compositing = "pre-integrated"`): each
//! sample closes the segment that ends at it, read from the view's table
//! ([`crate::optics::segments`]) at the values of its two ends and lit at the sample by the
//! mean of its two ends' gradients; a ray's last stretch, shorter than Δt, is its last
//! sample's value held over it, corrected for its length, as the sampled loop takes it.
//!
//! Invariants: segment `k − 1 → k` of a full Δt is composited at sample `k`, the stretch of
//! sample `k` past the last full segment at sample `k` after it, in sample order, by the
//! same operations on every node, so a ray's result does not depend on where its segments
//! ran (the value at a segment's front is the ray's `prev`, carried with it). A sample is
//! passed over only where the segment ending at it is transparent: its cell's values and the
//! front's all lie below the table's first entry that shows ([`View::may_skip`]). A sample
//! whose front was passed over and whose own value shows reads its front again, exactly,
//! before compositing; one whose value lies below too closes a transparent segment, whatever
//! the front's exact value. So skipping changes no pixel.

use crate::counters::Counters;
use crate::optics::segments::{Layout, Segments};
use crate::optics::transfer::corrected_opacity;
use crate::trace::deferred::Deferred;
use crate::trace::lattice::Lattice;
use crate::trace::lighting::{self, Unshadowed};
use crate::trace::reading::{Lanes, Reading, Value};
use crate::trace::runway::{self, CellTest, Inside, Next, Read, Run, Runway};
use crate::trace::skipping::Skipper;
use crate::trace::state::{RayState, Stop};
use crate::trace::view::View;
use crate::volume::field::{self, Site};
use crate::volume::sample::Sample;
use crate::volume::slab::Slab;
use glam::{Vec3, Vec4};

/// Advance `ray` of `view`, composited pre-integrated (the view's table placed by `layout`),
/// through the samples `slab` owns; `lanes`: whether samples read the node field's lanes.
pub(crate) fn composite<T: Sample>(
    view: &View,
    slab: &Slab<'_, T>,
    layout: &Layout,
    lanes: bool,
    ray: &mut RayState,
    counters: &mut Counters,
) -> Stop {
    // The host hands every node of a pre-integrated view its table (its tests fail a fabric
    // that does not); a slab without it, or with another view's, has nothing this view may
    // composite by, and the ray passes.
    let Some(table) = slab.segments().filter(|t| t.layout() == layout) else {
        ray.k = ray.lattice.last.saturating_add(1);
        return Stop::Exit;
    };
    match lanes {
        true => samples(view, slab, table, Lanes, ray, counters),
        false => samples(view, slab, table, Value, ray, counters),
    }
}

/// What a sample composites, in order: the segment ending at it (where one does and is a
/// full Δt), then its own stretch where it stands for one shorter than Δt.
#[derive(Clone, Copy)]
struct Closing {
    /// Samples below this one stand for a whole segment: [`Lattice::full_below`].
    full_below: u32,
    /// Cell edges per world unit.
    per_edge: f32,
}

impl Closing {
    fn of(view: &View, lattice: &Lattice) -> Self {
        Closing {
            full_below: lattice.full_below(),
            per_edge: 1.0 / view.cell_edge(),
        }
    }

    /// The segment ending at sample `k` (value `v`, the segment's front value `front`, none at
    /// a ray's first sample): colour in `xyz`, opacity in `w`.
    #[inline(always)]
    fn segment(&self, table: &Segments<'_>, k: u32, front: Option<f32>, v: f32) -> Vec4 {
        match front {
            // A front with `k = 0` comes only from a malformed ray: no segment.
            Some(f) if k.wrapping_sub(1) < self.full_below => table.segment(f, v),
            _ => Vec4::ZERO,
        }
    }

    /// Sample `k`'s own stretch, where it is shorter than Δt (the ray's last): its value held
    /// over it.
    #[inline(always)]
    fn stretch(&self, table: &Segments<'_>, lattice: &Lattice, k: u32, v: f32) -> Vec4 {
        if k < self.full_below {
            return Vec4::ZERO;
        }
        let (color, opacity) = table.per_edge(v);
        color.extend(corrected_opacity(
            opacity,
            lattice.segment(k) * self.per_edge,
        ))
    }
}

/// The front value of the segment ending at sample `k`, whose own value is `v`: the ray's
/// last value read; where samples were passed over since, `v` itself if it lies below the
/// table's first entry that shows (the segment is transparent whatever its front), else the
/// front read again by `again`; none at a ray's first sample.
#[inline(always)]
fn front(
    layout: &Layout,
    (prev, stale, primed): (f32, bool, bool),
    v: f32,
    again: impl FnOnce() -> f32,
) -> Option<f32> {
    if !primed {
        None
    } else if !stale {
        Some(prev)
    } else if layout.below(v) {
        Some(v)
    } else {
        Some(again())
    }
}

/// The loop for one way of reading: each sample through the general step, except in the
/// slab's interior, where [`run`] takes them.
#[inline(always)]
fn samples<T: Sample, R: Reading<T>>(
    view: &View,
    slab: &Slab<'_, T>,
    table: &Segments<'_>,
    read: R,
    ray: &mut RayState,
    counters: &mut Counters,
) -> Stop {
    let spec = view.spec();
    let grid = slab.grid();
    let layout = *table.layout();
    let mut turned = None;
    let mut skipper = Skipper::new(view, slab, ray, &mut turned);
    skipper.pass_depth_bound(view, slab, ray, view.may_skip(ray), counters);
    let light = Unshadowed::new(view, ray.ray.dir_world);
    let inner = Runway::of(view, slab, &skipper, R::cells(slab));
    let mut inside_to: Option<u32> = None;
    let stepped = runway::stepped_distances(spec.dt);
    let closing = Closing::of(view, &ray.lattice);
    let (mut color, mut weight) = (ray.color, ray.weight);
    // The gradient at the front of the segment ending at `ray.k`, where this call read it.
    let mut g_front: Option<Vec3> = None;
    let stop = loop {
        if ray.k > ray.lattice.last {
            break Stop::Exit;
        }
        if let (Some(end), Some(runway)) = (inside_to, &inner) {
            // A run needs a front for its first segment: a ray that has read or passed a
            // sample before.
            if ray.k <= end && ray.primed {
                let ran = runway::through!(runway, end, stepped, |inside| {
                    run(
                        view,
                        slab,
                        (table, closing),
                        read,
                        inside,
                        (ray, &mut g_front),
                        (&light, &mut color, &mut weight),
                        &mut skipper,
                        counters,
                    )
                });
                match ran {
                    Run::Done => continue,
                    Run::Terminated => break Stop::Terminated,
                    Run::Unread => {}
                }
            }
        }
        let at = (inner.as_ref(), &mut inside_to);
        let may_skip = View::may_skip;
        let probe = match runway::before_read(view, slab, ray, at, &mut skipper, may_skip, counters)
        {
            Next::Leave(plane) => break Stop::Leave { plane },
            Next::Again => continue,
            Next::Read(probe) => probe,
        };
        counters.samples += 1;
        let site = probe.corner.site(grid);
        let p = probe.p4.truncate();
        let (v, gradient) = read.read(view, slab, (p, &site), counters);
        let k = ray.k;
        // The front's position: where it is read again, or its gradient found, should this
        // call not have them.
        let front_at = |ray: &RayState| ray.ray.at(ray.lattice.t(k.saturating_sub(1)));
        if ray.prev_stale {
            g_front = None;
        }
        let front = front(&layout, (ray.prev, ray.prev_stale, ray.primed), v, || {
            // Read as if it had not been passed over, counted as the run counts it.
            counters.samples += 1;
            let p = front_at(ray);
            let site = field::locate(grid, spec.model, p);
            let (value, g) = read.read(view, slab, (p, &site), counters);
            g_front = g;
            value
        });
        let closed = [
            closing.segment(table, k, front, v),
            closing.stretch(table, &ray.lattice, k, v),
        ];
        let known = g_front;
        let (ended, back) = close(
            view,
            slab,
            &light,
            closed,
            (p, &site, gradient),
            |c| {
                known.unwrap_or_else(|| {
                    lighting::gradient(view, slab, (front_at(ray), None, None), c)
                })
            },
            (&mut color, &mut weight),
            None,
            counters,
        );
        g_front = back;
        ray.prev = v;
        ray.primed = true;
        ray.prev_stale = false;
        ray.k += 1;
        if ended {
            break Stop::Terminated;
        }
    };
    ray.color = color;
    ray.weight = weight;
    stop
}

/// The samples from `ray.k` through `inside.end`, all in the interior, of a ray that has
/// read or passed a sample before: each passed over where the map calls its cell empty and
/// the segment ending there may be passed ([`View::may_skip`]), else read, and its segment
/// closed. A sample whose front was passed over outside the interior, and whose own value
/// shows, is left unread and uncounted for the general step, which reads its front where it
/// lies. The same operations as the general step on each sample, so the same bits and the
/// same counts.
#[allow(
    clippy::too_many_arguments,
    reason = "inlined into one caller; the arguments are the loop's state"
)]
#[inline(always)]
fn run<T: Sample, R: Reading<T>, E: CellTest>(
    view: &View,
    slab: &Slab<'_, T>,
    (table, closing): (&Segments<'_>, Closing),
    read: R,
    inside: &Inside<'_, '_, R::Node, E>,
    (ray, g_front): (&mut RayState, &mut Option<Vec3>),
    (light, color, weight): (&Unshadowed<'_>, &mut Vec3, &mut f32),
    skipper: &mut Skipper<'_>,
    totals: &mut Counters,
) -> Run {
    let (lattice, r) = (ray.lattice, ray.ray);
    let layout = *table.layout();
    let mut local = Counters::default();
    let counters = &mut local;
    let mut k = ray.k;
    let mut looked = inside.look(lattice, r, k);
    // Where the slab holds a node field larger than the caches (read here: a shaded view
    // reads its lanes wherever it is held), ask for cells ahead as the sampled loop does.
    let hint = slab
        .prefetched_field()
        .map(|_| inside.hint_offset(&r, lattice.dt));
    let (mut prev, mut stale) = (ray.prev, ray.prev_stale);
    if stale {
        *g_front = None;
    }
    let mut read_again = 0;
    let mut waiting = Deferred::new();
    let tabled = light.table().is_some();
    let end = loop {
        if k > inside.end {
            break Run::Done;
        }
        let at = if view.may_pass(prev, stale) {
            let Some(at) = inside.step(
                slab,
                (ray, lattice, r),
                skipper,
                (&mut k, &mut looked),
                hint,
            ) else {
                stale = true;
                *g_front = None;
                continue;
            };
            at
        } else {
            inside.take(lattice, r, k, &mut looked, hint)
        };
        let Read { q, cell, lo, index } = at;
        // Where the front was passed over, its cell, should the segment show: in the
        // interior, else the general step reads it.
        let again = match stale {
            true => {
                let q = r.at4(lattice.t(k.saturating_sub(1)));
                let (cell, lo) = field::interior_corner(q);
                match inside.interior.holds(q) {
                    true => inside.cells.at_index(inside.cells.index(lo)),
                    false => None,
                }
                .map(|nodes| (nodes, (q - cell).truncate()))
            }
            false => None,
        };
        if stale && again.is_none() {
            break Run::Unread;
        }
        let Some(nodes) = inside.cells.at_index(index) else {
            break Run::Unread;
        };
        let frac = (q - cell).truncate();
        counters.samples += 1;
        let (v, gradient) = read.read_cell(slab, nodes, frac, counters);
        let front = match again {
            None => Some(prev),
            Some(_) if layout.below(v) => Some(v),
            Some((nodes, frac)) => {
                // Counted with the samples once the passed-over ones are.
                read_again += 1;
                let (value, g) = read.read_cell(slab, nodes, frac, counters);
                *g_front = g;
                Some(value)
            }
        };
        prev = v;
        stale = false;
        let closed = [
            closing.segment(table, k, front, v),
            closing.stretch(table, &lattice, k, v),
        ];
        let site = Site {
            lo,
            hi: lo.map(|c| c + 1),
            frac,
        };
        let known = *g_front;
        let (ended, back) = close(
            view,
            slab,
            light,
            closed,
            (q.truncate(), &site, gradient),
            |c| {
                known.unwrap_or_else(|| {
                    let front_at = r.at(lattice.t(k.saturating_sub(1)));
                    lighting::gradient(view, slab, (front_at, None, None), c)
                })
            },
            (color, weight),
            tabled.then_some(&mut waiting),
            counters,
        );
        *g_front = back;
        k += 1;
        if ended {
            break Run::Terminated;
        }
    };
    if tabled {
        waiting.light(light, color, counters);
    }
    local.skipped += runway::passed_over(ray.k, k, local.samples);
    local.samples += read_again;
    ray.k = k;
    ray.prev = prev;
    ray.prev_stale = stale;
    ray.primed = true;
    totals.add(&local);
    end
}

/// Composite what a sample closes (`closed`: the segment ending at it, then its own short
/// stretch) into `color` and `weight`, lit at the sample (`p`, its `site`, its gradient
/// `back` where the read gave it): a segment by the mean of its two ends' gradients (the
/// front's from `front`), so that its light, like its colour, is second order in Δt; the
/// stretch by the sample's own. Where `waiting` is given, lights by the shading table wait
/// there. Whether the ray's light fell to the cutoff, and the sample's gradient where it was
/// given or found, the next segment's front.
#[allow(
    clippy::too_many_arguments,
    reason = "inlined into both loops; the arguments are their state"
)]
#[inline(always)]
fn close<T: Sample>(
    view: &View,
    slab: &Slab<'_, T>,
    light: &Unshadowed<'_>,
    closed: [Vec4; 2],
    (p, site, back): (Vec3, &Site, Option<Vec3>),
    front: impl FnOnce(&mut Counters) -> Vec3,
    (color, weight): (&mut Vec3, &mut f32),
    mut waiting: Option<&mut Deferred>,
    counters: &mut Counters,
) -> (bool, Option<Vec3>) {
    let shaded = view.spec().shading.is_some();
    let mut back = back;
    let mut front = Some(front);
    for (i, c) in closed.into_iter().enumerate() {
        let alpha = c.w;
        if !(alpha > 0.0) {
            continue;
        }
        let g = match shaded {
            true => {
                let gb = match back {
                    Some(g) => g,
                    None => *back.insert(lighting::gradient(
                        view,
                        slab,
                        (p, Some(site), None),
                        counters,
                    )),
                };
                match (i, front.take()) {
                    (0, Some(front)) => Some(0.5 * (front(counters) + gb)),
                    _ => Some(gb),
                }
            }
            false => None,
        };
        let (base, share) = (c.truncate(), *weight * alpha);
        match (waiting.as_deref_mut(), g) {
            (Some(batch), Some(g)) => batch.push((g, base, share), light, color, counters),
            (batch, _) => {
                if let Some(batch) = batch {
                    // What waits comes first: the colour adds in sample order.
                    batch.light(light, color, counters);
                }
                *color += light.color(slab, base, (p, site, g), counters) * share;
            }
        }
        *weight *= 1.0 - alpha;
        if !(*weight > view.spec().cutoff) {
            counters.early_terminations += 1;
            return (true, back);
        }
    }
    (false, back)
}

//! The ray marcher: an explicit-state iterator over a ray's lattice samples that lie in one
//! slab. It stops at the first event a caller must act on: a surface hit, the ray leaving the
//! slab (the caller forwards it), the ray leaving the volume, or early termination. A
//! composited view's samples go through [`crate::trace::composite`]'s loop, a surface view's
//! through the search here; both ask `crate::trace::skipping` what they may pass over.
//!
//! Invariants: the state ([`RayState`]) is all a ray needs to continue on any node: lattice,
//! next sample index `k`, the previous sample's value, accumulated colour and weight. A sample
//! is processed only by the slab owning its plane; a step is never shortened. Surfaces found in
//! one segment are reported nearest first (ties by surface order), each once: `done_here`
//! remembers which the current segment has already reported, so a transparency continuation
//! re-examines the segment and finds the next. Where a ray enters the volume already inside a
//! surface, the cut face is the surface ("capping"): the outside of the volume counts as below
//! every iso value, and the cut face is lit with the face's normal.

use crate::counters::Counters;
use crate::optics::surface::{self, IsoSurface};
use crate::trace::composite::composite;
use crate::trace::runway::{self, CellTest, Inside, Next, Read, Runway};
use crate::trace::skipping::Skipper;
pub use crate::trace::state::{Hit, RayKind, RayState, Stop};
use crate::trace::view::{Mode, View};
use crate::volume::field;
use crate::volume::grid::Model;
use crate::volume::sample::Sample;
use crate::volume::slab::Slab;
use glam::Vec3;

/// Advance `ray` through the samples `slab` owns.
pub fn march<T: Sample>(
    view: &View,
    slab: &Slab<'_, T>,
    ray: &mut RayState,
    counters: &mut Counters,
) -> Stop {
    match &view.spec().mode {
        Mode::Composite(tf) => composite(view, slab, tf, ray, counters),
        Mode::Surfaces(surfaces) => search(view, slab, surfaces, ray, counters),
    }
}

/// The surface search: each sample's value against the one before it, until a crossing
/// (primary and transparency rays) or until too little light is left (shadow rays).
fn search<T: Sample>(
    view: &View,
    slab: &Slab<'_, T>,
    surfaces: &[IsoSurface],
    ray: &mut RayState,
    counters: &mut Counters,
) -> Stop {
    let spec = view.spec();
    let grid = slab.grid();
    let mut turned = None;
    let mut skipper = Skipper::new(view, slab, ray, &mut turned);
    skipper.pass_depth_bound(view, slab, ray, view.may_skip(ray), counters);
    // Where the interior's samples need no more of the skipping than their cell's leap
    // distance: a run through it takes the samples below every iso value. Not asked for a
    // ray whose depth bound passed it out of the volume; a shadow ray weighs every crossing,
    // and takes the general step throughout.
    let inner = match ray.kind {
        RayKind::Shadow => None,
        _ if ray.k > ray.lattice.last => None,
        _ => Runway::of(view, slab, &skipper, Some(slab.cells())),
    };
    // The interior's last sample, once a sample inside is found.
    let mut inside_to: Option<u32> = None;
    let stepped = runway::stepped_distances(spec.dt);
    loop {
        if ray.k > ray.lattice.last {
            return Stop::Exit;
        }
        if let (Some(end), Some(runway)) = (inside_to, &inner) {
            // Only where the ray may skip and has a sample before this one: the run's
            // samples are then those the general step would read or skip without a crossing.
            if ray.k <= end && ray.primed && view.may_skip(ray) {
                let searched = runway::through!(runway, end, stepped, |inside| {
                    below(view, slab, inside, ray, &mut skipper, counters)
                });
                if let Searched::Done = searched {
                    continue;
                }
            }
        }
        // The corner decides whether the sample is read; the rest of its site only if so.
        let at = (inner.as_ref(), &mut inside_to);
        let may_skip = View::may_skip;
        let probe = match runway::before_read(view, slab, ray, at, &mut skipper, may_skip, counters)
        {
            Next::Leave(plane) => return Stop::Leave { plane },
            Next::Again => continue,
            Next::Read(probe) => probe,
        };
        counters.samples += 1;
        let site = probe.corner.site(grid);
        let v = field::value_at(slab, spec.model, &site, counters);
        if ray.prev_stale {
            ray.prev_stale = false;
            ray.prev = if view.below_surfaces(v) {
                // The skipped predecessor lay below every iso value too, so nothing crosses
                // between them and its exact value is never read: a value below every iso
                // value, as `v` is, gives every test below the same answer.
                v
            } else {
                // A crossing may end here: the predecessor's exact value, for the crossing
                // test and refinement, from the same expression as if it had not been skipped.
                counters.samples += 1;
                Reader(slab, spec.model, inner.as_ref())
                    .value(ray.ray.at(ray.lattice.t(ray.k.saturating_sub(1))), counters)
            };
        }
        if ray.kind == RayKind::Shadow {
            if ray.primed {
                for s in surfaces
                    .iter()
                    .filter(|s| surface::crosses(ray.prev, v, s.iso))
                {
                    ray.weight *= s.transparency;
                }
            }
            if !(ray.weight > spec.cutoff) {
                counters.early_terminations += 1;
                return Stop::Terminated;
            }
        } else if let Some(hit) = nearest_crossing(
            view,
            &Reader(slab, spec.model, inner.as_ref()),
            surfaces,
            ray,
            probe.t,
            probe.p4.truncate(),
            v,
            counters,
        ) {
            ray.done_here |= 1 << hit.surface;
            counters.crossings += 1;
            return Stop::Hit(hit);
        }
        ray.prev = v;
        ray.primed = true;
        ray.done_here = 0;
        ray.k += 1;
    }
}

/// Where a run through the interior of a surface search stopped.
enum Searched {
    /// Past its last sample.
    Done,
    /// At a sample the general step examines: one not below every iso value (a crossing may
    /// end there), or one the storage cannot give whole (never in the interior, but the
    /// general step can read anything).
    Examine,
}

/// The samples from `ray.k` through `inside.end`, all in the interior, of a ray that is not a
/// shadow ray, has read or passed a sample before, and may skip ([`View::may_skip`]): each
/// passed over by stepping or leaping from a cell the map calls empty, or read, for as long
/// as what it reads is below every iso value. Those are the samples at which the general
/// step finds no crossing: it would pass over the same ones (a ray whose last sample read
/// is below every iso value may skip), read the same values (the interior's cell and
/// fractions, [`crate::trace::interior`]) and count them alike. The first sample not below
/// is left unread and uncounted for the general step, with the ray's state as the general
/// step would have left it: the last value read, or a stale one after a skip.
#[inline(always)]
fn below<T: Sample, E: CellTest>(
    view: &View,
    slab: &Slab<'_, T>,
    inside: &Inside<'_, '_, T, E>,
    ray: &mut RayState,
    skipper: &mut Skipper<'_>,
    totals: &mut Counters,
) -> Searched {
    let (lattice, r) = (ray.lattice, ray.ray);
    // Counted here and added once at the end, in registers (as the composited run).
    let mut local = Counters::default();
    let mut k = ray.k;
    let mut looked = inside.look(lattice, r, k);
    // The last value read, and whether samples were passed over since.
    let (mut prev, mut stale) = (ray.prev, ray.prev_stale);
    let searched = loop {
        if k > inside.end {
            break Searched::Done;
        }
        let Some(Read { q, cell, lo, index }) = inside.step(
            slab,
            (ray, lattice, r),
            skipper,
            (&mut k, &mut looked),
            None,
        ) else {
            stale = true;
            continue;
        };
        let Some(nodes) = inside.cells.at_index(index) else {
            break Searched::Examine;
        };
        let v = field::lerp_cell(nodes, (q - cell).truncate());
        if !view.below_surfaces(v) {
            // A crossing is near: its light reads the gradient from the node field's lanes
            // at this cell or the one before, which the search (reading the slab) has not
            // touched. Asked for now, the field's lines come while the crossing is refined.
            if let Some(field) = slab.nodes() {
                field.cells().prefetch(lo);
            }
            break Searched::Examine;
        }
        local.samples += 1;
        local.interpolations += 1;
        prev = v;
        stale = false;
        k += 1;
    };
    local.skipped += runway::passed_over(ray.k, k, local.samples);
    ray.k = k;
    ray.prev = prev;
    ray.prev_stale = stale;
    totals.add(&local);
    searched
}

/// How the search reads the field between its samples (a skipped predecessor, a
/// refinement's points): [`Runway::value`] where a point is inside the interior, else
/// [`field::value`]; the same value and count either way.
struct Reader<'r, 'a, T: Sample>(&'r Slab<'a, T>, Model, Option<&'r Runway<'a, T>>);

impl<T: Sample> Reader<'_, '_, T> {
    /// The field's value at index-space `p`.
    #[inline]
    fn value(&self, p: Vec3, counters: &mut Counters) -> f32 {
        let Reader(slab, model, runway) = *self;
        match runway.and_then(|runway| runway.value(p.extend(0.0))) {
            Some(v) => {
                counters.interpolations += 1;
                v
            }
            None => field::value(slab, model, p, counters),
        }
    }
}

/// The nearest surface crossing not yet reported on the segment ending at sample `k` (value
/// `v` at `p`, parameter `t`).
#[allow(
    clippy::too_many_arguments,
    reason = "one call site; the arguments are the sample being examined"
)]
fn nearest_crossing<T: Sample>(
    view: &View,
    read: &Reader<'_, '_, T>,
    surfaces: &[IsoSurface],
    ray: &RayState,
    t: f32,
    p: Vec3,
    v: f32,
    counters: &mut Counters,
) -> Option<Hit> {
    let pending = |i: usize| ray.done_here & (1 << i) == 0;
    if !ray.primed {
        if ray.kind == RayKind::Shadow {
            return None;
        }
        // The first sample: the outside of the volume is below every iso value, so a surface
        // whose inside contains the sample is cut by the volume's boundary here.
        let index =
            (0..surfaces.len()).find(|&i| pending(i) && surface::inside(v, surfaces[i].iso))?;
        let normal = ray.entry.outward_normal().unwrap_or(-ray.ray.dir_world);
        return Some(Hit {
            surface: index as u8,
            t,
            point: p,
            cap_normal: Some(normal),
        });
    }
    if view.below_surfaces(ray.prev) && view.below_surfaces(v) {
        // Both ends outside every surface: nothing crosses (most samples, in one test).
        return None;
    }
    let t_prev = ray.lattice.t(ray.k.saturating_sub(1));
    let mut best: Option<(f32, usize)> = None;
    for (i, s) in surfaces.iter().enumerate() {
        if !pending(i) || !surface::crosses(ray.prev, v, s.iso) {
            continue;
        }
        let f = surface::refine(s.iso, ray.prev, v, view.spec().refine_steps, |f| {
            counters.refinements += 1;
            read.value(ray.ray.at(t_prev + f * (t - t_prev)), counters)
        });
        if best.is_none_or(|(bf, _)| f < bf) {
            best = Some((f, i));
        }
    }
    let (f, index) = best?;
    let t_hit = t_prev + f * (t - t_prev);
    Some(Hit {
        surface: index as u8,
        t: t_hit,
        point: ray.ray.at(t_hit),
        cap_normal: None,
    })
}

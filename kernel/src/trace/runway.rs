//! A ray's way through its slab's interior for one call of a sample loop: the box of samples
//! inside ([`Interior`]), the storage's whole cells there, what tells which of them are empty
//! (a cell leap map, read at the cell's place in the storage or by its corner), and the leap
//! distances a loop steps over rather than leaps; and the general step's questions of a
//! sample before a loop reads it ([`before_read`]: its owner, the way into the interior, the
//! skipping), asked alike by every loop. The composited loops and the surface search each run
//! their own loop over the interior; what may be passed over is the general step's, cell for
//! cell, so a run and the general step pass over the same samples.
//!
//! Invariants: a runway exists only for the cell model, where the skipping asks nothing of an
//! interior sample but its cell's leap distance ([`Skipper::per_cell`]) and the storage holds
//! every cell inside; a distance of 0 is a cell that may show.

use crate::counters::Counters;
use crate::skip::cell_leaps::HeldLeaps;
use crate::skip::node_leaps::NodeLeaps;
use crate::trace::interior::Interior;
use crate::trace::lattice::Lattice;
use crate::trace::ray::Ray;
use crate::trace::skipping::{skip_to, Probe, Skipper};
use crate::trace::state::RayState;
use crate::trace::view::View;
use crate::volume::cells::{Cells, HeldCells};
use crate::volume::field;
use crate::volume::grid::Model;
use crate::volume::sample::Sample;
use crate::volume::slab::Slab;
use glam::Vec4;

/// The interior of one call: its box, its storage's whole cells (`U` per node) and what tells
/// their empty cells.
pub(crate) struct Runway<'a, U> {
    pub(crate) interior: Interior,
    pub(crate) cells: HeldCells<'a, U>,
    pub(crate) test: Test<'a>,
}

impl<'a, U: Copy> Runway<'a, U> {
    /// The runway of `view`'s ray through `slab`, whose skipping is `skipper`, reading
    /// `cells` (the storage its loop reads); `None` where the model or the skipping asks more
    /// of a sample than its cell's distance, or no cell is inside.
    // Inlined: a call's set-up is a fifth of a short ray's work, and inlined into the loop's
    // caller most of it folds away.
    #[inline(always)]
    pub(crate) fn of<T: Sample>(
        view: &View,
        slab: &Slab<'_, T>,
        skipper: &Skipper<'a>,
        cells: Option<Cells<'a, U>>,
    ) -> Option<Self> {
        let (Model::Cell, Some(leaps), Some(cells)) =
            (view.spec().model, skipper.per_cell(), cells)
        else {
            return None;
        };
        let owned = slab.owned();
        let planes = cells.cell_planes();
        let interior = Interior::new(
            slab.grid(),
            owned.start.max(planes.start)..owned.end.min(planes.end),
        )?;
        let (x, y_end, z_end) = interior.cells();
        let cells = cells.holding(x.clone(), y_end, z_end)?;
        let test = match (leaps, skipper.node_leaps()) {
            (Some(_), Some(map)) => Test::AtIndex(AtIndex::new(map, &cells)),
            (Some(leaps), None) => Test::Held(leaps.holding(x, y_end, z_end)?),
            (None, _) => Test::Every,
        };
        Some(Runway {
            interior,
            cells,
            test,
        })
    }
}

/// Where the general step goes from sample `ray.k` ([`before_read`]).
pub(crate) enum Next {
    /// Out of the slab's owned planes, at this plane: the ray leaves the call.
    Leave(u32),
    /// On at the loop's top: the sample begins a run through the interior, or it and the
    /// samples after it were passed over.
    Again,
    /// Read the sample, whose probe this is.
    Read(Probe),
}

/// The general step's questions of sample `ray.k` before any loop reads it, the same in each
/// loop: whose it is, whether it begins the run through the interior (`inner`; once found,
/// the run's last sample in `inside_to`), and what the skipping passes over from it, where
/// the ray may skip (`may_skip`, asked only then: a surface view's answer reads the iso
/// values).
#[allow(
    clippy::too_many_arguments,
    reason = "inlined into each loop; the arguments are the loop's state"
)]
#[inline(always)]
pub(crate) fn before_read<T: Sample, U: Copy, S: Fn(&View, &RayState) -> bool>(
    view: &View,
    slab: &Slab<'_, T>,
    ray: &mut RayState,
    (inner, inside_to): (Option<&Runway<'_, U>>, &mut Option<u32>),
    skipper: &mut Skipper<'_>,
    may_skip: S,
    counters: &mut Counters,
) -> Next {
    let probe = Probe::of(ray, slab.grid(), view.spec().model, ray.k);
    let plane = probe.corner.plane();
    if !slab.owns(plane) {
        return Next::Leave(plane);
    }
    if let (None, Some(runway)) = (*inside_to, inner) {
        if runway.interior.holds(probe.p4) {
            // A run through the interior takes this sample.
            *inside_to = Some(runway.interior.last(ray, ray.k));
            return Next::Again;
        }
    }
    if let Some(last) = skipper.empty_run(view, slab, ray, &probe, may_skip(view, ray)) {
        skip_to(view, ray, last, counters);
        return Next::Again;
    }
    Next::Read(probe)
}

/// A run through the interior: its storage's whole cells, what says which cells are empty,
/// its last sample, and the leap distances it steps over rather than leaps.
pub(crate) struct Inside<'c, 'a, U, E> {
    pub(crate) interior: &'c Interior,
    pub(crate) cells: &'c HeldCells<'a, U>,
    pub(crate) test: &'c E,
    pub(crate) end: u32,
    pub(crate) stepped: u8,
}

/// `$body` with `$inside` bound to the run ([`Inside`]) through `$runway` to its sample `$end`,
/// stepping over leap distances up to `$stepped`: the body compiled once for each way the
/// runway tells empty cells, so that each loop holds only its own test. Both sample loops
/// enter their runs through it. (A macro: a closure cannot be generic over the test's type.)
macro_rules! through {
    ($runway:expr, $end:expr, $stepped:expr, |$inside:ident| $body:expr) => {{
        use $crate::trace::runway::{EveryCell, Inside, Test};
        let runway = $runway;
        macro_rules! with {
            ($test:expr) => {{
                let $inside = &Inside {
                    interior: &runway.interior,
                    cells: &runway.cells,
                    test: $test,
                    end: $end,
                    stepped: $stepped,
                };
                $body
            }};
        }
        match &runway.test {
            Test::AtIndex(test) => with!(test),
            Test::Held(test) => with!(test),
            Test::Every => with!(&EveryCell),
        }
    }};
}
pub(crate) use through;

/// Where a composited loop's run through the interior stopped.
pub(crate) enum Run {
    /// Past its last sample.
    Done,
    /// At a sample the general step reads: one the storage cannot give whole (never in an
    /// interior the storage defines, but the general step can read anything), or one whose
    /// passed-over predecessor a pre-integrated run must read again outside the interior.
    Unread,
    /// Too little light left.
    Terminated,
}

/// How many samples ahead of the one it looks at a run asks for a cell, where it asks
/// ([`Inside::step`]): on SOD's composited view four was faster than eight and sixteen
/// (docs/speed-log.md).
const HINT_SAMPLES: f32 = 4.0;

/// A run's sample to be read: its index-space point, its cell's low corner as whole floats
/// and as integers, and the cell's place in the run's storage.
pub(crate) struct Read {
    pub(crate) q: Vec4,
    pub(crate) cell: Vec4,
    pub(crate) lo: [u32; 3],
    pub(crate) index: usize,
}

/// A sample of a run looked at one sample before the loop asks about it: where it lies and
/// its cell's distance in the map. Which way the loop goes at a sample (step, leap or read)
/// follows that map byte, a load at the end of a chain of arithmetic from the sample's
/// index; looked at while the loop still works on the sample before, the load is under way
/// by the time its branch is asked, and a mispredicted branch restarts the loop with the
/// next sample's byte in hand rather than behind the chain. (The map's byte was the
/// composited loop's costliest wait: docs/speed-log.md.) Any index may be looked at: past
/// the run's end the look is of some place, its distance bounds-checked, and never read.
#[derive(Clone, Copy)]
pub(crate) struct Look {
    q: Vec4,
    index: usize,
    distance: u8,
}

impl<U: Copy, E: CellTest> Inside<'_, '_, U, E> {
    /// The offset in the run's storage from a sample's place to the place [`HINT_SAMPLES`]
    /// samples (`dt` apart) on along `line`, each axis's share rounded to whole nodes: what
    /// [`Inside::step`] asks for ahead of each sample it looks at. A hint, so only near: the
    /// place it names is within a node or so of the cell the ray reaches there.
    #[inline]
    pub(crate) fn hint_offset(&self, line: &Ray, dt: f32) -> usize {
        // Saturating: a NaN or enormous step names some place, which a hint may.
        let steps = (line.dir * (dt * HINT_SAMPLES)).round();
        self.cells
            .offset([steps.x as i64, steps.y as i64, steps.z as i64])
    }

    /// Sample `k` of a ray on `lattice` along `line`, looked at: where a loop over the run
    /// starts.
    #[inline(always)]
    pub(crate) fn look(&self, lattice: Lattice, line: Ray, k: u32) -> Look {
        let q = line.at4(lattice.t(k));
        let (_, lo) = field::interior_corner(q);
        let index = self.cells.index(lo);
        Look {
            q,
            index,
            distance: self.test.distance(lo, index),
        }
    }

    /// Sample `k` of `ray` (`lattice` and `line` its lattice and line, held by the caller's
    /// loop; `looked` that sample looked at), inside the run: passed over where its cell's
    /// distance in the map says the cell is empty (stepped below the stepped distances, else
    /// a leap over the cube the map promises, as the general step passes over the same
    /// samples) and `k` moved on to the next sample to look at; else where to read it.
    /// `looked` moves on with `k`. Both sample loops ask this first of every sample, and
    /// count what it passed over once, when they return: every index they moved past and did
    /// not read ([`passed_over`]).
    ///
    /// Where `hint` is the storage offset of a cell some samples on ([`Inside::hint_offset`]),
    /// that cell's rows and map byte are asked for as each sample is looked at: in storage
    /// larger than the caches a run waited on those two loads (docs/speed-log.md). A
    /// parameter, not a field of the run: held in the run, the compiler kept it in memory
    /// and the loop around the hints spilled its registers (843 M instructions a fast frame
    /// against 763 M).
    #[inline(always)]
    pub(crate) fn step<T: Sample>(
        &self,
        slab: &Slab<'_, T>,
        (ray, lattice, line): (&RayState, Lattice, Ray),
        skipper: &mut Skipper<'_>,
        (k, looked): (&mut u32, &mut Look),
        hint: Option<usize>,
    ) -> Option<Read> {
        let at = *k;
        let here = *looked;
        // Looked at before `here`'s distance decides the way on.
        *looked = self.look(lattice, line, at.wrapping_add(1));
        self.ask_ahead(looked, hint);
        if (1..=self.stepped).contains(&here.distance) {
            // The same samples as a leap, fewer instructions.
            *k = at + 1;
            return None;
        }
        // Found again rather than carried: registers held from sample to sample cost more
        // than the truncation.
        let (cell, lo) = field::interior_corner(here.q);
        if here.distance > 0 {
            let last = skipper.leap_inside(slab, ray, (at, self.end), cell, here.distance);
            *k = last + 1;
            *looked = self.look(lattice, line, *k);
            return None;
        }
        Some(Read {
            q: here.q,
            cell,
            lo,
            index: here.index,
        })
    }
}

impl<U: Copy, E: CellTest> Inside<'_, '_, U, E> {
    /// Sample `k` (`looked` that sample looked at), to be read whatever its cell's distance
    /// in the map: where a loop may not pass over it (pre-integrated compositing, whose
    /// segment ending there starts at a value that shows). `looked` moves on to `k + 1`, as
    /// [`Inside::step`] moves it for a sample it hands to be read, and asks ahead of it as
    /// that does where `hint` is an offset.
    #[inline(always)]
    pub(crate) fn take(
        &self,
        lattice: Lattice,
        line: Ray,
        k: u32,
        looked: &mut Look,
        hint: Option<usize>,
    ) -> Read {
        let here = *looked;
        *looked = self.look(lattice, line, k.wrapping_add(1));
        self.ask_ahead(looked, hint);
        let (cell, lo) = field::interior_corner(here.q);
        Read {
            q: here.q,
            cell,
            lo,
            index: here.index,
        }
    }

    /// Where `hint` is the storage offset of a cell some samples on ([`Inside::hint_offset`]),
    /// ask for that cell's rows and map byte from the sample just `looked` at.
    #[inline(always)]
    fn ask_ahead(&self, looked: &Look, hint: Option<usize>) {
        if let Some(offset) = hint {
            let place = looked.index.wrapping_add(offset);
            self.test.prefetch(place);
            self.cells.prefetch(place);
        }
    }
}

/// The samples a loop over a run passed over, counted once when it returns rather than
/// sample by sample: every index from `from` to `to` (where it stopped) that it did not
/// read (`read` of them) it passed over, since [`Inside::step`] moves a loop only past
/// samples it passes over or hands to it to read.
#[inline(always)]
pub(crate) fn passed_over(from: u32, to: u32, read: u64) -> u64 {
    debug_assert!(
        to >= from && u64::from(to - from) >= read,
        "{from} {to} {read}"
    );
    u64::from(to.saturating_sub(from)).saturating_sub(read)
}

impl<T: Sample> Runway<'_, T> {
    /// The field's value at index-space `q` where `q` is inside the interior, read whole from
    /// the runway's storage of the slab's own samples: there [`field::value`]'s in every bit
    /// (the interior's cell and fractions are [`field::locate`]'s, [`crate::trace::interior`]),
    /// one interpolation. `None` outside.
    #[inline]
    pub(crate) fn value(&self, q: Vec4) -> Option<f32> {
        if !self.interior.holds(q) {
            return None;
        }
        let (cell, lo) = field::interior_corner(q);
        let nodes = self.cells.at_index(self.cells.index(lo))?;
        Some(field::lerp_cell(nodes, (q - cell).truncate()))
    }
}

/// The greatest cell leap distance that a run through the interior passes sample by sample
/// rather than by leaping, for a step of `dt` cell edges. A leap's turn (its cube's exit,
/// checked, and the landing's cell) costs about four samples' cell tests, and a ray has
/// about `d / dt` samples in a cube of `d` cells: stepping pays below about `4·dt`, as
/// measured on SOD at two steps (docs/speed-log.md). Either way the same samples are passed
/// over.
pub(crate) fn stepped_distances(dt: f32) -> u8 {
    // Saturating: a NaN or negative step steps over nothing.
    (4.0 * dt) as u8
}

/// What a run through the interior asks of a sample's cell before reading it: its distance
/// in a cell leap map, 0 where the cell may show.
pub(crate) trait CellTest {
    /// The distance of the cell whose low node is `lo`, at `index` in the run's storage.
    fn distance(&self, lo: [u32; 3], index: usize) -> u8;

    /// A hint that the distance at `index` (any place) is asked soon; nothing where the
    /// test's layout is not the storage's.
    #[inline(always)]
    fn prefetch(&self, _index: usize) {}
}

/// How a run through the interior tells empty cells.
pub(crate) enum Test<'a> {
    /// By a cell leap map laid out as the storage it reads.
    AtIndex(AtIndex<'a>),
    /// By a cell leap map of its own layout.
    Held(HeldLeaps<'a>),
    /// The slab carries no skipping structures: every cell may show.
    Every,
}

/// A cell leap map laid out as the slab's nodes ([`NodeLeaps`]), read where the run's storage
/// holds the cell's nodes, one offset away: the run's storage and the map share the grid's
/// strides and differ only in their first plane.
pub(crate) struct AtIndex<'a> {
    map: NodeLeaps<'a>,
    /// From a place in the run's storage to the same node's in the map (wrapping).
    offset: usize,
}

impl<'a> AtIndex<'a> {
    fn new<U: Copy>(map: NodeLeaps<'a>, cells: &HeldCells<'_, U>) -> Self {
        let (first, plane) = cells.planes();
        // (first − map's first) planes, as a wrapping offset.
        let planes = i64::from(first) - i64::from(map.first());
        AtIndex {
            map,
            offset: (planes as isize as usize).wrapping_mul(plane),
        }
    }
}

impl CellTest for AtIndex<'_> {
    #[inline(always)]
    fn distance(&self, _: [u32; 3], index: usize) -> u8 {
        self.map.at(index.wrapping_add(self.offset))
    }

    #[inline(always)]
    fn prefetch(&self, index: usize) {
        self.map.prefetch(index.wrapping_add(self.offset));
    }
}

/// The slab carries no skipping structures: every cell may show.
pub(crate) struct EveryCell;

impl CellTest for EveryCell {
    #[inline(always)]
    fn distance(&self, _: [u32; 3], _: usize) -> u8 {
        0
    }
}

impl CellTest for HeldLeaps<'_> {
    #[inline(always)]
    fn distance(&self, lo: [u32; 3], _: usize) -> u8 {
        HeldLeaps::distance(self, lo)
    }
}

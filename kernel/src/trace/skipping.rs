//! Empty-space skipping as the sample loops ask it: one question per sample, "from this
//! sample on, how far does nothing contribute?", answered from the structures a slab carries
//! for the ray's octant (depth bounds, cell leap maps, block leaps, cell masks), so that a
//! loop holds no skipping of its own.
//!
//! Invariants: a run is only ever claimed empty when every sample in it is provably empty for
//! the view ([`crate::skip`]'s invariant), stays in the slab's owned planes and on the
//! lattice; every estimate of where a run ends is checked with the samples' own arithmetic,
//! so estimates decide how far a jump goes, never whether a sample that shows is skipped.

use crate::counters::Counters;
use crate::skip::blocks::Blocks;
use crate::skip::bounds::Depths;
use crate::skip::cell_leaps::CellLeaps;
use crate::skip::cells::{self, CellMask};
use crate::skip::node_leaps::NodeLeaps;
use crate::skip::scan;
use crate::trace::state::{RayKind, RayState};
use crate::trace::view::View;
use crate::volume::field;
use crate::volume::grid::{Grid, Model};
use crate::volume::sample::Sample;
use crate::volume::slab::Slab;
use glam::{BVec4A, Vec4};

/// A ray's skipping in one slab for one call of a sample loop: the structures the slab
/// carries, read for the ray's octant, and what the call has found of them so far.
pub(crate) struct Skipper<'s> {
    /// Single empty cells are skipped in the cell model only: a voxel-model sample reads one
    /// node, no more than the mask would.
    by_cell: bool,
    /// The blocks as this ray reads them: the leap map of its direction's octant.
    blocks: Option<&'s Blocks<'s>>,
    /// Where the view has a cell leap map for this octant, a ray leaps from cell to cell by
    /// it, and asks no block.
    cell_leaps: Option<CellLeaps<'s>>,
    /// Else a run through empty cells scans the samples after it where that pays for this
    /// ray ([`scan::pays`]), or jumps over a box of empty cells.
    masks: Option<scan::Masks<'s>>,
    /// A primary ray's depth bounds, until [`Skipper::depth_run`] has read them.
    depths: Option<Depths<'s>>,
    /// What the last sample's block says: consecutive samples mostly share a block, and its
    /// verdict (a leap distance or the test against the view) is not free.
    known: Option<Verdict>,
    /// Found at the first jump whose exit is estimated: many calls end before one.
    exits: Option<Exits>,
}

impl<'s> Skipper<'s> {
    /// The skipping `slab` offers `ray` under `view`. The slab's blocks are read in place
    /// where they face the ray's octant (the host turns them toward the primary rays'), else
    /// turned into `turned`: a copy of them for every ray would cost more than most rays'
    /// skipping.
    #[inline]
    pub(crate) fn new<T: Sample>(
        view: &View,
        slab: &'s Slab<'_, T>,
        ray: &RayState,
        turned: &'s mut Option<Blocks<'s>>,
    ) -> Self {
        let by_cell = view.spec().model == Model::Cell;
        let octant = crate::skip::octant::Octant::of(ray.ray.dir);
        let blocks: Option<&'s Blocks<'s>> = match slab.blocks() {
            Some(blocks) if blocks.octant() == octant => Some(blocks),
            Some(blocks) => Some(turned.insert(blocks.toward(octant))),
            None => None,
        };
        let cell_leaps = match blocks {
            Some(blocks) if by_cell => CellLeaps::of(blocks),
            _ => None,
        };
        let masks = match blocks {
            Some(blocks)
                if by_cell && cell_leaps.is_none() && scan::pays(&ray.ray, &ray.lattice) =>
            {
                scan::Masks::of(blocks, slab.grid(), slab.owned())
            }
            _ => None,
        };
        // A primary ray passes at once over the samples before its pixel's depth bound: they
        // lie in no cell the masks keep, so the turns below would skip each of them.
        let depths = match blocks {
            Some(blocks) if by_cell && ray.kind == RayKind::Primary => blocks.depths(),
            _ => None,
        };
        Skipper {
            by_cell,
            blocks,
            cell_leaps,
            masks,
            depths,
            known: None,
            exits: None,
        }
    }

    /// Asked once, before a call's first sample: the last sample from `ray.k` on that lies
    /// before the primary ray's depth bound (and in owned planes), which no sample before it
    /// passes; `None` where there is no bound, `ray.k` is not before it, or the loop is about
    /// to stop the ray (past its lattice, or outside the slab's owned planes). `may_skip` is
    /// as for [`Skipper::empty_run`]. Apart from the per-sample question, so that the loop
    /// carries no state that only its first sample reads.
    #[inline]
    fn depth_run<T: Sample>(
        &mut self,
        slab: &Slab<'_, T>,
        ray: &RayState,
        may_skip: bool,
    ) -> Option<u32> {
        let bound = self.depths.take()?.bound(ray.pixel);
        if !may_skip || ray.k > ray.lattice.last {
            return None;
        }
        // Depth bounds serve the cell model only.
        let probe = Probe::of(ray, slab.grid(), Model::Cell, ray.k);
        if !(probe.t < bound && slab.owns(probe.corner.plane())) {
            return None;
        }
        Some(before_bound(ray, slab, bound, &mut self.exits))
    }

    /// Before a call's first sample: pass over the samples before the primary ray's depth
    /// bound ([`Skipper::depth_run`]), if any.
    #[inline]
    pub(crate) fn pass_depth_bound<T: Sample>(
        &mut self,
        view: &View,
        slab: &Slab<'_, T>,
        ray: &mut RayState,
        may_skip: bool,
        counters: &mut Counters,
    ) {
        if let Some(last) = self.depth_run(slab, ray, may_skip) {
            skip_to(view, ray, last, counters);
        }
    }

    /// The cell leap map of [`Skipper::per_cell`] laid out as the slab's nodes, where the
    /// slab carries it.
    #[inline]
    pub(crate) fn node_leaps(&self) -> Option<NodeLeaps<'s>> {
        self.cell_leaps?;
        self.blocks?.node_leaps()
    }

    /// What a run through the slab's interior ([`crate::trace::interior`]) asks of the
    /// skipping at each sample, where that is one question of the sample's cell: its distance
    /// in the cell leap map (`Some(Some(map))`), or nothing (`Some(None)`: the slab carries no
    /// skipping structures). `None` where [`Skipper::empty_run`] asks more of a sample (block
    /// verdicts, cell masks).
    #[inline]
    pub(crate) fn per_cell(&self) -> Option<Option<CellLeaps<'s>>> {
        match (self.blocks, self.cell_leaps) {
            (None, _) => Some(None),
            (Some(_), Some(leaps)) => Some(Some(leaps)),
            (Some(_), None) => None,
        }
    }

    /// The last sample from `k` on, at most `end`, that stays in the cube of empty cells the
    /// cell leap map promises ahead of the cell whose low corner is `cell` (whole floats) at
    /// `distance` (at least 1): one leap of a run through the slab's interior
    /// ([`crate::trace::interior`]), whose samples up to `end` are all owned. Where it lands
    /// is left to the run, which reads the landing's cell for its own sample anyway.
    // Not inlined: a leap is rarer than a sample and needs many registers, which the run
    // through the interior, inlined around it, would then spill on every sample
    // (docs/speed-log.md).
    #[inline(never)]
    pub(crate) fn leap_inside<T: Sample>(
        &mut self,
        slab: &Slab<'_, T>,
        ray: &RayState,
        (k, end): (u32, u32),
        cell: Vec4,
        distance: u8,
    ) -> u32 {
        let exits = self.exits.get_or_insert_with(|| Exits::new(ray));
        let far = cube_far(cell, distance, exits);
        last_short_of_before(ray, k, end, slab.grid(), far, exits)
    }

    /// The last sample of a run from `ray.k` (at `probe`, in an owned plane) in which no
    /// sample contributes to `view`; `None` where sample `ray.k` may. `may_skip` is whether
    /// the ray's state lets it skip at all ([`View::may_skip`]).
    #[inline(always)]
    pub(crate) fn empty_run<T: Sample>(
        &mut self,
        view: &View,
        slab: &Slab<'_, T>,
        ray: &RayState,
        probe: &Probe,
        may_skip: bool,
    ) -> Option<u32> {
        let corner = &probe.corner;
        if let Some(leaps) = &self.cell_leaps {
            let distance = leaps.distance(corner.lo);
            if !may_skip || distance == 0 {
                return None;
            }
            // Provably nothing in this cell or in the cube of cells ahead of it.
            let exits = self.exits.get_or_insert_with(|| Exits::new(ray));
            // The corner found it already (cell leaps serve the cell model only).
            let cell = corner
                .cell()
                .unwrap_or_else(|| field::cell4(slab.grid(), probe.p4));
            return Some(cell_leap(ray, slab, leaps, cell, distance, exits));
        }
        let blocks = self.blocks?;
        let block = blocks.block_of(corner.lo);
        let here = match self.known {
            Some(v) if v.block == block => v,
            _ => {
                let v = Verdict::of(view, blocks, block);
                self.known = Some(v);
                v
            }
        };
        if !may_skip {
            return None;
        }
        if let Some(reach) = here.reach {
            // Provably nothing here: no crossing, no opacity. The lattice index moves on,
            // over every further sample in the same slab whose block is within `reach`, and
            // on through the empty blocks after it.
            return Some(leap(ray, slab, blocks, block, reach, view.spec().model));
        }
        if self.by_cell && here.cells & cells::bit(corner.lo) == 0 {
            // An empty cell of a block that is not empty: this sample and the ones after it
            // in empty cells, scanned, or in the cube of empty cells ahead.
            return Some(match &self.masks {
                Some(masks) => ray.k + scan::empty_run(&ray.ray, &ray.lattice, ray.k, masks),
                None => {
                    let exits = self.exits.get_or_insert_with(|| Exits::new(ray));
                    cell_run(ray, slab, blocks, corner.lo, here.cells, exits)
                }
            });
        }
        None
    }
}

/// Where a lattice sample lies: its parameter, its position in four lanes (as `locate` takes
/// it) and its corner.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Probe {
    pub(crate) t: f32,
    pub(crate) p4: Vec4,
    pub(crate) corner: field::Corner,
}

impl Probe {
    /// Sample `k` of `ray`.
    #[inline(always)]
    pub(crate) fn of(ray: &RayState, grid: &Grid, model: Model, k: u32) -> Probe {
        let t = ray.lattice.t(k);
        let p4 = ray.ray.at4(t);
        Probe {
            t,
            p4,
            corner: field::corner4(grid, model, p4),
        }
    }
}

/// What a block says about the samples in it, for one view.
#[derive(Clone, Copy, Debug)]
struct Verdict {
    block: (u32, u32, u32),
    /// How far around this block every block is empty, in blocks; `None`: this one is not.
    reach: Option<u32>,
    /// Its cells the view cannot skip: none where the block is empty (`reach` is `Some`).
    cells: CellMask,
}

impl Verdict {
    /// Read only what decides: the range where no leap map speaks, the cells where the
    /// block is not empty.
    #[inline]
    fn of(view: &View, blocks: &Blocks<'_>, block: (u32, u32, u32)) -> Verdict {
        let entry = blocks.entry(block);
        let reach = match entry.leap() {
            Some(distance) => reach_of(distance),
            None => view.empty(entry.range()).then_some(0),
        };
        Verdict {
            block,
            reach,
            cells: match reach {
                Some(_) => 0,
                None => entry.cells(),
            },
        }
    }
}

/// How many blocks ahead of a block every block is empty, from its leap map's chessboard
/// `distance` to the nearest that is not; `None` for a block that is not empty (0).
#[inline]
fn reach_of(distance: u8) -> Option<u32> {
    distance.checked_sub(1).map(u32::from)
}

/// Skip samples `ray.k ..= last`, which provably contribute nothing.
#[inline]
pub(crate) fn skip_to(view: &View, ray: &mut RayState, last: u32, counters: &mut Counters) {
    counters.skipped += u64::from(last - ray.k + 1);
    if view.reads_predecessor() {
        ray.primed = true;
        ray.prev_stale = true;
        ray.done_here = 0;
    }
    ray.k = last + 1;
}

/// What estimating where a ray leaves a box of cells needs of it, found at the first run
/// through an empty cell in a call of a sample loop: the estimate multiplies by reciprocals
/// instead of dividing. It is only an estimate: every landing is checked with the samples'
/// own arithmetic, so its rounding decides how far a jump goes, never whether a sample that
/// shows is skipped.
#[derive(Clone, Copy, Debug)]
struct Exits {
    origin: Vec4,
    /// `1 / dir` per axis (infinite where the ray does not move along it; not read there).
    inv_dir: Vec4,
    /// Axes the ray moves along (never `w`), and those it moves up.
    moving: BVec4A,
    rising: BVec4A,
    inv_dt: f32,
}

impl Exits {
    fn new(ray: &RayState) -> Exits {
        let dir = ray.ray.dir.extend(0.0);
        Exits {
            origin: ray.ray.origin.extend(0.0),
            inv_dir: Vec4::ONE / dir,
            moving: dir.cmpne(Vec4::ZERO),
            rising: dir.cmpgt(Vec4::ZERO),
            inv_dt: 1.0 / ray.lattice.dt,
        }
    }

    /// About how many lattice steps after parameter `t` the ray reaches the first of the
    /// planes `faces` (one per axis; those it does not move along are not read), zero where
    /// that cannot be told.
    #[inline]
    fn steps(&self, t: f32, faces: Vec4) -> u32 {
        let at = Vec4::select(
            self.moving,
            (faces - self.origin) * self.inv_dir,
            Vec4::INFINITY,
        );
        let ahead = ((at.min_element() - t) * self.inv_dt).max(0.0);
        if ahead.is_finite() {
            ahead as u32
        } else {
            0
        }
    }
}

/// The last sample of the run starting at `ray.k` (a cell-model sample in the empty cell
/// whose low corner is `cell`, in a block whose cells the view cannot skip are `mask`) that
/// stays in the box of empty cells [`cells::empty_box`] finds ahead of that cell for the
/// octant `blocks` serve, and in `slab`'s owned planes ([`last_short_of`]).
#[inline]
fn cell_run<T: Sample>(
    ray: &RayState,
    slab: &Slab<'_, T>,
    blocks: &Blocks<'_>,
    cell: [u32; 3],
    mask: CellMask,
    exits: &Exits,
) -> u32 {
    let offset = cell.map(|c| c % crate::skip::blocks::BLOCK);
    let (first, last) = cells::empty_box(mask, offset, blocks.octant());
    let face = |a: usize, end: [u32; 3], past: u32| (cell[a] - offset[a] + end[a] + past) as f32;
    let lo = Vec4::new(face(0, first, 0), face(1, first, 0), face(2, first, 0), 0.0);
    let hi = Vec4::new(face(0, last, 1), face(1, last, 1), face(2, last, 1), 0.0);
    let far = OwnedFaces::of(slab).clamp(Vec4::select(exits.rising, hi, lo));
    last_short_of(ray, ray.k, slab.grid(), far, exits)
}

/// The faces of a slab's owned planes, as a box's far faces are clamped to them: a
/// cell-model sample's plane is its cell's, so the owned cells span `[start, end)` in X.
#[derive(Clone, Copy, Debug)]
struct OwnedFaces {
    floor: Vec4,
    ceiling: Vec4,
}

impl OwnedFaces {
    #[inline]
    fn of<T: Sample>(slab: &Slab<'_, T>) -> OwnedFaces {
        let owned = slab.owned();
        OwnedFaces {
            floor: Vec4::new(owned.start as f32, f32::MIN, f32::MIN, f32::MIN),
            ceiling: Vec4::new(owned.end as f32, f32::MAX, f32::MAX, f32::MAX),
        }
    }

    /// A box's far faces (one per axis, as [`last_short_of`] reads them), nor past the
    /// owned planes' faces. The box holds the cell the run starts in, which is owned, so a
    /// face clamped stays ahead of that cell.
    #[inline]
    fn clamp(&self, far: Vec4) -> Vec4 {
        far.max(self.floor).min(self.ceiling)
    }
}

/// The last sample from sample `k` on (a cell-model sample in a box of cells the view can
/// skip, in owned planes) that stays in that box and in those planes, given by its far faces
/// `far`, clamped to the owned planes' ([`OwnedFaces::clamp`]): on each axis the ray moves
/// up, the box's upper face; on every other, its lower face. Every sample between lies there
/// too.
///
/// Cells and owner planes are monotone along the lattice, each axis the way the ray moves (as
/// the positions are, and the clamp and floor after them), so a sample after `k` lies in the
/// box and in the owned planes exactly when its cell is short of `far` on every axis the ray
/// moves up and at or past it on every other (there the ray moves down, or keeps its cell).
/// The exit ([`Exits::steps`]) is only an estimate: each candidate is checked so, with the
/// samples' own arithmetic, halving on failure.
#[inline]
fn last_short_of(ray: &RayState, k: u32, grid: &Grid, far: Vec4, exits: &Exits) -> u32 {
    last_short_of_before(ray, k, ray.lattice.last, grid, far, exits)
}

/// [`last_short_of`], at most sample `limit`.
#[inline]
fn last_short_of_before(
    ray: &RayState,
    k: u32,
    limit: u32,
    grid: &Grid,
    far: Vec4,
    exits: &Exits,
) -> u32 {
    let in_box = |c: Vec4| {
        let inside = (exits.rising & c.cmplt(far)) | (!exits.rising & c.cmpge(far));
        inside.bitmask() & 0b111 == 0b111
    };
    let mut n = exits.steps(ray.lattice.t(k), far).min(limit - k.min(limit));
    while n > 0 && !in_box(field::cell4(grid, ray.ray.at4(ray.lattice.t(k + n)))) {
        n /= 2;
    }
    k + n
}

/// The last sample of the cell leaps starting at `ray.k`, a cell-model sample in the cell
/// whose low corner is `cell` (whole floats, [`field::cell4`]), at `distance` (at least 1) in
/// `leaps`: the last that stays in the cube of cells reaching `distance − 1` ahead of that
/// cell for the map's octant and in `slab`'s owned planes ([`last_short_of`]), then on from
/// the sample after it for as long as that sample is on the lattice, owned, and in a cell
/// the map calls empty: what a sample loop would do next, turn by turn. So the run ends
/// just before the first sample that is in a cell the map does not call empty or in a plane
/// `slab` does not own, whatever the estimates: they only decide how many turns that takes.
#[inline]
fn cell_leap<T: Sample>(
    ray: &RayState,
    slab: &Slab<'_, T>,
    leaps: &CellLeaps<'_>,
    mut cell: Vec4,
    mut distance: u8,
    exits: &Exits,
) -> u32 {
    let grid = slab.grid();
    let owned = OwnedFaces::of(slab);
    let mut k = ray.k;
    loop {
        let far = owned.clamp(cube_far(cell, distance, exits));
        let last = last_short_of(ray, k, grid, far, exits);
        let next = match last.checked_add(1) {
            Some(next) if next <= ray.lattice.last => next,
            _ => return last,
        };
        let landing = field::cell4(grid, ray.ray.at4(ray.lattice.t(next)));
        let lo = field::whole_lanes(landing);
        if !slab.owns(lo[0]) {
            return last;
        }
        match leaps.distance(lo) {
            0 => return last,
            d => (k, cell, distance) = (next, landing, d),
        }
    }
}

/// The far faces of the cube of cells a cell leap map's `distance` (at least 1) promises empty
/// ahead of the cell whose low corner is `cell`, for the octant `exits` moves in: `distance`
/// cells up from the cell's low face on each axis the ray moves up, or its lowest cell's low
/// face, `distance − 1` cells down, on every other.
#[inline]
fn cube_far(cell: Vec4, distance: u8, exits: &Exits) -> Vec4 {
    let d = f32::from(distance);
    cell + Vec4::select(exits.rising, Vec4::splat(d), Vec4::splat(1.0 - d))
}

/// The last sample from `ray.k` on (owned, at a parameter below `bound`) that is below
/// `bound` and in `slab`'s owned planes ([`last_short_of`]; every plane when the slab owns
/// them all). Its parameter is found from `bound`, then checked with the samples' own
/// arithmetic, which is monotone in the index. `exits` is found only where the owned planes'
/// faces are asked: a slab that owns every plane, as one node does, has none to find.
#[inline]
fn before_bound<T: Sample>(
    ray: &RayState,
    slab: &Slab<'_, T>,
    bound: f32,
    exits: &mut Option<Exits>,
) -> u32 {
    let (k, lattice) = (ray.k, &ray.lattice);
    let left = lattice.last - k.min(lattice.last);
    let owned = slab.owned();
    let left = match owned.start == 0 && owned.end >= slab.grid().dims()[0] {
        true => left,
        false => {
            let exits = exits.get_or_insert_with(|| Exits::new(ray));
            // The owned planes' faces along X; no face along the other axes.
            let far = OwnedFaces::of(slab).clamp(Vec4::select(
                exits.rising,
                Vec4::splat(f32::MAX),
                Vec4::splat(f32::MIN),
            ));
            last_short_of(ray, k, slab.grid(), far, exits) - k
        }
    };
    let estimate = ((bound - lattice.t(k)) / lattice.dt).max(0.0);
    let mut n = match estimate.is_finite() {
        true => (estimate as u32).min(left),
        false => left,
    };
    // The estimate errs by a step or two where it is finite: step back, then halve.
    let mut misses = 0;
    while n > 0 && !(lattice.t(k + n) < bound) {
        n = if misses < 3 { n - 1 } else { n / 2 };
        misses += 1;
    }
    k + n
}

/// The last sample of the leaps starting at `ray.k`, in `block`, whose leap map says every
/// block within `reach` ahead is empty: a [`skip_run`] over that box, then another from the
/// sample after it for as long as that sample is on the lattice, in `slab`'s planes and in a
/// block the map calls empty (distance at least 1). That is what a sample loop would do
/// next, turn by turn, with the same samples and verdicts ([`Verdict::of`] reads the same
/// distance, and a ray that has skipped may skip again: [`skip_to`] leaves it with nothing
/// pending, and [`View::may_skip`] asks no more). On a noisy volume most empty blocks have
/// one ahead that is not, so most leaps cross a single block, and a turn of the loop would
/// cost more than the leap itself.
#[inline]
fn leap<T: Sample>(
    ray: &RayState,
    slab: &Slab<'_, T>,
    blocks: &Blocks<'_>,
    mut block: (u32, u32, u32),
    mut reach: u32,
    model: Model,
) -> u32 {
    let grid = slab.grid();
    let mut k = ray.k;
    loop {
        let last = skip_run(ray, k, slab, blocks, block, reach, model);
        let next = match last.checked_add(1) {
            Some(next) if next <= ray.lattice.last => next,
            _ => return last,
        };
        let probe = Probe::of(ray, grid, model, next);
        if !slab.owns(probe.corner.plane()) {
            return last;
        }
        let landing = blocks.block_of(probe.corner.lo);
        match blocks.leap(landing).and_then(reach_of) {
            Some(ahead) => {
                block = landing;
                reach = ahead;
                k = next;
            }
            None => return last,
        }
    }
}

/// The last sample of the run starting at sample `k` (in `block`) that stays in `slab` and in
/// the blocks at most `reach` ahead of `block` along each axis (`blocks` serve the ray's
/// octant): every sample between lies there too, since positions, cells and owner planes are
/// monotone along the lattice, each axis the way the octant says, and those blocks form a
/// box. The exit point is only an estimate; each candidate is checked with the exact
/// arithmetic of the samples themselves, halving on failure.
fn skip_run<T: Sample>(
    ray: &RayState,
    k: u32,
    slab: &Slab<'_, T>,
    blocks: &Blocks<'_>,
    block: (u32, u32, u32),
    reach: u32,
    model: Model,
) -> u32 {
    let (mut lo, mut hi) = blocks.bounds(block, reach, model);
    // Nor past the owned planes (their faces, under the model's ownership rule).
    let shift = crate::skip::blocks::face_shift(model);
    let owned = slab.owned();
    lo.x = lo.x.max(owned.start as f32 - shift);
    hi.x = hi.x.min(owned.end as f32 - shift);
    let (o, d, t) = (ray.ray.origin, ray.ray.dir, ray.lattice.t(k));
    let mut t_out = f32::INFINITY;
    for a in 0..3 {
        if d[a] > 0.0 {
            t_out = t_out.min((hi[a] - o[a]) / d[a]);
        } else if d[a] < 0.0 {
            t_out = t_out.min((lo[a] - o[a]) / d[a]);
        }
    }
    let ahead = ((t_out - t) / ray.lattice.dt).max(0.0);
    let mut n = if ahead.is_finite() {
        (ahead as u32).min(ray.lattice.last - k.min(ray.lattice.last))
    } else {
        0
    };
    let grid = slab.grid();
    while n > 0 {
        let q = ray.ray.at4(ray.lattice.t(k + n));
        let at = field::corner4(grid, model, q);
        let landing = blocks.block_of(at.lo);
        // A leap lands only in a block the map itself calls empty: a voxel-model sample on
        // the grid's last X face reads a column past the blocks', whose range is unknown. Its
        // own block is in its box and empty, the common landing, so it is asked first.
        let lands = landing == block
            || (blocks.reaches(block, landing, reach)
                && blocks.leap(landing).is_some_and(|d| d > 0));
        if slab.owns(at.plane()) && lands {
            return k + n;
        }
        n /= 2;
    }
    k
}

//! Each node's storage for one view: its slab (loaded, or shifted to it by message), and the
//! empty-space skipping structures it builds for the view (min/max blocks, leap maps, cell
//! masks and leaps, depth bounds), in memory it owns, split across threads for speed.
//!
//! Invariant: skipping changes no pixel, and a node's structures are built from the planes it
//! stores alone, so they are the same bits however the build is split or where it runs.

use crate::memory::parts::{even_parts, run_parts, split_sizes, Part};
use crate::memory::ranges::{Classified, KeptMaps, SlabRanges, Verdicts};
use std::borrow::Cow;
use std::ops::Range;
use std::sync::Arc;
use voxcube_kernel::node::partition::Partition;
use voxcube_kernel::node::topology::Layout;
use voxcube_kernel::skip::node_leaps::NodeLeaps;
use voxcube_kernel::trace::view::View;
use voxcube_kernel::volume::grid::Grid;
use voxcube_kernel::volume::sample::SampleKind;
use voxcube_kernel::volume::slab::stored_planes;

/// How a node skips empty space: whether it does, whether its jumps leap over every empty
/// block around, and whether it skips single empty cells inside blocks that are not empty
/// (a debug option each; none changes a pixel).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SkipMode {
    /// Skip provably empty samples with min/max blocks.
    pub skip: bool,
    /// Leap by chessboard distances over empty blocks (only when skipping).
    pub leap: bool,
    /// Skip samples in empty cells of blocks that are not empty, by one view's cell masks
    /// (only when skipping, and in the cell model).
    pub cells: bool,
    /// Leap from empty cell to empty cell by distances between the cells the masks keep
    /// (only with cell masks; `voxcube_kernel::skip::cell_leaps`).
    pub cell_leaps: bool,
    /// Pass over the pixels of a row that a node certainly does not start, or that
    /// certainly miss, without setting up their rays (parallel projections only;
    /// `voxcube_kernel::trace::starts`).
    pub rows: bool,
    /// Pass a primary ray at once over the samples before its pixel's depth bound (only
    /// with cell masks, parallel projections; `voxcube_kernel::skip::depths`).
    pub depths: bool,
    /// Hold the fast tier's node field where the view reads one (`crate::memory::nodes`): not a
    /// skip, but an acceleration decided alike; without it the same lanes are computed on
    /// the fly.
    pub nodes: bool,
    /// Hold each cell's value range, built once per volume (`crate::memory::ranges`), so that a
    /// view's cell masks classify them; without them each view's masks read the nodes, the
    /// same bits.
    pub ranges: bool,
}

impl SkipMode {
    /// Every sample evaluated, every primary ray set up.
    pub const OFF: SkipMode = SkipMode {
        skip: false,
        leap: false,
        cells: false,
        cell_leaps: false,
        rows: false,
        depths: false,
        nodes: true,
        ranges: true,
    };
    /// Empty samples skipped by whole blocks, each jump ending at its block's faces.
    pub const BLOCKS: SkipMode = SkipMode {
        skip: true,
        leap: false,
        cells: false,
        cell_leaps: false,
        rows: true,
        depths: false,
        nodes: true,
        ranges: true,
    };
    /// Empty samples skipped by whole blocks, each jump leaping over every empty block around.
    pub const LEAPS: SkipMode = SkipMode {
        skip: true,
        leap: true,
        cells: false,
        cell_leaps: false,
        rows: true,
        depths: false,
        nodes: true,
        ranges: true,
    };
    /// Leaps, and single empty cells skipped too (the default).
    pub const ALL: SkipMode = SkipMode {
        skip: true,
        leap: true,
        cells: true,
        cell_leaps: true,
        rows: true,
        depths: true,
        nodes: true,
        ranges: true,
    };

    /// `view` as this mode renders it: without its row leaps when `rows` is off.
    pub fn view<'v>(&self, view: &'v View) -> Cow<'v, View> {
        if self.rows {
            Cow::Borrowed(view)
        } else {
            Cow::Owned(view.clone().without_row_leaps())
        }
    }
}

/// Whether a node skipping as `mode` says holds a node field for `view`: where the view reads
/// one ([`View::reads_node_field`]) and `mode` holds it. The one rule the budget and the builds
/// both follow.
pub fn holds_node_field(view: &View, mode: SkipMode) -> bool {
    mode.nodes && view.reads_node_field()
}

/// Bytes per grid node of the node field a node skipping as `mode` says holds for `view` over
/// samples of `kind` ([`holds_node_field`]; none where it holds none).
pub fn node_field_bytes(view: &View, mode: SkipMode, kind: SampleKind) -> usize {
    match holds_node_field(view, mode) {
        true => kind.node_bytes(),
        false => 0,
    }
}

/// Whether a node skipping as `mode` says builds cell masks for `view`: in the cell model.
pub fn has_cell_masks(view: &View, mode: SkipMode) -> bool {
    mode.skip && mode.cells && view.spec().model == voxcube_kernel::volume::grid::Model::Cell
}

/// Bytes per min/max block of the cells' ranges a node skipping as `mode` says holds for
/// `view` over samples of `kind`: where it builds cell masks and `mode` holds them; none
/// otherwise.
pub fn cell_range_bytes(view: &View, mode: SkipMode, kind: SampleKind) -> usize {
    use voxcube_kernel::skip::cell_ranges::BlockCells;
    match mode.ranges && has_cell_masks(view, mode) {
        true => match kind {
            SampleKind::U8 => size_of::<BlockCells<u8>>(),
            SampleKind::U16 => size_of::<BlockCells<u16>>(),
            SampleKind::I16 => size_of::<BlockCells<i16>>(),
            SampleKind::F32 => size_of::<BlockCells<f32>>(),
        },
        false => 0,
    }
}

/// Whether a node skipping as `mode` says takes depth bounds for `view`: with cell masks, in
/// the cell model, for a parallel projection.
pub fn has_depths(view: &View, mode: SkipMode) -> bool {
    let by_cell = view.spec().model == voxcube_kernel::volume::grid::Model::Cell;
    let parallel = matches!(
        view.spec().camera.projection(),
        voxcube_kernel::trace::camera::Projection::Orthographic { .. }
    );
    mode.skip && mode.cells && mode.depths && by_cell && parallel
}

/// Bytes of the depth bounds a node of a machine of `clusters` clusters holds for `view`,
/// skipping as `mode` says: a bound per pixel of its cluster's rows (the first cluster's,
/// which has the most), or none ([`has_depths`]).
pub fn depth_bytes(view: &View, mode: SkipMode, clusters: u16) -> usize {
    let rows = voxcube_kernel::node::topology::Rows::of_cluster(0, clusters);
    match (has_depths(view, mode), rows) {
        (true, Some(rows)) => {
            let (width, height) = (view.spec().width, view.spec().height);
            rows.count(height) as usize * width as usize * size_of::<f32>()
        }
        _ => 0,
    }
}

/// The octants whose cell leap maps a node skipping as `mode` says holds for `view`: the one
/// its primary rays take (transparency rays go on the same way), which trace nearly all
/// samples. Any ray of another octant, as shadow rays mostly are, leaps by blocks; one in
/// that octant, of whatever kind, leaps by the map. None without cell masks, which they
/// are built from, and none when the primary rays take several octants: each map costs a
/// pass over every cell, and each octant's rays are then only a share of the image.
/// None either where depth bounds pass the primary rays over the cells before their first
/// that shows and a cell holds fewer of their samples ([`samples_per_cell`]) than the map's
/// pass over every cell repays: for surfaces whose maps are built for each frame (`kept`
/// false, [`maps_kept`]) [`MAP_SAMPLES_PER_CELL`] (most such rays end at a crossing soon
/// after their bound), for kept maps and composited views, whose rays go on through the
/// volume after it, [`COMPOSITE_MAP_SAMPLES_PER_CELL`].
pub fn cell_leap_octants(view: &View, mode: SkipMode, kept: bool) -> u8 {
    let by_cell = view.spec().model == voxcube_kernel::volume::grid::Model::Cell;
    let primary = voxcube_kernel::skip::leaps::primary_octants(view);
    let surfaces = matches!(
        view.spec().mode,
        voxcube_kernel::trace::view::Mode::Surfaces(_)
    );
    let least = match surfaces && !kept {
        true => MAP_SAMPLES_PER_CELL,
        false => COMPOSITE_MAP_SAMPLES_PER_CELL,
    };
    let sparse = has_depths(view, mode) && samples_per_cell(view).is_some_and(|n| n < least);
    match mode.skip && mode.cells && mode.cell_leaps && by_cell && primary.count_ones() == 1 {
        true if !sparse => primary,
        _ => 0,
    }
}

/// The samples a cell must hold, on average, for a surfaces view with depth bounds to build
/// cell leap maps for each frame: below it the map's pass over every cell costs more than
/// the turns it saves. Timed on SOD over image sizes (docs/speed-log.md), the two are about
/// even at 16 a cell; the paper's view holds 8. Maps kept for later frames
/// ([`maps_kept`]) are taken as a composited view's are: the paper's view's further frame
/// then costs a fifth fewer instructions, its first about the same.
pub const MAP_SAMPLES_PER_CELL: f64 = 16.0;

/// Whether a surfaces view takes cell leap maps as one whose maps outlive the frame
/// ([`cell_leap_octants`]' `kept`): a byte volume's, whose verdicts on byte ranges views of
/// many transfer functions and iso values share, where its cells' value ranges are held
/// (`mode.ranges`). Other volumes keep their masks and maps for views of the same verdicts
/// too, but take maps only where one frame repays them: on the Marschner–Lobb function at
/// 128³, an orbit of four frames (each a new octant) took 27–39 ms a frame with maps taken
/// as kept, 17–29 ms without (docs/speed-log.md).
pub fn maps_kept(kind: SampleKind, mode: SkipMode) -> bool {
    kind == SampleKind::U8 && mode.ranges
}

/// The samples a cell must hold, on average, for a composited view with depth bounds to take
/// cell leap maps. A map's pass over every cell costs the same whatever the image, while what
/// it saves a frame follows the samples: on the molecule resampled to 512³ at 350×250 (0.34
/// samples a cell) a map saved 20–40 ms of a 300–360 ms frame and took 1.0–1.2 s to build,
/// some thirty frames' savings, so an orbit, which turns through four octants, lost by it; at
/// 256³ (1.37 a cell) it saved 55 ms of 215 for about 0.1 s (docs/speed-log.md).
pub const COMPOSITE_MAP_SAMPLES_PER_CELL: f64 = 1.0;

/// The octants (by index, ascending) whose bits `mask` sets: the order the maps of a set of
/// octants are stored in.
fn octants_of(mask: u8) -> impl Iterator<Item = usize> {
    (0..voxcube_kernel::skip::octant::OCTANTS).filter(move |o| mask >> o & 1 == 1)
}

/// How many of a parallel view's lattice samples a cell holds on average, over the rays
/// that cross it: a cell's world volume over the world area of a pixel times the step.
/// `None` for a perspective view, whose pixels' areas grow with depth.
pub fn samples_per_cell(view: &View) -> Option<f64> {
    let spec = view.spec();
    let voxcube_kernel::trace::camera::Projection::Orthographic { width } =
        spec.camera.projection()
    else {
        return None;
    };
    let pixel = f64::from(width) / f64::from(spec.width.max(1));
    let inv = view.inv_spacing();
    let cell = 1.0 / (f64::from(inv.x) * f64::from(inv.y) * f64::from(inv.z));
    Some(cell / (pixel * pixel * f64::from(spec.dt)))
}

/// A node's storage for skipping empty space in one view: its min/max blocks, their
/// chessboard distances ahead (a map per octant the view's rays take), their cell masks, the
/// distances between cells (a map per octant of the primary rays) and the pixels' depth
/// bounds, each empty when that acceleration is off.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Skipping {
    /// The volume's blocks for the slab, shared with every view's.
    ranges: Arc<Vec<voxcube_kernel::skip::blocks::Range>>,
    /// One leap map per octant in `octants`, in octant order.
    leaps: Vec<u8>,
    octants: u8,
    /// The view's masks, shared with the next view of the same verdicts.
    cells: Arc<Vec<voxcube_kernel::skip::cells::CellMask>>,
    /// One cell leap map per octant in `cell_octants`, in octant order, shared as `cells`.
    cell_leaps: Arc<Vec<u8>>,
    /// Where `cell_octants` is one octant: its map laid out as the slab's stored nodes
    /// (`node_leaps::NodeLeaps`), shared as `cells`.
    node_leaps: Arc<Vec<u8>>,
    cell_octants: u8,
    /// The view's depth bounds over the slab, a bound per pixel of the rows `depth_rows` of
    /// an image `depth_width` wide.
    depths: Vec<f32>,
    depth_rows: voxcube_kernel::node::topology::Rows,
    depth_width: u32,
    /// The octants of the view's primary rays: the blocks face them where they are one, so
    /// that those rays, nearly all, read them in place.
    primary: u8,
}

impl Skipping {
    /// Bytes of each structure held for the view, by name: leap maps, cell masks, cell leap
    /// maps and depth bounds (the min/max blocks it shares are the volume's,
    /// [`SlabRanges`]).
    pub fn bytes(&self) -> [(&'static str, usize); 4] {
        [
            ("leap maps", self.leaps.len()),
            ("cell masks", size_of_val(self.cells.as_slice())),
            (
                "cell leap maps",
                self.cell_leaps.len() + self.node_leaps.len(),
            ),
            ("depth bounds", size_of_val(self.depths.as_slice())),
        ]
    }

    /// The skipping storage of `slab` for `view` (`mode`): its blocks (`mode.skip`, from the
    /// slab's value `ranges`, built once per volume: [`super::built::Built::ranges`]), their
    /// distances for each octant of ray directions the view takes (`mode.leap`) and cell
    /// masks (`mode.cells`, cell model only), classified from the cells' ranges where
    /// `ranges` holds them, else read from the slab's nodes.
    pub fn build<T: voxcube_kernel::volume::sample::Sample + Sync>(
        slab: &voxcube_kernel::volume::slab::Slab<'_, T>,
        ranges: &SlabRanges<T>,
        view: &View,
        mode: SkipMode,
    ) -> Skipping {
        Skipping::build_on(slab, ranges, view, mode, 1)
    }

    /// [`Skipping::build`] with depth bounds for the image rows `rows` only: a node's, whose
    /// cluster traces those (`topology::Layout::cluster_rows`).
    pub fn build_for<T: voxcube_kernel::volume::sample::Sample + Sync>(
        slab: &voxcube_kernel::volume::slab::Slab<'_, T>,
        ranges: &SlabRanges<T>,
        view: &View,
        mode: SkipMode,
        rows: voxcube_kernel::node::topology::Rows,
    ) -> Skipping {
        Skipping::build_rows_on(slab, ranges, view, mode, 1, rows)
    }

    /// [`Skipping::build`] on up to `threads` OS threads: the masks split by block columns,
    /// each octant's distances (one pass over every block) beside the masks. The same bits:
    /// a column's masks depend on its own nodes only. A machine's start-up is on every
    /// frame's clock. The depth bounds cover every row: the in-process fabrics share a ring
    /// position's storage among its clusters, whose nodes read their own rows.
    pub fn build_on<T: voxcube_kernel::volume::sample::Sample + Sync>(
        slab: &voxcube_kernel::volume::slab::Slab<'_, T>,
        ranges: &SlabRanges<T>,
        view: &View,
        mode: SkipMode,
        threads: usize,
    ) -> Skipping {
        let all = voxcube_kernel::node::topology::Rows::ALL;
        Skipping::build_rows_on(slab, ranges, view, mode, threads, all)
    }

    fn build_rows_on<T: voxcube_kernel::volume::sample::Sample + Sync>(
        slab: &voxcube_kernel::volume::slab::Slab<'_, T>,
        ranges: &SlabRanges<T>,
        view: &View,
        mode: SkipMode,
        threads: usize,
        rows: voxcube_kernel::node::topology::Rows,
    ) -> Skipping {
        use voxcube_kernel::skip::blocks::Blocks;
        use voxcube_kernel::skip::minmax::extent;
        if !mode.skip {
            return Skipping::default();
        }
        let (_, _, len) = extent(slab);
        let Ok(blocks) = Blocks::new(slab.grid(), slab.stored(), &ranges.blocks) else {
            return Skipping::default();
        };
        // First the cell masks: without them no single cell is skipped. They are kept with
        // the ranges for the next view with the same verdicts, and their cell leap maps
        // beside them.
        let by_cell = has_cell_masks(view, mode);
        let held = ranges.holds_cells() && mode.ranges;
        let verdicts = (by_cell && held).then(|| match T::KIND {
            SampleKind::U8 => Verdicts::Bytes(Box::new(
                voxcube_kernel::skip::cells::ByteVerdicts::of(view),
            )),
            _ => Verdicts::Of(Box::new(view.emptiness())),
        });
        let kept = verdicts.as_ref().and_then(|v| ranges.kept(v));
        let cells = match (&kept, by_cell) {
            (Some(kept), _) => Arc::clone(&kept.masks),
            (None, true) => Arc::new(masks(slab, ranges, &blocks, view, held, threads)),
            (None, false) => Arc::default(),
        };
        // Which blocks keep a cell, a bit each, made once with the masks: the depth bounds
        // of every frame walk the columns by them rather than by every mask.
        let kept_bits = match &kept {
            Some(kept) => Arc::clone(&kept.kept_bits),
            None => Arc::new(which_keep_words(&cells, blocks.shape().1)),
        };
        // Then everything that reads the whole slab's blocks or masks, in one set of parts, in
        // this order: the depth bounds in parts of rows, a leap map for each octant the
        // view's rays take, and a cell leap map in parts of planes for each octant of the
        // primary rays.
        let octants = match mode.leap {
            true => voxcube_kernel::skip::leaps::octants(view),
            false => 0,
        };
        let maps = octants.count_ones() as usize;
        let mut leaps = vec![0; maps * len];
        let with_masks = blocks.with_cells(&cells).ok().filter(|_| !cells.is_empty());
        let cell_octants = match with_masks {
            Some(_) => {
                let kept = maps_kept(T::KIND, mode) && verdicts.is_some();
                cell_leap_octants(view, mode, kept)
            }
            None => 0,
        };
        let per_map = len * voxcube_kernel::skip::cell_leaps::PER_BLOCK;
        let kept_maps = kept
            .as_ref()
            .and_then(|kept| kept.maps.iter().find(|m| m.octants == cell_octants))
            .cloned();
        let building = match kept_maps {
            Some(_) => 0,
            None => cell_octants,
        };
        let mut cell_leaps = vec![0; building.count_ones() as usize * per_map];
        let (width, height) = (view.spec().width as usize, view.spec().height);
        let worded = with_masks.and_then(|blocks| blocks.with_kept(&kept_bits).ok());
        let bounded = worded.as_ref().filter(|_| has_depths(view, mode));
        let held = rows.count(height);
        let mut depths = match bounded {
            Some(_) => vec![0.0; held as usize * width],
            None => Vec::new(),
        };
        let mut jobs: Vec<Part<'_>> = Vec::new();
        // Depth bounds from the masks, where the view's rays are parallel and near enough:
        // the rows in parts, one a thread, each into its own piece of the map
        // (`depths::build_places`: the same bits). A part passes over the other parts' blocks
        // and cells at the cost of placing them on the rows; parts of block columns, each
        // with a map to merge, cost more than they saved at 1024×768.
        //
        // They go first: on SOD's paper view they are the longest parts, and the thread that
        // ends its part first then builds the leap map; with the map first, its thread would
        // take the second depth part after it and end well after the other.
        if let Some(with_masks) = bounded {
            let n = threads.clamp(1, held.max(1) as usize) as u32;
            let places = even_parts(held, n);
            let sizes: Vec<usize> = places.iter().map(|p| p.len() * width).collect();
            for (out, places) in split_sizes(&mut depths, sizes.into_iter()).zip(places) {
                jobs.push(Box::new(move || {
                    voxcube_kernel::skip::depths::build_places(with_masks, view, rows, places, out)
                        .is_ok()
                }));
            }
        }
        let depth_jobs = jobs.len();
        // A leap map, like the masks, depends on the blocks' verdicts alone: one kept for these
        // verdicts and an octant is copied, not built again.
        let chosen = octants_of(octants);
        for (map, octant) in leaps.chunks_mut(len).zip(chosen) {
            let held = kept.as_ref().and_then(|k| k.block_map(octant));
            if let Some(held) = held.filter(|held| held.len() == map.len()) {
                map.copy_from_slice(&held);
                jobs.push(Box::new(|| true));
                continue;
            }
            let (blocks, octant) = (
                &blocks,
                voxcube_kernel::skip::octant::Octant::from_index(octant),
            );
            jobs.push(Box::new(move || {
                voxcube_kernel::skip::leaps::build(blocks, view, octant, map).is_ok()
            }));
        }
        if let Some(with_masks) = &with_masks {
            let chosen = octants_of(building);
            // Each map in parts of planes, one a thread: a part is built with the planes ahead
            // of it that its distances depend on, and keeps its own. The parts even out what
            // each thread builds (`cell_leaps::part`).
            use voxcube_kernel::skip::cell_leaps::with_planes_ahead;
            use voxcube_kernel::skip::cell_leaps::{build_planes, part, plane_len, planes};
            let (all, plane) = (planes(with_masks), plane_len(with_masks));
            let n = threads.clamp(1, all.max(1));
            for (map, octant) in cell_leaps.chunks_mut(per_map).zip(chosen) {
                let octant = voxcube_kernel::skip::octant::Octant::from_index(octant);
                let parts: Vec<Range<usize>> = (0..n).map(|i| part(i, n, all, octant)).collect();
                let sizes: Vec<usize> = parts.iter().map(|p| p.len() * plane).collect();
                let pieces = split_sizes(map, sizes.into_iter());
                for (out, part) in pieces.zip(parts).filter(|(_, p)| !p.is_empty()) {
                    jobs.push(Box::new(move || {
                        let region = with_planes_ahead(part.clone(), all, octant);
                        if region == part {
                            return build_planes(with_masks, octant, part, out).is_ok();
                        }
                        let mut built = vec![0; region.len() * plane];
                        let at = (part.start - region.start) * plane;
                        let ok = build_planes(with_masks, octant, region, &mut built).is_ok();
                        match built.get(at..at + out.len()) {
                            Some(own) if ok => {
                                out.copy_from_slice(own);
                                true
                            }
                            _ => false,
                        }
                    }));
                }
            }
        }
        let built = run_parts(jobs, threads);
        let (depths_built, built) = built.split_at(depth_jobs);
        let (maps_built, cells_built) = built.split_at(maps);
        let (leaps, octants) = match maps_built.iter().all(|&b| b) {
            true => (leaps, octants),
            false => (Vec::new(), 0),
        };
        let (cell_leaps, cell_octants, node_leaps) =
            match (kept_maps, cells_built.iter().all(|&b| b)) {
                (Some(kept), _) => (kept.maps, kept.octants, kept.nodes),
                (None, true) if cell_octants != 0 => {
                    let nodes = with_masks
                        .as_ref()
                        .map(|blocks| node_layout(slab, blocks, &cell_leaps, cell_octants))
                        .unwrap_or_default();
                    (Arc::new(cell_leaps), cell_octants, Arc::new(nodes))
                }
                _ => (Arc::default(), 0, Arc::default()),
            };
        if let Some(verdicts) = verdicts {
            // Beside the maps kept for these verdicts: an orbit's frames turn through the
            // octants and come back to each, and every frame of one octant reads one map.
            let (mut maps, mut block_maps) = kept
                .map(|kept| (kept.maps, kept.block_maps))
                .unwrap_or_default();
            let new = cell_octants != 0 && maps.iter().all(|m| m.octants != cell_octants);
            if new && maps.len() < voxcube_kernel::skip::octant::OCTANTS {
                maps.push(KeptMaps {
                    octants: cell_octants,
                    maps: Arc::clone(&cell_leaps),
                    nodes: Arc::clone(&node_leaps),
                });
            }
            let chosen = octants_of(octants);
            for (map, octant) in leaps.chunks(len.max(1)).zip(chosen) {
                if block_maps.iter().all(|(o, _)| *o != octant) {
                    block_maps.push((octant, Arc::new(map.to_vec())));
                }
            }
            ranges.keep(Classified {
                verdicts,
                masks: Arc::clone(&cells),
                kept_bits: Arc::clone(&kept_bits),
                maps,
                block_maps,
            });
        }
        if !depths_built.iter().all(|&b| b) {
            depths = Vec::new();
        }
        Skipping {
            ranges: Arc::clone(&ranges.blocks),
            leaps,
            octants,
            cells,
            cell_leaps,
            cell_octants,
            node_leaps,
            depths,
            depth_rows: rows,
            depth_width: view.spec().width,
            primary: voxcube_kernel::skip::leaps::primary_octants(view),
        }
    }

    /// `slab`, skipping empty space with this storage (unchanged when it holds none).
    pub fn apply<'a, T: voxcube_kernel::volume::sample::Sample>(
        &'a self,
        slab: voxcube_kernel::volume::slab::Slab<'a, T>,
    ) -> voxcube_kernel::volume::slab::Slab<'a, T> {
        if self.ranges.is_empty() {
            return slab;
        }
        let Ok(blocks) =
            voxcube_kernel::skip::blocks::Blocks::new(slab.grid(), slab.stored(), &self.ranges)
        else {
            return slab;
        };
        let blocks = match blocks.with_leaps(&self.leaps, self.octants) {
            Ok(leaping) if self.octants != 0 => leaping,
            _ => blocks,
        };
        let blocks = match blocks.with_cells(&self.cells) {
            Ok(masked) if !self.cells.is_empty() => masked,
            _ => blocks,
        };
        let blocks = match blocks.with_cell_leaps(&self.cell_leaps, self.cell_octants) {
            Ok(leaping) if self.cell_octants != 0 => leaping,
            _ => blocks,
        };
        let blocks = match (sole_octant(self.cell_octants), self.node_leaps.is_empty()) {
            (Some(octant), false) => blocks.with_node_leaps(NodeLeaps::new(
                &self.node_leaps,
                slab.stored().start,
                octant,
            )),
            _ => blocks,
        };
        let blocks = match self.depths.is_empty() {
            true => blocks,
            false => blocks.with_depths(voxcube_kernel::skip::depths::Depths::new(
                &self.depths,
                self.depth_width,
                self.depth_rows,
            )),
        };
        let blocks = match sole_octant(self.primary) {
            Some(octant) => blocks.toward(octant),
            None => blocks,
        };
        slab.with_blocks(blocks)
    }
}

/// The octant of `octants` (a bit each) where they are one.
fn sole_octant(octants: u8) -> Option<voxcube_kernel::skip::octant::Octant> {
    (octants.count_ones() == 1).then(|| {
        voxcube_kernel::skip::octant::Octant::from_index(octants.trailing_zeros() as usize)
    })
}

/// The cell leap map in `maps` (of `octants`, with `blocks` and their masks) laid out as
/// `slab` stores its nodes, over its stored planes, where `octants` is one octant; none
/// otherwise (the marcher then reads the map in its own layout).
fn node_layout<T: voxcube_kernel::volume::sample::Sample>(
    slab: &voxcube_kernel::volume::slab::Slab<'_, T>,
    blocks: &voxcube_kernel::skip::blocks::Blocks<'_>,
    maps: &[u8],
    octants: u8,
) -> Vec<u8> {
    use voxcube_kernel::skip::cell_leaps::{fill_node_layout, CellLeaps};
    let Some(octant) = sole_octant(octants) else {
        return Vec::new();
    };
    let toward = blocks.toward(octant);
    let Ok(leaps) = CellLeaps::new(&toward, maps) else {
        return Vec::new();
    };
    let stored = slab.stored();
    let mut out = vec![0; stored.len() * slab.grid().plane_len()];
    match fill_node_layout(&leaps, slab.grid(), stored, &mut out) {
        Ok(()) => out,
        Err(_) => Vec::new(),
    }
}

/// The which-keep words of `masks` (columns of `ny` blocks, `skip::blocks::kept_bits`);
/// none for no masks, or where they do not fill whole columns.
fn which_keep_words(masks: &[voxcube_kernel::skip::cells::CellMask], ny: u32) -> Vec<u64> {
    use voxcube_kernel::skip::blocks::{kept_bits, kept_words};
    let columns = masks.len().checked_div(ny as usize).unwrap_or(0);
    let mut words = vec![0; columns * kept_words(ny)];
    match kept_bits(masks, ny, &mut words) {
        Ok(()) => words,
        Err(_) => Vec::new(),
    }
}

/// The cell masks of `slab` (`blocks` from its `ranges`) for `view`, in parts of the block
/// columns on up to `threads` OS threads (each part reads its own blocks' cells): classified
/// from the cells' ranges where they are `held`, else read from the nodes; none where a part
/// fails.
fn masks<T: voxcube_kernel::volume::sample::Sample + Sync>(
    slab: &voxcube_kernel::volume::slab::Slab<'_, T>,
    ranges: &SlabRanges<T>,
    blocks: &voxcube_kernel::skip::blocks::Blocks<'_>,
    view: &View,
    held: bool,
    threads: usize,
) -> Vec<voxcube_kernel::skip::cells::CellMask> {
    use voxcube_kernel::skip::cells;
    let per = voxcube_kernel::skip::blocks::column_len(slab.grid());
    let columns = blocks.shape().0;
    let parts = even_parts(columns, threads.clamp(1, columns.max(1) as usize) as u32);
    let sizes: Vec<usize> = parts.iter().map(|c| c.len() * per).collect();
    let mut masks = vec![0; ranges.blocks.len()];
    let jobs = split_sizes(&mut masks, sizes.iter().copied())
        .zip(parts)
        .map(|(out, cols)| -> Part<'_> {
            let own = cols.clone();
            let cells = ranges
                .cells
                .get(cols.start as usize * per..cols.end as usize * per);
            Box::new(move || match (held, cells) {
                (true, Some(cells)) => {
                    cells::classify_columns(cells, blocks, view, own, out).is_ok()
                }
                _ => cells::build_columns(slab, blocks, view, own, out).is_ok(),
            })
        })
        .collect();
    match run_parts(jobs, threads).into_iter().all(|built| built) {
        true => masks,
        false => Vec::new(),
    }
}

/// What every node of an in-process machine holds before its first message: its stored
/// planes, and the skipping storage of its ring position for the view.
#[derive(Debug)]
pub struct NodeStorage<'d, T: voxcube_kernel::volume::sample::Sample> {
    grid: Grid,
    layout: Layout,
    ghost: u32,
    /// Owned planes by ring position.
    planes: Vec<Range<u32>>,
    /// Stored planes by node id.
    storage: Vec<Cow<'d, [T]>>,
    /// By ring position: every cluster holds the same slab there.
    skipping: Vec<Skipping>,
    /// The node field by ring position, as `skipping`.
    fields: Vec<Arc<crate::memory::nodes::NodeField<T::Node>>>,
    /// The view's pre-integration table, lent to every node.
    segments: crate::memory::segments::SegmentTable,
}

impl<'d, T: voxcube_kernel::volume::sample::Sample + Sync> NodeStorage<'d, T> {
    /// Each node's stored planes: its own storage after a plane shift (`shifted`, by node
    /// id), else its slab of `partition` in `data`, which every cluster holds alike at a ring
    /// position. Nothing is skipped until [`NodeStorage::with_skipping`].
    pub fn new(
        grid: &Grid,
        layout: Layout,
        partition: &Partition,
        ghost: u32,
        data: &'d [T],
        shifted: Option<Vec<Vec<T>>>,
    ) -> NodeStorage<'d, T> {
        let plane = grid.plane_len();
        let planes: Vec<Range<u32>> = (0..partition.slabs())
            .map(|j| partition.planes(j))
            .collect();
        let storage = match shifted {
            Some(storages) => storages.into_iter().map(Cow::Owned).collect(),
            None => (0..layout.nodes() as u16)
                .map(|node| {
                    let j = usize::from(layout.place(node).1);
                    let s = stored_planes(grid, planes[j].clone(), ghost);
                    Cow::Borrowed(&data[s.start as usize * plane..s.end as usize * plane])
                })
                .collect(),
        };
        NodeStorage {
            grid: *grid,
            layout,
            ghost,
            planes,
            storage,
            skipping: Vec::new(),
            fields: Vec::new(),
            segments: Default::default(),
        }
    }

    /// The same storage, with the skipping storage and node field of each ring position for
    /// `view` (`mode`), built from cluster 0's node there on up to `threads` OS threads; the
    /// value ranges and fields taken from, or kept in, what the volume has `built`.
    pub fn with_skipping(
        mut self,
        view: &View,
        mode: SkipMode,
        threads: usize,
        built: &crate::memory::built::Built,
    ) -> NodeStorage<'d, T> {
        let slabs: Vec<_> = (0..self.layout.size())
            .map(|j| self.bare_slab(self.layout.node(0, j)).ok())
            .collect();
        let skipping = slabs
            .iter()
            .map(|s| {
                s.as_ref()
                    .map(|s| {
                        let cells = cell_range_bytes(view, mode, T::KIND) > 0;
                        let ranges = built.ranges(s, cells, threads);
                        Skipping::build_on(s, &ranges, view, mode, threads)
                    })
                    .unwrap_or_default()
            })
            .collect();
        let fields = slabs
            .iter()
            .map(|s| {
                s.as_ref()
                    .map(|s| built.field(s, holds_node_field(view, mode), threads))
                    .unwrap_or_default()
            })
            .collect();
        drop(slabs);
        self.skipping = skipping;
        self.fields = fields;
        self.segments = crate::memory::segments::SegmentTable::of(view);
        self
    }

    /// Node `node`'s slab, skipping empty space as its ring position's storage says.
    pub fn slab(
        &self,
        node: u16,
    ) -> Result<voxcube_kernel::volume::slab::Slab<'_, T>, voxcube_kernel::volume::slab::SlabError>
    {
        let j = usize::from(self.layout.place(node).1);
        let slab = self.skipping[j].apply(self.bare_slab(node)?);
        let slab = match self.fields.get(j) {
            Some(field) => field.apply(slab),
            None => slab,
        };
        Ok(self.segments.apply(slab))
    }

    fn bare_slab(
        &self,
        node: u16,
    ) -> Result<voxcube_kernel::volume::slab::Slab<'_, T>, voxcube_kernel::volume::slab::SlabError>
    {
        let j = usize::from(self.layout.place(node).1);
        voxcube_kernel::volume::slab::Slab::new(
            self.grid,
            self.planes[j].clone(),
            self.ghost,
            &self.storage[usize::from(node)],
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::dataset::VolumeData;
    use crate::input::scene::Scene;

    /// The default scene's molecule composited from `azimuth`, framed as the paper framed
    /// SOD.
    fn view_from(azimuth: f32) -> (crate::input::dataset::Volume, View) {
        let text = format!(
            "[[datasets]]\nname = \"m\"\nbuiltin = \"molecule\"\n[[datasets.views]]\nmode = \"composite\"\n[datasets.views.camera]\nazimuth = {azimuth:?}\nwidth = 175.0\n{}",
            crate::experiments::sod::COMPOSITE_TRANSFER
        );
        let mut jobs = Scene::parse(&text, "t.toml", std::path::Path::new("."))
            .and_then(Scene::load)
            .unwrap_or_else(|e| panic!("{e}"));
        let job = jobs.remove(0);
        let view = job.views.into_iter().next().map(|v| v.view);
        (job.volume, view.unwrap_or_else(|| panic!("a view")))
    }

    /// `view` on `grid` with its transfer function's control points moved `by` in value.
    fn shifted(view: &View, by: f32, grid: &Grid) -> View {
        use voxcube_kernel::optics::transfer::{ControlPoint, TransferFunction};
        use voxcube_kernel::trace::view::Mode;
        let mut spec = view.spec().clone();
        if let Mode::Composite(tf) = &spec.mode {
            let points: Vec<_> = tf
                .points()
                .iter()
                .map(|p| ControlPoint {
                    value: p.value + by,
                    ..*p
                })
                .collect();
            let tf = TransferFunction::new(&points).unwrap_or_else(|e| panic!("{e}"));
            spec.mode = Mode::Composite(tf);
        }
        View::new(spec, grid).unwrap_or_else(|e| panic!("{e}"))
    }

    #[test]
    fn frames_of_a_signed_or_float_volume_share_one_classification_and_another_function_its_own() {
        let (bytes, first) = view_from(45.0);
        let (_, turned) = view_from(135.0);
        let VolumeData::U8(data) = &bytes.data else {
            unreachable!("the molecule is bytes")
        };
        // The molecule in Hounsfield-like units, and as floats: the same verdicts on its
        // values shifted, by a transfer function shifted alike.
        let (first, turned) = (
            shifted(&first, -1000.0, &bytes.grid),
            shifted(&turned, -1000.0, &bytes.grid),
        );
        let words: Vec<i16> = data.iter().map(|&v| i16::from(v) - 1000).collect();
        let floats: Vec<f32> = words.iter().map(|&v| f32::from(v)).collect();
        fn check<T: voxcube_kernel::volume::sample::Sample + Sync>(
            grid: Grid,
            data: &[T],
            first: &View,
            turned: &View,
        ) {
            let slab = voxcube_kernel::volume::slab::Slab::whole(grid, data)
                .unwrap_or_else(|e| panic!("{e}"));
            let ranges = SlabRanges::build(&slab, true, 1);
            let a = Skipping::build(&slab, &ranges, first, SkipMode::ALL);
            let b = Skipping::build(&slab, &ranges, turned, SkipMode::ALL);
            let again = Skipping::build(&slab, &ranges, first, SkipMode::ALL);
            assert!(!a.cells.is_empty());
            assert!(
                Arc::ptr_eq(&a.cells, &b.cells),
                "{:?}: one classification",
                T::KIND
            );
            assert!(Arc::ptr_eq(&a.cell_leaps, &again.cell_leaps));
            // The same bits as a classification afresh.
            let fresh = Skipping::build(
                &slab,
                &SlabRanges::build(&slab, true, 1),
                first,
                SkipMode::ALL,
            );
            assert_eq!(fresh.cells, a.cells);
            assert_eq!(fresh.cell_leaps, a.cell_leaps);
            assert_eq!(fresh.leaps, a.leaps);
            // Another transfer function (clear up to a value 40 higher): masks of its own.
            let other = shifted(first, 40.0, &grid);
            let c = Skipping::build(&slab, &ranges, &other, SkipMode::ALL);
            assert!(!Arc::ptr_eq(&a.cells, &c.cells));
            assert_ne!(a.cells, c.cells, "the sweep's masks see the move");
        }
        check(bytes.grid, &words, &first, &turned);
        check(bytes.grid, &floats, &first, &turned);
    }

    #[test]
    fn an_orbit_s_frames_share_one_map_per_octant() {
        let (volume, first) = view_from(45.0);
        let (_, turned) = view_from(135.0);
        let VolumeData::U8(data) = &volume.data else {
            unreachable!("the molecule is bytes")
        };
        let slab = voxcube_kernel::volume::slab::Slab::whole(volume.grid, data)
            .unwrap_or_else(|e| panic!("{e}"));
        let ranges = SlabRanges::build(&slab, true, 1);
        let octant = |v: &View| cell_leap_octants(v, SkipMode::ALL, true);
        assert!(octant(&first) != 0 && octant(&turned) != 0);
        assert_ne!(
            octant(&first),
            octant(&turned),
            "the turn changes the octant"
        );
        let a = Skipping::build(&slab, &ranges, &first, SkipMode::ALL);
        let b = Skipping::build(&slab, &ranges, &turned, SkipMode::ALL);
        let again = Skipping::build(&slab, &ranges, &first, SkipMode::ALL);
        let back = Skipping::build(&slab, &ranges, &turned, SkipMode::ALL);
        assert!(Arc::ptr_eq(&a.cells, &b.cells), "one classification");
        assert!(!a.cell_leaps.is_empty() && !Arc::ptr_eq(&a.cell_leaps, &b.cell_leaps));
        // Back in an octant seen before: its map, not a new one, and the same bits as a map
        // built afresh.
        assert!(Arc::ptr_eq(&a.cell_leaps, &again.cell_leaps));
        assert!(Arc::ptr_eq(&a.node_leaps, &again.node_leaps));
        assert!(Arc::ptr_eq(&b.cell_leaps, &back.cell_leaps));
        let fresh = Skipping::build(
            &slab,
            &SlabRanges::build(&slab, true, 1),
            &first,
            SkipMode::ALL,
        );
        assert_eq!(fresh.cell_leaps, a.cell_leaps);
        assert_eq!(fresh.node_leaps, a.node_leaps);
        // The block leap maps too: one kept per octant, copied into a view of it.
        let verdicts = Verdicts::Bytes(Box::new(voxcube_kernel::skip::cells::ByteVerdicts::of(
            &first,
        )));
        let kept = ranges.kept(&verdicts).unwrap_or_else(|| panic!("kept"));
        assert_eq!(kept.block_maps.len(), 2);
        assert!(!a.leaps.is_empty());
        assert_eq!(again.leaps, a.leaps);
        assert_eq!(fresh.leaps, a.leaps);
        assert_eq!(back.leaps, b.leaps);
        assert_ne!(a.leaps, b.leaps);
    }
}

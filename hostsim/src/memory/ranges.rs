//! A slab's value ranges: its min/max blocks and each block's cells' ranges
//! (`voxcube_kernel::skip::cell_ranges`). They depend on the samples of its stored planes
//! alone, so they are built once per volume and set of stored planes ([`super::built`]); a
//! view's skipping ([`crate::memory::storage::Skipping`]) classifies them.
//!
//! A slab's cell masks and cell leap maps are a function of its cells' ranges and a view's
//! verdicts on ranges ([`Verdicts`]: for bytes, the verdict on every byte range; for other
//! samples, everything the view's verdict reads), so the last masks a view classified are
//! kept here too, with a cell leap map and a block leap map for each octant views of them
//! have taken, for the next view with the same verdicts: an orbit's next frame (its frames
//! turn through the octants and come back to each), a bench's next repetition, a view of
//! the same transfer function from elsewhere.
//!
//! Invariant: a build split over threads by block columns gives the same bits as one pass
//! (each column's blocks and cells read its own nodes only); a build that fails holds no
//! blocks, and a view then skips nothing; what is kept is handed out only for equal
//! verdicts.

use crate::memory::parts::{even_parts, run_parts, split_sizes, Part};
use std::sync::{Arc, Mutex, PoisonError};
use voxcube_kernel::skip::blocks::{column_len, Blocks, CellMask, Range};
use voxcube_kernel::skip::cell_ranges::{self, BlockCells};
use voxcube_kernel::skip::cells::ByteVerdicts;
use voxcube_kernel::trace::view::Emptiness;
use voxcube_kernel::volume::sample::Sample;
use voxcube_kernel::volume::slab::Slab;

/// A slab's min/max blocks and their cells' ranges, in the blocks' order; no cells where
/// they were not asked for, and neither where the build failed.
#[derive(Debug, Default)]
pub struct SlabRanges<T> {
    /// The blocks' ranges, shared with every view's skipping storage.
    pub blocks: Arc<Vec<Range>>,
    /// Each block's cells' ranges.
    pub cells: Vec<BlockCells<T>>,
    /// The last masks classified from them, with their cell and block leap maps.
    kept: Mutex<Option<Classified>>,
}

/// What a view's masks of a slab depend on besides the slab's ranges: two views with equal
/// verdicts give the same masks and leap maps, bit for bit.
#[derive(Clone, Debug, PartialEq)]
pub enum Verdicts {
    /// A byte volume's: the verdict on every range of byte values, which views with other
    /// transfer functions may share.
    Bytes(Box<ByteVerdicts>),
    /// Other samples': everything the view's verdict on a range reads (a kilobyte or so).
    Of(Box<Emptiness>),
}

/// A slab's cell masks for some verdicts, and the cell leap maps built from them.
#[derive(Clone, Debug)]
pub struct Classified {
    /// The verdicts they were classified by.
    pub verdicts: Verdicts,
    /// The masks, one per block.
    pub masks: Arc<Vec<CellMask>>,
    /// Their which-keep words (`voxcube_kernel::skip::blocks::kept_bits`).
    pub kept_bits: Arc<Vec<u64>>,
    /// The cell leap maps built from them, one set per set of octants views have taken
    /// (an orthographic view takes one octant: at most eight sets).
    pub maps: Vec<KeptMaps>,
    /// The blocks' leap maps for the same verdicts, one per octant ([`Octant::index`]) views
    /// have taken.
    ///
    /// [`Octant::index`]: voxcube_kernel::skip::octant::Octant::index
    pub block_maps: Vec<(usize, Arc<Vec<u8>>)>,
}

impl Classified {
    /// The blocks' leap map kept for octant `octant` ([`Classified::block_maps`]), if any.
    pub fn block_map(&self, octant: usize) -> Option<Arc<Vec<u8>>> {
        let (_, map) = self.block_maps.iter().find(|(o, _)| *o == octant)?;
        Some(Arc::clone(map))
    }
}

/// Cell leap maps kept with the masks they were built from.
#[derive(Clone, Debug)]
pub struct KeptMaps {
    /// The octants they serve, a bit each.
    pub octants: u8,
    /// A map per octant, in octant order.
    pub maps: Arc<Vec<u8>>,
    /// The map laid out as the slab's nodes (`voxcube_kernel::skip::node_leaps::NodeLeaps`),
    /// or none.
    pub nodes: Arc<Vec<u8>>,
}

impl<T: Sample + Sync> SlabRanges<T> {
    /// Those of `slab` (its cells' where `with_cells`), on up to `threads` OS threads, each
    /// a part of the block columns: first its blocks' ranges, then its cells', which read
    /// only its own blocks (`Blocks::of_columns`).
    pub fn build(slab: &Slab<'_, T>, with_cells: bool, threads: usize) -> SlabRanges<T> {
        let (x0, x1, len) = voxcube_kernel::skip::minmax::extent(slab);
        let per = column_len(slab.grid());
        let columns = x1 - x0;
        let parts = even_parts(columns, threads.clamp(1, columns.max(1) as usize) as u32);
        let sizes: Vec<usize> = parts.iter().map(|c| c.len() * per).collect();
        let mut blocks = vec![Range::UNKNOWN; len];
        let mut cells = match with_cells {
            true => vec![BlockCells::default(); len],
            false => Vec::new(),
        };
        let pieces = split_sizes(&mut blocks, sizes.iter().copied())
            .zip(split_sizes(&mut cells, sizes.iter().copied()));
        let jobs = pieces
            .zip(parts)
            .map(|((out, cells), cols)| -> Part<'_> {
                let cells = with_cells.then_some(cells);
                Box::new(move || {
                    if voxcube_kernel::skip::minmax::build_columns(slab, cols.clone(), out).is_err()
                    {
                        return false;
                    }
                    let Some(cells) = cells else {
                        return true;
                    };
                    let own = 0..cols.len() as u32;
                    Blocks::of_columns(slab.grid(), slab.stored(), cols, out)
                        .and_then(|part| cell_ranges::build_columns(slab, &part, own, cells))
                        .is_ok()
                })
            })
            .collect();
        match run_parts(jobs, threads).into_iter().all(|built| built) {
            true => SlabRanges {
                blocks: Arc::new(blocks),
                cells,
                kept: Mutex::default(),
            },
            false => SlabRanges::default(),
        }
    }

    /// The masks (and maps) kept for `verdicts`, if the last ones kept were classified by
    /// them.
    pub fn kept(&self, verdicts: &Verdicts) -> Option<Classified> {
        let kept = self.kept.lock().unwrap_or_else(PoisonError::into_inner);
        kept.as_ref().filter(|k| k.verdicts == *verdicts).cloned()
    }

    /// Keep `classified` in place of what was kept.
    pub fn keep(&self, classified: Classified) {
        *self.kept.lock().unwrap_or_else(PoisonError::into_inner) = Some(classified);
    }

    /// Whether it holds its cells' ranges.
    pub fn holds_cells(&self) -> bool {
        !self.cells.is_empty()
    }

    /// Bytes of the cells' ranges (the blocks' are [`crate::memory::storage::Skipping::bytes`]'s).
    pub fn cell_bytes(&self) -> usize {
        size_of_val(self.cells.as_slice())
    }
}

//! Min/max blocks for empty-space skipping: for each block of `BLOCK`³ cells, the least and
//! greatest value of its nodes, so every value the field takes inside the block (nearest or
//! trilinear) lies in that range.
//!
//! A node builds its blocks from its own stored planes into storage it provides. A block at
//! the slab's end, only part of whose planes the node stores, takes the range of the nodes it
//! stores: every value the field takes at a sample the node owns lies in it, since an owned
//! sample reads stored nodes only (with at least one ghost plane, as every view's slabs have,
//! its cell's far corner is stored), and the node asks its blocks about no other sample. A
//! block none of whose planes the node stores is marked unknown (an infinite range) and is
//! never skipped. The tracer skips a sample only when the block says it provably contributes
//! nothing, and skipping never changes an image; which samples a node skips is therefore free
//! to differ from node to node. Blocks may carry one view's chessboard distances ahead, one
//! map per octant of ray directions ([`crate::skip::leaps`]), so that a jump crosses every empty
//! block ahead at once, and one view's cell masks ([`crate::skip::cells`]), so that an empty cell
//! inside a block that is not empty is skipped too.

use crate::skip::bounds::Depths;
use crate::skip::node_leaps::NodeLeaps;
use crate::skip::octant::Octant;
use crate::volume::grid::Grid;
use crate::volume::grid::Model;
pub use crate::volume::sample::Range;
use core::fmt;
use glam::Vec3;

/// The blocks of a column whose masks keep a cell, in order along the column (rising or
/// falling), as `(index, mask)`: most blocks of a big volume keep none, and these are passed
/// over 64 at a time (a word of which-keep bits per 64 masks) instead of one by one. The
/// words are read from the column's [`kept_bits`] where the blocks carry them, else made
/// from its masks as the walk comes to them.
#[derive(Clone, Debug)]
pub struct KeptBlocks<'a> {
    column: &'a [CellMask],
    /// The column's which-keep words, where given: `column.len().div_ceil(64)` of them.
    words: Option<&'a [u64]>,
    rising: bool,
    /// Words of the column taken so far, in the order of the walk.
    taken: usize,
    /// Index in the column of bit 0 of `bits`.
    base: usize,
    /// Which blocks of the current word keep a cell and are yet to be yielded.
    bits: u64,
}

impl<'a> KeptBlocks<'a> {
    /// The blocks of `column` that keep a cell, by rising index where `rising`.
    pub fn new(column: &'a [CellMask], rising: bool) -> Self {
        KeptBlocks {
            column,
            words: None,
            rising,
            taken: 0,
            base: 0,
            bits: 0,
        }
    }
}

impl Iterator for KeptBlocks<'_> {
    type Item = (u32, CellMask);

    #[inline]
    fn next(&mut self) -> Option<(u32, CellMask)> {
        const WORD: usize = u64::BITS as usize;
        while self.bits == 0 {
            let words = self.column.len().div_ceil(WORD);
            if self.taken >= words {
                return None;
            }
            let word = match self.rising {
                true => self.taken,
                false => words - 1 - self.taken,
            };
            self.taken += 1;
            self.base = word * WORD;
            self.bits = match self.words {
                Some(words) => words.get(word).copied().unwrap_or(0),
                None => word_of(self.column.get(self.base..).unwrap_or(&[])),
            };
        }
        let bit = match self.rising {
            true => self.bits.trailing_zeros(),
            false => u64::BITS - 1 - self.bits.leading_zeros(),
        };
        self.bits &= !(1u64 << bit);
        let index = self.base + bit as usize;
        let mask = self.column.get(index).copied().unwrap_or(0);
        Some((u32::try_from(index).unwrap_or(u32::MAX), mask))
    }
}

/// Bit `i` set where the `i`-th of (up to) the first 64 `masks` keeps a cell.
#[inline]
fn word_of(masks: &[CellMask]) -> u64 {
    masks
        .iter()
        .take(u64::BITS as usize)
        .enumerate()
        .fold(0, |bits, (i, &mask)| bits | u64::from(mask != 0) << i)
}

/// Which-keep words per column of `ny` blocks ([`kept_bits`]).
pub fn kept_words(ny: u32) -> usize {
    (ny as usize).div_ceil(u64::BITS as usize)
}

/// Bytes of the which-keep words ([`kept_bits`]) of the masks of a slab storing planes
/// `stored` of `grid`: for a node's budget.
pub fn kept_bytes(grid: &Grid, stored: core::ops::Range<u32>) -> usize {
    let [_, ny, nz] = grid.dims();
    let (x0, x1, _) = extent_for(grid, stored);
    (x1 - x0) as usize * count(nz) as usize * kept_words(count(ny)) * size_of::<u64>()
}

/// Fill `out` with the which-keep words of `masks` (a slab's, in storage order, columns of
/// `ny` blocks): [`kept_words`] per column, bit `i` of a column's word `w` set where its block
/// `64·w + i` keeps a cell. They depend on the masks alone, so they are made once with them
/// and read by every later walk over the columns ([`KeptBlocks`]) instead of every mask.
pub fn kept_bits(masks: &[CellMask], ny: u32, out: &mut [u64]) -> Result<(), BlocksError> {
    let per = kept_words(ny);
    let columns = masks.len().checked_div(ny as usize).unwrap_or(0);
    BlocksError::check_storage(columns * per, out.len())?;
    for (column, words) in masks
        .chunks_exact(ny.max(1) as usize)
        .zip(out.chunks_exact_mut(per.max(1)))
    {
        for (i, word) in words.iter_mut().enumerate() {
            *word = word_of(column.get(i * u64::BITS as usize..).unwrap_or(&[]));
        }
    }
    Ok(())
}

/// Cells per block edge.
pub const BLOCK: u32 = 4;

/// Cells in a block.
pub const PER_BLOCK: usize = (BLOCK * BLOCK * BLOCK) as usize;

/// One bit per cell of a block: bit `x + 4·y + 16·z` for the cell at offset `(x, y, z)` from
/// the block's low corner.
pub type CellMask = u64;

/// Every cell may show: what a block says without a mask.
pub const ALL: CellMask = CellMask::MAX;

/// Y nodes of a line of blocks gathered at a time by [`Blocks::build`] (sixteen blocks), on
/// the stack: the kernel's memory stays fixed for any grid.
pub(crate) const GATHER: usize = 16 * BLOCK as usize;

/// Why blocks cannot be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BlocksError {
    /// Storage of the wrong length.
    Storage {
        /// Entries needed.
        needed: usize,
        /// Entries given.
        given: usize,
    },
    /// Block columns `start..end` asked for, past the slab's `columns`.
    Columns {
        /// First column asked for (from the slab's first).
        start: u32,
        /// One past the last.
        end: u32,
        /// The slab's block columns.
        columns: u32,
    },
}

impl fmt::Display for BlocksError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            BlocksError::Storage { needed, given } => write!(
                f,
                "block storage holds {given} ranges, the slab needs {needed}"
            ),
            BlocksError::Columns {
                start,
                end,
                columns,
            } => write!(
                f,
                "block columns {start}..{end} asked for, the slab has {columns}"
            ),
        }
    }
}

impl core::error::Error for BlocksError {}

impl BlocksError {
    /// `Ok` when storage of `given` entries holds the `needed`.
    pub fn check_storage(needed: usize, given: usize) -> Result<(), BlocksError> {
        match given == needed {
            true => Ok(()),
            false => Err(BlocksError::Storage { needed, given }),
        }
    }
}

/// One block of [`Blocks::entry`], its index found once. Each of its facts is a read of its
/// own table, made when asked: on a volume larger than the caches each read is a miss, and a
/// block that the leap map says is empty needs neither its range nor its cells.
#[derive(Clone, Copy, Debug)]
pub struct Entry<'b, 'a> {
    blocks: &'b Blocks<'a>,
    /// The block's index in every table; `None` outside the slab's columns.
    index: Option<usize>,
}

impl Entry<'_, '_> {
    /// Its range ([`Blocks::range`]).
    #[inline]
    pub fn range(&self) -> Range {
        self.index
            .and_then(|i| self.blocks.data.get(i).copied())
            .unwrap_or(Range::UNKNOWN)
    }

    /// Its chessboard distance, when the blocks carry a leap map ([`Blocks::leap`]).
    #[inline]
    pub fn leap(&self) -> Option<u8> {
        let leaps = self.blocks.leaps?;
        Some(self.index.and_then(|i| leaps.get(i).copied()).unwrap_or(0))
    }

    /// Its cells the view cannot skip ([`Blocks::cells`]).
    #[inline]
    pub fn cells(&self) -> CellMask {
        match (self.index, self.blocks.cells) {
            (Some(i), Some(cells)) => cells.get(i).copied().unwrap_or(ALL),
            _ => ALL,
        }
    }
}

/// A slab's blocks: global block columns `[x0, x1)` × all Y × all Z.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Blocks<'a> {
    data: &'a [Range],
    /// One view's leap maps ([`crate::skip::leaps`]), one per octant in `octants` (in octant order),
    /// one after the other.
    maps: &'a [u8],
    octants: u8,
    /// The octant whose rays the marcher traces, and its leap map when there is one: its
    /// rays may leap.
    toward: Octant,
    leaps: Option<&'a [u8]>,
    /// One view's cell masks ([`crate::skip::cells`]), when the marcher may skip single cells.
    cells: Option<&'a [CellMask]>,
    /// Their which-keep words ([`kept_bits`]), where the host made them.
    kept: Option<&'a [u64]>,
    /// One view's cell leap maps ([`crate::skip::cell_leaps`]), one per octant in `cell_octants`,
    /// and the one of the octant traced, when there is one.
    cell_maps: &'a [u8],
    cell_octants: u8,
    cell_leaps: Option<&'a [u8]>,
    /// One octant's cell leap map laid out as the slab's nodes, where the host gave one.
    node_leaps: Option<NodeLeaps<'a>>,
    /// One view's depth bounds ([`crate::skip::depths`]), a bound per pixel of the rows held, when
    /// its primary rays may pass over the samples before them.
    depths: Option<Depths<'a>>,
    x0: u32,
    x1: u32,
    ny: u32,
    nz: u32,
}

/// How far below an integer coordinate `i` the points reading cell or node `i` begin under
/// `model`: a voxel-model node is read from half a unit before it, a cell from its corner.
pub fn face_shift(model: Model) -> f32 {
    match model {
        Model::Voxel => 0.5,
        Model::Cell => 0.0,
    }
}

/// Blocks along an axis of `n` nodes (`n − 1` cells, at least one block).
pub(crate) fn count(n: u32) -> u32 {
    n.saturating_sub(1).div_ceil(BLOCK).max(1)
}

/// The nodes of block `b` along an axis of `n` nodes: its cells' corners, so neighbouring
/// blocks share a plane of nodes.
pub(crate) fn nodes(b: u32, n: u32) -> core::ops::Range<u32> {
    b * BLOCK..((b + 1) * BLOCK).min(n.saturating_sub(1)) + 1
}

/// The global block columns the stored planes `stored` of `grid` touch, and the storage
/// their blocks need (also before any slab exists, for budgets).
pub fn extent_for(grid: &Grid, stored: core::ops::Range<u32>) -> (u32, u32, usize) {
    let [nx, ny, nz] = grid.dims();
    let x0 = (stored.start / BLOCK).min(count(nx) - 1);
    let x1 = (stored.end.saturating_sub(1) / BLOCK + 1)
        .min(count(nx))
        .max(x0 + 1);
    (
        x0,
        x1,
        (x1 - x0) as usize * count(ny) as usize * count(nz) as usize,
    )
}

/// Blocks in one block column of `grid` (one block along X, every Y and Z): the unit in
/// which a build may be split.
pub fn column_len(grid: &Grid) -> usize {
    let [_, ny, nz] = grid.dims();
    count(ny) as usize * count(nz) as usize
}

/// `Ok` when `columns` are block columns of a slab with `slab_columns` of them.
pub(crate) fn check_columns(
    columns: &core::ops::Range<u32>,
    slab_columns: u32,
) -> Result<(), BlocksError> {
    match columns.start <= columns.end && columns.end <= slab_columns {
        true => Ok(()),
        false => Err(BlocksError::Columns {
            start: columns.start,
            end: columns.end,
            columns: slab_columns,
        }),
    }
}

impl<'a> Blocks<'a> {
    /// The blocks in `data`, filled by [`crate::skip::minmax::build`] for a slab storing the
    /// planes `stored` of `grid`.
    pub fn new(
        grid: &Grid,
        stored: core::ops::Range<u32>,
        data: &'a [Range],
    ) -> Result<Blocks<'a>, BlocksError> {
        let (x0, x1, _) = extent_for(grid, stored.clone());
        Blocks::of_columns(grid, stored, 0..x1 - x0, data)
    }

    /// The global block coordinates of the cell or node a sample reads, whose low corner is
    /// `lo` ([`Site::lo`](crate::volume::field::Site::lo)): what [`Blocks::at`] reads. Monotone along a ray, as the corners
    /// are.
    #[inline]
    pub fn block_of(&self, lo: [u32; 3]) -> (u32, u32, u32) {
        // A voxel-model node on the grid's last face belongs to the last block (X needs no
        // clamp: a column past the slab's reads as unknown).
        let [x, y, z] = lo;
        (
            x / BLOCK,
            (y / BLOCK).min(self.ny - 1),
            (z / BLOCK).min(self.nz - 1),
        )
    }

    /// The index-space box of the blocks that rays of [`Blocks::toward`]'s octant reach from
    /// block `(bx, by, bz)` going at most `reach` blocks ahead along each axis, under `model`,
    /// for estimating where a ray leaves it (the estimate is always checked exactly).
    pub fn bounds(&self, block: (u32, u32, u32), reach: u32, model: Model) -> (Vec3, Vec3) {
        // Per axis, the first and last block of the box.
        let span = |axis: usize, b: u32| self.toward.span(axis, b, reach);
        let spans = [span(0, block.0), span(1, block.1), span(2, block.2)];
        let face = |b: u32| b as f32 * BLOCK as f32 - face_shift(model);
        let lo = Vec3::from_array(spans.map(|(first, _)| face(first)));
        let hi = Vec3::from_array(spans.map(|(_, last)| face(last.saturating_add(1))));
        (lo, hi)
    }

    /// Whether block `to` lies in the box of [`Blocks::bounds`] around `from`: at most `reach`
    /// blocks ahead of it along each axis, and nowhere behind.
    #[inline]
    pub fn reaches(&self, from: (u32, u32, u32), to: (u32, u32, u32), reach: u32) -> bool {
        // `t` in `Octant::span(axis, f, reach)`, without its saturating ends: every leap's
        // landing asks, so the saturation is paid once a leap.
        let ahead = |axis: usize, f: u32, t: u32| match self.toward.down(axis) {
            true => t <= f && f - t <= reach,
            false => t >= f && t - f <= reach,
        };
        ahead(0, from.0, to.0) && ahead(1, from.1, to.1) && ahead(2, from.2, to.2)
    }

    /// The range of the block holding the cell (or node) whose low corner is `lo`
    /// ([`Site::lo`](crate::volume::field::Site::lo); unknown outside the slab's columns).
    #[inline]
    pub fn at(&self, lo: [u32; 3]) -> Range {
        // The cell (cell model) or node (voxel model) the point reads, then its block; a node
        // on a block's upper face belongs to both blocks, and both include it.
        self.range(self.block_of(lo))
    }

    /// The range of block `(bx, by, bz)` (global block coordinates; unknown outside).
    #[inline]
    pub fn range(&self, block: (u32, u32, u32)) -> Range {
        self.index(block)
            .and_then(|i| self.data.get(i).copied())
            .unwrap_or(Range::UNKNOWN)
    }

    /// Where block `(bx, by, bz)` sits in the storage order (X columns slowest, then Z, then
    /// Y), or `None` outside the slab's columns.
    #[inline]
    fn index(&self, (bx, by, bz): (u32, u32, u32)) -> Option<usize> {
        if bx < self.x0 || bx >= self.x1 {
            return None;
        }
        Some(
            ((bx - self.x0) as usize * self.nz as usize + bz as usize) * self.ny as usize
                + by as usize,
        )
    }

    /// Every block's range, in storage order.
    pub fn ranges(&self) -> &'a [Range] {
        self.data
    }

    /// The ranges of block columns `columns` (counted from the slab's first), in storage order.
    pub fn columns(&self, columns: core::ops::Range<u32>) -> Result<&'a [Range], BlocksError> {
        check_columns(&columns, self.x1 - self.x0)?;
        let len = (self.ny * self.nz) as usize;
        Ok(&self.data[columns.start as usize * len..columns.end as usize * len])
    }

    /// The blocks of block columns `columns` (counted from the first) of a slab storing the
    /// planes `stored` of `grid`, in `data`, filled for them by
    /// [`crate::skip::minmax::build_columns`]: a part of the slab's blocks, whose first
    /// column is the first of `columns`, for work on those columns alone (their cell masks,
    /// built right after their ranges, with no wait for the other columns').
    pub fn of_columns(
        grid: &Grid,
        stored: core::ops::Range<u32>,
        columns: core::ops::Range<u32>,
        data: &'a [Range],
    ) -> Result<Blocks<'a>, BlocksError> {
        let (x0, x1, _) = extent_for(grid, stored);
        check_columns(&columns, x1 - x0)?;
        BlocksError::check_storage(columns.len() * column_len(grid), data.len())?;
        let [_, ny, nz] = grid.dims();
        Ok(Blocks {
            data,
            maps: &[],
            octants: 0,
            toward: Octant::default(),
            leaps: None,
            cells: None,
            kept: None,
            cell_maps: &[],
            cell_octants: 0,
            cell_leaps: None,
            node_leaps: None,
            depths: None,
            x0: x0 + columns.start,
            x1: x0 + columns.end,
            ny: count(ny),
            nz: count(nz),
        })
    }

    /// Blocks along X (the slab's columns), Y and Z.
    pub fn shape(&self) -> (u32, u32, u32) {
        (self.x1 - self.x0, self.ny, self.nz)
    }

    /// The global X coordinate of the slab's first block column.
    pub fn first_column(&self) -> u32 {
        self.x0
    }

    /// The same blocks, leaping by the maps in `maps`: one per octant in `octants` (bit
    /// [`Octant::index`]), in octant order ([`crate::skip::leaps::build`] for the view being traced:
    /// a map built for another view may skip samples that show). Tracing octant 0 until
    /// [`Blocks::toward`] says otherwise.
    pub fn with_leaps(self, maps: &'a [u8], octants: u8) -> Result<Blocks<'a>, BlocksError> {
        BlocksError::check_storage(self.data.len() * octants.count_ones() as usize, maps.len())?;
        Ok(Blocks {
            maps,
            octants,
            ..self
        }
        .toward(Octant::default()))
    }

    /// The same blocks, for tracing rays of `octant`: they leap by its map, or by none when
    /// the blocks hold none for it.
    #[inline]
    pub fn toward(self, octant: Octant) -> Blocks<'a> {
        // Maps of `len` bytes, one per octant in `octants`, in octant order: this octant's.
        let of = |maps: &'a [u8], octants: u8, len: usize| {
            let bit = 1u8 << octant.index();
            let rank = (octants & (bit - 1)).count_ones() as usize;
            match octants & bit {
                0 => None,
                _ => maps.get(rank * len..(rank + 1) * len),
            }
        };
        let len = self.data.len();
        let leaps = of(self.maps, self.octants, len);
        let cell_leaps = of(self.cell_maps, self.cell_octants, len * PER_BLOCK);
        Blocks {
            toward: octant,
            leaps,
            cell_leaps,
            ..self
        }
    }

    /// The same blocks, leaping cell by cell by the maps in `maps`: one per octant in
    /// `octants`, in octant order ([`crate::skip::cell_leaps::build`] from the cell masks of the view
    /// being traced, like a leap map). An octant left out leaps by blocks and scans cells.
    pub fn with_cell_leaps(self, maps: &'a [u8], octants: u8) -> Result<Blocks<'a>, BlocksError> {
        let per_map = self.data.len() * PER_BLOCK;
        BlocksError::check_storage(per_map * octants.count_ones() as usize, maps.len())?;
        Ok(Blocks {
            cell_maps: maps,
            cell_octants: octants,
            ..self
        }
        .toward(self.toward))
    }

    /// The cell leap map of [`Blocks::toward`]'s octant, when the blocks carry one (read it
    /// with [`crate::skip::cell_leaps::CellLeaps::of`]).
    #[inline]
    pub fn cell_leap_map(&self) -> Option<&'a [u8]> {
        self.cell_leaps
    }

    /// The same blocks, with `map`: the cell leap map of its octant laid out as the slab's
    /// nodes ([`crate::skip::cell_leaps::fill_node_layout`]).
    pub fn with_node_leaps(self, map: NodeLeaps<'a>) -> Blocks<'a> {
        Blocks {
            node_leaps: Some(map),
            ..self
        }
    }

    /// The cell leap map laid out as the slab's nodes, when the blocks carry one for
    /// [`Blocks::toward`]'s octant and a cell leap map for it too.
    #[inline]
    pub fn node_leaps(&self) -> Option<NodeLeaps<'a>> {
        self.node_leaps
            .filter(|map| map.octant() == self.toward && self.cell_leaps.is_some())
    }

    /// The same blocks, with the depth bounds `depths` ([`crate::skip::depths::build`] from these
    /// blocks' masks for the view being traced, like a leap map).
    pub fn with_depths(self, depths: Depths<'a>) -> Blocks<'a> {
        Blocks {
            depths: Some(depths),
            ..self
        }
    }

    /// The depth bounds, when the blocks carry them.
    #[inline]
    pub fn depths(&self) -> Option<Depths<'a>> {
        self.depths
    }

    /// The octant whose rays these blocks serve.
    pub fn octant(&self) -> Octant {
        self.toward
    }

    /// The same blocks, skipping single cells by the masks in `cells` ([`crate::skip::cells::build`]
    /// for the view being traced, like a leap map).
    pub fn with_cells(self, cells: &'a [CellMask]) -> Result<Blocks<'a>, BlocksError> {
        BlocksError::check_storage(self.data.len(), cells.len())?;
        Ok(Blocks {
            cells: Some(cells),
            // Words made from other masks say nothing of these.
            kept: None,
            ..self
        })
    }

    /// All that block `(bx, by, bz)` holds, found at one index: [`Blocks::range`],
    /// [`Blocks::leap`] and [`Blocks::cells`], each read when asked, for the marcher
    /// entering a block.
    #[inline]
    pub fn entry(&self, block: (u32, u32, u32)) -> Entry<'_, 'a> {
        Entry {
            blocks: self,
            index: self.index(block),
        }
    }

    /// Every block's cell mask, in storage order, when the blocks carry masks.
    pub fn masks(&self) -> Option<&'a [CellMask]> {
        self.cells
    }

    /// The masks of the blocks of column `(bx, bz)`, by `by`: a column's blocks are together
    /// in the storage order. Empty without masks or outside the slab's columns.
    pub fn column_masks(&self, bx: u32, bz: u32) -> &'a [CellMask] {
        let (Some(cells), Some(start)) = (self.cells, self.index((bx, 0, bz))) else {
            return &[];
        };
        cells.get(start..start + self.ny as usize).unwrap_or(&[])
    }

    /// The blocks of column `(bx, bz)` that keep a cell, as `(by, mask)`, by rising `by`
    /// where `rising`, else by falling: [`KeptBlocks`]. None without masks or outside the
    /// slab's columns.
    pub fn kept_in_column(&self, bx: u32, bz: u32, rising: bool) -> KeptBlocks<'a> {
        let column = self.column_masks(bx, bz);
        let per = kept_words(self.ny);
        let words = match (self.kept, self.index((bx, 0, bz))) {
            (Some(kept), Some(start)) if !column.is_empty() => {
                let first = start / self.ny.max(1) as usize * per;
                kept.get(first..first + per)
            }
            _ => None,
        };
        KeptBlocks {
            words,
            ..KeptBlocks::new(column, rising)
        }
    }

    /// The same blocks, their masks' which-keep words ([`kept_bits`] of them) read by
    /// [`Blocks::kept_in_column`]; refused where `kept` is not as long as their masks' words
    /// (none without masks).
    pub fn with_kept(self, kept: &'a [u64]) -> Result<Blocks<'a>, BlocksError> {
        let masks = self.cells.map_or(0, <[CellMask]>::len);
        let columns = masks.checked_div(self.ny as usize).unwrap_or(0);
        BlocksError::check_storage(columns * kept_words(self.ny), kept.len())?;
        Ok(Blocks {
            kept: Some(kept),
            ..self
        })
    }

    /// The cells of block `(bx, by, bz)` the view cannot skip: every cell without masks or
    /// outside the slab's columns.
    #[inline]
    pub fn cells(&self, block: (u32, u32, u32)) -> CellMask {
        self.cells
            .and_then(|cells| cells.get(self.index(block)?).copied())
            .unwrap_or(ALL)
    }

    /// Block `(bx, by, bz)`'s chessboard distance to the nearest block ahead, for rays of
    /// [`Blocks::toward`]'s octant, that the view cannot skip (0 outside the slab's columns),
    /// or `None` without a leap map for that octant.
    #[inline]
    pub fn leap(&self, block: (u32, u32, u32)) -> Option<u8> {
        let leaps = self.leaps?;
        Some(
            self.index(block)
                .and_then(|i| leaps.get(i).copied())
                .unwrap_or(0),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::counters::Counters;
    use crate::skip::minmax::extent;
    use crate::volume::field;
    use crate::volume::grid::Grid;
    use crate::volume::sample::Sample;
    use crate::volume::slab::Slab;

    #[test]
    fn every_field_value_a_slab_owns_lies_in_its_block() {
        let grid = Grid::new([9, 7, 6], Vec3::ONE).unwrap();
        let data: [u8; 9 * 7 * 6] = core::array::from_fn(|i| (i * 37 % 251) as u8);
        let plane = grid.plane_len();
        let mut c = Counters::default();
        let mut checked = 0;
        // The whole volume, and slabs whose end blocks the slab stores only in part: those
        // blocks hold the range of their stored nodes, which every owned sample reads.
        for (owned, ghost) in [
            (0..9, 0),
            (0..5, 1),
            (5..9, 1),
            (2..6, 1),
            (1..3, 2),
            (6..7, 1),
        ] {
            let stored = crate::volume::slab::stored_planes(&grid, owned.clone(), ghost);
            let part = &data[stored.start as usize * plane..stored.end as usize * plane];
            let slab = Slab::new(grid, owned, ghost, part).unwrap();
            let mut storage = [Range::UNKNOWN; 3 * 2 * 2];
            let (_, _, n) = extent(&slab);
            crate::skip::minmax::build(&slab, &mut storage[..n]).unwrap();
            let blocks = Blocks::new(slab.grid(), slab.stored(), &storage[..n]).unwrap();
            for i in 0..400 {
                let p = Vec3::new(
                    (i % 17) as f32 * 0.5,
                    (i % 13) as f32 * 0.47,
                    (i % 11) as f32 * 0.46,
                );
                for model in [Model::Cell, Model::Voxel] {
                    let site = field::locate(&grid, model, p);
                    if !slab.owns(site.plane()) {
                        continue;
                    }
                    let v = field::value(&slab, model, p, &mut c);
                    let r = blocks.at(site.lo);
                    assert!(r.min <= v && v <= r.max, "{p} {model:?}: {v} outside {r:?}");
                    checked += 1;
                }
            }
        }
        assert_eq!(c.slab_misses, 0);
        assert!(checked > 2000, "{checked} samples checked");
    }

    /// A block's range by definition: the least and greatest of its nodes (the corners of
    /// its cells, `4b ..= 4b + 4` on each axis, cut at the grid's last node) that the slab
    /// stores, or unknown when it stores none of them.
    fn defined<T: Sample>(slab: &Slab<'_, T>, block: [u32; 3]) -> Range {
        let dims = slab.grid().dims();
        let span = |a: usize| block[a] * BLOCK..=(block[a] * BLOCK + BLOCK).min(dims[a] - 1);
        let mut r = Range {
            min: f32::INFINITY,
            max: f32::NEG_INFINITY,
        };
        let mut any = false;
        for x in span(0).filter(|x| slab.stored().contains(x)) {
            for y in span(1) {
                for z in span(2) {
                    let v = slab.get(x, y, z).unwrap().to_f32();
                    (r.min, r.max, any) = (r.min.min(v), r.max.max(v), true);
                }
            }
        }
        match any {
            true => r,
            false => Range::UNKNOWN,
        }
    }

    /// Every block of `slab` as [`Blocks::build`] makes it equals the definition; returns
    /// how many of them the slab stores whole and in part.
    fn check<T: Sample>(slab: &Slab<'_, T>) -> [usize; 2] {
        let mut storage = [Range::UNKNOWN; 256];
        let (x0, x1, n) = extent(slab);
        crate::skip::minmax::build(slab, &mut storage[..n]).unwrap();
        let blocks = Blocks::new(slab.grid(), slab.stored(), &storage[..n]).unwrap();
        // Built in two parts, cut at every column: the same bits.
        let (cols, len) = (x1 - x0, column_len(slab.grid()));
        let bits = |r: &[Range]| {
            r.iter()
                .map(|r| (r.min.to_bits(), r.max.to_bits()))
                .eq(storage[..n]
                    .iter()
                    .map(|r| (r.min.to_bits(), r.max.to_bits())))
        };
        for cut in 0..=cols {
            let mut split = [Range { min: 7.0, max: 7.0 }; 256];
            let (a, b) = split[..n].split_at_mut(cut as usize * len);
            crate::skip::minmax::build_columns(slab, 0..cut, a).unwrap();
            crate::skip::minmax::build_columns(slab, cut..cols, b).unwrap();
            assert!(bits(&split[..n]), "cut at column {cut} of {cols}");
        }
        let (_, by, bz) = blocks.shape();
        let mut seen = [0; 2];
        for bx in x0..x1 {
            for cy in 0..by {
                for cz in 0..bz {
                    let want = defined(slab, [bx, cy, cz]);
                    assert_eq!(blocks.range((bx, cy, cz)), want, "block {bx} {cy} {cz}");
                    assert_ne!(want, Range::UNKNOWN, "every column holds a stored plane");
                    let planes = bx * BLOCK..=(bx * BLOCK + BLOCK).min(slab.grid().dims()[0] - 1);
                    let whole = planes.clone().all(|x| slab.stored().contains(&x));
                    seen[usize::from(!whole)] += 1;
                }
            }
        }
        seen
    }

    #[test]
    fn every_block_is_the_range_of_its_nodes() {
        let mut next = crate::testing::xorshift(0x5eed_b10c);
        // Y (along the rows) longer than one gathering, and one node past it; X and Z with
        // a short last block; a single node along Y.
        let shapes = [[9, 140, 7], [6, 66, 5], [5, 65, 9], [3, 1, 2], [13, 20, 3]];
        let mut bytes = [0u8; 9 * 140 * 7];
        let mut floats = [0f32; 9 * 140 * 7];
        let mut seen = [0; 2];
        for dims in shapes {
            let grid = Grid::new(dims, Vec3::ONE).unwrap();
            for (b, f) in bytes.iter_mut().zip(&mut floats) {
                *b = next() as u8;
                *f = (next() % 20_001) as f32 * 0.1 - 1000.0;
            }
            let n = grid.plane_len() * dims[0] as usize;
            let mut add = |[k, u]: [usize; 2]| seen = [seen[0] + k, seen[1] + u];
            add(check(&Slab::whole(grid, &bytes[..n]).unwrap()));
            add(check(&Slab::whole(grid, &floats[..n]).unwrap()));
            // Partial slabs: ghost planes on either side, so blocks at their ends are stored
            // in part.
            let [nx, ..] = dims;
            for (owned, ghost) in [(1..nx / 2, 1), (nx / 2..nx, 0), (0..nx.div_ceil(3), 2)] {
                if owned.is_empty() {
                    continue;
                }
                let stored = crate::volume::slab::stored_planes(&grid, owned.clone(), ghost);
                let part = stored.start as usize * grid.plane_len()
                    ..stored.end as usize * grid.plane_len();
                add(check(
                    &Slab::new(grid, owned.clone(), ghost, &bytes[part.clone()]).unwrap(),
                ));
                add(check(
                    &Slab::new(grid, owned, ghost, &floats[part]).unwrap(),
                ));
            }
        }
        // Both kinds were compared, in numbers.
        assert!(seen[0] > 500 && seen[1] > 50, "whole, in part: {seen:?}");
    }

    #[test]
    fn a_block_at_the_slabs_end_holds_the_range_of_its_stored_planes() {
        let grid = Grid::new([13, 2, 2], Vec3::ONE).unwrap();
        // Plane x holds 10·x: a block's range tells which of its planes it read.
        let data: [u8; 4 * 4] = core::array::from_fn(|i| (10 * (3 + i / 4)) as u8);
        // Owns planes 4..6 with one ghost plane: stores 3..7. Block 0 (planes 0..=4) stores
        // 3 and 4, block 1 (planes 4..=8) 4 to 6, and block 2 lies past the slab.
        let slab = Slab::new(grid, 4..6, 1, &data).unwrap();
        let (x0, x1, n) = extent(&slab);
        assert_eq!((x0, x1), (0, 2));
        let mut storage = [Range::UNKNOWN; 2];
        assert_eq!(n, 2);
        crate::skip::minmax::build(&slab, &mut storage).unwrap();
        let blocks = Blocks::new(slab.grid(), slab.stored(), &storage).unwrap();
        let at = |x: f32| blocks.at(field::locate(&grid, Model::Cell, Vec3::new(x, 0.0, 0.0)).lo);
        assert_eq!(
            at(3.0),
            Range {
                min: 30.0,
                max: 40.0
            }
        );
        assert_eq!(
            at(5.0),
            Range {
                min: 40.0,
                max: 60.0
            }
        );
        assert_eq!(at(9.0), Range::UNKNOWN);
        assert!(crate::skip::minmax::build(&slab, &mut [Range::UNKNOWN; 3]).is_err());
    }

    #[test]
    fn an_entry_is_what_the_block_holds() {
        let grid = Grid::new([13, 9, 6], Vec3::ONE).unwrap();
        let data: [u8; 13 * 9 * 6] = core::array::from_fn(|i| (i * 53 % 241) as u8);
        let plane = grid.plane_len();
        let slab = Slab::new(grid, 5..9, 1, &data[4 * plane..10 * plane]).unwrap();
        let (x0, x1, n) = extent(&slab);
        let mut storage = [Range::UNKNOWN; 12];
        crate::skip::minmax::build(&slab, &mut storage[..n]).unwrap();
        let bare = Blocks::new(slab.grid(), slab.stored(), &storage[..n]).unwrap();
        let leaps: [u8; 12] = core::array::from_fn(|i| i as u8 * 3);
        let masks: [CellMask; 12] = core::array::from_fn(|i| (i as u64) << 17 | 5);
        let full = bare
            .with_leaps(&leaps[..n], 1)
            .and_then(|b| b.with_cells(&masks[..n]))
            .unwrap();
        let mut inside = 0;
        for blocks in [bare, full] {
            // Every block, and the columns on either side of the slab's.
            for bx in x0.saturating_sub(1)..x1 + 1 {
                for by in 0..2 {
                    for bz in 0..2 {
                        let b = (bx, by, bz);
                        let e = blocks.entry(b);
                        assert_eq!(
                            (e.range(), e.leap(), e.cells()),
                            (blocks.range(b), blocks.leap(b), blocks.cells(b)),
                            "{b:?}"
                        );
                        // A column's masks as one slice: each block's as `cells` reads it.
                        let column = blocks.column_masks(bx, bz);
                        match column.get(by as usize) {
                            Some(&mask) => assert_eq!(mask, blocks.cells(b), "{b:?}"),
                            None => assert!(column.is_empty() && blocks.cells(b) == ALL, "{b:?}"),
                        }
                        inside += usize::from(
                            e.range() != Range::UNKNOWN && e.leap().is_some_and(|d| d > 0),
                        );
                    }
                }
            }
        }
        assert!(inside >= 3, "{inside} entries with a range and a distance");
    }

    #[test]
    fn a_column_s_kept_blocks_are_those_with_cells_in_order_either_way() {
        let mut next = crate::testing::xorshift(0x9e37_79b9);
        let mut column = [0 as CellMask; 200];
        for len in [0, 1, 2, 63, 64, 65, 127, 128, 129, 200] {
            for density in [0, 1, 8, 32, 64] {
                let column = &mut column[..len];
                for mask in column.iter_mut() {
                    // Masks of every bit, the top one too; most zero at low densities.
                    let keep = density > 0 && next() % 64 < density;
                    *mask = match keep {
                        true => u64::from(next()) << (next() % 33) | 1 << (63 * (next() % 2)),
                        false => 0,
                    };
                }
                let kept: heapless::Vec<(u32, CellMask), 200> = (0..len as u32)
                    .zip(column.iter().copied())
                    .filter(|&(_, mask)| mask != 0)
                    .collect();
                // The words made as the walk comes to them, and read from `kept_bits`.
                let mut words = [0u64; 4];
                let words = &mut words[..kept_words(len as u32)];
                if len > 0 {
                    kept_bits(column, len as u32, words).unwrap();
                }
                for given in [None, Some(&*words)] {
                    let walk = |rising| KeptBlocks {
                        words: given,
                        ..KeptBlocks::new(column, rising)
                    };
                    let rising: heapless::Vec<_, 200> = walk(true).collect();
                    assert_eq!(rising, kept, "{len} {density}");
                    let mut falling: heapless::Vec<_, 200> = walk(false).collect();
                    falling.reverse();
                    assert_eq!(falling, kept, "{len} {density}");
                }
            }
        }
    }

    /// Blocks carrying their masks' which-keep words walk each column as those without do;
    /// words of another length are refused, and new masks drop the words made of the old.
    #[test]
    fn kept_words_walk_every_column_as_the_masks_do() {
        let grid = Grid::new([30, 300, 9], Vec3::ONE).unwrap();
        let data = [0u8; 30 * 300 * 9];
        let slab = Slab::whole(grid, &data).unwrap();
        let (_, _, n) = extent(&slab);
        let mut ranges = [Range::UNKNOWN; 8 * 75 * 2];
        crate::skip::minmax::build(&slab, &mut ranges[..n]).unwrap();
        let blocks = Blocks::new(&grid, slab.stored(), &ranges[..n]).unwrap();
        let (cols, ny, nz) = blocks.shape();
        let mut next = crate::testing::xorshift(0x0bad_cafe);
        let mut masks = [0 as CellMask; 8 * 75 * 2];
        for mask in masks[..n].iter_mut() {
            *mask = match next() % 5 {
                0 => u64::from(next()) | 1,
                _ => 0,
            };
        }
        let masked = blocks.with_cells(&masks[..n]).unwrap();
        let mut words = [0u64; 8 * 2 * 2];
        let len = (cols * nz) as usize * kept_words(ny);
        kept_bits(&masks[..n], ny, &mut words[..len]).unwrap();
        let worded = masked.with_kept(&words[..len]).unwrap();
        for bx in 0..cols {
            for bz in 0..nz {
                for rising in [true, false] {
                    let a: heapless::Vec<_, 80> = masked.kept_in_column(bx, bz, rising).collect();
                    let b: heapless::Vec<_, 80> = worded.kept_in_column(bx, bz, rising).collect();
                    assert_eq!(a, b, "column {bx} {bz}");
                }
            }
        }
        assert!(masked.with_kept(&words[..len - 1]).is_err());
        assert!(worded.with_cells(&masks[..n]).unwrap().kept.is_none());
        let mut longer = [0u64; 8 * 2 * 2 + 1];
        assert!(kept_bits(&masks[..n], ny, &mut longer[..len + 1]).is_err());
    }

    #[test]
    fn columns_past_the_slab_or_the_wrong_storage_are_refused() {
        let grid = Grid::new([13, 2, 2], Vec3::ONE).unwrap();
        let data = [5u8; 13 * 4];
        let slab = Slab::whole(grid, &data).unwrap();
        let (x0, x1, n) = extent(&slab);
        assert_eq!((x1 - x0, n), (3, 3));
        let mut one = [Range::UNKNOWN; 1];
        let past = BlocksError::Columns {
            start: 3,
            end: 4,
            columns: 3,
        };
        assert_eq!(
            crate::skip::minmax::build_columns(&slab, 3..4, &mut one),
            Err(past)
        );
        let mut said = heapless::String::<80>::new();
        fmt::Write::write_fmt(&mut said, format_args!("{past}")).unwrap();
        assert_eq!(said, "block columns 3..4 asked for, the slab has 3");
        #[allow(
            clippy::reversed_empty_ranges,
            reason = "the reversed range is the bad input"
        )]
        let reversed = crate::skip::minmax::build_columns(&slab, 2..1, &mut one);
        assert!(matches!(reversed, Err(BlocksError::Columns { .. })));
        assert_eq!(
            crate::skip::minmax::build_columns(&slab, 1..3, &mut one),
            Err(BlocksError::Storage {
                needed: 2,
                given: 1
            })
        );
        crate::skip::minmax::build_columns(&slab, 2..3, &mut one).unwrap();
        assert_eq!(one[0], Range { min: 5.0, max: 5.0 });
        let mut all = [Range::UNKNOWN; 3];
        crate::skip::minmax::build(&slab, &mut all).unwrap();
        let blocks = Blocks::new(slab.grid(), slab.stored(), &all).unwrap();
        assert_eq!(blocks.columns(1..3).map(<[Range]>::len), Ok(2));
        assert!(matches!(
            blocks.columns(0..4),
            Err(BlocksError::Columns { .. })
        ));
    }
}

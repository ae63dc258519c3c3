//! Cell masks: for each min/max block of a slab, which of its 4³ cells a view cannot skip,
//! one bit per cell, so that a sample in an empty cell of a block that is not empty as a
//! whole is skipped too, without its trilinear read.
//!
//! Invariants: a cleared bit is a proof, the same proof a block gives: every value of the
//! trilinear field inside the cell lies between the least and greatest of the cell's eight
//! nodes ([`crate::skip::cell_ranges`]), and the view calls that range empty
//! ([`View::empty`]). Where that cannot be shown the bit is set: every cell of a block whose
//! range is unknown, and every cell with a corner on a plane the slab does not store (in a
//! block at the slab's ends). A block the view skips as a whole has no bit set (the marcher
//! never asks). Masks serve the cell model only; voxel-model samples read a single node, and
//! skipping one would save nothing. Like a leap map, a mask belongs to one view; the cells'
//! ranges it classifies belong to the volume, and a mask classified from them
//! ([`classify_columns`]) is the one built from the nodes ([`build_columns`]), bit for bit.
//! Building them takes at most about 18 KiB of stack (a block's nodes and their ranges, and
//! the remembered verdicts) and no other memory than the masks.

use crate::skip::blocks::{Blocks, BlocksError, Range, BLOCK};
pub use crate::skip::blocks::{CellMask, ALL};
use crate::skip::cell_ranges::{self, BlockCells};
use crate::skip::octant::Octant;
use crate::trace::view::{Mode, View};
use crate::volume::sample::{Sample, SampleKind};
use crate::volume::slab::Slab;

/// The bit, within its block, of the cell whose low corner is `lo` ([`crate::volume::field::Site::lo`]
/// of a cell-model sample). The corner is `4·block + offset` along every axis in the cell model,
/// so the offset is the corner modulo the block edge.
#[inline]
pub fn bit(lo: [u32; 3]) -> CellMask {
    let [x, y, z] = lo.map(|c| c % BLOCK);
    1 << (x + BLOCK * (y + BLOCK * z))
}

/// `SPANS[step][4·lo + hi]`: bits `lo..=hi` of every `4^step`-th bit (`lo ≤ hi < 4`).
const SPANS: [[CellMask; 16]; 3] = {
    let mut spans = [[0; 16]; 3];
    let mut step = 0;
    while step < 3 {
        let mut i = 0;
        while i < 16 {
            let (lo, hi) = (i / 4, i % 4);
            let mut c = lo;
            while c <= hi {
                spans[step][i] |= 1 << (c * (1 << (2 * step)));
                c += 1;
            }
            i += 1;
        }
        step += 1;
    }
    spans
};

/// The cells of the box with corners `lo` and `hi` (offsets within a block, inclusive): a
/// row of X bits, copied to every Y of the range and then every Z by multiplying with one
/// bit per copy (the copies never overlap, so nothing carries).
#[inline]
fn box_bits(lo: [u32; 3], hi: [u32; 3]) -> CellMask {
    let span = |a: usize| SPANS[a][(lo[a] * 4 + hi[a]) as usize % 16];
    span(0) * span(1) * span(2)
}

/// A box of empty cells of a block (`mask`, set bits not empty) that holds cell `at`
/// (offsets within the block, its bit cleared) and reaches only ahead of it for rays of
/// `toward`: its corners, inclusive. The largest cube reaching ahead from `at`, cut at the
/// block's faces, whose cells are all empty. A ray in `at` stays in empty cells until it
/// leaves the box. (Growing each axis on its own finds larger boxes, at four times the
/// instructions: more than the samples it saves.)
pub fn empty_box(mask: CellMask, at: [u32; 3], toward: Octant) -> ([u32; 3], [u32; 3]) {
    // The cube of `r` cells ahead, cut at the block's faces; it stops growing once `r`
    // passes the room ahead on every axis.
    let cube = |r: u32| -> ([u32; 3], [u32; 3]) {
        let span = |a: usize| {
            let (first, last) = toward.span(a, at[a], r);
            (first, last.min(BLOCK - 1))
        };
        let [x, y, z] = [span(0), span(1), span(2)];
        ([x.0, y.0, z.0], [x.1, y.1, z.1])
    };
    let room = |a: usize| match toward.down(a) {
        true => at[a],
        false => BLOCK - 1 - at[a],
    };
    let most = room(0).max(room(1)).max(room(2));
    let mut r = 0;
    while r < most {
        let (lo, hi) = cube(r + 1);
        if box_bits(lo, hi) & mask != 0 {
            break;
        }
        r += 1;
    }
    cube(r)
}

/// Fill `out` (one mask per block of `blocks`, in the blocks' order) with the cells of each
/// block that `view` cannot skip, from `slab`'s nodes (the slab the blocks were built from).
pub fn build<T: Sample>(
    slab: &Slab<'_, T>,
    blocks: &Blocks<'_>,
    view: &View,
    out: &mut [CellMask],
) -> Result<(), BlocksError> {
    build_columns(slab, blocks, view, 0..blocks.shape().0, out)
}

/// Fill `out` with the masks of block columns `columns` of `blocks` (counted from the slab's
/// first), as [`build`] fills their part of its storage: a build split by columns gives the
/// same bits. One pass over the slab's nodes, for a host that holds no [`BlockCells`].
pub fn build_columns<T: Sample>(
    slab: &Slab<'_, T>,
    blocks: &Blocks<'_>,
    view: &View,
    columns: core::ops::Range<u32>,
    out: &mut [CellMask],
) -> Result<(), BlocksError> {
    let mut verdicts = Verdicts::new::<T>(view);
    each_block(blocks, view, columns, out, |b, _| {
        cell_ranges::of_block(slab, b).map(|cells| verdicts.mask(&cells))
    })
}

/// Fill `out` with the masks of block columns `columns` of `blocks`, as [`build_columns`]
/// does, from their cells' ranges `cells` ([`cell_ranges::build_columns`] of the same
/// columns): a classification of ranges built once per volume, the same bits.
pub fn classify_columns<T: Sample>(
    cells: &[BlockCells<T>],
    blocks: &Blocks<'_>,
    view: &View,
    columns: core::ops::Range<u32>,
    out: &mut [CellMask],
) -> Result<(), BlocksError> {
    BlocksError::check_storage(out.len(), cells.len())?;
    let mut verdicts = Verdicts::new::<T>(view);
    each_block(blocks, view, columns, out, |_, i| {
        cells.get(i).map(|cells| verdicts.mask(cells))
    })
}

/// Each block of columns `columns` into its mask in `out`: none where the view skips the
/// block as a whole, all where its range is unknown, else `mask` of its coordinates and
/// index among the columns' blocks (all where that gives none).
fn each_block(
    blocks: &Blocks<'_>,
    view: &View,
    columns: core::ops::Range<u32>,
    out: &mut [CellMask],
    mut mask: impl FnMut([u32; 3], usize) -> Option<CellMask>,
) -> Result<(), BlocksError> {
    let ranges = blocks.columns(columns.clone())?;
    BlocksError::check_storage(ranges.len(), out.len())?;
    let (_, ny, nz) = blocks.shape();
    let x0 = blocks.first_column() + columns.start;
    let mut masks = out.iter_mut().zip(ranges).enumerate();
    for bx in x0..x0 + columns.len() as u32 {
        for bz in 0..nz {
            for by in 0..ny {
                let Some((i, (out, range))) = masks.next() else {
                    return Ok(());
                };
                *out = if view.empty(*range) {
                    0
                } else if *range == Range::UNKNOWN {
                    ALL
                } else {
                    mask([bx, by, bz], i).unwrap_or(ALL)
                };
            }
        }
    }
    Ok(())
}

/// Slots of [`Verdicts::Remembered`].
const SLOTS: usize = 1024;

/// The greatest value a byte takes.
const BYTES: usize = u8::MAX as usize + 1;

/// A view's verdicts on cells' ranges ([`View::empty`], a pure function of the range).
/// Emptiness is monotone in the range (a range inside an empty one is empty: the premise
/// of every min/max proof), so for byte samples one table says it all: for each least
/// value, the greatest value up to which the range is empty. Other samples' verdicts
/// are remembered by range, exactly: cells repeat a few ranges.
#[allow(
    clippy::large_enum_variant,
    reason = "one lives on the stack for a build; the kernel has no heap to box the larger"
)]
enum Verdicts<'v> {
    /// `reach[lo]`: the greatest `hi` whose range from `lo` is empty, −1 where none is.
    Bytes { reach: [i16; BYTES] },
    /// A surfaces view: the greatest corner alone decides ([`View::below_surfaces`]).
    ByGreatest { view: &'v View },
    /// By slot: the range's bits, and whether the view calls it empty.
    Remembered {
        view: &'v View,
        seen: [Option<(u64, bool)>; SLOTS],
    },
}

impl<'v> Verdicts<'v> {
    fn new<T: Sample>(view: &'v View) -> Verdicts<'v> {
        if T::KIND == SampleKind::U8 {
            return Verdicts::Bytes { reach: reach(view) };
        }
        match view.spec().mode {
            Mode::Surfaces(_) => Verdicts::ByGreatest { view },
            Mode::Composite(_) => Verdicts::Remembered {
                view,
                seen: [None; SLOTS],
            },
        }
    }

    /// The cells of `block` that the view cannot skip.
    #[inline]
    fn mask<T: Sample>(&mut self, block: &BlockCells<T>) -> CellMask {
        let mut mask: CellMask = 0;
        let cells = block.lo.iter().zip(&block.hi);
        match self {
            Verdicts::Bytes { reach } => {
                for (i, (lo, hi)) in cells.enumerate() {
                    // Exact: a byte's value is a whole number below 256.
                    let (lo, hi) = (lo.to_f32() as u8, hi.to_f32() as i16);
                    mask |= CellMask::from(hi > reach[usize::from(lo)]) << i;
                }
            }
            Verdicts::ByGreatest { view } => {
                for (i, (_, hi)) in cells.enumerate() {
                    mask |= CellMask::from(!view.below_surfaces(hi.to_f32())) << i;
                }
            }
            Verdicts::Remembered { view, seen } => {
                for (i, (lo, hi)) in cells.enumerate() {
                    let r = Range {
                        min: lo.to_f32(),
                        max: hi.to_f32(),
                    };
                    let key = u64::from(r.min.to_bits()) << 32 | u64::from(r.max.to_bits());
                    // Fibonacci hashing: the top bits of the product mix every bit of the key.
                    let slot = (key.wrapping_mul(0x9e37_79b9_7f4a_7c15) >> 54) as usize % SLOTS;
                    let empty = match seen[slot] {
                        Some((known, empty)) if known == key => empty,
                        _ => {
                            let empty = view.empty(r);
                            seen[slot] = Some((key, empty));
                            empty
                        }
                    };
                    mask |= CellMask::from(!empty) << i;
                }
            }
        }
        (mask & block.present) | block.unknown
    }
}

/// Everything a byte volume's cell masks depend on in a view, beside the volume's cells'
/// ranges: its verdict on every range of byte values, and on a block of unknown range. Two
/// views with equal verdicts give such a volume the same masks, bit for bit, so a host may
/// keep a view's masks for the next view with the same verdicts (an orbit's next frame, a
/// bench's next repetition).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ByteVerdicts {
    reach: [i16; BYTES],
    unknown_empty: bool,
}

impl ByteVerdicts {
    /// `view`'s verdicts (about 512 of [`View::empty`]).
    pub fn of(view: &View) -> ByteVerdicts {
        ByteVerdicts {
            reach: reach(view),
            unknown_empty: view.empty(Range::UNKNOWN),
        }
    }
}

/// For each byte value `lo`, the greatest `hi` such that `view` calls the range `lo..=hi`
/// empty, −1 where it does not call `lo` alone empty. Each `lo` starts from the last reach
/// found: by monotonicity a range inside an empty one is empty, so about 512 verdicts in all.
fn reach(view: &View) -> [i16; BYTES] {
    let empty = |lo: usize, hi: usize| {
        view.empty(Range {
            min: lo as f32,
            max: hi as f32,
        })
    };
    let mut reach = [-1; BYTES];
    let mut last = 0;
    for (lo, out) in reach.iter_mut().enumerate() {
        if !empty(lo, lo) {
            continue;
        }
        let mut hi = last.max(lo);
        while hi + 1 < BYTES && empty(lo, hi + 1) {
            hi += 1;
        }
        // Below 256.
        *out = hi as i16;
        last = hi;
    }
    reach
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::counters::Counters;
    use crate::optics::surface::IsoSurface;
    use crate::optics::transfer::{ControlPoint, TransferFunction};
    use crate::trace::camera::{Camera, Projection};
    use crate::trace::view::Mode;
    use crate::volume::field::{self, Site};
    use crate::volume::grid::{Grid, Model};
    use glam::Vec3;

    fn view(grid: &Grid, mode: Mode) -> View {
        let centre = Vec3::splat(4.0);
        let camera = Camera::look_at(
            centre + Vec3::new(20.0, 5.0, 9.0),
            centre,
            Vec3::Y,
            Projection::Orthographic { width: 20.0 },
        )
        .unwrap();
        let spec = crate::testing::spec(camera, mode);
        View::new(spec, grid).unwrap()
    }

    /// Surfaces at `isos`; compositing whose opacity is zero up to `clear`; and compositing
    /// of a band, zero again from 60 above `clear` on, so that a cell's least corner decides
    /// too.
    fn views(grid: &Grid, isos: &[f32], clear: f32) -> [View; 3] {
        let mut surfaces = heapless::Vec::new();
        for &iso in isos {
            let _ = surfaces.push(IsoSurface {
                iso,
                color: Vec3::ONE,
                transparency: 0.0,
            });
        }
        let point = |value: f32, opacity: f32| ControlPoint {
            value,
            color: Vec3::ONE,
            opacity,
        };
        let tf = TransferFunction::new(&[point(clear, 0.0), point(clear + 40.0, 0.5)]).unwrap();
        let band = TransferFunction::new(&[
            point(clear, 0.0),
            point(clear + 30.0, 0.5),
            point(clear + 60.0, 0.0),
        ])
        .unwrap();
        [
            view(grid, Mode::Surfaces(surfaces)),
            view(grid, Mode::Composite(tf)),
            view(grid, Mode::Composite(band)),
        ]
    }

    #[test]
    fn views_of_equal_emptiness_call_every_range_alike_and_a_moved_verdict_is_told_apart() {
        use crate::trace::view::Accuracy;
        let grid = Grid::new([9, 9, 9], Vec3::ONE).unwrap();
        let with = |v: &View, f: &dyn Fn(&mut crate::trace::view::ViewSpec)| {
            let mut spec = v.spec().clone();
            f(&mut spec);
            View::new(spec, &grid).unwrap()
        };
        let fast = |v: &View| with(v, &|s| s.accuracy = Accuracy::Fast);
        // Another camera and step (the exact tier reads neither), another colour in the fast
        // tier (its table's opacities alone tell).
        let elsewhere = |v: &View| {
            with(v, &|s| {
                s.dt = 0.25;
                s.camera = Camera::look_at(
                    Vec3::new(-9.0, 30.0, 2.0),
                    Vec3::splat(4.0),
                    Vec3::Z,
                    Projection::Orthographic { width: 14.0 },
                )
                .unwrap();
            })
        };
        let recoloured = |v: &View| {
            with(v, &|s| {
                if let Mode::Composite(tf) = &s.mode {
                    let points: heapless::Vec<ControlPoint, 8> = tf
                        .points()
                        .iter()
                        .map(|p| ControlPoint {
                            color: Vec3::new(0.1, 0.9, 0.4),
                            ..*p
                        })
                        .collect();
                    s.mode = Mode::Composite(TransferFunction::new(&points).unwrap());
                }
            })
        };
        let mut next = crate::testing::xorshift(0xe3_9d7);
        let mut ranges: heapless::Vec<Range, 600> = heapless::Vec::new();
        for _ in 0..590 {
            let (a, b) = ((next() % 3000) as f32 * 0.1, (next() % 3000) as f32 * 0.1);
            let _ = ranges.push(Range {
                min: a.min(b),
                max: a.max(b),
            });
        }
        let _ = ranges.push(Range::UNKNOWN);
        let alike = |a: &View, b: &View| ranges.iter().all(|r| a.empty(*r) == b.empty(*r));
        // One view at a time: a view holds its tables, and a test thread's stack is small.
        let base = |i: usize, isos: &[f32], clear: f32| {
            let [surfaces, ramp, band] = views(&grid, isos, clear);
            [surfaces, ramp, band].into_iter().nth(i).unwrap()
        };
        let same = |a: View, b: View| {
            assert_eq!(a.emptiness(), b.emptiness(), "{:?}", a.spec().mode);
            assert!(alike(&a, &b));
        };
        for i in 0..3 {
            let v = base(i, &[50.0, 80.0], 20.0);
            same(v.clone(), elsewhere(&v));
            same(fast(&v), fast(&elsewhere(&v)));
            same(fast(&v), fast(&recoloured(&v)));
            // Any moved verdict is told apart: another least iso value, another clear value.
            let moved = base(i, &[51.0, 80.0], 21.0);
            assert!(!alike(&v, &moved), "the sweep sees the move");
            assert_ne!(v.emptiness(), moved.emptiness());
            assert_ne!(fast(&v).emptiness(), fast(&moved).emptiness());
        }
        // A tier's verdicts are its own: the exact tier's are the function's, the fast one's
        // its table's.
        let ramp = base(1, &[50.0, 80.0], 20.0);
        assert_ne!(ramp.emptiness(), fast(&ramp).emptiness());
    }

    /// A cell's bit by definition: its eight nodes read one by one (the far node of an axis of
    /// one node is the near one), set unless the view calls their range empty or a node is
    /// not stored.
    fn defined<T: Sample>(slab: &Slab<'_, T>, view: &View, cell: [u32; 3]) -> bool {
        let dims = slab.grid().dims();
        let mut r = Range {
            min: f32::INFINITY,
            max: f32::NEG_INFINITY,
        };
        for corner in 0..8 {
            let node: [u32; 3] =
                core::array::from_fn(|a| (cell[a] + (corner >> a & 1)).min(dims[a] - 1));
            let Some(v) = slab.get(node[0], node[1], node[2]) else {
                return true;
            };
            r.min = r.min.min(v.to_f32());
            r.max = r.max.max(v.to_f32());
        }
        !view.empty(r)
    }

    #[test]
    fn every_mask_is_its_cells_by_definition_and_every_cleared_cell_is_empty() {
        let mut next = crate::testing::xorshift(0x0ce1_1500);
        let (mut cleared, mut set) = (0, 0);
        for round in 0..60 {
            let dims = [1 + next() % 12, 1 + next() % 10, 1 + next() % 11];
            let grid = Grid::new(dims, Vec3::ONE).unwrap();
            // Smooth blobs over a noise floor, so that blocks hold both empty and full cells.
            let mut data = [0u8; 12 * 10 * 11];
            let n = grid.plane_len() * dims[0] as usize;
            let (cx, cy, cz) = (next() % 12, next() % 10, next() % 11);
            for (i, v) in data.iter_mut().take(n).enumerate() {
                let (x, rest) = ((i / grid.plane_len()) as u32, i % grid.plane_len());
                let (z, y) = (
                    (rest / dims[1] as usize) as u32,
                    (rest % dims[1] as usize) as u32,
                );
                let d2 = x.abs_diff(cx).pow(2) + y.abs_diff(cy).pow(2) + z.abs_diff(cz).pow(2);
                *v = (200u32.saturating_sub(d2 * 12) + next() % 30) as u8;
            }
            let data = &data[..n];
            // The whole volume, and a partial slab whose outer blocks lack planes.
            let whole = Slab::whole(grid, data).unwrap();
            let owned = dims[0] / 3..(dims[0] / 3 + 2).min(dims[0]);
            let stored = crate::volume::slab::stored_planes(&grid, owned.clone(), 1);
            let part = &data[stored.start as usize * grid.plane_len()..]
                [..(stored.end - stored.start) as usize * grid.plane_len()];
            let partial = Slab::new(grid, owned, 1, part).unwrap();
            let iso = 40.0 + (round % 5) as f32 * 30.0;
            for slab in [whole, partial] {
                let mut ranges = [Range::UNKNOWN; 3 * 3 * 3];
                let (_, _, len) = crate::skip::minmax::extent(&slab);
                crate::skip::minmax::build(&slab, &mut ranges[..len]).unwrap();
                let blocks = Blocks::new(slab.grid(), slab.stored(), &ranges[..len]).unwrap();
                for view in views(&grid, &[iso, iso + 50.0], iso - 20.0) {
                    let mut masks = [0; 3 * 3 * 3];
                    build(&slab, &blocks, &view, &mut masks[..len]).unwrap();
                    // Built in two parts, cut at every column: the same masks.
                    let cols = blocks.shape().0;
                    let per = crate::skip::blocks::column_len(&grid);
                    for cut in 0..=cols {
                        let mut split = [0x5a5a; 3 * 3 * 3];
                        let (a, b) = split[..len].split_at_mut(cut as usize * per);
                        build_columns(&slab, &blocks, &view, 0..cut, a).unwrap();
                        build_columns(&slab, &blocks, &view, cut..cols, b).unwrap();
                        assert_eq!(split[..len], masks[..len], "cut at column {cut}");
                    }
                    // Classified from the cells' ranges, built once: the same masks.
                    let classified = classified(&slab, &blocks, &view);
                    assert_eq!(classified[..len], masks[..len], "classified");
                    let masked = blocks.with_cells(&masks[..len]).unwrap();
                    // Every cell of every stored block against the definition.
                    let cells = dims.map(|n| n.saturating_sub(1).max(1));
                    for x in slab.stored() {
                        for y in 0..cells[1] {
                            for z in 0..cells[2] {
                                let x = x.min(cells[0] - 1);
                                let site = Site {
                                    lo: [x, y, z],
                                    hi: [x, y, z],
                                    frac: Vec3::ZERO,
                                };
                                let block = masked.block_of(site.lo);
                                let shows = masked.cells(block) & bit(site.lo) != 0;
                                // A block of unknown range proves nothing of its cells.
                                let range = masked.range(block);
                                let expected = !view.empty(range)
                                    && (range == Range::UNKNOWN
                                        || defined(&slab, &view, [x, y, z]));
                                assert_eq!(shows, expected, "{dims:?} cell {x} {y} {z}");
                            }
                        }
                    }
                    // Every value read in a cleared cell is one the view calls empty.
                    let mut c = Counters::default();
                    for _ in 0..400 {
                        let p = Vec3::new(
                            (next() % 1000) as f32 / 1000.0 * dims[0] as f32,
                            (next() % 1000) as f32 / 1000.0 * dims[1] as f32,
                            (next() % 1000) as f32 / 1000.0 * dims[2] as f32,
                        );
                        let site = field::locate(&grid, Model::Cell, p);
                        if !slab.owns(site.plane()) {
                            continue;
                        }
                        let block = masked.block_of(site.lo);
                        if masked.cells(block) & bit(site.lo) != 0 {
                            set += 1;
                            continue;
                        }
                        cleared += 1;
                        let v = field::value_at(&slab, Model::Cell, &site, &mut c);
                        let r = Range { min: v, max: v };
                        assert!(view.empty(r), "{dims:?} {p}: {v} shows in a cleared cell");
                    }
                }
            }
        }
        // Both outcomes are exercised.
        assert!(cleared > 1000 && set > 1000, "{cleared} cleared, {set} set");
    }

    /// The masks of `blocks` (of `slab`, at most 27) for `view`, classified from their
    /// cells' ranges.
    fn classified<T: Sample>(
        slab: &Slab<'_, T>,
        blocks: &Blocks<'_>,
        view: &View,
    ) -> [CellMask; 3 * 3 * 3] {
        let (cols, ny, nz) = blocks.shape();
        let len = (cols * ny * nz) as usize;
        let mut cells = [BlockCells::default(); 3 * 3 * 3];
        cell_ranges::build_columns(slab, blocks, 0..cols, &mut cells[..len]).unwrap();
        let mut masks = [0x5a5a; 3 * 3 * 3];
        classify_columns(&cells[..len], blocks, view, 0..cols, &mut masks[..len]).unwrap();
        masks
    }

    /// Whether `reach` gives `view`'s verdict on every range of byte values.
    fn reach_agrees(reach: &[i16; BYTES], view: &View) -> bool {
        (0..BYTES).all(|lo| {
            (lo..BYTES).all(|hi| {
                let r = Range {
                    min: lo as f32,
                    max: hi as f32,
                };
                (hi as i16 <= reach[lo]) == view.empty(r)
            })
        })
    }

    #[test]
    fn the_byte_table_gives_the_views_verdict_on_every_range() {
        let grid = Grid::new([9, 9, 9], Vec3::ONE).unwrap();
        let mut tables = 0;
        for clear in [0.0, 20.0, 99.5, 200.0, 254.0] {
            for view in views(&grid, &[clear + 10.0, clear + 60.0], clear) {
                let table = reach(&view);
                assert!(reach_agrees(&table, &view), "clear {clear}");
                // The negative control: a table one value too generous anywhere it can be
                // is caught.
                for lo in (0..BYTES).filter(|&lo| (0..255).contains(&table[lo])) {
                    let mut wrong = table;
                    wrong[lo] += 1;
                    assert!(!reach_agrees(&wrong, &view), "clear {clear}, lo {lo}");
                    tables += 1;
                }
            }
        }
        assert!(tables > 100, "{tables}");
    }

    /// Masks of `data` (a blob, as its values are converted by `to`) built from the nodes and
    /// classified from its cells' ranges, for each of [`views`].
    fn both_ways<T: Sample>(to: impl Fn(u8) -> T, scale: f32) -> usize {
        let mut next = crate::testing::xorshift(0x7a61_e5c0);
        let dims = [11, 9, 10];
        let grid = Grid::new(dims, Vec3::ONE).unwrap();
        let data: [T; 11 * 9 * 10] = core::array::from_fn(|i| {
            let (x, y, z) = (i / 90, i % 9, (i / 9) % 10);
            let d2 = (x.abs_diff(5).pow(2) + y.abs_diff(4).pow(2) + z.abs_diff(5).pow(2)) as u32;
            to((200u32.saturating_sub(d2 * 10) + next() % 30) as u8)
        });
        let slab = Slab::whole(grid, &data).unwrap();
        let mut ranges = [Range::UNKNOWN; 3 * 3 * 3];
        let (_, _, len) = crate::skip::minmax::extent(&slab);
        crate::skip::minmax::build(&slab, &mut ranges[..len]).unwrap();
        let blocks = Blocks::new(slab.grid(), slab.stored(), &ranges[..len]).unwrap();
        let mut kept = 0;
        for view in views(&grid, &[90.0 * scale, 150.0 * scale], 60.0 * scale) {
            let mut built = [0; 3 * 3 * 3];
            build(&slab, &blocks, &view, &mut built[..len]).unwrap();
            let classified = classified(&slab, &blocks, &view);
            assert_eq!(built[..len], classified[..len], "{:?}", T::KIND);
            kept += built.iter().map(|m| m.count_ones() as usize).sum::<usize>();
        }
        kept
    }

    #[test]
    fn masks_classified_from_cells_ranges_are_the_masks_of_the_nodes_for_every_sample_kind() {
        let kept = [
            both_ways(|v| v, 1.0),
            both_ways(|v| u16::from(v) * 200, 200.0),
            both_ways(|v| f32::from(v) * 0.37, 0.37),
        ];
        // Neither all nor none of the cells kept.
        for k in kept {
            assert!(k > 100 && k < 3 * 27 * 64 - 100, "{kept:?}");
        }
    }

    #[test]
    fn an_empty_box_is_the_largest_empty_cube_ahead_in_the_block() {
        let mut next = crate::testing::xorshift(0xb0c5_0064);
        let mut grown = 0;
        // The cells of a box, one bit at a time.
        let cells = |lo: [u32; 3], hi: [u32; 3]| {
            let mut bits: CellMask = 0;
            for x in lo[0]..=hi[0] {
                for y in lo[1]..=hi[1] {
                    for z in lo[2]..=hi[2] {
                        bits |= bit([x, y, z]);
                    }
                }
            }
            bits
        };
        for round in 0..4000 {
            // From nearly full to nearly empty blocks.
            let density = round % 8;
            let mut mask: CellMask = 0;
            for b in 0..64 {
                if next() % 8 < density {
                    mask |= 1 << b;
                }
            }
            let at = [next() % 4, next() % 4, next() % 4];
            mask &= !bit(at);
            let toward = Octant::from_index((next() % 8) as usize);
            // By definition: the cube of `r` cells ahead of `at` on every axis, cut at the
            // block's faces, for the largest `r` whose cube is empty.
            let cube = |r: u32| {
                let (mut lo, mut hi) = (at, at);
                for a in 0..3 {
                    match toward.down(a) {
                        true => lo[a] = at[a].saturating_sub(r),
                        false => hi[a] = (at[a] + r).min(3),
                    }
                }
                (lo, hi)
            };
            let r = (0..4)
                .filter(|&r| cells(cube(r).0, cube(r).1) & mask == 0)
                .max();
            let expected = cube(r.unwrap_or(0));
            let found = empty_box(mask, at, toward);
            assert_eq!(found, expected, "{mask:#x} {at:?} {toward:?}");
            assert_eq!(cells(found.0, found.1) & mask, 0);
            assert_eq!(box_bits(found.0, found.1), cells(found.0, found.1));
            grown += usize::from(found.0 != found.1);
        }
        assert!(grown > 1000, "boxes beyond one cell were checked: {grown}");
    }

    #[test]
    fn blocks_without_masks_skip_no_cell() {
        let grid = Grid::new([5, 5, 5], Vec3::ONE).unwrap();
        let data = [7u8; 125];
        let slab = Slab::whole(grid, &data).unwrap();
        let mut ranges = [Range::UNKNOWN; 1];
        crate::skip::minmax::build(&slab, &mut ranges).unwrap();
        let blocks = Blocks::new(slab.grid(), slab.stored(), &ranges).unwrap();
        assert_eq!(blocks.cells((0, 0, 0)), ALL);
        let [surfaces, ..] = views(&grid, &[100.0], 50.0);
        let mut masks = [ALL; 1];
        build(&slab, &blocks, &surfaces, &mut masks).unwrap();
        // The block lies below the surface as a whole: no cell of it is asked about.
        assert_eq!(masks, [0]);
        assert!(build(&slab, &blocks, &surfaces, &mut [0; 2]).is_err());
    }
}

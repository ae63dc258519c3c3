//! Pre-integrated segments, the fast tier's compositing between samples (Engel, Kraus & Ertl
//! 2001): for a view's Δt, the colour and opacity of a whole segment over which the value
//! runs linearly from its front sample's to its back sample's, tabulated over both values
//! at [`ENTRIES`] entries spread evenly over the transfer function's control points and read
//! at the nearest. A sample composites the segment that ends at it, so the transfer
//! function's detail between two samples (a thin shell of material, a narrow peak) is
//! integrated rather than missed, and the quadrature along the ray becomes second order in
//! Δt where sampling is first.
//!
//! The table integrates the transfer function as its entries give it, opacity per cell edge
//! and colour running linearly from one entry to the next: each such piece is given its
//! mean extinction (`κ = −ln(1 − opacity)` per edge) and its emission-weighted colour, and a
//! segment over `n` entry steps is its `n` pieces composited front to back, each `Δt / n`
//! edges long.
//!
//! Invariants: a table is built from the transfer function and Δt alone by one fixed sequence
//! of operations, so its entries are the same bits wherever it is built; a segment whose two
//! values and every entry between read zero opacity has opacity exactly zero, so every
//! segment between two values below [`Layout::first_shown`] is transparent, and skipping by
//! that bound ([`Layout::empty`]) stays a bound, never an approximation of the image.

use crate::optics::classify::nearest;
use crate::optics::transfer::{corrected_opacity, TransferFunction};
use core::fmt;
use glam::{Vec3, Vec4};

/// Entries over the transfer function's domain: for a byte volume whose function spans its
/// 256 values, one a value unit apart.
pub const ENTRIES: usize = 256;

/// Segments in a table: one per front entry and back entry, front-major.
const SEGMENTS: usize = ENTRIES * ENTRIES;

/// The cells of a table: its segments, then the transfer function at each entry (colour,
/// opacity per cell edge) for the last stretch of a ray, shorter than Δt.
pub const LEN: usize = SEGMENTS + ENTRIES;

/// Bytes of a table: what a node holds for a pre-integrated view.
pub const BYTES: usize = LEN * size_of::<Vec4>();

/// The greatest opacity per cell edge a piece is given: an opacity of 1 would be an infinite
/// extinction, whose colour weights are not numbers. `1 − 2⁻²⁴`, an extinction of `24·ln 2`
/// per edge: light through one edge of it is below every cutoff.
const MAX_OPACITY: f64 = 1.0 - 1.0 / (1u32 << 24) as f64;

/// Gauss–Legendre's eight nodes on `[0, 1]` (the first four; the rest mirror them) and their
/// weights.
const GAUSS_NODES: [f64; 4] = [
    0.019_855_071_751_231_856,
    0.101_666_761_293_186_63,
    0.237_233_795_041_835_5,
    0.408_282_678_752_175_1,
];
const GAUSS_WEIGHTS: [f64; 4] = [
    0.050_614_268_145_188_13,
    0.111_190_517_226_687_24,
    0.156_853_322_938_943_64,
    0.181_341_891_689_181,
];

/// A piece whose opacity per edge runs linearly from `a` to `b` across it: its mean
/// extinction per edge (`∫κ`, with `u` running over `[0, 1]`), and where its emission's
/// weight lies (`∫u·κ / ∫κ`, a half where it has none), so that its colour, linear too, is
/// emitted as `c_a + (c_b − c_a)·that`. In `f64` by eight-point Gauss–Legendre: `κ` is smooth
/// across a piece but for a logarithm's rise toward an opacity of 1.
fn piece(a: f64, b: f64) -> (f64, f64) {
    let kappa = |u: f64| -libm::log1p(-(a + (b - a) * u));
    let (mut total, mut moment) = (0.0, 0.0);
    for (x, w) in GAUSS_NODES.into_iter().zip(GAUSS_WEIGHTS) {
        for u in [x, 1.0 - x] {
            let k = kappa(u);
            total += w * k;
            moment += w * u * k;
        }
    }
    let toward_b = if total > 0.0 { moment / total } else { 0.5 };
    (total, toward_b)
}

/// What places a value in a table, apart from its cells: where its entries start and how
/// they scale, the step they are integrated for, and the first entry that shows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Layout {
    /// The value of entry 0, and entries per value unit.
    lo: f32,
    per_unit: f32,
    /// The segment length the table holds, in cell edges.
    dt: f32,
    /// The first entry whose opacity is above zero ([`ENTRIES`] where none is).
    first_shown: u32,
}

impl Layout {
    /// The layout of `tf`'s table for segments `dt` cell edges long (a positive finite
    /// number).
    pub fn of(tf: &TransferFunction, dt: f32) -> Result<Layout, SegmentsError> {
        if !(dt > 0.0 && dt.is_finite()) {
            return Err(SegmentsError::Step(dt));
        }
        let (lo, hi) = tf.domain();
        let first_shown = (0..ENTRIES)
            .find(|&m| tf.eval(entry_value(lo, hi, m)).1 > 0.0)
            .unwrap_or(ENTRIES) as u32;
        Ok(Layout {
            lo,
            per_unit: if hi > lo {
                (ENTRIES - 1) as f32 / (hi - lo)
            } else {
                0.0
            },
            dt,
            first_shown,
        })
    }

    /// The entry value `v` reads: the nearest, clamped to the table (NaN reads entry 0), as
    /// the pre-classified table finds its entries.
    #[inline]
    fn index(&self, v: f32) -> usize {
        nearest::<ENTRIES>(v, self.lo, self.per_unit)
    }

    /// Whether `v` reads an entry before the first that shows: a segment between two such
    /// values is transparent.
    #[inline]
    pub fn below(&self, v: f32) -> bool {
        (self.index(v) as u32) < self.first_shown
    }

    /// Whether every value in `[min, max]` reads an entry before the first that shows (the
    /// entry a value reads never decreases with it). A NaN bound proves nothing.
    #[inline]
    pub fn empty(&self, min: f32, max: f32) -> bool {
        min <= max && self.below(max)
    }

    /// The bits [`Layout::empty`] reads: two layouts with equal keys call every range alike.
    pub fn key(&self) -> (u32, u32, u32) {
        (self.lo.to_bits(), self.per_unit.to_bits(), self.first_shown)
    }

    /// The segment length the table holds, in cell edges.
    pub fn dt(&self) -> f32 {
        self.dt
    }

    /// The first entry whose opacity is above zero ([`ENTRIES`] where none is).
    pub fn first_shown(&self) -> u32 {
        self.first_shown
    }
}

/// The value of entry `m` of a table over `[lo, hi]`: from both ends, so the last entry is
/// the last control point exactly.
fn entry_value(lo: f32, hi: f32, m: usize) -> f32 {
    lo + (hi - lo) * (m as f32 / (ENTRIES - 1) as f32)
}

/// Why a table cannot be built or read.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SegmentsError {
    /// The storage handed in is not [`LEN`] cells.
    Length {
        /// Cells handed in.
        got: usize,
    },
    /// The segment length is not a positive finite number of cell edges.
    Step(f32),
}

impl fmt::Display for SegmentsError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SegmentsError::Length { got } => {
                write!(f, "a pre-integration table holds {LEN} cells, not {got}")
            }
            SegmentsError::Step(dt) => {
                write!(f, "a pre-integration table needs a positive step, not {dt}")
            }
        }
    }
}

impl core::error::Error for SegmentsError {}

/// Build `tf`'s table of `layout` ([`Layout::of`] the same function) into `out` ([`LEN`]
/// cells).
pub fn build(
    tf: &TransferFunction,
    layout: &Layout,
    out: &mut [Vec4],
) -> Result<(), SegmentsError> {
    let got = out.len();
    let out: &mut [Vec4; LEN] = out.try_into().map_err(|_| SegmentsError::Length { got })?;
    let dt = layout.dt;
    let (lo, hi) = tf.domain();
    let mut color = [Vec3::ZERO; ENTRIES];
    let mut opacity = [0.0f64; ENTRIES];
    for m in 0..ENTRIES {
        let (c, o) = tf.eval(entry_value(lo, hi, m));
        color[m] = c;
        opacity[m] = f64::from(o).clamp(0.0, MAX_OPACITY);
        out[SEGMENTS + m] = c.extend(o);
        // A segment that stays at one entry: its opacity corrected for the whole step.
        out[m * ENTRIES + m] = c.extend(corrected_opacity(o, dt));
    }
    // Piece `m` lies between entries `m` and `m + 1`.
    let mut piece_extinction = [0.0f32; ENTRIES - 1];
    let mut piece_color = [Vec3::ZERO; ENTRIES - 1];
    for m in 0..ENTRIES - 1 {
        let (k, toward_b) = piece(opacity[m], opacity[m + 1]);
        piece_extinction[m] = k as f32;
        piece_color[m] = color[m] + (color[m + 1] - color[m]) * toward_b as f32;
    }
    let mut scratch = Scratch::new();
    let mut rising = [Vec4::ZERO; ENTRIES - 1];
    let mut falling = [Vec4::ZERO; ENTRIES - 1];
    for n in 1..ENTRIES {
        let length = dt / n as f32;
        for m in 0..ENTRIES - 1 {
            let through = libm::expf(-piece_extinction[m] * length);
            let piece = (piece_color[m] * (1.0 - through)).extend(through);
            rising[m] = piece;
            // The same pieces met from the other end: a falling value crosses them in turn.
            falling[ENTRIES - 2 - m] = piece;
        }
        scratch.windows(&rising, n, |i, w| out[i * ENTRIES + i + n] = finished(w));
        scratch.windows(&falling, n, |x, w| {
            let front = ENTRIES - 1 - x;
            out[front * ENTRIES + front - n] = finished(w);
        });
    }
    Ok(())
}

/// Pieces composited front to back, as `(C, T)`: the colour they send toward the eye in
/// `xyz`, the light they let through in `w`. `a` in front of `b`.
#[inline]
fn over(a: Vec4, b: Vec4) -> Vec4 {
    (a.truncate() + a.w * b.truncate()).extend(a.w * b.w)
}

/// A segment's cell from its composited pieces: its mean colour (what it sends over its
/// opacity, so that a sample loop lights and weighs it as a sampled colour) and opacity.
#[inline]
fn finished(w: Vec4) -> Vec4 {
    let alpha = 1.0 - w.w;
    if alpha > 0.0 {
        (w.truncate() / alpha).extend(alpha)
    } else {
        Vec4::ZERO
    }
}

/// Room to composite every run of `n` consecutive pieces in time proportional to the pieces
/// rather than to `n` times them: the pieces fall into blocks of `n`, and a run is the tail
/// of one block in front of the head of the next.
struct Scratch {
    /// `tails[x]`: pieces `x` to its block's end.
    tails: [Vec4; ENTRIES - 1],
    /// `heads[x]`: pieces from its block's start to `x`.
    heads: [Vec4; ENTRIES - 1],
}

impl Scratch {
    fn new() -> Self {
        Scratch {
            tails: [Vec4::ZERO; ENTRIES - 1],
            heads: [Vec4::ZERO; ENTRIES - 1],
        }
    }

    /// `emit(i, run)` for every run of `n` pieces starting at `i`, front to back.
    fn windows(
        &mut self,
        pieces: &[Vec4; ENTRIES - 1],
        n: usize,
        mut emit: impl FnMut(usize, Vec4),
    ) {
        let count = pieces.len();
        for start in (0..count).step_by(n) {
            let end = (start + n).min(count);
            let block = &pieces[start..end];
            let mut tail = Vec4::new(0.0, 0.0, 0.0, 1.0);
            for (x, &piece) in block.iter().enumerate().rev() {
                tail = over(piece, tail);
                self.tails[start + x] = tail;
            }
            let mut head = Vec4::new(0.0, 0.0, 0.0, 1.0);
            for (x, &piece) in block.iter().enumerate() {
                head = over(head, piece);
                self.heads[start + x] = head;
            }
        }
        for i in 0..=count - n {
            let run = if i % n == 0 {
                self.tails[i]
            } else {
                over(self.tails[i], self.heads[i + n - 1])
            };
            emit(i, run);
        }
    }
}

/// A view's pre-integration table, as a node holds it.
#[derive(Clone, Copy, Debug)]
pub struct Segments<'a> {
    layout: Layout,
    cells: &'a [Vec4; LEN],
}

impl<'a> Segments<'a> {
    /// The table `cells`, built by [`build`] with `layout`.
    pub fn new(layout: Layout, cells: &'a [Vec4]) -> Result<Self, SegmentsError> {
        let cells = cells
            .try_into()
            .map_err(|_| SegmentsError::Length { got: cells.len() })?;
        Ok(Segments { layout, cells })
    }

    /// Where values fall in the table.
    pub fn layout(&self) -> &Layout {
        &self.layout
    }

    /// The whole segment from value `front` to value `back`: its mean colour in `xyz`, its
    /// opacity in `w`.
    #[inline]
    pub fn segment(&self, front: f32, back: f32) -> Vec4 {
        let (f, b) = (self.layout.index(front), self.layout.index(back));
        self.cells[(f * ENTRIES + b) % LEN]
    }

    /// Colour and opacity per cell edge at value `v` (for a stretch shorter than Δt, whose
    /// opacity the caller corrects for its own length).
    #[inline]
    pub fn per_edge(&self, v: f32) -> (Vec3, f32) {
        let e = self.cells[(SEGMENTS + self.layout.index(v)) % LEN];
        (e.truncate(), e.w)
    }
}

#[cfg(test)]
mod tests {
    // A whole table is a megabyte, more than a test thread's stack and the kernel has no
    // heap: the tests of whole tables are the tests crate's (`tests/tests/preintegrated.rs`).
    use super::*;
    use crate::optics::transfer::ControlPoint;

    #[test]
    fn a_piece_of_constant_opacity_has_its_extinction_and_a_piece_of_none_has_none() {
        for a in [0.0, 1e-6, 0.3, 0.9, MAX_OPACITY] {
            let (k, weight) = piece(a, a);
            let exact = -libm::log1p(-a);
            assert!(
                (k - exact).abs() <= 1e-12 * exact.max(1.0),
                "{a}: {k} {exact}"
            );
            assert!((weight - 0.5).abs() < 1e-12, "{a}: {weight}");
        }
        assert_eq!(piece(0.0, 0.0), (0.0, 0.5));
        // Opacity rising across the piece: its emission lies toward the opaque end, and its
        // extinction is the integral of −ln(1 − a − (b − a)u), closed form for a linear a.
        let (a, b) = (0.1f64, 0.8f64);
        let f = |y: f64| (1.0 - y) * (1.0 - y).ln() + y;
        let (k, weight) = piece(a, b);
        assert!((k - (f(b) - f(a)) / (b - a)).abs() < 1e-7, "{k}");
        assert!(weight > 0.5 && weight < 1.0, "{weight}");
    }

    #[test]
    fn every_run_of_pieces_is_its_pieces_composited_in_turn() {
        let mut next = crate::testing::xorshift(0x5e9_0e17);
        let unit = |x: u32| (x >> 8) as f32 / (1u32 << 24) as f32;
        let mut pieces = [Vec4::ZERO; ENTRIES - 1];
        for p in pieces.iter_mut() {
            let through = unit(next());
            *p = (Vec3::new(unit(next()), unit(next()), unit(next())) * (1.0 - through))
                .extend(through);
        }
        let mut scratch = Scratch::new();
        for n in [1, 2, 3, 7, 64, 100, ENTRIES - 1] {
            let mut seen = 0;
            scratch.windows(&pieces, n, |i, run| {
                let alone = pieces[i..i + n]
                    .iter()
                    .fold(Vec4::new(0.0, 0.0, 0.0, 1.0), |acc, &p| over(acc, p));
                assert!(
                    (run - alone).abs().max_element() < 1e-5,
                    "{n} at {i}: {run} {alone}"
                );
                seen += 1;
            });
            assert_eq!(seen, ENTRIES - n, "{n}");
        }
    }

    #[test]
    fn a_layout_finds_the_first_entry_that_shows_and_refuses_a_bad_step() {
        let p = |value, opacity| ControlPoint {
            value,
            color: Vec3::ONE,
            opacity,
        };
        let tf =
            TransferFunction::new(&[p(0.0, 0.0), p(100.0, 0.0), p(255.0, 1.0)]).expect("valid");
        let layout = Layout::of(&tf, 0.5).expect("a step");
        // Entries are one value unit apart: entry 100 is the last of zero opacity.
        assert_eq!(layout.first_shown(), 101);
        assert!(layout.below(100.4) && !layout.below(100.6));
        assert!(layout.empty(-1e9, 100.0) && !layout.empty(-1e9, 101.0));
        assert!(!layout.empty(f32::NAN, 0.0) && !layout.empty(0.0, f32::NAN));
        assert!(
            layout.below(f32::NAN),
            "NaN reads entry 0, as the table does"
        );
        for dt in [f32::NAN, 0.0, -1.0, f32::INFINITY] {
            assert!(
                matches!(Layout::of(&tf, dt), Err(SegmentsError::Step(_))),
                "{dt}"
            );
        }
    }
}

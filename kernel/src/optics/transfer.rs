//! The piecewise-linear transfer function of compositing: data value to colour and opacity.
//!
//! Invariants: 1 to [`MAX_POINTS`] control points, values strictly increasing and finite,
//! colours and opacities in `[0, 1]`. Below the first point the first applies, above the last
//! the last. Opacity is defined for a path of one cell edge; [`corrected_opacity`] rescales
//! it to any segment length so that compositing obeys Beer–Lambert.

use core::fmt;
use glam::Vec3;
use heapless::Vec;

/// Most control points a transfer function holds.
pub const MAX_POINTS: usize = 16;

/// One control point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ControlPoint {
    /// Data value.
    pub value: f32,
    /// Colour, each channel in `[0, 1]`.
    pub color: Vec3,
    /// Opacity of one cell edge of material, in `[0, 1]`.
    pub opacity: f32,
}

/// Why a transfer function cannot be built.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum TransferError {
    /// No control points.
    Empty,
    /// More than [`MAX_POINTS`] points.
    TooMany,
    /// Point `index` does not have a value greater than the point before it, or is not finite.
    NotIncreasing {
        /// Index of the offending point.
        index: usize,
    },
    /// Point `index` has a colour channel or opacity outside `[0, 1]`.
    OutOfRange {
        /// Index of the offending point.
        index: usize,
    },
}

impl fmt::Display for TransferError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            TransferError::Empty => write!(f, "a transfer function needs at least one point"),
            TransferError::TooMany => {
                write!(f, "a transfer function holds at most {MAX_POINTS} points")
            }
            TransferError::NotIncreasing { index } => {
                write!(
                    f,
                    "point {index}: values must be finite and strictly increasing"
                )
            }
            TransferError::OutOfRange { index } => {
                write!(
                    f,
                    "point {index}: colour channels and opacity must lie in [0, 1]"
                )
            }
        }
    }
}

impl core::error::Error for TransferError {}

/// Where a data value falls among a transfer function's control points.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Span {
    /// On point `i`'s value, or beyond the first or last point (which then applies).
    At(usize),
    /// Between points `i` and `i + 1`, the fraction `f` of the way.
    Between(usize, f32),
}

/// A transfer function.
#[derive(Clone, Debug, PartialEq)]
pub struct TransferFunction {
    points: Vec<ControlPoint, MAX_POINTS>,
}

impl TransferFunction {
    /// A transfer function from control points, checked.
    pub fn new(points: &[ControlPoint]) -> Result<TransferFunction, TransferError> {
        if points.is_empty() {
            return Err(TransferError::Empty);
        }
        let points = Vec::from_slice(points).map_err(|()| TransferError::TooMany)?;
        for (index, p) in points.iter().enumerate() {
            if !p.value.is_finite() || (index > 0 && p.value <= points[index - 1].value) {
                return Err(TransferError::NotIncreasing { index });
            }
            let in_unit = |v: f32| (0.0..=1.0).contains(&v);
            if !(p.color.to_array().into_iter().all(in_unit) && in_unit(p.opacity)) {
                return Err(TransferError::OutOfRange { index });
            }
        }
        Ok(TransferFunction { points })
    }

    /// The control points.
    pub fn points(&self) -> &[ControlPoint] {
        &self.points
    }

    /// Where data value `v` falls among the control points: one lookup that
    /// [`TransferFunction::opacity_at`] and [`TransferFunction::color_at`] share, so a sample
    /// found transparent never pays for its colour.
    pub fn span(&self, v: f32) -> Span {
        let pts = &self.points;
        let (first, last) = match (pts.first(), pts.last()) {
            (Some(f), Some(l)) => (f, l),
            _ => return Span::At(0),
        };
        if !(v > first.value) {
            // Also catches NaN: it maps to the first point, never to NaN.
            return Span::At(0);
        }
        if v >= last.value {
            return Span::At(pts.len() - 1);
        }
        // The points at or below `v`, counted without a branch: a binary search's branches
        // follow the data from sample to sample and are mispredicted, and the points are few.
        // The values strictly increase, so this is the search's index; `v` lies strictly
        // inside the domain, so it is at least 1 and below the count.
        let i = pts.iter().map(|p| usize::from(p.value <= v)).sum::<usize>();
        let (a, b) = (&pts[i - 1], &pts[i]);
        Span::Between(i - 1, (v - a.value) / (b.value - a.value))
    }

    /// The per-cell-edge opacity at `span`.
    pub fn opacity_at(&self, span: Span) -> f32 {
        self.mix(span, |p| p.opacity, 0.0, |a, b, f| a + (b - a) * f)
    }

    /// The colour at `span`.
    pub fn color_at(&self, span: Span) -> Vec3 {
        self.mix(span, |p| p.color, Vec3::ZERO, |a, b, f| a + (b - a) * f)
    }

    /// A point's `field` at `span`, or `lerp` between two points' (`none` past the points).
    fn mix<V: Copy>(
        &self,
        span: Span,
        field: impl Fn(&ControlPoint) -> V,
        none: V,
        lerp: impl Fn(V, V, f32) -> V,
    ) -> V {
        match span {
            Span::At(i) => self.points.get(i).map_or(none, field),
            Span::Between(i, f) => match (self.points.get(i), self.points.get(i + 1)) {
                (Some(a), Some(b)) => lerp(field(a), field(b), f),
                _ => none,
            },
        }
    }

    /// Colour and per-cell-edge opacity at data value `v`.
    pub fn eval(&self, v: f32) -> (Vec3, f32) {
        let span = self.span(v);
        (self.color_at(span), self.opacity_at(span))
    }

    /// The values of the first and last control points: outside them the function is
    /// constant.
    pub fn domain(&self) -> (f32, f32) {
        match (self.points.first(), self.points.last()) {
            (Some(f), Some(l)) => (f.value, l.value),
            _ => (0.0, 0.0),
        }
    }

    /// The opacity of [`TransferFunction::eval`] alone (equal to it in every bit).
    pub fn opacity(&self, v: f32) -> f32 {
        self.opacity_at(self.span(v))
    }
}

impl TransferFunction {
    /// The greatest opacity over values in `[lo, hi]`: a piecewise-linear function is greatest
    /// at an end or at a control point between.
    pub fn max_opacity(&self, lo: f32, hi: f32) -> f32 {
        let inner = self
            .points
            .iter()
            .filter(|p| p.value > lo && p.value < hi)
            .map(|p| p.opacity);
        inner.fold(self.opacity(lo).max(self.opacity(hi)), f32::max)
    }
}

/// Opacity of a segment `length_in_edges` cell edges long of material whose one-edge opacity
/// is `alpha`: `1 - (1 - alpha)^length`, computed as `1 - exp(length · ln(1 - alpha))`.
#[inline]
pub fn corrected_opacity(alpha: f32, length_in_edges: f32) -> f32 {
    if !(alpha > 0.0) || !(length_in_edges > 0.0) {
        return 0.0;
    }
    if alpha >= 1.0 {
        return 1.0;
    }
    1.0 - libm::expf(length_in_edges * libm::log1pf(-alpha))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cp(value: f32, c: f32, opacity: f32) -> ControlPoint {
        ControlPoint {
            value,
            color: Vec3::splat(c),
            opacity,
        }
    }

    #[test]
    fn evaluates_piecewise_linearly_and_clamps() {
        let tf = TransferFunction::new(&[cp(10.0, 0.0, 0.0), cp(20.0, 1.0, 0.5)]).unwrap();
        assert_eq!(tf.eval(0.0), (Vec3::ZERO, 0.0));
        assert_eq!(tf.eval(15.0), (Vec3::splat(0.5), 0.25));
        assert_eq!(tf.eval(99.0), (Vec3::ONE, 0.5));
        assert_eq!(tf.eval(f32::NAN), (Vec3::ZERO, 0.0));
    }

    #[test]
    fn opacity_alone_equals_eval_in_every_bit() {
        let tf =
            TransferFunction::new(&[cp(10.0, 0.2, 0.0), cp(60.0, 0.7, 0.15), cp(200.0, 1.0, 0.8)])
                .unwrap();
        for i in -100..3000 {
            let v = i as f32 * 0.1 + 0.013;
            assert_eq!(tf.opacity(v).to_bits(), tf.eval(v).1.to_bits(), "{v}");
        }
        assert_eq!(tf.opacity(f32::NAN), 0.0);
    }

    /// What `span` finds by counting is what a binary search over the points finds (its form
    /// before), for functions of every length and values on, beside and between the points.
    #[test]
    fn the_segment_counted_is_the_one_a_binary_search_finds() {
        let searched = |tf: &TransferFunction, v: f32| {
            let pts = tf.points();
            let (first, last) = (pts[0].value, pts[pts.len() - 1].value);
            if !(v > first) {
                Span::At(0)
            } else if v >= last {
                Span::At(pts.len() - 1)
            } else {
                let i = pts.partition_point(|p| p.value <= v);
                Span::Between(
                    i - 1,
                    (v - pts[i - 1].value) / (pts[i].value - pts[i - 1].value),
                )
            }
        };
        for n in 1..=MAX_POINTS {
            // Uneven steps, so that no two segments are alike.
            let points: Vec<ControlPoint, MAX_POINTS> = (0..n)
                .map(|i| cp(i as f32 * 7.0 + (i * i) as f32 * 0.37 - 20.0, 0.5, 0.1))
                .collect();
            let tf = TransferFunction::new(&points).unwrap();
            let mut values: Vec<f32, 512> = Vec::new();
            for p in tf.points() {
                let v = p.value;
                for w in [
                    v,
                    v * (1.0 + f32::EPSILON),
                    v * (1.0 - f32::EPSILON),
                    v + 0.5,
                    v - 0.5,
                    v + 3.3,
                ] {
                    let _ = values.push(w);
                }
            }
            for w in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY, -1e30, 1e30] {
                let _ = values.push(w);
            }
            for &v in &values {
                let (got, want) = (tf.span(v), searched(&tf, v));
                match (got, want) {
                    (Span::Between(i, f), Span::Between(j, g)) => {
                        assert_eq!((i, f.to_bits()), (j, g.to_bits()), "{n} points, {v}")
                    }
                    _ => assert_eq!(got, want, "{n} points, {v}"),
                }
            }
        }
    }

    #[test]
    fn bad_functions_are_refused() {
        assert_eq!(TransferFunction::new(&[]), Err(TransferError::Empty));
        assert_eq!(
            TransferFunction::new(&[cp(1.0, 0.0, 0.0), cp(1.0, 0.0, 0.0)]),
            Err(TransferError::NotIncreasing { index: 1 })
        );
        assert_eq!(
            TransferFunction::new(&[cp(1.0, 2.0, 0.0)]),
            Err(TransferError::OutOfRange { index: 0 })
        );
        assert_eq!(
            TransferFunction::new(&[cp(0.0, 0.0, 0.0); 17]),
            Err(TransferError::TooMany)
        );
    }

    #[test]
    fn opacity_correction_composes_like_beer_lambert() {
        let a = corrected_opacity(0.3, 1.0);
        assert!((a - 0.3).abs() < 1e-6);
        let half = corrected_opacity(0.3, 0.5);
        assert!(((1.0 - half) * (1.0 - half) - 0.7).abs() < 1e-6);
        assert_eq!(corrected_opacity(1.0, 0.5), 1.0);
        assert_eq!(corrected_opacity(1.0, 0.0), 0.0);
        assert_eq!(corrected_opacity(f32::NAN, 1.0), 0.0);
    }
}

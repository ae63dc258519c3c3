//! Lights and local illumination: Lambert diffuse, Phong specular and ambient, from a normal
//! derived from the object-space gradient.
//!
//! Invariants: a normal is always unit and finite. The gradient points toward higher values,
//! so the surface normal is its opposite (pointing out of `{ f ≥ iso }`). A gradient whose
//! squared length is not above [`MIN_GRADIENT_SQUARED`] (zero, tiny or NaN) is replaced by the
//! fallback normal: the direction back toward the viewer, which lights the point as if it faced
//! the eye, the least surprising choice for flat or constant data. Lighting is two-sided: the
//! normal is flipped to face the viewer. Point lights do not attenuate with distance.

use core::fmt;
use glam::{Vec3, Vec3A};

/// Most lights one view has.
pub const MAX_LIGHTS: usize = 4;

/// Below this squared gradient length (field units per world unit, squared) a gradient gives
/// no usable direction and the fallback normal is used.
pub const MIN_GRADIENT_SQUARED: f32 = 1e-12;

/// Where a light is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightKind {
    /// Infinitely far; `direction` is the unit direction light travels (from light to scene).
    Directional {
        /// Unit direction of travel, world.
        direction: Vec3,
    },
    /// At a world position (inside the volume or out).
    Point {
        /// World position.
        position: Vec3,
    },
}

/// A light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Light {
    /// Where it is.
    pub kind: LightKind,
    /// Colour and intensity, each channel `≥ 0`.
    pub color: Vec3,
    /// Whether it casts shadows (traces shadow rays).
    pub shadows: bool,
}

/// Why a light is unusable.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LightError {
    /// Direction zero or not finite.
    Direction,
    /// Position not finite.
    Position,
    /// Colour channel negative or not finite.
    Color,
}

impl fmt::Display for LightError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            LightError::Direction => "direction must be finite and non-zero",
            LightError::Position => "position must be finite",
            LightError::Color => "color channels must be finite and >= 0",
        })
    }
}

impl core::error::Error for LightError {}

impl Light {
    /// A directional light travelling along `direction` (normalised here).
    pub fn directional(direction: Vec3, color: Vec3, shadows: bool) -> Result<Light, LightError> {
        let direction = direction.normalize_or_zero();
        if direction == Vec3::ZERO || !direction.is_finite() {
            return Err(LightError::Direction);
        }
        Light::checked(Light {
            kind: LightKind::Directional { direction },
            color,
            shadows,
        })
    }

    /// A point light at `position`.
    pub fn point(position: Vec3, color: Vec3, shadows: bool) -> Result<Light, LightError> {
        if !position.is_finite() {
            return Err(LightError::Position);
        }
        Light::checked(Light {
            kind: LightKind::Point { position },
            color,
            shadows,
        })
    }

    fn checked(light: Light) -> Result<Light, LightError> {
        if light.color.is_finite() && light.color.min_element() >= 0.0 {
            Ok(light)
        } else {
            Err(LightError::Color)
        }
    }

    /// The direction [`Light::toward`] gives from every point, for a directional light;
    /// `None` for a point light, whose direction depends on the point.
    pub fn toward_everywhere(&self) -> Option<Vec3> {
        match self.kind {
            LightKind::Directional { direction } => Some(-direction),
            LightKind::Point { .. } => None,
        }
    }

    /// Unit direction from world point `p` toward the light and the distance to it (infinite
    /// for a directional light); `None` when `p` is at the light.
    pub fn toward(&self, p: Vec3) -> Option<(Vec3, f32)> {
        match self.kind {
            LightKind::Directional { direction } => Some((-direction, f32::INFINITY)),
            LightKind::Point { position } => {
                let d = position - p;
                let dist = d.length();
                (dist > 0.0 && dist.is_finite()).then(|| (d / dist, dist))
            }
        }
    }
}

/// Coefficients of the illumination model.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shading {
    /// Ambient coefficient.
    pub ambient: f32,
    /// Lambert diffuse coefficient.
    pub diffuse: f32,
    /// Phong specular coefficient.
    pub specular: f32,
    /// Phong exponent.
    pub shininess: f32,
}

impl Default for Shading {
    fn default() -> Shading {
        Shading {
            ambient: 0.2,
            diffuse: 0.7,
            specular: 0.3,
            shininess: 24.0,
        }
    }
}

/// The unit normal facing the viewer at a point with world gradient `gradient`, seen along
/// `view_dir`; and whether the fallback was used.
// Always inlined: the exact tier's composited loop shades by it on every sample that shows,
// and the compiler's own choice, which moved with unrelated code, cost a call each.
#[inline(always)]
pub fn normal(gradient: Vec3, view_dir: Vec3) -> (Vec3, bool) {
    if !usable(gradient) {
        return (-view_dir, true);
    }
    let n = -gradient / libm::sqrtf(gradient.length_squared());
    (face_viewer(n, view_dir), false)
}

/// Whether `gradient` gives a direction to shade by: its squared length finite and above
/// [`MIN_GRADIENT_SQUARED`].
#[inline(always)]
pub fn usable(gradient: Vec3) -> bool {
    let len2 = gradient.length_squared();
    len2 > MIN_GRADIENT_SQUARED && len2.is_finite()
}

/// `n` or `-n`, whichever faces against `view_dir`.
#[inline]
pub fn face_viewer(n: Vec3, view_dir: Vec3) -> Vec3 {
    if n.dot(view_dir) > 0.0 {
        -n
    } else {
        n
    }
}

/// The light `light_dir` (unit, toward the light) of colour `light_color` reflects off a
/// point of colour `base` with unit normal `n`, seen along `view_dir`: Lambert plus Phong,
/// before shadowing. Zero when the light is behind the surface. With `highlights` (the fast
/// tier) the highlight is read from that table instead of `powf`.
///
/// Computed in glam's `Vec3A`, whose fourth lane repeats the third: the same operations as
/// `Vec3`'s, lane for lane, and the same order in the dot products, so the same bits. Inlined
/// into a sample loop, `Vec3` arithmetic packed into vector registers leaves stale values in
/// the unused lane, and a stale subnormal there costs a microcode assist on every multiply
/// (docs/speed-log.md); a lane that repeats a real component cannot be stale.
#[inline(always)]
pub fn direct(
    s: &Shading,
    highlights: Option<&Highlights>,
    base: Vec3,
    n: Vec3,
    view_dir: Vec3,
    light_dir: Vec3,
    light_color: Vec3,
) -> Vec3 {
    let Some((n_dot_l, r_dot_v)) = cosines(n, view_dir, light_dir) else {
        return Vec3::ZERO;
    };
    let diffuse = Vec3A::from(base) * (s.diffuse * n_dot_l);
    let specular = match highlights {
        Some(table) if r_dot_v > 0.0 => table.at(r_dot_v),
        None if r_dot_v > 0.0 && !highlight_vanishes(diffuse.into(), s, r_dot_v) => {
            s.specular * libm::powf(r_dot_v, s.shininess)
        }
        _ => 0.0,
    };
    (Vec3A::from(light_color) * (diffuse + Vec3A::splat(specular))).into()
}

/// The cosines Lambert and Phong weigh a light by, at unit normal `n` seen along `view_dir`,
/// the light toward `light_dir`: the normal's with the light, and the reflection's with the
/// way back to the viewer; `None` when the light is behind the surface. In `Vec3A`, as
/// [`direct`] says why.
#[inline(always)]
fn cosines(n: Vec3, view_dir: Vec3, light_dir: Vec3) -> Option<(f32, f32)> {
    let (n, light_dir) = (Vec3A::from(n), Vec3A::from(light_dir));
    let n_dot_l = n.dot(light_dir);
    if !(n_dot_l > 0.0) {
        return None;
    }
    let reflected = n * (2.0 * n_dot_l) - light_dir;
    Some((n_dot_l, reflected.dot(-Vec3A::from(view_dir))))
}

/// What [`direct`] multiplies the light's colour by, split for a point of any colour: the
/// diffuse coefficient (to multiply the point's colour by) and the highlight (by `powf`);
/// both zero when the light is behind the surface.
pub fn terms(s: &Shading, n: Vec3, view_dir: Vec3, light_dir: Vec3) -> (f32, f32) {
    let Some((n_dot_l, r_dot_v)) = cosines(n, view_dir, light_dir) else {
        return (0.0, 0.0);
    };
    let specular = if r_dot_v > 0.0 {
        s.specular * libm::powf(r_dot_v, s.shininess)
    } else {
        0.0
    };
    (s.diffuse * n_dot_l, specular)
}

/// Intervals of the fast tier's highlight table over cosines in `[0, 1]`.
pub const HIGHLIGHT_STEPS: usize = 1024;

/// The fast tier's highlights: `specular · x^shininess` tabulated at [`HIGHLIGHT_STEPS`] + 1
/// evenly spaced cosines `x` in `[0, 1]` and read by linear interpolation, as production
/// ray casters shade from tables. Built from the shading alone, the same bits on every node.
#[derive(Clone, Debug, PartialEq)]
pub struct Highlights {
    table: [f32; HIGHLIGHT_STEPS + 1],
}

impl Highlights {
    /// The table of `s`'s highlight.
    pub fn new(s: &Shading) -> Highlights {
        let mut table = [0.0; HIGHLIGHT_STEPS + 1];
        for (i, t) in table.iter_mut().enumerate() {
            *t = s.specular * libm::powf(i as f32 / HIGHLIGHT_STEPS as f32, s.shininess);
        }
        Highlights { table }
    }

    /// The highlight at cosine `x` (above 0; 1 and beyond, and NaN, read the last entry).
    #[inline]
    pub fn at(&self, x: f32) -> f32 {
        // In [0, HIGHLIGHT_STEPS] (NaN reads 1), where truncation floors.
        #[allow(
            clippy::manual_clamp,
            reason = "`clamp` keeps a NaN, which must read the last entry"
        )]
        let f = x.min(1.0).max(0.0) * HIGHLIGHT_STEPS as f32;
        let i = (voxcube_simd::trunc_u32(f) as usize).min(HIGHLIGHT_STEPS - 1);
        let (a, b) = (self.table[i], self.table[i + 1]);
        a + (b - a) * (f - i as f32)
    }
}

/// The greatest whole exponent [`highlight_vanishes`] raises a cosine to.
const POWER_CAP: u32 = 64;

/// `2⁻¹⁰⁰`: [`highlight_vanishes`] takes a smaller power as this, far above what underflow in
/// its squaring can lose.
const POWER_FLOOR: f32 = f32::from_bits(0x0d80_0000);

/// Whether the highlight `s.specular · powf(x, s.shininess)` (`x` the reflection's cosine,
/// above 0) would leave every channel of `diffuse` unchanged when added to it: then `powf`
/// is not called (on a composited frame many of its calls change nothing:
/// docs/speed-log.md), and the colour is the same in every bit. Shown from an upper bound,
/// never from `powf`:
/// - for `0 < x < 1` and an exponent of at least `n` (its whole part, at most
///   [`POWER_CAP`]), `x^shininess ≤ x^n`;
/// - `x^n` by repeated squaring in `f32` errs by less than `(n + 12)·2⁻²⁴ < 2⁻¹⁷` of itself
///   in the normal range, and a result below `2⁻¹⁰⁰` is taken as `2⁻¹⁰⁰`, above whatever
///   underflow lost;
/// - `powf` is allowed twice the exact power (it errs by a few units in the last place), and
///   the product with `specular` rounds by `2⁻²⁴`;
/// - a non-negative term below half a unit in the last place of a positive, normal channel
///   rounds back to that channel (round to nearest).
///
/// So when 16 times `specular` times the bound is at most the least channel's unit in the
/// last place, the term is below half of it with room, and adding it is adding 0.
#[inline]
fn highlight_vanishes(diffuse: Vec3, s: &Shading, x: f32) -> bool {
    // Every channel positive and normal (a NaN is not; an infinite one stays so).
    if !(x < 1.0) || !diffuse.cmpge(Vec3::splat(f32::MIN_POSITIVE)).all() {
        return false;
    }
    // `View::new` holds the exponent finite and not negative.
    let mut exponent = (s.shininess as u32).min(POWER_CAP);
    let (mut power, mut square) = (1.0f32, x);
    while exponent > 0 {
        if exponent & 1 == 1 {
            power *= square;
        }
        square *= square;
        exponent >>= 1;
    }
    let bound = power.max(POWER_FLOOR);
    // The least unit in the last place is the least channel's.
    let least = diffuse.min_element();
    let least_ulp = f32::from_bits(least.to_bits() + 1) - least;
    16.0 * s.specular * bound <= least_ulp
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_highlight_table_is_within_a_hundredth_of_a_level_of_powf() {
        let s = Shading::default();
        let table = Highlights::new(&s);
        assert_eq!(table.at(1.0), s.specular);
        assert_eq!(table.at(2.0), s.specular, "beyond 1 reads the last entry");
        assert_eq!(
            table.at(f32::NAN),
            s.specular,
            "NaN reads the last entry, never NaN"
        );
        let mut worst = 0.0f32;
        for i in 1..=20_000 {
            let x = i as f32 / 20_000.0;
            let exact = s.specular * libm::powf(x, s.shininess);
            worst = worst.max((table.at(x) - exact).abs());
        }
        assert!(worst < 1e-2 / 255.0, "worst error {worst}");
    }

    #[test]
    fn degenerate_gradients_fall_back_to_facing_the_viewer() {
        let view = Vec3::new(0.0, 0.0, -1.0);
        assert_eq!(normal(Vec3::ZERO, view), (Vec3::Z, true));
        assert_eq!(normal(Vec3::NAN, view), (Vec3::Z, true));
        assert_eq!(normal(Vec3::splat(f32::INFINITY), view), (Vec3::Z, true));
        let (n, fallback) = normal(Vec3::new(0.0, 0.0, -3.0), view);
        assert!(!fallback);
        assert_eq!(n, Vec3::Z);
        // Two-sided: a gradient pointing at the viewer still gives a normal facing it.
        assert_eq!(normal(Vec3::new(0.0, 0.0, 3.0), view).0, Vec3::Z);
    }

    #[test]
    fn lights_behind_the_surface_add_nothing() {
        let s = Shading::default();
        let d = direct(&s, None, Vec3::ONE, Vec3::Z, -Vec3::Z, -Vec3::Z, Vec3::ONE);
        assert_eq!(d, Vec3::ZERO);
        let d = direct(&s, None, Vec3::ONE, Vec3::Z, -Vec3::Z, Vec3::Z, Vec3::ONE);
        assert!((d - Vec3::splat(s.diffuse + s.specular)).length() < 1e-6);
    }

    /// The illumination model as written before [`highlight_vanishes`]: `powf` on every
    /// positive cosine.
    fn phong(s: &Shading, base: Vec3, n: Vec3, view: Vec3, light: Vec3, color: Vec3) -> Vec3 {
        let n_dot_l = n.dot(light);
        if !(n_dot_l > 0.0) {
            return Vec3::ZERO;
        }
        let r_dot_v = (n * (2.0 * n_dot_l) - light).dot(-view);
        let specular = if r_dot_v > 0.0 {
            s.specular * libm::powf(r_dot_v, s.shininess)
        } else {
            0.0
        };
        color * (base * (s.diffuse * n_dot_l) + Vec3::splat(specular))
    }

    /// Near the line: cosines whose highlight is from a thousandth of the least channel's
    /// unit in the last place to 64 of them, for exponents whole and not, below 1 and past
    /// [`POWER_CAP`], channels across binades and on their edges. Where the highlight is said
    /// to vanish, adding it changes no channel. The check has something to catch: the cases
    /// where a highlight under two units changes a channel (what a rule letting such terms
    /// through would miss) are counted, as are the cases passed over.
    #[test]
    fn a_highlight_said_to_vanish_changes_no_channel() {
        let mut next = crate::testing::xorshift(0x5bec_0001);
        let mut unit = move || (next() >> 8) as f32 / (1u32 << 24) as f32;
        let (mut vanished, mut caught) = (0u32, 0u32);
        for case in 0..200_000 {
            let channel = |u: f32, edge: bool| match edge {
                // A power of two: the unit above it is twice the one below.
                true => libm::exp2f(libm::floorf(-20.0 * u)),
                false => libm::exp2f(-20.0 * u + 2.0),
            };
            let edge = case % 7 == 0;
            let diffuse = Vec3::new(
                channel(unit(), edge),
                channel(unit(), false),
                channel(unit(), false),
            );
            let s = Shading {
                specular: [0.0, 0.01, 0.3, 1.0, 5.0][case % 5] * (0.5 + unit()),
                shininess: [0.0, 0.5, 1.0, 3.0, 7.5, 24.0, 24.9, 64.0, 200.0][case % 9],
                ..Shading::default()
            };
            let least = diffuse.min_element();
            let ulp = f32::from_bits(least.to_bits() + 1) - least;
            // A cosine whose highlight is about `k` units of the least channel.
            let k = libm::exp2(f64::from(unit()) * 16.0 - 10.0);
            let x = match s.specular > 0.0 && s.shininess > 0.0 {
                true => libm::pow(
                    k * f64::from(ulp) / f64::from(s.specular),
                    1.0 / f64::from(s.shininess),
                ) as f32,
                false => unit(),
            };
            if !(x > 0.0 && x < 1.0) {
                continue;
            }
            let term = s.specular * libm::powf(x, s.shininess);
            let changed = (diffuse + Vec3::splat(term)) != diffuse;
            if highlight_vanishes(diffuse, &s, x) {
                vanished += 1;
                assert!(
                    !changed,
                    "case {case}: {diffuse:?} {s:?} x = {x}: the highlight {term} shows"
                );
            } else if changed && term < 2.0 * ulp {
                caught += 1;
            }
        }
        assert!(vanished > 20_000, "only {vanished} highlights passed over");
        assert!(caught > 5_000, "only {caught} small highlights that show");
    }

    /// The light a point reflects is the model's in every bit, `powf` called or not: random
    /// normals, lights and views (many highlights faint, some bright), colours with a channel
    /// at zero, and the coefficients across their range.
    #[test]
    fn direct_light_is_the_phong_model_in_every_bit() {
        let mut next = crate::testing::xorshift(0x5bec_0002);
        let mut unit = move || (next() >> 8) as f32 / (1u32 << 24) as f32;
        let direction = |unit: &mut dyn FnMut() -> f32| {
            let v = Vec3::new(unit() - 0.5, unit() - 0.5, unit() - 0.5);
            v.try_normalize().unwrap_or(Vec3::Z)
        };
        for case in 0..100_000 {
            let (n, view, light) = (
                direction(&mut unit),
                direction(&mut unit),
                direction(&mut unit),
            );
            let mut base = Vec3::new(unit(), unit(), unit());
            if case % 7 == 0 {
                base.y = 0.0;
            }
            let s = Shading {
                ambient: 0.2,
                diffuse: unit(),
                specular: [0.0, 0.3, 1.0, 4.0][case % 4] * unit(),
                shininess: [0.0, 0.7, 2.0, 24.0, 100.0][case % 5],
            };
            let color = Vec3::new(unit(), 1.0, 2.0 * unit());
            let (ours, model) = (
                direct(&s, None, base, n, view, light, color),
                phong(&s, base, n, view, light, color),
            );
            assert_eq!(
                ours.to_array().map(f32::to_bits),
                model.to_array().map(f32::to_bits),
                "case {case}"
            );
        }
    }

    #[test]
    fn bad_lights_are_refused() {
        assert_eq!(
            Light::directional(Vec3::ZERO, Vec3::ONE, false),
            Err(LightError::Direction)
        );
        assert_eq!(
            Light::point(Vec3::NAN, Vec3::ONE, false),
            Err(LightError::Position)
        );
        assert_eq!(
            Light::point(Vec3::ZERO, -Vec3::ONE, false),
            Err(LightError::Color)
        );
        let l = Light::point(Vec3::X, Vec3::ONE, true).unwrap();
        assert_eq!(l.toward(Vec3::X), None);
    }
}

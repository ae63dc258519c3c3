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
use glam::Vec3;

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
pub fn normal(gradient: Vec3, view_dir: Vec3) -> (Vec3, bool) {
    let len2 = gradient.length_squared();
    if !(len2 > MIN_GRADIENT_SQUARED) || !len2.is_finite() {
        return (-view_dir, true);
    }
    let n = -gradient / libm::sqrtf(len2);
    (face_viewer(n, view_dir), false)
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
/// before shadowing. Zero when the light is behind the surface.
pub fn direct(
    s: &Shading,
    base: Vec3,
    n: Vec3,
    view_dir: Vec3,
    light_dir: Vec3,
    light_color: Vec3,
) -> Vec3 {
    let n_dot_l = n.dot(light_dir);
    if !(n_dot_l > 0.0) {
        return Vec3::ZERO;
    }
    let reflected = n * (2.0 * n_dot_l) - light_dir;
    let r_dot_v = reflected.dot(-view_dir);
    let specular = if r_dot_v > 0.0 {
        s.specular * libm::powf(r_dot_v, s.shininess)
    } else {
        0.0
    };
    light_color * (base * (s.diffuse * n_dot_l) + Vec3::splat(specular))
}

#[cfg(test)]
mod tests {
    use super::*;

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
        let d = direct(&s, Vec3::ONE, Vec3::Z, -Vec3::Z, -Vec3::Z, Vec3::ONE);
        assert_eq!(d, Vec3::ZERO);
        let d = direct(&s, Vec3::ONE, Vec3::Z, -Vec3::Z, Vec3::Z, Vec3::ONE);
        assert!((d - Vec3::splat(s.diffuse + s.specular)).length() < 1e-6);
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

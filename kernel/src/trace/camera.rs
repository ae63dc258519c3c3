//! The camera: an orthonormal frame at the eye and a projection, giving each pixel's primary
//! ray in world space.
//!
//! Invariants: `forward`, `right` and `up` are unit and mutually orthogonal; a camera is built
//! only from a finite eye, a target distinct from it, and an up vector not parallel to the
//! view direction. Pixel `(px, py)` is sampled at its centre; row 0 is the top of the image.

use core::fmt;
use glam::Vec3;

/// How the image plane maps to rays.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Projection {
    /// Parallel rays; `width` world units span the image width.
    Orthographic {
        /// World width of the image.
        width: f32,
    },
    /// Rays from the eye; `fov_y` radians span the image height.
    Perspective {
        /// Vertical field of view, radians, in `(0, π)`.
        fov_y: f32,
    },
}

/// Why a camera cannot be built.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CameraError {
    /// Eye, target or up is not finite.
    NotFinite,
    /// Eye and target coincide: there is no view direction.
    EyeAtTarget,
    /// `up` is zero or parallel to the view direction.
    UpParallel,
    /// Orthographic width not finite and positive, or field of view outside `(0, π)`.
    BadProjection,
}

impl fmt::Display for CameraError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            CameraError::NotFinite => "eye, look_at and up must be finite",
            CameraError::EyeAtTarget => {
                "eye and look_at are the same point: there is no view direction"
            }
            CameraError::UpParallel => "up is zero or parallel to the view direction",
            CameraError::BadProjection => {
                "orthographic width must be finite and > 0, perspective fov in (0, 180) degrees"
            }
        })
    }
}

impl core::error::Error for CameraError {}

/// A camera.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    eye: Vec3,
    forward: Vec3,
    right: Vec3,
    up: Vec3,
    projection: Projection,
}

impl Camera {
    /// A camera at `eye` looking at `target`, `up` pointing to the top of the image.
    pub fn look_at(
        eye: Vec3,
        target: Vec3,
        up: Vec3,
        projection: Projection,
    ) -> Result<Camera, CameraError> {
        if !(eye.is_finite() && target.is_finite() && up.is_finite()) {
            return Err(CameraError::NotFinite);
        }
        let forward = (target - eye).normalize_or_zero();
        if forward == Vec3::ZERO {
            return Err(CameraError::EyeAtTarget);
        }
        let right = forward.cross(up).normalize_or_zero();
        if right == Vec3::ZERO || right.length_squared() < 0.5 {
            return Err(CameraError::UpParallel);
        }
        let up = right.cross(forward);
        let ok = match projection {
            Projection::Orthographic { width } => width.is_finite() && width > 0.0,
            Projection::Perspective { fov_y } => fov_y > 0.0 && fov_y < core::f32::consts::PI,
        };
        if !ok {
            return Err(CameraError::BadProjection);
        }
        Ok(Camera {
            eye,
            forward,
            right,
            up,
            projection,
        })
    }

    /// The eye position (world).
    pub fn eye(&self) -> Vec3 {
        self.eye
    }

    /// The unit view direction (world).
    pub fn forward(&self) -> Vec3 {
        self.forward
    }

    /// The unit vectors toward the image's right and top (world).
    pub fn image_axes(&self) -> (Vec3, Vec3) {
        (self.right, self.up)
    }

    /// The projection.
    pub fn projection(&self) -> Projection {
        self.projection
    }

    /// World-space origin and unit direction of the ray through the centre of pixel
    /// `(px, py)` of a `width × height` image. Always inline (`#[inline]` alone was not
    /// taken): returned from a call, the pair goes through the stack, and the caller's
    /// 16-byte load of a 12-byte vector waits for the stores to retire (a store-forwarding
    /// stall on every primary ray's set-up).
    #[inline(always)]
    pub fn primary(&self, px: u32, py: u32, width: u32, height: u32) -> (Vec3, Vec3) {
        let (w, h) = (width.max(1) as f32, height.max(1) as f32);
        // Image-plane coordinates in [-1/2, 1/2] of the width and height.
        let sx = (px as f32 + 0.5) / w - 0.5;
        let sy = 0.5 - (py as f32 + 0.5) / h;
        match self.projection {
            Projection::Orthographic { width } => {
                let height = width * h / w;
                (
                    self.eye + self.right * (sx * width) + self.up * (sy * height),
                    self.forward,
                )
            }
            Projection::Perspective { fov_y } => {
                let half_h = libm::tanf(0.5 * fov_y);
                let half_w = half_h * w / h;
                let dir =
                    self.forward + self.right * (2.0 * sx * half_w) + self.up * (2.0 * sy * half_h);
                (self.eye, dir.normalize())
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orthographic_pixels_are_parallel_and_centred() {
        let cam = Camera::look_at(
            Vec3::new(0.0, 0.0, 10.0),
            Vec3::ZERO,
            Vec3::Y,
            Projection::Orthographic { width: 4.0 },
        )
        .unwrap();
        let (o, d) = cam.primary(0, 0, 4, 2);
        assert_eq!(d, -Vec3::Z);
        assert_eq!(o, Vec3::new(-1.5, 0.5, 10.0));
        let (o, _) = cam.primary(3, 1, 4, 2);
        assert_eq!(o, Vec3::new(1.5, -0.5, 10.0));
    }

    #[test]
    fn perspective_centre_ray_is_the_view_direction() {
        let cam = Camera::look_at(
            Vec3::ZERO,
            Vec3::X,
            Vec3::Z,
            Projection::Perspective { fov_y: 1.0 },
        )
        .unwrap();
        let (_, d) = cam.primary(1, 1, 3, 3);
        assert!((d - Vec3::X).length() < 1e-6);
    }

    #[test]
    fn degenerate_cameras_are_refused() {
        let ortho = Projection::Orthographic { width: 1.0 };
        assert_eq!(
            Camera::look_at(Vec3::ONE, Vec3::ONE, Vec3::Y, ortho),
            Err(CameraError::EyeAtTarget)
        );
        assert_eq!(
            Camera::look_at(Vec3::ZERO, Vec3::Y, Vec3::Y, ortho),
            Err(CameraError::UpParallel)
        );
        assert_eq!(
            Camera::look_at(Vec3::NAN, Vec3::Y, Vec3::Y, ortho),
            Err(CameraError::NotFinite)
        );
        let bad = Projection::Perspective { fov_y: 4.0 };
        assert_eq!(
            Camera::look_at(Vec3::ZERO, Vec3::X, Vec3::Y, bad),
            Err(CameraError::BadProjection)
        );
    }
}

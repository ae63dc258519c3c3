//! The whole state of a ray in flight: what a forwarded-ray message carries, so that a ray
//! continues on the next node exactly where it stopped; and why a sample loop stopped it.
//!
//! Invariant: a ray's position is its lattice index `k`, never an accumulated float; every
//! field a node needs to go on is here, so a ray's result does not depend on where it ran.

use crate::trace::lattice::Lattice;
use crate::trace::ray::{Entry, Ray};
use glam::Vec3;

/// What a ray is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RayKind {
    /// From the eye through a pixel.
    Primary,
    /// Continuing a primary ray past a semi-transparent surface.
    Transparency,
    /// From a surface point toward a shadow-casting light.
    Shadow,
}

/// All the state of a ray in flight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RayState {
    /// What the ray is for.
    pub kind: RayKind,
    /// The pixel it contributes to (row-major).
    pub pixel: u32,
    /// The ray.
    pub ray: Ray,
    /// Its samples.
    pub lattice: Lattice,
    /// How it entered the volume (for capping).
    pub entry: Entry,
    /// Next sample to process.
    pub k: u32,
    /// Field value of sample `k - 1`, valid when `primed`.
    pub prev: f32,
    /// Whether `prev` holds a sample of this ray.
    pub primed: bool,
    /// Whether `prev` was skipped: its value is unknown but below every iso value (it is
    /// evaluated again, exactly, before it is needed).
    pub prev_stale: bool,
    /// Surfaces (bit per index) already reported on the segment ending at sample `k`.
    pub done_here: u16,
    /// Transparency rays between the primary ray and this one.
    pub depth: u8,
    /// Light still reaching the eye from here: for primary and transparency rays the product
    /// of `1 − opacity` of the surfaces in front; for shadow rays the visibility so far; when
    /// compositing the transmittance.
    pub weight: f32,
    /// Colour accumulated front to back (compositing).
    pub color: Vec3,
}

impl RayState {
    /// A fresh ray starting at sample `k`.
    pub fn new(
        kind: RayKind,
        pixel: u32,
        ray: Ray,
        lattice: Lattice,
        entry: Entry,
        k: u32,
    ) -> RayState {
        RayState {
            kind,
            pixel,
            ray,
            lattice,
            entry,
            k,
            prev: 0.0,
            primed: false,
            prev_stale: false,
            done_here: 0,
            depth: 0,
            weight: 1.0,
            color: Vec3::ZERO,
        }
    }
}

/// A surface crossing.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Index of the surface in the view.
    pub surface: u8,
    /// Ray parameter of the crossing.
    pub t: f32,
    /// Index-space position.
    pub point: Vec3,
    /// For a cut face where the ray entered the volume: its normal (world).
    pub cap_normal: Option<Vec3>,
}

/// Why marching stopped.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Stop {
    /// Crossed a surface (primary and transparency rays).
    Hit(Hit),
    /// The next sample belongs to `plane`, which this slab does not own.
    Leave {
        /// The owner plane of the next sample.
        plane: u32,
    },
    /// No samples left: the ray has left the volume.
    Exit,
    /// Too little light left for anything behind to show.
    Terminated,
}

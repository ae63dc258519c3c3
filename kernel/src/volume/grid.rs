//! The regular grid of a dataset: its dimensions, its spacing, the interpolation model, and
//! the integer rule that says which X plane owns a sample.
//!
//! Invariants: every dimension is at least 1 and the sample count fits in `usize`; spacing is
//! finite and positive. World coordinates are index coordinates times spacing, so voxel
//! `(0, 0, 0)` sits at the world origin.

use core::fmt;
use glam::{Vec3, Vec4};

/// How values between grid nodes are defined (the paper's two readings of a regular dataset).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Model {
    /// *Voxel-based*: the value is constant in the cube around each node (nearest neighbour).
    /// The dataset occupies `[-0.5, n - 0.5]` on each axis.
    Voxel,
    /// *Cell-based*: the value varies trilinearly inside each cell between eight nodes.
    /// The dataset occupies `[0, n - 1]` on each axis.
    Cell,
}

/// Why a grid cannot be built.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum GridError {
    /// A dimension is zero.
    ZeroDimension {
        /// Axis index (0 = X).
        axis: usize,
    },
    /// The product of the dimensions overflows `usize`.
    TooManySamples,
    /// A dimension exceeds [`MAX_DIM`].
    TooLong {
        /// Axis index (0 = X).
        axis: usize,
        /// The dimension.
        n: u32,
    },
    /// A spacing component is not finite and positive.
    BadSpacing {
        /// Axis index (0 = X).
        axis: usize,
        /// The offending value.
        value: f32,
    },
}

impl fmt::Display for GridError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        const AXES: [&str; 3] = ["x", "y", "z"];
        match *self {
            GridError::ZeroDimension { axis } => {
                write!(
                    f,
                    "dimension {} is zero; every dimension must be at least 1",
                    AXES[axis % 3]
                )
            }
            GridError::TooManySamples => {
                write!(f, "the dimensions' product overflows the address space")
            }
            GridError::TooLong { axis, n } => write!(
                f,
                "dimension {} is {n}; at most {MAX_DIM} samples per axis",
                AXES[axis % 3]
            ),
            GridError::BadSpacing { axis, value } => write!(
                f,
                "spacing {} is {value}; it must be finite and greater than zero",
                AXES[axis % 3]
            ),
        }
    }
}

impl core::error::Error for GridError {}

/// Most samples along one axis: index-space positions are `f32`, which hold every whole
/// number up to 2^24 exactly, so every node and cell boundary has its own coordinate; and
/// the sample loop turns whole coordinates up to 2^23 into indices by adding 2^23
/// ([`crate::volume::field::locate`]), without checking each lane.
pub const MAX_DIM: u32 = 1 << 23;

/// A regular grid of `dims[0] × dims[1] × dims[2]` samples, X fastest in files.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Grid {
    dims: [u32; 3],
    spacing: Vec3,
    inv_spacing: Vec3,
    /// `n - 1` and `max(n - 2, 0)` per axis, as floats, in the lanes the sample loop uses.
    last: (Vec4, Vec4),
}

impl Grid {
    /// A grid, checked.
    pub fn new(dims: [u32; 3], spacing: Vec3) -> Result<Grid, GridError> {
        let mut count: usize = 1;
        for (axis, &n) in dims.iter().enumerate() {
            if n == 0 {
                return Err(GridError::ZeroDimension { axis });
            }
            if n > MAX_DIM {
                return Err(GridError::TooLong { axis, n });
            }
            count = count
                .checked_mul(n as usize)
                .ok_or(GridError::TooManySamples)?;
        }
        for (axis, value) in spacing.to_array().into_iter().enumerate() {
            if !(value.is_finite() && value > 0.0) {
                return Err(GridError::BadSpacing { axis, value });
            }
        }
        let inv_spacing = Vec3::ONE / spacing;
        if !inv_spacing.is_finite() {
            // Spacing so small its reciprocal overflows: reject rather than trace infinities.
            let axis = inv_spacing
                .to_array()
                .iter()
                .position(|v| !v.is_finite())
                .unwrap_or(0);
            return Err(GridError::BadSpacing {
                axis,
                value: spacing[axis],
            });
        }
        let lanes = |f: fn(u32) -> u32| {
            Vec4::new(f(dims[0]) as f32, f(dims[1]) as f32, f(dims[2]) as f32, 0.0)
        };
        Ok(Grid {
            dims,
            spacing,
            inv_spacing,
            last: (lanes(|n| n - 1), lanes(|n| n.saturating_sub(2))),
        })
    }

    /// Samples along X, Y, Z.
    pub fn dims(&self) -> [u32; 3] {
        self.dims
    }

    /// World distance between neighbouring samples along X, Y, Z.
    pub fn spacing(&self) -> Vec3 {
        self.spacing
    }

    /// `1 / spacing`, per axis.
    pub fn inv_spacing(&self) -> Vec3 {
        self.inv_spacing
    }

    /// The smallest spacing: the world length of one "cell edge" for step sizes and opacity.
    pub fn cell_edge(&self) -> f32 {
        self.spacing.min_element()
    }

    /// Samples in one X plane (`ny · nz`).
    pub fn plane_len(&self) -> usize {
        self.dims[1] as usize * self.dims[2] as usize
    }

    /// The dataset's bounding box in index coordinates under `model`.
    pub fn index_box(&self, model: Model) -> (Vec3, Vec3) {
        let n = Vec3::new(
            self.dims[0] as f32,
            self.dims[1] as f32,
            self.dims[2] as f32,
        );
        match model {
            Model::Cell => (Vec3::ZERO, n - Vec3::ONE),
            Model::Voxel => (Vec3::splat(-0.5), n - Vec3::splat(0.5)),
        }
    }

    /// The dataset's bounding box in world coordinates under `model`.
    pub fn world_box(&self, model: Model) -> (Vec3, Vec3) {
        let (lo, hi) = self.index_box(model);
        (lo * self.spacing, hi * self.spacing)
    }

    /// The last node and the last cell's low node per axis (`n - 1` and `max(n - 2, 0)`),
    /// as floats in lanes x, y, z (w is 0): where index-space points clamp.
    #[inline]
    pub fn last_indices(&self) -> (Vec4, Vec4) {
        self.last
    }

    /// The X plane that owns a sample at index-space `x`: the lower plane of its cell (cell
    /// model) or its nearest plane (voxel model), clamped into the grid.
    ///
    /// This is the integer rule of ownership: a sample belongs to the slab whose half-open
    /// range of planes contains this number. It is computed from the sample's position by
    /// the same arithmetic on every node, so every node agrees on it.
    #[inline]
    pub fn owner_plane(&self, x: f32, model: Model) -> u32 {
        let x = match model {
            Model::Cell => x,
            Model::Voxel => x + 0.5,
        };
        floor_index(x).min(self.last_owner_plane(model))
    }

    /// The highest plane [`Grid::owner_plane`] gives: the last cell's (cell model) or the
    /// last node's (voxel model). Every sample beyond it belongs to it.
    #[inline]
    pub fn last_owner_plane(&self, model: Model) -> u32 {
        match model {
            Model::Cell => self.dims[0].saturating_sub(2),
            Model::Voxel => self.dims[0] - 1,
        }
    }
}

/// `⌊x⌋` as an index: 0 for negative `x` and NaN, saturating at `u32::MAX`. Equal to
/// `libm::floorf(x).max(0.0) as u32` for every `f32`, without a call: for positive `x`
/// truncation is the floor, and `as` saturates. Every cell, node and block lookup of the
/// sample loop goes through here, and `floorf` without SSE4.1 is a software routine.
#[inline]
pub fn floor_index(x: f32) -> u32 {
    if x > 0.0 {
        x as u32
    } else {
        0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn owner_plane_is_the_cell_or_nearest_plane_clamped() {
        let g = Grid::new([4, 2, 2], Vec3::ONE).unwrap();
        assert_eq!(g.owner_plane(0.0, Model::Cell), 0);
        assert_eq!(g.owner_plane(0.999, Model::Cell), 0);
        assert_eq!(g.owner_plane(1.0, Model::Cell), 1);
        assert_eq!(
            g.owner_plane(3.0, Model::Cell),
            2,
            "the last node belongs to the last cell"
        );
        assert_eq!(g.owner_plane(-1.0, Model::Cell), 0);
        assert_eq!(g.owner_plane(f32::NAN, Model::Cell), 0);
        assert_eq!(g.owner_plane(0.49, Model::Voxel), 0);
        assert_eq!(g.owner_plane(0.5, Model::Voxel), 1);
        assert_eq!(g.owner_plane(3.49, Model::Voxel), 3);
        assert_eq!(g.owner_plane(9.0, Model::Voxel), 3);
    }

    #[test]
    fn floor_index_is_the_clamped_floor_for_every_kind_of_float() {
        let reference = |x: f32| libm::floorf(x).max(0.0) as u32;
        let special = [
            0.0,
            -0.0,
            -0.5,
            0.5,
            1.0 - f32::EPSILON / 2.0,
            1.0,
            4_294_967_040.0,
            4_294_967_296.0,
            f32::MAX,
            f32::MIN,
            f32::MIN_POSITIVE,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        for x in special {
            assert_eq!(floor_index(x), reference(x), "{x}");
        }
        // A stride through every bit pattern: signs, subnormals, all exponents, NaNs.
        for bits in (0..=u32::MAX).step_by(9_973) {
            let x = f32::from_bits(bits);
            assert_eq!(floor_index(x), reference(x), "{x} ({bits:#x})");
        }
    }

    #[test]
    fn bad_grids_are_refused() {
        assert_eq!(
            Grid::new([0, 1, 1], Vec3::ONE),
            Err(GridError::ZeroDimension { axis: 0 })
        );
        assert!(matches!(
            Grid::new([1, 1, 1], Vec3::new(1.0, 0.0, 1.0)),
            Err(GridError::BadSpacing { axis: 1, .. })
        ));
        assert!(matches!(
            Grid::new([1, 1, 1], Vec3::new(1.0, 1.0, 1e-45)),
            Err(GridError::BadSpacing { axis: 2, .. })
        ));
        assert!(Grid::new([u32::MAX, u32::MAX, u32::MAX], Vec3::ONE).is_err());
        assert_eq!(
            Grid::new([2, MAX_DIM + 1, 1], Vec3::ONE),
            Err(GridError::TooLong {
                axis: 1,
                n: MAX_DIM + 1
            })
        );
        assert!(Grid::new([MAX_DIM, 1, 1], Vec3::ONE).is_ok());
    }
}

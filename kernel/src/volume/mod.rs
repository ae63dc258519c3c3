//! The volume one node holds: sample types, the grid, the slab of planes a node owns with its
//! ghosts, and the continuous field a slab defines (nearest and trilinear reads, gradients).
//!
//! Invariant: every read a node makes lies in its stored planes; the ghost planes are wide
//! enough for the interpolation and gradient stencils, so no node asks another for voxels.

pub mod cells;
pub mod field;
pub mod grid;
pub mod lanes;
pub mod nodes;
pub mod sample;
pub mod slab;

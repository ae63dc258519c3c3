//! The voxcube node kernel: everything one node of a hypercube multicomputer does to ray
//! trace its slab of a regular volume, in fixed memory, with no allocation, I/O or clock.
//!
//! The kernel traces in *index space* (voxel `(i, j, k)` sits at `(i, j, k)`) with the ray
//! parameter `t` measured in world units, so anisotropic spacing costs nothing per sample.
//! Every sample of every ray sits on the global lattice `t_k = t_entry + k·Δt` of
//! [`lattice`], and belongs to the slab that owns its plane ([`grid::Grid::owner_plane`]):
//! this is what makes an image bit-identical for any partition of the volume.
//!
//! Map of the crate:
//! - data: [`sample`], [`grid`], [`slab`], [`field`] (nearest and trilinear reads, gradients);
//! - empty-space skipping: [`blocks`] (min/max blocks), [`leaps`] (a view's chessboard
//!   distances between them, ahead of each octant of ray directions), [`cells`] (a view's
//!   empty cells inside them), [`cell_leaps`] (distances between those cells), [`depths`]
//!   (each pixel's ray parameter before its first cell that shows), [`scan`] (a ray's next
//!   samples against those cells);
//! - geometry: [`ray`] (box clipping), [`lattice`], [`camera`];
//! - appearance: [`transfer`], [`surface`], [`shade`], [`lighting`], [`view`] (one view's parameters and the
//!   effects it calls for);
//! - tracing: [`march`] (the explicit-state ray marcher that stops at slab boundaries),
//!   [`tree`] (the one formula that combines a ray tree), [`trace`] (a whole pixel on one slab),
//!   [`pixel`] (colour to RGBA8), [`counters`].
#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![allow(
    clippy::neg_cmp_op_on_partial_ord,
    reason = "`!(x > limit)` is the kernel's NaN-catching idiom: it is true for NaN, `x <= limit` is not"
)]

pub mod blocks;
pub mod camera;
pub mod cell_leaps;
pub mod cells;
pub mod counters;
pub mod depths;
pub mod field;
pub mod flow;
pub mod grid;
pub mod lattice;
pub mod leaps;
pub mod lighting;
pub mod march;
pub mod msg;
pub mod partition;
pub mod pixel;
pub mod port;
pub mod ray;
pub mod record;
pub mod sample;
pub mod scan;
pub mod shade;
pub mod shift;
pub mod slab;
pub mod starts;
pub mod stats;
pub mod surface;
#[cfg(test)]
mod testing;
pub mod topology;
pub mod trace;
pub mod transfer;
pub mod tree;
pub mod view;
pub mod worker;

pub use glam::Vec3;
/// The fixed-capacity containers the kernel's types are built from, for hosts that fill them.
pub use heapless;

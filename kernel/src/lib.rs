//! The voxcube node kernel: everything one node of a hypercube multicomputer does to ray
//! trace its slab of a regular volume, in fixed memory, with no allocation, I/O or clock.
//!
//! The kernel traces in *index space* (voxel `(i, j, k)` sits at `(i, j, k)`) with the ray
//! parameter `t` measured in world units, so anisotropic spacing costs nothing per sample.
//! Every sample of every ray sits on the global lattice `t_k = t_entry + k·Δt` of
//! [`trace::lattice`], and belongs to the slab that owns its plane ([`volume::grid::Grid::owner_plane`]):
//! this is what makes an image bit-identical for any partition of the volume.
//!
//! Map of the crate, by role (each folder's own page says what it owns):
//! - [`volume`]: sample types, the grid, a node's slab, the field (reads and gradients);
//! - [`skip`]: empty-space skipping behind one small face the marcher uses;
//! - [`optics`]: transfer function, iso-surfaces, shading, lighting;
//! - [`trace`]: camera, rays, the lattice, one view, the marcher, the ray tree, a whole pixel;
//! - [`node`]: the worker, its port and messages, flow control, records, partition, topology,
//!   plane shifting, statistics;
//! - [`counters`]: the work counters every part adds to.
#![no_std]
#![forbid(unsafe_code)]
#![deny(missing_docs)]
#![allow(
    clippy::neg_cmp_op_on_partial_ord,
    reason = "`!(x > limit)` is the kernel's NaN-catching idiom: it is true for NaN, `x <= limit` is not"
)]

pub mod counters;
pub mod node;
pub mod optics;
pub mod skip;
#[cfg(test)]
mod testing;
pub mod trace;
pub mod volume;

pub use glam::{Vec3, Vec4};
/// The fixed-capacity containers the kernel's types are built from, for hosts that fill them.
pub use heapless;

//! Tracing: the camera and its rays, the global sample lattice, one view's parameters, the
//! explicit-state marcher that stops at slab boundaries, the one formula that combines a ray
//! tree, the in-process tracer of a whole pixel, and the colour-to-RGBA8 step.
//!
//! Invariant: a ray's samples sit at `t_k = t_entry + k·Δt` for integer `k`, computed the same
//! way on every node and never accumulated; a sample belongs to the slab owning its plane.

pub mod camera;
pub mod composite;
pub(crate) mod deferred;
pub(crate) mod interior;
pub mod lattice;
pub mod lighting;
pub mod march;
pub mod pixel;
pub(crate) mod preintegrated;
pub mod ray;
pub(crate) mod reading;
pub(crate) mod runway;
pub(crate) mod skipping;
pub mod starts;
pub mod state;
pub mod tracer;
pub mod tree;
pub mod view;

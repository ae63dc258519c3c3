//! What comes in: the scene file ([`scene`]), the datasets it names ([`dataset`]), read from
//! files ([`formats`]) or generated ([`builtin`]), and what a view of them can show
//! ([`framing`]).
//!
//! Invariant: everything here is checked as it is read; what leaves this folder is a scene
//! and volumes the rest of the host can trust.

pub mod builtin;
pub mod dataset;
pub mod formats;
pub mod framing;
pub mod scene;

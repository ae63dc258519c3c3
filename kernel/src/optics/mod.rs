//! What a sample looks like: the transfer function of compositing, iso-surfaces and their
//! search, local illumination, and the lighting of one point before shadowing.
//!
//! Invariant: every function here is a pure function of its inputs, evaluated in one fixed
//! order, so the same sample gives the same bits on every node.

pub mod classify;
pub mod segments;
pub mod shade;
pub mod shading_table;
pub mod surface;
pub mod transfer;

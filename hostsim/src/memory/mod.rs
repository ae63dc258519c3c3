//! What a node holds, and whether it fits: the node budget against the machine's memory
//! ([`budget`]), each view's slab and skipping structures ([`storage`]), what is built once
//! per volume and shared by its views ([`built`]: the fast tier's node fields, [`nodes`],
//! and the slabs' value ranges, [`ranges`]), how those builds are split over threads
//! ([`parts`]), what a process really held ([`resident`]), and a pre-integrated view's table
//! ([`segments`]).
//!
//! Invariant: every structure a node holds is counted by the budget before it is built.

pub mod budget;
pub mod built;
pub mod huge;
pub mod nodes;
pub mod parts;
pub mod ranges;
pub mod resident;
pub mod segments;
pub mod storage;

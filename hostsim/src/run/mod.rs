//! Running a view on a machine: [`render`] (one view, directly or on a fabric of nodes),
//! [`balance`] (slab cuts by measured cost) and [`timeline`] (a simulated run's trace in
//! virtual time). The fabrics themselves are in [`crate::fabric`].

pub mod balance;
pub mod render;
pub mod timeline;

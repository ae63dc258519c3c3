//! The commands' work, one module each, that [`crate::cli`] parses and dispatches to:
//! [`render`] and [`info`]. `bench`, `paper`, `accuracy` and `explore` live with the other
//! experiments ([`crate::experiments`]).

pub mod info;
pub mod render;

//! The commands' work, one module each, that [`crate::cli`] parses and dispatches to. Here:
//! [`render`]; `info`, `bench`, `paper`, `accuracy` and `explore` live with their kind of
//! work ([`crate::info`], [`crate::experiments`]).

pub mod render;

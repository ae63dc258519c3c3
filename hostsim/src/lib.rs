//! The voxcube host: reads the scene file (the paper's input file) and datasets, drives the
//! node kernel, and writes images and reports. The `voxcube` binary is a thin shell over
//! [`cli`].
//!
//! Modules: [`scene`] (the TOML scene format, checked), [`dataset`] and [`formats`] (volumes
//! and their files), [`framing`] (what a view can show), [`builtin`] (procedural volumes), [`render`] (one view on one node),
//! [`output`] (PNG and checksums), [`report`] (summary and JSON), [`cli`].
#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod balance;
pub mod budget;
pub mod builtin;
pub mod cli;
pub mod dataset;
pub mod experiments;
pub mod fabric;
pub mod formats;
pub mod framing;
pub mod info;
pub mod nodes;
pub mod output;
pub mod parts;
pub mod profile;
pub mod render;
pub mod report;
pub mod rng;
pub mod scene;
pub mod storage;
pub mod timeline;

//! The voxcube host: reads the scene file (the paper's input file) and datasets, drives the
//! node kernel, and writes images and reports. The `voxcube` binary is a thin shell over
//! [`cli`].
//!
//! Modules, by role:
//! - input: [`scene`] (the TOML scene format, checked), [`dataset`] and [`formats`] (volumes
//!   and their files), [`builtin`] (procedural volumes), [`framing`] (what a view can show),
//!   [`info`] (`voxcube info`);
//! - a node's memory and storage: [`profile`] (machine profiles), [`budget`] (what a node
//!   holds, against its memory), [`storage`] (slabs and each view's skipping structures),
//!   [`built`] (what is built once per volume: [`nodes`], the fast tier's node fields, and
//!   [`ranges`], the slabs' value ranges), [`parts`] (builds split over threads),
//!   [`balance`] (cuts by measured cost);
//! - running: [`render`] (one view on a machine), [`fabric`] (the simulator, threads, MPI),
//!   [`rng`] (seeded schedules), [`timeline`] (virtual-time traces);
//! - output: [`output`] (PNG and checksums), [`report`] (summary and JSON);
//! - [`commands`] (each command's work: `render`), [`experiments`] (bench, paper, accuracy,
//!   explore) apart from the runtime, and [`cli`] (parses and dispatches).
#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod balance;
pub mod budget;
pub mod built;
pub mod builtin;
pub mod cli;
pub mod commands;
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
pub mod ranges;
pub mod render;
pub mod report;
pub mod rng;
pub mod scene;
pub mod storage;
pub mod timeline;

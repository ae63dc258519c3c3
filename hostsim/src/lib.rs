//! The voxcube host: reads the scene file (the paper's input file) and datasets, drives the
//! node kernel, and writes images and reports. The `voxcube` binary is a thin shell over
//! [`cli`].
//!
//! Modules, by role, each folder a role:
//! - [`input`]: the scene file, datasets and their file formats, built-in volumes, framing;
//! - [`memory`]: what a node holds (its budget, storage, and what is built once per volume);
//! - [`run`]: one view on a machine, balancing, timelines;
//! - [`fabric`]: the simulator, threads and MPI that carry the nodes' messages;
//! - [`output`]: images, checksums and reports;
//! - [`commands`] (each command's work: `render`, `info`) and [`experiments`] (bench, paper,
//!   accuracy, explore), apart from the runtime, and [`cli`] (parses and dispatches);
//! - two leaves every role reads, at the top so that no folder reaches up into another:
//!   [`profile`] (a machine: what its node memory holds and what each operation and message
//!   costs) and [`rng`] (the seeded generator of built-in volumes and simulated schedules).
#![forbid(unsafe_code)]
#![deny(missing_docs)]

pub mod cli;
pub mod commands;
pub mod experiments;
pub mod fabric;
pub mod input;
pub mod memory;
pub mod output;
pub mod profile;
pub mod rng;
pub mod run;

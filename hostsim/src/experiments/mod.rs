//! The experiments: what the project measures about itself, apart from the host's runtime.
//! The commands: [`bench`](mod@bench) (speed against VTK in the same run, [`peer`]; in
//! instructions, [`instructions`]; as the work grows, [`scale`]), [`paper`] (the paper's
//! tables in simulated nCUBE 2 time, from [`runs`], with the profile's constants [`fit`]),
//! [`accuracy`] (what accuracy costs in time; against VTK's, [`frontier`]) and [`explore`] (schedules explored on the
//! simulator for deadlocks and invariants). What they share: SOD and the paper's view
//! ([`sod`]), one error ([`error`]) and line charts ([`chart`]).
//!
//! Invariant: an experiment only drives the runtime (scenes, fabrics, reports) through its
//! public face; nothing in the runtime depends on an experiment.

pub mod accuracy;
pub mod bench;
pub mod chart;
pub mod error;
pub mod explore;
pub mod fit;
pub mod frontier;
pub mod instructions;
pub mod paper;
pub mod peer;
pub mod phases;
pub mod runs;
pub mod scale;
pub mod sod;

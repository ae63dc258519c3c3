//! What goes out: files written whole or not at all, PNG images and the pixel checksum
//! ([`files`]), and the report of what each view cost, for people and as JSON ([`report`]).

pub mod files;
pub mod report;

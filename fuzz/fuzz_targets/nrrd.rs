//! The NRRD, raw or gzip reader, given any bytes as `input.nrrd`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| voxcube_fuzz::read_as("input.nrrd", data));

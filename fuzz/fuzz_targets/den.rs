//! The Levoy's .den reader, given any bytes as `input.den`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| voxcube_fuzz::read_as("input.den", data));

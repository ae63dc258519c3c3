//! The CCP4/MRC reader, given any bytes as `input.map`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| voxcube_fuzz::read_as("input.map", data));

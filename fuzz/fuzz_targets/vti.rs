//! The VTK XML image data reader, given any bytes as `input.vti`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| voxcube_fuzz::read_as("input.vti", data));

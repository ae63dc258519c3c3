//! The MetaImage, raw or zlib reader, given any bytes as `input.mha`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| voxcube_fuzz::read_as("input.mha", data));

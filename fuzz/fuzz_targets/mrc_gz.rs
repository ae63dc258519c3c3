//! The gzipped CCP4/MRC reader, given any bytes as `input.ccp4.gz`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| voxcube_fuzz::read_as("input.ccp4.gz", data));

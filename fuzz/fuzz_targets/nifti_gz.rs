//! The gzipped NIfTI-1 reader, given any bytes as `input.nii.gz`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| voxcube_fuzz::read_as("input.nii.gz", data));

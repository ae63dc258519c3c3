//! The legacy VTK reader, given any bytes as `input.vtk`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| voxcube_fuzz::read_as("input.vtk", data));

//! The one DICOM file reader, given any bytes as `input.dcm`.
#![no_main]

libfuzzer_sys::fuzz_target!(|data: &[u8]| voxcube_fuzz::read_as("input.dcm", data));

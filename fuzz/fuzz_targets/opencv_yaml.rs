//! See `gantry_fuzz::opencv_yaml`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gantry_fuzz::opencv_yaml(data));

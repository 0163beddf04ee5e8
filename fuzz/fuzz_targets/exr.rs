//! See `gantry_fuzz::exr`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gantry_fuzz::exr(data));

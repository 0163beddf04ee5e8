//! See `gantry_fuzz::samples_checkpoint`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gantry_fuzz::samples_checkpoint(data));

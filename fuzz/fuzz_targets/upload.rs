//! See `gantry_fuzz::upload`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gantry_fuzz::upload(data));

//! See `gantry_fuzz::npy`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gantry_fuzz::npy(data));

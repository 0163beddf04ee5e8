//! See `gantry_fuzz::reduce_model`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gantry_fuzz::reduce_model(data));

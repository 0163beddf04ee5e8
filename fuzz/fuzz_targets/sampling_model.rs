//! See `gantry_fuzz::sampling_model`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gantry_fuzz::sampling_model(data));

//! See `gantry_fuzz::merl_binary_structured`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gantry_fuzz::merl_binary_structured(data));

//! See `gantry_fuzz::merl_binary`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gantry_fuzz::merl_binary(data));

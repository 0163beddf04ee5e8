//! See `gantry_fuzz::material_spec`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gantry_fuzz::material_spec(data));

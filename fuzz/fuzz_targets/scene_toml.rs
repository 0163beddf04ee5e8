//! See `gantry_fuzz::scene_toml`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gantry_fuzz::scene_toml(data));

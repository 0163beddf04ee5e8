//! See `gantry_fuzz::recovery_scene_toml`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gantry_fuzz::recovery_scene_toml(data));

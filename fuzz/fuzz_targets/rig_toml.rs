//! See `gantry_fuzz::rig_toml`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gantry_fuzz::rig_toml(data));

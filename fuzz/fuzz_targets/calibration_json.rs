//! See `gantry_fuzz::calibration_json`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gantry_fuzz::calibration_json(data));

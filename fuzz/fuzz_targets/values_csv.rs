//! See `gantry_fuzz::values_csv`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gantry_fuzz::values_csv(data));

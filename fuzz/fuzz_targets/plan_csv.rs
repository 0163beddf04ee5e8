//! See `gantry_fuzz::plan_csv`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gantry_fuzz::plan_csv(data));

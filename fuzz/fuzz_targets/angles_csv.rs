//! See `gantry_fuzz::angles_csv`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gantry_fuzz::angles_csv(data));

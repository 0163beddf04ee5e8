//! See `gantry_fuzz::obj`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gantry_fuzz::obj(data));

//! See `gantry_fuzz::grbl_response`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gantry_fuzz::grbl_response(data));

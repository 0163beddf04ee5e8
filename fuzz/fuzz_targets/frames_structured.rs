//! See `gantry_fuzz::frames_structured`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gantry_fuzz::frames_structured(data));

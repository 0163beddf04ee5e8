//! See `gantry_fuzz::rgl_bsdf`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gantry_fuzz::rgl_bsdf(data));

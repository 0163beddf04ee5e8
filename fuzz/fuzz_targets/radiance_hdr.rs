//! See `gantry_fuzz::radiance_hdr`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gantry_fuzz::radiance_hdr(data));

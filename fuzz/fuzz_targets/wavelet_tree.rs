//! See `gantry_fuzz::wavelet_tree`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gantry_fuzz::wavelet_tree(data));

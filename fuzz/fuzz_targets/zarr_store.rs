//! See `gantry_fuzz::zarr_store`.
#![no_main]
libfuzzer_sys::fuzz_target!(|data: &[u8]| gantry_fuzz::zarr_store(data));

//! Common wavelet basis files.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = wavelet::CommonBasis::from_bytes(data);
});

//! Compressed wavelet material (`.wtree`) files, and the coefficient tree built from them.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(m) = wavelet::CompressedMaterial::from_bytes(data) {
        let _ = wavelet::WaveletBrdf::new(&m, "fuzz");
    }
});

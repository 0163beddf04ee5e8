//! NumPy `.npy` arrays (the neural-BRDF weights).
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = brdf::npy::parse(data, std::path::Path::new("fuzz.npy"));
});

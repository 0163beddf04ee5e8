//! The sampling crate's model file (basis for reconstruction from few samples).
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = sampling::model_file::from_bytes(data);
});

//! `model.bin` of the reduction (PCA basis, charts).
#![no_main]
use libfuzzer_sys::fuzz_target;
include!("../common/scratch.rs");

fuzz_target!(|data: &[u8]| {
    let p = scratch("model.bin", data);
    let _ = reduce::model::Model::load(&p);
});

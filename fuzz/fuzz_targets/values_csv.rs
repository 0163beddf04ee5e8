//! Measured values CSV.
#![no_main]
use libfuzzer_sys::fuzz_target;
include!("../common/scratch.rs");

fuzz_target!(|data: &[u8]| {
    let p = scratch("values.csv", data);
    let _ = sampling::Measurements::read_csv(&p);
});

//! Sampling plan CSV.
#![no_main]
use libfuzzer_sys::fuzz_target;
include!("../common/scratch.rs");

fuzz_target!(|data: &[u8]| {
    let p = scratch("plan.csv", data);
    let _ = sampling::Plan::read_csv(&p);
});

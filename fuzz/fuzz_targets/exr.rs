//! OpenEXR input (HDR images of the job directory, read through `hdr::read_exr`).
#![no_main]
use libfuzzer_sys::fuzz_target;
include!("../common/scratch.rs");

fuzz_target!(|data: &[u8]| {
    let p = scratch("exr", data);
    let _ = hdr::read_exr(&p);
});

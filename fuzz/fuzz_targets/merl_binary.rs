//! MERL `.binary` tables: three dimensions then doubles.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = brdf::merl::parse(data, std::path::Path::new("fuzz.binary"));
});

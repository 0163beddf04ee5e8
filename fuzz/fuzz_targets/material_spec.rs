//! Material spec strings (`merl:NAME`, `ggx:alpha=…`, …).
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = brdf::spec::parse(text);
    }
});

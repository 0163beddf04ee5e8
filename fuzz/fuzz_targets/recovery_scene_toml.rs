//! Recovery scene TOML (photos, lights, geometry of an inverse-rendering problem).
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = recover::scene::RecoveryScene::parse(text, std::path::Path::new("/nonexistent-fuzz-dir"));
    }
});

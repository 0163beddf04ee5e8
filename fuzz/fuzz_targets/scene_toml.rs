//! Render scene TOML. Only analytic material specs resolve without data, so the resolver refuses
//! tabulated ones (the parser, not the data loader, is under test); mesh paths point nowhere.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = render::scene_file::parse_scene(
            text,
            std::path::Path::new("/nonexistent-fuzz-dir"),
            &render::scene_file::SpecResolver,
        );
    }
});

//! Wavefront OBJ meshes.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = render::mesh::parse_obj(text, std::path::Path::new("fuzz.obj"));
    }
});

//! Radiance `.hdr` (RGBE) input: light probes and photographs, read through
//! `render::Image::decode_hdr` (flat and run-length encoded scanlines, with a pixel limit).
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(img) = render::Image::decode_hdr(data, std::path::Path::new("fuzz.hdr")) {
        assert!(img.width() * img.height() <= render::image::MAX_HDR_PIXELS);
        assert!(img.pixels().iter().flatten().all(|v| v.is_finite() && *v >= 0.0));
    }
});

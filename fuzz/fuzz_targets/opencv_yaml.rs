//! OpenCV camera calibration YAML.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = calib::opencv::OpenCvCamera::from_yaml(text, std::path::Path::new("fuzz.yml"));
    }
});

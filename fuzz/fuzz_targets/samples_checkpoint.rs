//! Position checkpoints (`positions/NNN.samples`), raw bytes.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = binning::PositionSamples::parse(data, std::path::Path::new("fuzz.samples"));
});

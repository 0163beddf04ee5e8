//! Raw frame files (`frames/NNN.frames`, GBFRAME2 with CRC, and the older GBFRAME1).
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = gantry_hal::decode_frames(data);
});

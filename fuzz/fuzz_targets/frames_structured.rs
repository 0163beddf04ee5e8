//! Frame files with the GBFRAME2 magic and a correct CRC-32 around a mutated body, so that the
//! fuzzer reaches the frame decoder behind the checksum.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut out = b"GBFRAME2".to_vec();
    out.extend_from_slice(data);
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    let _ = gantry_hal::decode_frames(&out);
});

//! Position checkpoints with a valid header and checksum around a mutated body, so that the
//! fuzzer reaches the record decoder behind the checksum.
#![no_main]
use libfuzzer_sys::fuzz_target;

fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes {
        h ^= *b as u64;
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

fuzz_target!(|data: &[u8]| {
    if data.len() < 13 {
        return;
    }
    let (head, body) = data.split_at(13);
    let mut out = b"GBSAMPL1".to_vec();
    out.extend_from_slice(&head[..4]);
    out.extend_from_slice(&head[4..12]);
    // The count: mostly the true one, sometimes a lie (chosen by the fuzzer).
    let count = if head[12] & 1 == 0 {
        (body.len() / 8) as u64
    } else {
        u64::from(head[12]) << (head[12] % 48)
    };
    out.extend_from_slice(&count.to_le_bytes());
    out.extend_from_slice(body);
    let h = fnv1a(body);
    out.extend_from_slice(&h.to_le_bytes());
    let _ = binning::PositionSamples::parse(&out, std::path::Path::new("fuzz.samples"));
});

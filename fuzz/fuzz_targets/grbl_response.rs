//! GRBL response lines: the line classifier (ok, error:N, ALARM:N, status reports, messages)
//! and the status report parser.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    for line in text.split('\n') {
        let _ = gantry_hal::grbl::Response::classify(line);
        let _ = gantry_hal::grbl::parse_status(line);
    }
});

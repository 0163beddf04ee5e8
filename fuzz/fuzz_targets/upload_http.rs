//! See `gantry_fuzz::upload_http`.
#![no_main]
libfuzzer_sys::fuzz_target!(
    // Built before the first input: opening the server (the light probe and its sampling
    // tables) takes over a second with the sanitizer, which the per-input limit would count.
    init: {
        gantry_fuzz::upload_server();
    },
    |data: &[u8]| gantry_fuzz::upload_http(data)
);

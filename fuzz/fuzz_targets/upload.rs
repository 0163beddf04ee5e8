//! The editor's upload endpoint, `POST /api/uploads?name=…`, through the server's HTTP router
//! (no socket): the fuzzer's bytes up to the first zero are the file name (percent-encoded
//! into the query), the rest is the body. Every answer must be `201 Created` or a client
//! error (4xx) with a JSON message, never a server error, a panic or a hang; the name an
//! upload gets is always made of letters, digits, `-` and `_`.
#![no_main]
use axum::body::Body;
use axum::http::{Request, StatusCode};
use libfuzzer_sys::fuzz_target;
use std::fmt::Write;
use std::sync::{Arc, OnceLock};
use tower::ServiceExt;

struct Server {
    runtime: tokio::runtime::Runtime,
    router: axum::Router,
}

fn server() -> &'static Server {
    static S: OnceLock<Server> = OnceLock::new();
    S.get_or_init(|| {
        let app = serve::App::new(serve::Config {
            // No corpus, no model: the upload path only.
            environment: None,
            upload_limit: 1 << 20,
            ..serve::Config::default()
        })
        .expect("server");
        Server {
            runtime: tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .expect("runtime"),
            router: serve::api::router(Arc::new(app)),
        }
    })
}

fuzz_target!(
    // Built before the first input: opening the server (the light probe and its sampling
    // tables) takes over a second with the sanitizer, which the per-input limit would count.
    init: {
        server();
    },
    |data: &[u8]| {
        let split = data.iter().position(|&b| b == 0).unwrap_or(data.len());
        let (name, body) = (&data[..split], data.get(split + 1..).unwrap_or(&[]));
        let stem = serve::library::upload_stem(&String::from_utf8_lossy(name));
        assert!(stem.len() <= 48);
        assert!(stem
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || c == '-' || c == '_'));
        let mut query = String::new();
        for b in name {
            let _ = write!(query, "%{b:02X}");
        }
        let request = Request::builder()
            .method("POST")
            .uri(format!("/api/uploads?name={query}"))
            .header("content-type", "application/octet-stream")
            .body(Body::from(body.to_vec()))
            .expect("request");
        let s = server();
        let response = s
            .runtime
            .block_on(s.router.clone().oneshot(request))
            .expect("infallible router");
        let status = response.status();
        assert!(
            status == StatusCode::CREATED || status.is_client_error(),
            "upload answered {status}"
        );
    }
);

//! The page, embedded in the binary: no CDN, no network.

/// The page.
pub const INDEX_HTML: &str = include_str!("../assets/index.html");
/// Its script (plain ES2020, no framework).
pub const APP_JS: &str = include_str!("../assets/app.js");
/// The real-time WebGL2 view (loaded by the page; the CPU previews stay when WebGL2 is missing).
pub const GPU_JS: &str = include_str!("../assets/gpu.js");
/// Its style sheet.
pub const APP_CSS: &str = include_str!("../assets/app.css");
/// The OpenAPI description of the JSON API.
pub const OPENAPI_JSON: &str = include_str!("../../../docs/serve.openapi.json");

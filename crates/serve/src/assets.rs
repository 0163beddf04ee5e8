//! The page, embedded in the binary: no CDN, no network.

/// The page.
pub const INDEX_HTML: &str = include_str!("../assets/index.html");
/// Its script (plain ES2020, no framework).
pub const APP_JS: &str = include_str!("../assets/app.js");
/// Its style sheet.
pub const APP_CSS: &str = include_str!("../assets/app.css");
/// The OpenAPI description of the JSON API.
pub const OPENAPI_JSON: &str = include_str!("../../../docs/serve.openapi.json");

//! Cross-crate end-to-end tests of the toolkit live in `tests/tests/`; this library is empty.
//!
//! ```sh
//! cargo test -p end-to-end
//! ```

//! `render` crate (under construction).

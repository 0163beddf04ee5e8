//! `sampling` crate (under construction).

//! `reduce` crate (under construction).

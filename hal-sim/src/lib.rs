//! `hal-sim` crate (under construction).

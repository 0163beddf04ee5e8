//! `calib` crate (under construction).

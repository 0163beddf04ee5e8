//! `binning` crate (under construction).

//! `wavelet` crate (under construction).

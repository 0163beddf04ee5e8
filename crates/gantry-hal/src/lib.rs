//! `gantry-hal` crate (under construction).

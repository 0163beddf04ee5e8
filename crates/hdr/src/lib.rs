//! `hdr` crate (under construction).

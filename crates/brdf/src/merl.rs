//! merl

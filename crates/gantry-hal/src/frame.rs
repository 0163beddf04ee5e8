//! Raw Bayer frames as the camera delivers them.

use crate::error::{HalError, HalResult};
use serde::{Deserialize, Serialize};

/// Colour filter arrangement of the 2 × 2 Bayer cell, named by its top-left, top-right,
/// bottom-left and bottom-right filters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum BayerPattern {
    /// R G / G B (the Retiga 1300 of the seed's rig).
    #[default]
    Rggb,
    /// B G / G R.
    Bggr,
    /// G R / B G.
    Grbg,
    /// G B / R G.
    Gbrg,
}

impl BayerPattern {
    /// Colour channel (0 = red, 1 = green, 2 = blue) of the photosite at column `x`, row `y`.
    #[inline]
    pub fn channel_at(self, x: usize, y: usize) -> usize {
        let cell = (y & 1) * 2 + (x & 1);
        let layout: [usize; 4] = match self {
            BayerPattern::Rggb => [0, 1, 1, 2],
            BayerPattern::Bggr => [2, 1, 1, 0],
            BayerPattern::Grbg => [1, 0, 2, 1],
            BayerPattern::Gbrg => [1, 2, 0, 1],
        };
        layout[cell]
    }
}

/// One raw exposure: `width × height` samples in row-major order, each the digital number (DN)
/// of one photosite, at most `2^bit_depth − 1`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BayerFrame {
    /// Sensor columns.
    pub width: usize,
    /// Sensor rows.
    pub height: usize,
    /// Bits per sample (10 for the gantry camera).
    pub bit_depth: u8,
    /// Colour filter arrangement.
    pub pattern: BayerPattern,
    /// Samples, row-major, `width * height` of them.
    pub data: Vec<u16>,
    /// Exposure time, seconds.
    pub exposure_s: f64,
    /// Rig-clock time at the start of the exposure, seconds.
    pub timestamp_s: f64,
    /// Sensor temperature during the exposure, °C.
    pub sensor_temperature_c: f64,
    /// Sequence number assigned by the camera.
    pub frame_number: u64,
}

impl BayerFrame {
    /// Builds a frame and checks it: dimensions match the data length and no sample exceeds the
    /// bit depth. Violations are [`HalError::CorruptedFrame`] (a frame that came from a device).
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        width: usize,
        height: usize,
        bit_depth: u8,
        pattern: BayerPattern,
        data: Vec<u16>,
        exposure_s: f64,
        timestamp_s: f64,
        sensor_temperature_c: f64,
        frame_number: u64,
    ) -> HalResult<Self> {
        let frame = Self {
            width,
            height,
            bit_depth,
            pattern,
            data,
            exposure_s,
            timestamp_s,
            sensor_temperature_c,
            frame_number,
        };
        frame.validate()?;
        Ok(frame)
    }

    /// Checks dimensions, sample range and metadata.
    pub fn validate(&self) -> HalResult<()> {
        let bad = |d: String| Err(HalError::CorruptedFrame { detail: d });
        if self.bit_depth == 0 || self.bit_depth > 16 {
            return bad(format!("bit depth {} outside 1..=16", self.bit_depth));
        }
        if self.width == 0 || self.height == 0 {
            return bad(format!("empty frame {}x{}", self.width, self.height));
        }
        if self.width.checked_mul(self.height) != Some(self.data.len()) {
            return bad(format!(
                "{} samples for a {}x{} frame",
                self.data.len(),
                self.width,
                self.height
            ));
        }
        if !(self.exposure_s.is_finite() && self.exposure_s > 0.0) {
            return bad(format!("exposure {} s", self.exposure_s));
        }
        if !self.timestamp_s.is_finite() || !self.sensor_temperature_c.is_finite() {
            return bad("non-finite timestamp or temperature".into());
        }
        let max = self.max_value();
        if let Some(i) = self.data.iter().position(|&v| v > max) {
            return bad(format!(
                "sample {} at ({}, {}) exceeds {}-bit range",
                self.data[i],
                i % self.width,
                i / self.width,
                self.bit_depth
            ));
        }
        Ok(())
    }

    /// Largest representable sample, `2^bit_depth − 1`.
    pub fn max_value(&self) -> u16 {
        ((1u32 << self.bit_depth) - 1) as u16
    }

    /// Sample at column `x`, row `y`.
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> u16 {
        self.data[y * self.width + x]
    }

    /// Colour channel of the photosite at (`x`, `y`).
    #[inline]
    pub fn channel_at(&self, x: usize, y: usize) -> usize {
        self.pattern.channel_at(x, y)
    }
}

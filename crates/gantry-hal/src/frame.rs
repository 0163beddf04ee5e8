//! Raw Bayer frames as the camera delivers them.

use crate::error::{HalError, HalResult};
use serde::{Deserialize, Serialize};

/// Colour filter arrangement of the 2 × 2 Bayer cell, named by its top-left, top-right,
/// bottom-left and bottom-right filters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum BayerPattern {
    /// R G / G B (the Retiga 1300 of the thesis's rig).
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
///
/// What a [`Camera`](crate::Camera) returns, the input of the HDR merge, and what a capture keeps
/// in its frame files ([`encode_frames`]).
///
/// # Examples
///
/// ```
/// use gantry_hal::{BayerFrame, BayerPattern};
///
/// // 4 × 2 photosites behind an RGGB filter, a 20 ms exposure at t = 1.5 s, sensor at 25 °C
/// let data = vec![10, 20, 30, 40, 50, 60, 70, 1023];
/// let frame = BayerFrame::new(4, 2, 10, BayerPattern::Rggb, data, 0.02, 1.5, 25.0, 3).unwrap();
/// assert_eq!(frame.max_value(), 1023);
/// assert_eq!(frame.get(3, 1), 1023);
/// // red at even columns of even rows, blue at odd columns of odd rows, green between
/// assert_eq!([frame.channel_at(0, 0), frame.channel_at(1, 0), frame.channel_at(1, 1)], [0, 1, 2]);
/// ```
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

/// Magic of a frame file written by [`encode_frames`]: the frames, then a CRC-32 of everything
/// before it.
pub const FRAME_FILE_MAGIC: &[u8; 8] = b"GBFRAME2";
/// Magic of frame files written before they carried a checksum (still read).
pub const FRAME_FILE_MAGIC_V1: &[u8; 8] = b"GBFRAME1";

/// A frame file that cannot be decoded: truncated, bit-flipped (checksum mismatch), or holding a
/// frame that fails [`BayerFrame::validate`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("malformed frame file: {0}")]
pub struct FrameFileError(pub String);

fn pattern_code(p: BayerPattern) -> u8 {
    match p {
        BayerPattern::Rggb => 0,
        BayerPattern::Bggr => 1,
        BayerPattern::Grbg => 2,
        BayerPattern::Gbrg => 3,
    }
}

/// Serialises a series of frames (one lamp position's exposures) into the frame-file layout:
///
/// ```text
/// "GBFRAME2"  u32 count
/// per frame:  u32 width, u32 height, u8 bit depth, u8 pattern (0 RGGB, 1 BGGR, 2 GRBG, 3 GBRG),
///             f64 exposure_s, f64 timestamp_s, f64 sensor_temperature_c, u64 frame_number,
///             width × height u16 samples
/// u32 CRC-32 (IEEE) of every byte before it
/// ```
///
/// All numbers are little-endian.
///
/// ```
/// use gantry_hal::{decode_frames, encode_frames, BayerFrame, BayerPattern};
/// let f = BayerFrame::new(2, 2, 10, BayerPattern::Rggb, vec![1, 2, 3, 1023], 0.01, 0.0, 25.0, 7)?;
/// let bytes = encode_frames(std::slice::from_ref(&f));
/// assert_eq!(decode_frames(&bytes)?, vec![f]);
/// let mut flipped = bytes.clone();
/// flipped[30] ^= 1;
/// assert!(decode_frames(&flipped).is_err());
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn encode_frames(frames: &[BayerFrame]) -> Vec<u8> {
    let samples: usize = frames.iter().map(|f| f.data.len()).sum();
    let mut out = Vec::with_capacity(16 + frames.len() * 42 + 2 * samples);
    out.extend_from_slice(FRAME_FILE_MAGIC);
    out.extend_from_slice(&(frames.len() as u32).to_le_bytes());
    for f in frames {
        out.extend_from_slice(&(f.width as u32).to_le_bytes());
        out.extend_from_slice(&(f.height as u32).to_le_bytes());
        out.push(f.bit_depth);
        out.push(pattern_code(f.pattern));
        for v in [f.exposure_s, f.timestamp_s, f.sensor_temperature_c] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        out.extend_from_slice(&f.frame_number.to_le_bytes());
        for v in &f.data {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

/// Reads the frames of a frame file written by [`encode_frames`] (or by the checksum-less first
/// version of the layout). Every length is checked against the bytes present before anything is
/// allocated, so a hostile header cannot make the reader allocate more than the file holds.
pub fn decode_frames(bytes: &[u8]) -> Result<Vec<BayerFrame>, FrameFileError> {
    let bad = |what: &str| FrameFileError(what.to_string());
    let magic = bytes
        .get(..8)
        .ok_or_else(|| bad("shorter than its header"))?;
    let body = if magic == FRAME_FILE_MAGIC {
        let n = bytes.len();
        if n < 12 {
            return Err(bad("shorter than its header"));
        }
        let (body, crc) = bytes.split_at(n - 4);
        let stored = u32::from_le_bytes([crc[0], crc[1], crc[2], crc[3]]);
        if crc32fast::hash(body) != stored {
            return Err(bad("checksum mismatch (truncated or corrupted)"));
        }
        &body[8..]
    } else if magic == FRAME_FILE_MAGIC_V1 {
        &bytes[8..]
    } else {
        return Err(bad("not a frame file (bad magic)"));
    };
    let mut pos = 0usize;
    let mut take = |n: usize| -> Result<&[u8], FrameFileError> {
        let end = pos.checked_add(n).ok_or_else(|| bad("length overflow"))?;
        let s = body.get(pos..end).ok_or_else(|| bad("truncated"))?;
        pos = end;
        Ok(s)
    };
    let u32_at = |s: &[u8]| u32::from_le_bytes([s[0], s[1], s[2], s[3]]);
    let f64_at = |s: &[u8]| f64::from_le_bytes(s.try_into().unwrap_or([0; 8]));
    let n = u32_at(take(4)?) as usize;
    // Every frame takes at least its 42-byte header.
    if n > body.len() / 42 + 1 {
        return Err(bad("frame count larger than the file can hold"));
    }
    let mut frames = Vec::with_capacity(n);
    for _ in 0..n {
        let w = u32_at(take(4)?) as usize;
        let h = u32_at(take(4)?) as usize;
        let depth = take(1)?[0];
        let pattern = match take(1)?[0] {
            0 => BayerPattern::Rggb,
            1 => BayerPattern::Bggr,
            2 => BayerPattern::Grbg,
            3 => BayerPattern::Gbrg,
            p => return Err(FrameFileError(format!("unknown Bayer pattern code {p}"))),
        };
        let e = f64_at(take(8)?);
        let t = f64_at(take(8)?);
        let temp = f64_at(take(8)?);
        let num = u64::from_le_bytes(take(8)?.try_into().unwrap_or([0; 8]));
        let count = w.checked_mul(h).ok_or_else(|| bad("frame size overflow"))?;
        let raw = take(
            count
                .checked_mul(2)
                .ok_or_else(|| bad("frame size overflow"))?,
        )?;
        let data = raw
            .chunks_exact(2)
            .map(|c| u16::from_le_bytes([c[0], c[1]]))
            .collect();
        let frame = BayerFrame::new(w, h, depth, pattern, data, e, t, temp, num)
            .map_err(|e| FrameFileError(format!("bad frame: {e}")))?;
        frames.push(frame);
    }
    if pos != body.len() {
        return Err(bad("trailing bytes after the last frame"));
    }
    Ok(frames)
}

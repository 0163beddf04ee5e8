//! Unpacking of 10-bit Bayer pixel formats as V4L2 cameras deliver them.

use crate::error::{HalError, HalResult};
use serde::{Deserialize, Serialize};

/// Memory layout of a 10-bit raw Bayer frame, as V4L2 cameras deliver it.
///
/// * [`Bayer10Format::MipiPacked`] — V4L2 `SRGGB10P` (`pRAA`) and relatives: four pixels in five
///   bytes; bytes 0–3 hold bits 9..2 of pixels 0–3, byte 4 holds their bits 1..0 (pixel 0 in bits
///   1..0, pixel 3 in bits 7..6).
/// * [`Bayer10Format::Lsb16`] — V4L2 `SRGGB10` (`RG10`): one little-endian 16-bit word per pixel,
///   value in bits 9..0, bits 15..10 zero.
/// * [`Bayer10Format::Msb16`] — one little-endian 16-bit word per pixel, value left-justified in
///   bits 15..6, bits 5..0 zero (as some machine-vision cameras send it).
///
/// Rows may be padded (`bytes_per_line` larger than the packed row). Padding bits that must be
/// zero but are not mean the data is corrupt and give [`HalError::CorruptedFrame`]; a buffer of
/// the wrong size gives [`HalError::InvalidPixelData`].
///
/// # Examples
///
/// Every layout packs and unpacks a frame exactly; padding bits that are set are caught:
///
/// ```
/// use gantry_hal::{pack_bayer10, unpack_bayer10, Bayer10Format, ErrorKind};
///
/// let samples: Vec<u16> = vec![0, 1, 512, 1023, 7, 300, 900, 64];
/// for format in [Bayer10Format::MipiPacked, Bayer10Format::Lsb16, Bayer10Format::Msb16] {
///     let raw = pack_bayer10(format, &samples, 4, 2).unwrap();
///     assert_eq!(raw.len(), 2 * format.row_bytes(4));
///     assert_eq!(unpack_bayer10(format, &raw, 4, 2, None).unwrap(), samples);
/// }
/// // in `Lsb16` the six high bits of every word must be zero
/// let mut raw = pack_bayer10(Bayer10Format::Lsb16, &samples, 4, 2).unwrap();
/// raw[1] |= 0x80;
/// let err = unpack_bayer10(Bayer10Format::Lsb16, &raw, 4, 2, None).unwrap_err();
/// assert_eq!(err.kind(), ErrorKind::CorruptedFrame);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Bayer10Format {
    /// Four pixels in five bytes (MIPI CSI-2 RAW10, V4L2 `pRAA`/`pBAA`/`pgAA`/`pGAA`).
    MipiPacked,
    /// 16-bit little-endian container, value in the low 10 bits (V4L2 `RG10`/`BG10`/...).
    Lsb16,
    /// 16-bit little-endian container, value in the high 10 bits.
    Msb16,
}

impl Bayer10Format {
    /// Bytes of one unpadded row of `width` pixels.
    pub fn row_bytes(self, width: usize) -> usize {
        match self {
            Bayer10Format::MipiPacked => width.div_ceil(4) * 5,
            Bayer10Format::Lsb16 | Bayer10Format::Msb16 => width * 2,
        }
    }

    /// The V4L2 four-character code of this layout for an RGGB mosaic.
    pub fn fourcc_rggb(self) -> [u8; 4] {
        match self {
            Bayer10Format::MipiPacked => *b"pRAA",
            Bayer10Format::Lsb16 => *b"RG10",
            Bayer10Format::Msb16 => *b"RG16",
        }
    }
}

/// Unpacks a raw buffer into `width × height` 10-bit samples, row-major.
///
/// `bytes_per_line` is the row stride of the buffer (`None` = unpadded rows).
pub fn unpack_bayer10(
    format: Bayer10Format,
    raw: &[u8],
    width: usize,
    height: usize,
    bytes_per_line: Option<usize>,
) -> HalResult<Vec<u16>> {
    if width == 0 || height == 0 {
        return Err(HalError::InvalidPixelData(format!(
            "empty frame {width}x{height}"
        )));
    }
    let row = format.row_bytes(width);
    let stride = bytes_per_line.unwrap_or(row);
    if stride < row {
        return Err(HalError::InvalidPixelData(format!(
            "stride {stride} shorter than a {width}-pixel row ({row} bytes)"
        )));
    }
    // The last row need not carry its padding.
    let need = stride * (height - 1) + row;
    if raw.len() < need || raw.len() > stride * height {
        return Err(HalError::InvalidPixelData(format!(
            "{} bytes for {width}x{height} in {format:?} with stride {stride} (expected {need}..={})",
            raw.len(),
            stride * height
        )));
    }
    let mut out = Vec::with_capacity(width * height);
    for y in 0..height {
        let line = &raw[y * stride..y * stride + row];
        match format {
            Bayer10Format::MipiPacked => {
                for (g, chunk) in line.chunks_exact(5).enumerate() {
                    let low = chunk[4];
                    for (k, &high) in chunk[..4].iter().enumerate() {
                        let x = g * 4 + k;
                        let v = ((high as u16) << 2) | ((low >> (2 * k)) & 0b11) as u16;
                        if x < width {
                            out.push(v);
                        } else if v != 0 {
                            return Err(corrupt(x, y, "non-zero padding pixel"));
                        }
                    }
                }
            }
            Bayer10Format::Lsb16 => {
                for (x, w) in line.chunks_exact(2).enumerate() {
                    let v = u16::from_le_bytes([w[0], w[1]]);
                    if v > 0x3FF {
                        return Err(corrupt(x, y, "bits above 10 set in LSB-aligned word"));
                    }
                    out.push(v);
                }
            }
            Bayer10Format::Msb16 => {
                for (x, w) in line.chunks_exact(2).enumerate() {
                    let v = u16::from_le_bytes([w[0], w[1]]);
                    if v & 0x3F != 0 {
                        return Err(corrupt(x, y, "low 6 bits set in MSB-aligned word"));
                    }
                    out.push(v >> 6);
                }
            }
        }
    }
    Ok(out)
}

fn corrupt(x: usize, y: usize, what: &str) -> HalError {
    HalError::CorruptedFrame {
        detail: format!("{what} at ({x}, {y})"),
    }
}

/// Packs 10-bit samples into `format` with unpadded rows: the inverse of [`unpack_bayer10`].
/// Used by the simulated camera so that its frames travel through the same unpacking path as a
/// real camera's.
pub fn pack_bayer10(
    format: Bayer10Format,
    samples: &[u16],
    width: usize,
    height: usize,
) -> HalResult<Vec<u8>> {
    if width * height != samples.len() || width == 0 {
        return Err(HalError::InvalidPixelData(format!(
            "{} samples for {width}x{height}",
            samples.len()
        )));
    }
    if let Some(v) = samples.iter().find(|&&v| v > 0x3FF) {
        return Err(HalError::InvalidPixelData(format!(
            "sample {v} exceeds 10 bits"
        )));
    }
    let mut out = Vec::with_capacity(format.row_bytes(width) * height);
    for row in samples.chunks_exact(width) {
        match format {
            Bayer10Format::MipiPacked => {
                for group in row.chunks(4) {
                    let mut low = 0u8;
                    for k in 0..4 {
                        let v = group.get(k).copied().unwrap_or(0);
                        out.push((v >> 2) as u8);
                        low |= ((v & 0b11) as u8) << (2 * k);
                    }
                    out.push(low);
                }
            }
            Bayer10Format::Lsb16 => row
                .iter()
                .for_each(|v| out.extend_from_slice(&v.to_le_bytes())),
            Bayer10Format::Msb16 => row
                .iter()
                .for_each(|v| out.extend_from_slice(&(v << 6).to_le_bytes())),
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn mipi_packed_known_bytes() {
        // Pixels 0x3FF, 0x001, 0x200, 0x155: high bytes FF 00 80 55; low bits 11, 01, 00, 01.
        let raw = [0xFF, 0x00, 0x80, 0x55, 0b01_00_01_11];
        let px = unpack_bayer10(Bayer10Format::MipiPacked, &raw, 4, 1, None).unwrap();
        assert_eq!(px, vec![0x3FF, 0x001, 0x200, 0x155]);
    }

    #[test]
    fn lsb16_and_msb16_known_words() {
        let px = unpack_bayer10(Bayer10Format::Lsb16, &[0xFF, 0x03, 0x34, 0x01], 2, 1, None);
        assert_eq!(px.unwrap(), vec![1023, 0x134]);
        // 0x134 << 6 = 0x4D00.
        let px = unpack_bayer10(Bayer10Format::Msb16, &[0x00, 0x4D, 0xC0, 0xFF], 2, 1, None);
        assert_eq!(px.unwrap(), vec![0x134, 1023]);
    }

    #[test]
    fn padded_rows_are_skipped() {
        // Two rows of 4 pixels, stride 8 (3 padding bytes per row, last row unpadded).
        let mut raw = vec![1, 2, 3, 4, 0, 0xAA, 0xAA, 0xAA];
        raw.extend_from_slice(&[5, 6, 7, 8, 0b11_11_11_11]);
        let px = unpack_bayer10(Bayer10Format::MipiPacked, &raw, 4, 2, Some(8)).unwrap();
        assert_eq!(px, vec![4, 8, 12, 16, 23, 27, 31, 35]);
    }

    #[test]
    fn wrong_sizes_and_garbage_are_typed_errors() {
        let e = unpack_bayer10(Bayer10Format::Lsb16, &[0; 7], 2, 2, None).unwrap_err();
        assert!(matches!(e, HalError::InvalidPixelData(_)));
        let e = unpack_bayer10(Bayer10Format::Lsb16, &[0; 8], 2, 2, Some(3)).unwrap_err();
        assert!(matches!(e, HalError::InvalidPixelData(_)));
        let e = unpack_bayer10(Bayer10Format::Lsb16, &[0, 0x04], 1, 1, None).unwrap_err();
        assert!(matches!(e, HalError::CorruptedFrame { .. }));
        let e = unpack_bayer10(Bayer10Format::Msb16, &[0x01, 0x00], 1, 1, None).unwrap_err();
        assert!(matches!(e, HalError::CorruptedFrame { .. }));
        let e = unpack_bayer10(Bayer10Format::MipiPacked, &[], 0, 1, None).unwrap_err();
        assert!(matches!(e, HalError::InvalidPixelData(_)));
    }

    proptest! {
        #![proptest_config(ProptestConfig {
            rng_seed: proptest::test_runner::RngSeed::Fixed(20261122),
            ..ProptestConfig::default()
        })]
        #[test]
        fn pack_unpack_round_trip(
            w in 1usize..13, h in 1usize..5, seed in any::<u64>(),
            fmt in prop_oneof![Just(Bayer10Format::MipiPacked), Just(Bayer10Format::Lsb16), Just(Bayer10Format::Msb16)],
        ) {
            let mut s = seed;
            let samples: Vec<u16> = (0..w * h).map(|_| {
                s = s.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                ((s >> 33) & 0x3FF) as u16
            }).collect();
            let raw = pack_bayer10(fmt, &samples, w, h).unwrap();
            prop_assert_eq!(raw.len(), fmt.row_bytes(w) * h);
            let back = unpack_bayer10(fmt, &raw, w, h, None).unwrap();
            prop_assert_eq!(back, samples);
        }
    }
}

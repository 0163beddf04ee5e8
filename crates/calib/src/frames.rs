//! Frame pre-processing for the target images: stacking repeated exposures of one pose, and
//! flat-field correction of the sensor's photo-response non-uniformity (PRNU).

use crate::error::{CalibError, CalibResult};
use gantry_hal::BayerFrame;

fn frame_error(what: &str, e: impl std::fmt::Display) -> CalibError {
    CalibError::Invalid(format!("{what}: {e}"))
}

/// Sum of `frames` (repeated exposures of one scene) as one frame of higher bit depth.
///
/// The sum is exact: n frames of b bits need b + ⌈log₂ n⌉ ≤ 16 bits. The frames must agree in
/// size, bit depth and Bayer pattern. The result's exposure is the total exposure; its time
/// stamp, temperature and frame number are those of the first frame.
pub fn stack_frames(frames: &[BayerFrame]) -> CalibResult<BayerFrame> {
    let first = frames.first().ok_or(CalibError::TooFewPoints {
        what: "frames to stack",
        got: 0,
        need: 1,
    })?;
    for (i, f) in frames.iter().enumerate() {
        f.validate()
            .map_err(|e| frame_error(&format!("frame {i} of the stack"), e))?;
        if (f.width, f.height, f.bit_depth, f.pattern)
            != (first.width, first.height, first.bit_depth, first.pattern)
        {
            return Err(CalibError::Invalid(format!(
                "frame {i} of the stack is {}x{} {}-bit {:?}, the first is {}x{} {}-bit {:?}",
                f.width,
                f.height,
                f.bit_depth,
                f.pattern,
                first.width,
                first.height,
                first.bit_depth,
                first.pattern
            )));
        }
    }
    if frames.len() == 1 {
        return Ok(first.clone());
    }
    let extra = usize::BITS - (frames.len() - 1).leading_zeros();
    let bits = first.bit_depth as u32 + extra;
    if bits > 16 {
        return Err(CalibError::Invalid(format!(
            "{} frames of {} bits need {bits} bits; at most 16 are stored",
            frames.len(),
            first.bit_depth
        )));
    }
    let mut sum = vec![0u32; first.data.len()];
    for f in frames {
        for (s, &v) in sum.iter_mut().zip(&f.data) {
            *s += v as u32;
        }
    }
    BayerFrame::new(
        first.width,
        first.height,
        bits as u8,
        first.pattern,
        sum.into_iter().map(|s| s as u16).collect(),
        frames.iter().map(|f| f.exposure_s).sum(),
        first.timestamp_s,
        first.sensor_temperature_c,
        first.frame_number,
    )
    .map_err(|e| frame_error("stacked frame", e))
}

/// Relative gain of every photosite, measured from a flat frame.
///
/// A checkerboard corner is located to about 0.9·σ/C pixels, σ the noise of one photosite and
/// C the black-to-white contrast, whatever the scale of the refinement. On the gantry camera
/// σ has two parts of similar size: photon noise, which falls as 1/√n when n exposures of the
/// same pose are summed, and the fixed ~1 % gain spread of the photosites, which does not. A
/// flat field (a stack of frames of a uniformly lit diffuser) measures that spread, and
/// dividing by it removes it; docs/calib.md has the measured effect on the calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct FlatField {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Gain of each photosite relative to its neighbours of the same colour, row-major.
    pub gain: Vec<f32>,
}

/// Half-width, in same-colour photosites, of the neighbourhood whose mean a photosite's value is
/// divided by (17 × 17 same-colour sites).
const FLAT_RADIUS: usize = 8;

impl FlatField {
    /// The gain map measured from flat frames: exposures of a uniformly lit diffuser in front
    /// of the lens, summed. Each photosite's sum is divided by the mean of the same-colour
    /// photosites around it (a 34 × 34 pixel neighbourhood), which removes the illumination's
    /// and the lens's slow variations and keeps the photosites' own gains.
    ///
    /// Errors: no frames, frames that differ in size, bit depth or pattern, a frame too dark
    /// (mean below 5 % of full scale) or with more than 1 % of its photosites saturated,
    /// either of which would not measure the gains.
    pub fn estimate(flats: &[BayerFrame]) -> CalibResult<Self> {
        let first = flats.first().ok_or(CalibError::TooFewPoints {
            what: "flat frames",
            got: 0,
            need: 1,
        })?;
        let (w, h) = (first.width, first.height);
        let mut sum = vec![0f64; w * h];
        let mut saturated = vec![false; w * h];
        for (i, flat) in flats.iter().enumerate() {
            flat.validate()
                .map_err(|e| frame_error(&format!("flat frame {i}"), e))?;
            if (flat.width, flat.height, flat.pattern) != (w, h, first.pattern) {
                return Err(CalibError::Invalid(format!(
                    "flat frame {i} is {}x{} {:?}, the first is {w}x{h} {:?}",
                    flat.width, flat.height, flat.pattern, first.pattern
                )));
            }
            let max = flat.max_value();
            let mut n_sat = 0usize;
            let mut mean = 0.0;
            for ((s, sat), &v) in sum.iter_mut().zip(saturated.iter_mut()).zip(&flat.data) {
                *s += v as f64;
                mean += v as f64;
                if v >= max {
                    *sat = true;
                    n_sat += 1;
                }
            }
            mean /= flat.data.len() as f64;
            if mean < 0.05 * max as f64 {
                return Err(CalibError::Invalid(format!(
                    "flat frame {i} too dark: mean {mean:.1} of full scale {max}"
                )));
            }
            if n_sat * 100 > flat.data.len() {
                return Err(CalibError::Invalid(format!(
                    "flat frame {i} saturated at {n_sat} of {} photosites",
                    flat.data.len()
                )));
            }
        }
        let mut gain = vec![1f32; w * h];
        // The four photosite lattices of the 2 × 2 Bayer cell, each treated on its own.
        for (ox, oy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            let (lw, lh) = ((w + 1 - ox) / 2, (h + 1 - oy) / 2);
            if lw == 0 || lh == 0 {
                continue;
            }
            // Integral image of the lattice.
            let mut integral = vec![0f64; (lw + 1) * (lh + 1)];
            for j in 0..lh {
                let mut row = 0.0;
                for i in 0..lw {
                    row += sum[(oy + 2 * j) * w + ox + 2 * i];
                    integral[(j + 1) * (lw + 1) + i + 1] = integral[j * (lw + 1) + i + 1] + row;
                }
            }
            let rect = |i0: usize, j0: usize, i1: usize, j1: usize| {
                integral[j1 * (lw + 1) + i1]
                    - integral[j0 * (lw + 1) + i1]
                    - integral[j1 * (lw + 1) + i0]
                    + integral[j0 * (lw + 1) + i0]
            };
            for j in 0..lh {
                let (j0, j1) = (j.saturating_sub(FLAT_RADIUS), (j + FLAT_RADIUS + 1).min(lh));
                for i in 0..lw {
                    let (i0, i1) = (i.saturating_sub(FLAT_RADIUS), (i + FLAT_RADIUS + 1).min(lw));
                    let local = rect(i0, j0, i1, j1) / ((i1 - i0) * (j1 - j0)) as f64;
                    let (x, y) = (ox + 2 * i, oy + 2 * j);
                    let v = sum[y * w + x];
                    // Dead, saturated or unlit photosites keep a unit gain.
                    let g = if local > 0.0 && !saturated[y * w + x] && v > 0.0 {
                        (v / local).clamp(0.5, 2.0)
                    } else {
                        1.0
                    };
                    gain[y * w + x] = g as f32;
                }
            }
        }
        tracing::debug!(
            width = w,
            height = h,
            frames = flats.len(),
            "flat field estimated"
        );
        Ok(Self {
            width: w,
            height: h,
            gain,
        })
    }

    /// The photosite values of `frame`, each divided by its gain.
    pub fn correct(&self, frame: &BayerFrame) -> CalibResult<Vec<f32>> {
        frame
            .validate()
            .map_err(|e| frame_error("frame to flat-field", e))?;
        if (frame.width, frame.height) != (self.width, self.height) {
            return Err(CalibError::Invalid(format!(
                "frame is {}x{}, the flat field {}x{}",
                frame.width, frame.height, self.width, self.height
            )));
        }
        Ok(frame
            .data
            .iter()
            .zip(&self.gain)
            .map(|(&v, &g)| v as f32 / g)
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gantry_hal::BayerPattern;

    fn frame(w: usize, h: usize, bits: u8, f: impl Fn(usize, usize) -> u16) -> BayerFrame {
        let data = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| f(x, y))
            .collect();
        BayerFrame::new(w, h, bits, BayerPattern::Rggb, data, 0.1, 0.0, 25.0, 1).unwrap()
    }

    #[test]
    fn stacking_sums_exactly_and_widens_the_bit_depth() {
        let frames: Vec<_> = (0..4)
            .map(|k| frame(6, 4, 10, |x, y| (1023 - k * 7 - x - 10 * y) as u16))
            .collect();
        let s = stack_frames(&frames).unwrap();
        assert_eq!(s.bit_depth, 12);
        assert!((s.exposure_s - 0.4).abs() < 1e-12);
        for y in 0..4 {
            for x in 0..6 {
                let want: u32 = frames.iter().map(|f| f.get(x, y) as u32).sum();
                assert_eq!(s.get(x, y) as u32, want);
            }
        }
        // Five frames need three more bits.
        let five: Vec<_> = (0..5).map(|_| frames[0].clone()).collect();
        assert_eq!(stack_frames(&five).unwrap().bit_depth, 13);
    }

    #[test]
    fn stacking_rejects_empty_mismatched_and_overflowing_stacks() {
        assert!(matches!(
            stack_frames(&[]),
            Err(CalibError::TooFewPoints { .. })
        ));
        let a = frame(6, 4, 10, |_, _| 1);
        let b = frame(6, 4, 12, |_, _| 1);
        assert!(matches!(
            stack_frames(&[a.clone(), b]),
            Err(CalibError::Invalid(_))
        ));
        let c = frame(4, 4, 10, |_, _| 1);
        assert!(stack_frames(&[a.clone(), c]).is_err());
        let many: Vec<_> = (0..65).map(|_| a.clone()).collect();
        assert!(stack_frames(&many).is_err());
    }

    #[test]
    fn flat_field_recovers_photosite_gains_under_smooth_illumination() {
        // Illumination fall-off × per-channel level × a photosite gain pattern.
        let (w, h) = (64, 48);
        let gain = |x: usize, y: usize| 1.0 + 0.02 * (((x * 7 + y * 13) % 11) as f64 - 5.0) / 5.0;
        let level = |x: usize, y: usize| {
            let ch = [0.7, 1.0, 1.0, 0.6][(x % 2) + 2 * (y % 2)];
            // A linear fall-off (its neighbourhood mean is its centre value).
            3000.0 * ch * (1.0 + 0.004 * (x as f64 - 32.0) - 0.003 * (y as f64 - 24.0))
        };
        let flat = frame(w, h, 12, |x, y| (level(x, y) * gain(x, y)).round() as u16);
        let ff = FlatField::estimate(std::slice::from_ref(&flat)).unwrap();
        // Away from the border the neighbourhood mean follows the smooth fall-off.
        let mut worst: f64 = 0.0;
        for y in 16..32 {
            for x in 16..48 {
                let g = ff.gain[y * w + x] as f64;
                // The local mean of the gain pattern is ~1, so the estimate is the gain.
                worst = worst.max((g / gain(x, y) - 1.0).abs());
            }
        }
        assert!(worst < 3e-3, "worst relative gain error {worst}");
        // Correcting a frame of the same scene leaves the smooth level only.
        let corrected = ff.correct(&flat).unwrap();
        let mut worst: f64 = 0.0;
        for y in 16..32 {
            for x in 16..48 {
                let want = level(x, y);
                worst = worst.max((corrected[y * w + x] as f64 / want - 1.0).abs());
            }
        }
        assert!(worst < 4e-3, "worst corrected deviation {worst}");
    }

    #[test]
    fn flat_field_rejects_dark_saturated_and_mismatched_frames() {
        let ok = frame(32, 32, 10, |_, _| 500);
        let dark = frame(32, 32, 10, |_, _| 10);
        assert!(matches!(
            FlatField::estimate(&[ok.clone(), dark]),
            Err(CalibError::Invalid(_))
        ));
        let sat = frame(32, 32, 10, |_, _| 1023);
        assert!(matches!(
            FlatField::estimate(&[sat]),
            Err(CalibError::Invalid(_))
        ));
        assert!(matches!(
            FlatField::estimate(&[]),
            Err(CalibError::TooFewPoints { .. })
        ));
        let other = frame(16, 32, 10, |_, _| 500);
        assert!(FlatField::estimate(&[ok.clone(), other.clone()]).is_err());
        let ff = FlatField::estimate(&[ok.clone(), ok]).unwrap();
        assert!(ff.gain.iter().all(|&g| (g - 1.0).abs() < 1e-6));
        assert!(ff.correct(&other).is_err());
    }
}

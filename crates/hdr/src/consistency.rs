//! Per-frame consistency of an exposure series with its merged fit: detects frames taken while
//! the lamp dropped out or flickered.

use crate::error::{HdrError, HdrResult};
use crate::merge::HdrImage;
use gantry_hal::BayerFrame;
use rayon::prelude::*;
use std::borrow::Borrow;

/// Agreement of one frame with the merged fit.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameCheck {
    /// Position of the frame in the input slice.
    pub index: usize,
    /// Exposure of the frame, seconds.
    pub exposure_s: f64,
    /// Number of pixels that entered the median.
    pub pixels: usize,
    /// Median of observed / fitted signal (NaN when no pixel qualified).
    pub ratio: f64,
}

/// Compares every frame of a series with the image merged from it, to detect frames taken
/// while the lamp dropped out or flickered.
///
/// For each frame, the pixels that have a fitted line in the merged image (at least 3 valid
/// exposures, positive rate, not hot; the correlation test is not required, since a bad frame is
/// exactly what spoils it) and whose sample lies inside the valid window give the ratio of
/// observed to fitted signal, `(v − offset) / (rate · t)`.
/// The median of these ratios is 1 for a frame that agrees with the line. A frame exposed while
/// the lamp was off for part of the exposure falls short by the missing fraction. After a flicker
/// jump, the later frames sit above or below the earlier ones. The median over thousands of
/// pixels is insensitive to the per-pixel noise, so deviations of a few percent are visible.
///
/// A bad frame also pulls the fit, so frames next to it deviate as well. The check tells
/// reliably *that* a series is inconsistent, and only roughly *which* frame is to blame. The
/// remedy is to repeat the whole series.
///
/// The pixels with a fitted line are found once; the frames are then checked in parallel.
///
/// # Examples
///
/// The lamp went dark for half of the third exposure: that frame falls short of the fitted
/// lines, and [`inconsistent_frames`] names the series as bad.
///
/// ```
/// use hdr::{check_frames, inconsistent_frames, merge, MergeOptions};
/// # use gantry_hal::{BayerFrame, BayerPattern};
/// # fn series(rates: &[f64], exposures: &[f64]) -> Vec<BayerFrame> {
/// #     exposures.iter().enumerate().map(|(i, &t)| {
/// #         let data = rates.iter().map(|r| (20.0 + r * t).round().min(1023.0) as u16).collect();
/// #         BayerFrame::new(rates.len(), 1, 10, BayerPattern::Rggb, data, t, i as f64, 25.0, i as u64)
/// #             .unwrap()
/// #     }).collect()
/// # }
///
/// let rates: Vec<f64> = (0..200).map(|i| 500.0 + 20.0 * i as f64).collect();
/// let mut frames = series(&rates, &[0.02, 0.03, 0.045, 0.07, 0.1, 0.15]);
/// for v in frames[2].data.iter_mut() {
///     *v = 20 + (*v - 20) / 2; // half the signal
/// }
/// let image = merge(&frames, None, &MergeOptions::default()).unwrap();
/// let checks = check_frames(&frames, &image).unwrap();
/// assert!(checks[2].ratio < 0.9, "{:?}", checks[2]);
/// assert!(inconsistent_frames(&checks, 0.05, 50).contains(&2));
/// ```
pub fn check_frames<F: Borrow<BayerFrame> + Sync>(
    frames: &[F],
    image: &HdrImage,
) -> HdrResult<Vec<FrameCheck>> {
    let (lo, hi) = (image.options.low_dn as f32, image.options.high_dn as f32);
    for (index, f) in frames.iter().enumerate() {
        let f = f.borrow();
        if f.width != image.width
            || f.height != image.height
            || f.data.len() != image.radiance.len()
        {
            return Err(HdrError::Dimensions(format!(
                "frame {index} is {}x{}, image {}x{}",
                f.width, f.height, image.width, image.height
            )));
        }
    }
    // Pixels with a fitted line: at least 3 valid exposures, positive rate, not hot.
    let fitted_line: Vec<u32> = (0..image.radiance.len())
        .filter(|&i| {
            image.count[i] >= 3
                && image.radiance[i] > 0.0
                && image.flags[i] & crate::flags::HOT == 0
        })
        .map(|i| i as u32)
        .collect();
    Ok(frames
        .par_iter()
        .enumerate()
        .map(|(index, f)| {
            let f = f.borrow();
            let t = f.exposure_s;
            let tf = t as f32;
            let mut ratios: Vec<f32> = Vec::with_capacity(fitted_line.len() / 4);
            for &i in &fitted_line {
                let i = i as usize;
                let v = f.data[i] as f32;
                if v < lo || v > hi {
                    continue;
                }
                let fitted = image.radiance[i] * tf;
                // Ratios of tiny predicted signals are dominated by noise.
                if fitted > 5.0 {
                    let r = (v - image.offset[i]) / fitted;
                    if r.is_finite() {
                        ratios.push(r);
                    }
                }
            }
            let pixels = ratios.len();
            let ratio = if pixels == 0 {
                f64::NAN
            } else {
                let mid = pixels / 2;
                let (_, m, _) = ratios.select_nth_unstable_by(mid, f32::total_cmp);
                *m as f64
            };
            FrameCheck {
                index,
                exposure_s: t,
                pixels,
                ratio,
            }
        })
        .collect())
}

/// Indices of the frames whose median ratio deviates from 1 by more than `tolerance` (e.g.
/// 0.02), considering only frames with at least `min_pixels` pixels in the median.
pub fn inconsistent_frames(checks: &[FrameCheck], tolerance: f64, min_pixels: usize) -> Vec<usize> {
    checks
        .iter()
        .filter(|c| c.pixels >= min_pixels && (c.ratio - 1.0).abs() > tolerance)
        .map(|c| c.index)
        .collect()
}

/// How well the pixels of a region fitted the line of value against exposure.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FitQuality {
    /// Pixels of the region fitted from enough exposures (not hot).
    pub fitted: usize,
    /// Of those, the pixels whose fit correlation was too low ([`crate::flags::LOW_CORRELATION`]).
    pub low_correlation: usize,
}

impl FitQuality {
    /// Share of the fitted pixels that fit badly (0 when none was fitted).
    pub fn low_fraction(&self) -> f64 {
        if self.fitted == 0 {
            0.0
        } else {
            self.low_correlation as f64 / self.fitted as f64
        }
    }
}

/// Fit quality of the merged `image` over the pixel indices `pixels`, counting the pixels with
/// at least `min_exposures` valid exposures that are not hot.
///
/// This complements [`check_frames`]: a frame taken in the wrong light breaks the linear fit of
/// many pixels at once, so the share of badly fitting pixels jumps, even where the per-frame
/// median ratios stay within tolerance. Noise alone leaves a fraction of a percent. Indices
/// outside the image are ignored.
pub fn fit_quality(
    image: &HdrImage,
    pixels: impl IntoIterator<Item = usize>,
    min_exposures: u16,
) -> FitQuality {
    use crate::merge::flags;
    let mut q = FitQuality {
        fitted: 0,
        low_correlation: 0,
    };
    for i in pixels {
        let (Some(&f), Some(&count)) = (image.flags.get(i), image.count.get(i)) else {
            continue;
        };
        if f & (flags::HOT | flags::TOO_FEW) != 0 || count < min_exposures {
            continue;
        }
        q.fitted += 1;
        if f & flags::LOW_CORRELATION != 0 {
            q.low_correlation += 1;
        }
    }
    q
}

//! Dark-frame defect map (thesis §3.3): photosites with excessive dark current.

use crate::error::{HdrError, HdrResult};
use crate::ladder::SEED_DARK_EXPOSURE_S;
use gantry_hal::BayerFrame;

/// How a dark frame is turned into a defect map.
#[derive(Debug, Clone, PartialEq)]
pub struct DarkFrameOptions {
    /// Raw samples strictly above this value (DN) mark a hot photosite. Seed: 16.
    pub threshold_dn: f64,
    /// Exposure the dark frame must have, seconds (`None` accepts any). Seed: 60 s. The
    /// threshold only means what the thesis means for this exposure.
    pub expected_exposure_s: Option<f64>,
}

impl Default for DarkFrameOptions {
    fn default() -> Self {
        Self {
            threshold_dn: 16.0,
            expected_exposure_s: Some(SEED_DARK_EXPOSURE_S),
        }
    }
}

/// Photosites excluded from the measurement, with what the dark frame told about the sensor
/// (thesis §3.3).
///
/// "I capture one image with 60 second exposure time and a closed lens cover ... The elements
/// that have values above 16 are considered to have excessive dark current values, and are not
/// used in the BRDF measurement process." The threshold applies to the raw sample (black level
/// included), as in the thesis; such photosites are masked for the whole capture.
///
/// # Examples
///
/// ```
/// use gantry_hal::{BayerFrame, BayerPattern};
/// use hdr::{DarkFrameOptions, DefectMap};
///
/// // a 60 s dark frame: black level 12 DN, one photosite with a high dark current
/// let dark = BayerFrame::new(4, 1, 10, BayerPattern::Rggb, vec![12, 13, 40, 12], 60.0, 0.0, 25.0, 0)
///     .unwrap();
/// let map = DefectMap::from_dark_frame(&dark, &DarkFrameOptions::default()).unwrap();
/// assert_eq!(map.threshold_dn(), 16.0);
/// assert_eq!(map.hot_pixels(), vec![(2, 0)]);
/// assert!(map.is_hot(2, 0) && !map.is_hot(1, 0));
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct DefectMap {
    width: usize,
    height: usize,
    hot: Vec<bool>,
    threshold_dn: f64,
    dark_exposure_s: f64,
    dark_median_dn: f64,
    dark_mean_dn: f64,
}

impl DefectMap {
    /// A map without defects (no dark frame taken).
    pub fn empty(width: usize, height: usize) -> Self {
        Self {
            width,
            height,
            hot: vec![false; width * height],
            threshold_dn: f64::INFINITY,
            dark_exposure_s: 0.0,
            dark_median_dn: f64::NAN,
            dark_mean_dn: f64::NAN,
        }
    }

    /// A map from an explicit mask (`true` = excluded), row-major `width × height`.
    pub fn from_mask(width: usize, height: usize, hot: Vec<bool>) -> HdrResult<Self> {
        if width.checked_mul(height) != Some(hot.len()) {
            return Err(HdrError::Dimensions(format!(
                "mask of {} entries for {width}x{height}",
                hot.len()
            )));
        }
        Ok(Self {
            hot,
            ..Self::empty(width, height)
        })
    }

    /// Classifies the photosites of a dark frame (lens covered): raw value above
    /// `opts.threshold_dn` is hot.
    pub fn from_dark_frame(frame: &BayerFrame, opts: &DarkFrameOptions) -> HdrResult<Self> {
        if !opts.threshold_dn.is_finite() {
            return Err(HdrError::InvalidOption(format!(
                "dark threshold {} DN",
                opts.threshold_dn
            )));
        }
        if frame.width.checked_mul(frame.height) != Some(frame.data.len()) || frame.width == 0 {
            return Err(HdrError::MalformedFrame {
                index: 0,
                detail: format!(
                    "{} samples for a {}x{} dark frame",
                    frame.data.len(),
                    frame.width,
                    frame.height
                ),
            });
        }
        if !(frame.exposure_s.is_finite() && frame.exposure_s > 0.0) {
            return Err(HdrError::InvalidExposure {
                index: 0,
                exposure_s: frame.exposure_s,
            });
        }
        if let Some(expected) = opts.expected_exposure_s {
            if (frame.exposure_s / expected - 1.0).abs() > 1e-3 {
                return Err(HdrError::DarkExposure {
                    got_s: frame.exposure_s,
                    expected_s: expected,
                });
            }
        }
        let hot: Vec<bool> = frame
            .data
            .iter()
            .map(|&v| v as f64 > opts.threshold_dn)
            .collect();
        // Statistics of the photosites that are not hot: a 1024-bin histogram is exact for
        // 10-bit data and cheap for any bit depth up to 16.
        let mut hist = vec![0u64; 1usize << frame.bit_depth.clamp(1, 16)];
        let (mut sum, mut n) = (0.0f64, 0u64);
        for (&v, &h) in frame.data.iter().zip(&hot) {
            if !h {
                let b = (v as usize).min(hist.len() - 1);
                hist[b] += 1;
                sum += v as f64;
                n += 1;
            }
        }
        let median = if n == 0 {
            f64::NAN
        } else {
            let half = n.div_ceil(2);
            let mut acc = 0;
            let mut m = f64::NAN;
            for (v, &c) in hist.iter().enumerate() {
                acc += c;
                if acc >= half {
                    m = v as f64;
                    break;
                }
            }
            m
        };
        let map = Self {
            width: frame.width,
            height: frame.height,
            hot,
            threshold_dn: opts.threshold_dn,
            dark_exposure_s: frame.exposure_s,
            dark_median_dn: median,
            dark_mean_dn: if n == 0 { f64::NAN } else { sum / n as f64 },
        };
        tracing::info!(
            hot = map.hot_count(),
            median_dn = median,
            "defect map from a {} s dark frame",
            frame.exposure_s
        );
        Ok(map)
    }

    /// Sensor columns.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Sensor rows.
    pub fn height(&self) -> usize {
        self.height
    }

    /// The mask, row-major (`true` = hot, excluded).
    pub fn mask(&self) -> &[bool] {
        &self.hot
    }

    /// Whether the photosite at column `x`, row `y` is excluded (`false` outside the sensor).
    pub fn is_hot(&self, x: usize, y: usize) -> bool {
        x < self.width && y < self.height && self.hot[y * self.width + x]
    }

    /// Number of excluded photosites.
    pub fn hot_count(&self) -> usize {
        self.hot.iter().filter(|&&h| h).count()
    }

    /// Excluded photosites as (column, row), row-major order.
    pub fn hot_pixels(&self) -> Vec<(usize, usize)> {
        self.hot
            .iter()
            .enumerate()
            .filter(|(_, &h)| h)
            .map(|(i, _)| (i % self.width, i / self.width))
            .collect()
    }

    /// Threshold used, DN (infinite for maps not made from a dark frame).
    pub fn threshold_dn(&self) -> f64 {
        self.threshold_dn
    }

    /// Exposure of the dark frame, seconds (0 for maps not made from a dark frame).
    pub fn dark_exposure_s(&self) -> f64 {
        self.dark_exposure_s
    }

    /// Median raw value of the photosites that are not hot, DN: the black level plus the typical
    /// dark signal accumulated over the dark exposure, rounded by the quantiser (NaN without a
    /// dark frame).
    pub fn dark_median_dn(&self) -> f64 {
        self.dark_median_dn
    }

    /// Mean raw value of the photosites that are not hot, DN (NaN without a dark frame).
    pub fn dark_mean_dn(&self) -> f64 {
        self.dark_mean_dn
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gantry_hal::BayerPattern;

    fn dark(data: Vec<u16>, w: usize, h: usize, t: f64) -> BayerFrame {
        BayerFrame::new(w, h, 10, BayerPattern::Rggb, data, t, 0.0, 25.0, 1).unwrap()
    }

    #[test]
    fn threshold_is_strictly_above_16_on_raw_values() {
        let f = dark(vec![4, 16, 17, 1023, 5, 3], 3, 2, 60.0);
        let m = DefectMap::from_dark_frame(&f, &DarkFrameOptions::default()).unwrap();
        assert_eq!(m.hot_pixels(), vec![(2, 0), (0, 1)]);
        assert!(m.is_hot(0, 1) && !m.is_hot(1, 0) && !m.is_hot(9, 9));
        // Median of the non-hot values 4, 16, 5, 3.
        assert_eq!(m.dark_median_dn(), 4.0);
        assert_eq!(m.dark_mean_dn(), 7.0);
    }

    #[test]
    fn wrong_exposure_and_malformed_frames_are_errors() {
        let f = dark(vec![4; 6], 3, 2, 30.0);
        assert!(matches!(
            DefectMap::from_dark_frame(&f, &DarkFrameOptions::default()),
            Err(HdrError::DarkExposure { .. })
        ));
        let opts = DarkFrameOptions {
            expected_exposure_s: None,
            ..Default::default()
        };
        assert!(DefectMap::from_dark_frame(&f, &opts).is_ok());
        let mut g = f.clone();
        g.data.pop();
        assert!(matches!(
            DefectMap::from_dark_frame(&g, &opts),
            Err(HdrError::MalformedFrame { .. })
        ));
        let bad = DarkFrameOptions {
            threshold_dn: f64::NAN,
            ..opts
        };
        assert!(DefectMap::from_dark_frame(&f, &bad).is_err());
        assert!(DefectMap::from_mask(2, 2, vec![false; 3]).is_err());
    }
}

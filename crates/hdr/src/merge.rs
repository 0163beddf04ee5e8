//! Per-pixel merge of an exposure series into a radiance image (thesis §3.3).

use crate::defect::DefectMap;
use crate::error::{HdrError, HdrResult};
use gantry_hal::BayerFrame;
use rayon::prelude::*;
use std::borrow::Borrow;

/// Photosites per work unit of the merge.
pub const BLOCK: usize = 256;

/// Most exposures one series may have (the valid exposures of a pixel are kept as a bit mask).
pub const MAX_EXPOSURES: usize = 64;

/// How the offset of the line (the value at zero exposure) is obtained.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Intercept {
    /// Fitted per pixel together with the slope (the thesis's line fit; needs two distinct
    /// exposures). Absorbs the black level and any fixed offset without calibration.
    Fitted,
    /// Fixed to a known black level (DN); only the slope is fitted.
    BlackLevel(f64),
}

/// Settings of the merge. [`Default`] gives the thesis's rule.
///
/// # Examples
///
/// ```
/// use hdr::{Intercept, MergeOptions};
///
/// let thesis = MergeOptions::default();
/// assert_eq!((thesis.low_dn, thesis.high_dn, thesis.min_correlation), (10.0, 1000.0, 0.998));
/// assert_eq!(thesis.intercept, Intercept::Fitted);
/// thesis.validate().unwrap();
/// // a line with a fitted offset needs two points at least
/// let loose = MergeOptions { min_valid: 1, ..MergeOptions::default() };
/// assert!(loose.validate().is_err());
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct MergeOptions {
    /// Samples below this value (DN) are discarded. Seed: 10.
    pub low_dn: f64,
    /// Samples above this value (DN) are discarded. Seed: 1000.
    pub high_dn: f64,
    /// Pixels whose correlation is below this are flagged. Seed: 0.998.
    pub min_correlation: f64,
    /// Pixels with fewer valid exposures are flagged (at least 2 with a fitted intercept).
    pub min_valid: usize,
    /// Offset handling.
    pub intercept: Intercept,
}

impl Default for MergeOptions {
    fn default() -> Self {
        Self {
            low_dn: 10.0,
            high_dn: 1000.0,
            min_correlation: 0.998,
            min_valid: 3,
            intercept: Intercept::Fitted,
        }
    }
}

impl MergeOptions {
    /// Checks the options.
    pub fn validate(&self) -> HdrResult<()> {
        let bad = |s: String| Err(HdrError::InvalidOption(s));
        if !(self.low_dn.is_finite() && self.high_dn.is_finite() && self.low_dn < self.high_dn) {
            return bad(format!("valid window {}..{} DN", self.low_dn, self.high_dn));
        }
        if !(-1.0..=1.0).contains(&self.min_correlation) {
            return bad(format!("minimum correlation {}", self.min_correlation));
        }
        match self.intercept {
            Intercept::Fitted if self.min_valid < 2 => {
                bad("a fitted intercept needs min_valid >= 2".into())
            }
            Intercept::BlackLevel(b) if !b.is_finite() => bad(format!("black level {b}")),
            _ if self.min_valid == 0 => bad("min_valid must be at least 1".into()),
            _ => Ok(()),
        }
    }
}

/// Bits of [`HdrImage::flags`], re-exported as `hdr::flags` (for example
/// `image.flags[i] & hdr::flags::HOT != 0`).
pub mod flags {
    /// Excluded by the defect map (hot photosite).
    pub const HOT: u8 = 1;
    /// Fewer valid exposures than [`super::MergeOptions::min_valid`].
    pub const TOO_FEW: u8 = 2;
    /// Correlation below [`super::MergeOptions::min_correlation`] (or undefined).
    pub const LOW_CORRELATION: u8 = 4;
    /// Above the valid window already in the shortest exposure: may be brighter than the
    /// series can measure.
    pub const SATURATED: u8 = 8;
    /// Below the valid window even in the longest exposure.
    pub const UNDEREXPOSED: u8 = 16;
    /// The flags that make a pixel invalid.
    pub const INVALIDATING: u8 = HOT | TOO_FEW | LOW_CORRELATION;
}

/// A merged radiance image, one value per photosite (raw Bayer layout, row-major).
#[derive(Debug, Clone, PartialEq)]
pub struct HdrImage {
    /// Sensor columns.
    pub width: usize,
    /// Sensor rows.
    pub height: usize,
    /// Radiance estimate (slope of the fit), DN/s; 0 where no slope could be fitted.
    pub radiance: Vec<f32>,
    /// Standard error of the slope, DN/s; NaN where the fit has no residual degrees of freedom.
    pub std_error: Vec<f32>,
    /// Offset of the line (value at zero exposure), DN: fitted, or the given black level; NaN
    /// where no line could be fitted.
    pub offset: Vec<f32>,
    /// Pearson correlation of the valid (exposure, value) pairs; NaN with fewer than two
    /// pairs or no variation.
    pub correlation: Vec<f32>,
    /// Whether the pixel passed every test (not hot, enough valid exposures, correlation).
    pub valid: Vec<bool>,
    /// Number of valid exposures used in the fit (0 for hot pixels).
    pub count: Vec<u16>,
    /// Bit set of [`flags`].
    pub flags: Vec<u8>,
    /// Exposure times of the series, ascending, seconds.
    pub exposures_s: Vec<f64>,
    /// The settings of the merge.
    pub options: MergeOptions,
}

impl HdrImage {
    /// Number of photosites.
    pub fn len(&self) -> usize {
        self.radiance.len()
    }

    /// Whether the image has no photosites.
    pub fn is_empty(&self) -> bool {
        self.radiance.is_empty()
    }

    /// Number of valid pixels.
    pub fn valid_count(&self) -> usize {
        self.valid.iter().filter(|&&v| v).count()
    }

    /// Row-major index of column `x`, row `y`.
    pub fn index(&self, x: usize, y: usize) -> usize {
        y * self.width + x
    }
}

/// Running sums of one block. Sums that depend on the exposure times only (count, Σt, Σt²,
/// Σ1/t) are not accumulated: the bit mask of the valid exposures gives them at the end.
struct Sums {
    mask: [u64; BLOCK],
    sv: [f64; BLOCK],
    svt: [f64; BLOCK],
    svw: [f64; BLOCK],
    svv: [f64; BLOCK],
    svvw: [f64; BLOCK],
}

impl Sums {
    fn zero() -> Box<Self> {
        Box::new(Self {
            mask: [0; BLOCK],
            sv: [0.0; BLOCK],
            svt: [0.0; BLOCK],
            svw: [0.0; BLOCK],
            svv: [0.0; BLOCK],
            svvw: [0.0; BLOCK],
        })
    }

    fn clear(&mut self) {
        self.mask.fill(0);
        for a in [
            &mut self.sv,
            &mut self.svt,
            &mut self.svw,
            &mut self.svv,
            &mut self.svvw,
        ] {
            a.fill(0.0);
        }
    }

    /// Adds the samples `src` of exposure number `k` (time `t`, weight `w = 1/t`).
    #[inline(always)]
    fn add_generic(&mut self, src: &[u16], k: u32, (t, w): (f64, f64), (lo, hi): (f64, f64)) {
        let len = src.len().min(BLOCK);
        let mask = &mut self.mask[..len];
        let (sv, svt, svw, svv, svvw) = (
            &mut self.sv[..len],
            &mut self.svt[..len],
            &mut self.svw[..len],
            &mut self.svv[..len],
            &mut self.svvw[..len],
        );
        let src = &src[..len];
        for j in 0..len {
            let v = src[j] as f64;
            let ok = v >= lo && v <= hi;
            let m = if ok { 1.0 } else { 0.0 };
            mask[j] |= (ok as u64) << k;
            let mv = m * v;
            sv[j] += mv;
            svt[j] += mv * t;
            svw[j] += mv * w;
            svv[j] += mv * v;
            svvw[j] += mv * v * w;
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    unsafe fn add_avx2(&mut self, src: &[u16], k: u32, tw: (f64, f64), win: (f64, f64)) {
        self.add_generic(src, k, tw, win)
    }

    /// Adds one exposure, with the widest vector instructions the CPU offers.
    #[inline]
    fn add(&mut self, simd: bool, src: &[u16], k: u32, tw: (f64, f64), win: (f64, f64)) {
        #[cfg(target_arch = "x86_64")]
        if simd {
            // SAFETY: `simd` is true only when the CPU reported AVX2 and FMA at run time.
            unsafe { self.add_avx2(src, k, tw, win) };
            return;
        }
        let _ = simd;
        self.add_generic(src, k, tw, win)
    }
}

/// Whether the AVX2/FMA path can be used on this CPU.
fn simd_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Per-exposure constants: time, time², weight.
struct Series {
    t: Vec<f64>,
    tt: Vec<f64>,
    w: Vec<f64>,
}

/// The fit of one pixel.
#[derive(Debug, Clone, Copy)]
struct PixelFit {
    rate: f64,
    offset: f64,
    std_error: f64,
    correlation: f64,
}

#[inline]
fn fit_pixel(s: &Sums, series: &Series, j: usize, intercept: Intercept) -> PixelFit {
    let (mut n, mut st, mut stt, mut sw) = (0.0, 0.0, 0.0, 0.0);
    let mut m = s.mask[j];
    while m != 0 {
        let k = m.trailing_zeros() as usize;
        m &= m - 1;
        n += 1.0;
        st += series.t[k];
        stt += series.tt[k];
        sw += series.w[k];
    }
    let (sv, svv, svt) = (s.sv[j], s.svv[j], s.svt[j]);
    let correlation = if n >= 2.0 {
        let vt = stt - st * st / n;
        let vv = svv - sv * sv / n;
        let cov = svt - st * sv / n;
        if vt > 0.0 && vv > 0.0 {
            (cov / (vt * vv).sqrt()).clamp(-1.0, 1.0)
        } else {
            f64::NAN
        }
    } else {
        f64::NAN
    };
    let (rate, std_error, offset) = match intercept {
        Intercept::Fitted => {
            // Weighted sums with w = 1/t: Σw, Σw·t = n, Σw·t² = Σt, Σw·v, Σw·t·v = Σv, Σw·v².
            let w = sw;
            if n < 2.0 || w <= 0.0 {
                (f64::NAN, f64::NAN, f64::NAN)
            } else {
                let s_tt = st - n * n / w;
                let s_tv = sv - n * s.svw[j] / w;
                let s_vv = s.svvw[j] - s.svw[j] * s.svw[j] / w;
                if s_tt <= 1e-12 * st {
                    (f64::NAN, f64::NAN, f64::NAN)
                } else {
                    let rate = s_tv / s_tt;
                    let se = if n > 2.0 {
                        let ss = (s_vv - rate * s_tv).max(0.0);
                        (ss / (n - 2.0) / s_tt).sqrt()
                    } else {
                        f64::NAN
                    };
                    (rate, se, (s.svw[j] - rate * n) / w)
                }
            }
        }
        Intercept::BlackLevel(b) => {
            if n < 1.0 {
                (f64::NAN, f64::NAN, b)
            } else {
                let y = sv - n * b;
                let rate = y / st;
                let se = if n > 1.0 {
                    let syy = s.svvw[j] - 2.0 * b * s.svw[j] + b * b * sw;
                    let ss = (syy - rate * y).max(0.0);
                    (ss / (n - 1.0) / st).sqrt()
                } else {
                    f64::NAN
                };
                (rate, se, b)
            }
        }
    };
    PixelFit {
        rate,
        std_error,
        correlation,
        offset,
    }
}

/// Checks the series and returns the frame order by ascending exposure.
fn check_series<F: Borrow<BayerFrame>>(
    frames: &[F],
    defects: Option<&DefectMap>,
    opts: &MergeOptions,
) -> HdrResult<Vec<usize>> {
    opts.validate()?;
    let first = frames.first().ok_or(HdrError::NoFrames)?.borrow();
    if frames.len() > MAX_EXPOSURES {
        return Err(HdrError::InvalidOption(format!(
            "{} frames; at most {MAX_EXPOSURES} per series",
            frames.len()
        )));
    }
    let (w, h) = (first.width, first.height);
    for (index, f) in frames.iter().enumerate() {
        let f = f.borrow();
        if f.width != w || f.height != h {
            return Err(HdrError::Dimensions(format!(
                "frame {index} is {}x{}, frame 0 is {w}x{h}",
                f.width, f.height
            )));
        }
        if f.width == 0 || f.height == 0 || f.width.checked_mul(f.height) != Some(f.data.len()) {
            return Err(HdrError::MalformedFrame {
                index,
                detail: format!("{} samples for {}x{}", f.data.len(), f.width, f.height),
            });
        }
        if f.bit_depth != first.bit_depth {
            return Err(HdrError::MalformedFrame {
                index,
                detail: format!("bit depth {} (frame 0: {})", f.bit_depth, first.bit_depth),
            });
        }
        if !(f.exposure_s.is_finite() && f.exposure_s > 0.0) {
            return Err(HdrError::InvalidExposure {
                index,
                exposure_s: f.exposure_s,
            });
        }
    }
    if let Some(d) = defects {
        if d.width() != w || d.height() != h {
            return Err(HdrError::Dimensions(format!(
                "defect map {}x{} for {w}x{h} frames",
                d.width(),
                d.height()
            )));
        }
    }
    let mut order: Vec<usize> = (0..frames.len()).collect();
    order.sort_by(|&a, &b| {
        frames[a]
            .borrow()
            .exposure_s
            .total_cmp(&frames[b].borrow().exposure_s)
    });
    let ts: Vec<f64> = order
        .iter()
        .map(|&k| frames[k].borrow().exposure_s)
        .collect();
    let distinct = 1 + ts.windows(2).filter(|p| p[1] > p[0]).count();
    if opts.intercept == Intercept::Fitted && distinct < 2 {
        return Err(HdrError::DegenerateSeries(
            "a fitted intercept needs at least two distinct exposure times".into(),
        ));
    }
    Ok(order)
}

/// Merges an exposure series of one lamp position into a radiance image (thesis §3.3).
///
/// `frames` may come in any order; they must share size and bit depth and have positive
/// exposure times. Photosites marked in `defects` are excluded (flag [`flags::HOT`]).
///
/// For every photosite the samples inside the valid window `[low_dn, high_dn]` of
/// [`MergeOptions`] (the thesis's 10 and 1000 DN) are fitted by a line `value = offset + rate ·
/// exposure`; the slope `rate` (DN/s) is the radiance estimate. See `docs/hdr.md` for the
/// treatment of black level and dark current.
///
/// # The fit
///
/// The noise of a CCD sample grows with its signal (shot noise), so the fit is weighted: weight
/// `1/t` for an exposure of `t` seconds, i.e. variance proportional to the expected signal. The
/// weights depend on the exposure time only, never on the measured value, which keeps the
/// estimator free of the bias that value-dependent weights introduce. With a known black level
/// `b` ([`Intercept::BlackLevel`]) the weighted fit through `(0, b)` reduces to the ratio
/// estimator `Σ(v − b) / Σt`, the maximum-likelihood estimate for Poisson counts; with a fitted
/// offset ([`Intercept::Fitted`], the thesis's "fit a line") it is weighted least squares with
/// two unknowns.
///
/// The reported standard error is the fit's own (residual scatter, `n − p` degrees of freedom);
/// the correlation is Pearson's coefficient of the valid (exposure, value) pairs, the quantity
/// the thesis tests ("higher than 0.998").
///
/// # Speed
///
/// Pixels are processed in blocks of `BLOCK` (256) photosites: for one block the frames are
/// streamed one after the other through five running sums and a bit mask per pixel (kept in L1
/// cache, vectorisable), then each pixel is finalised. Blocks run in parallel with rayon. The result does not depend on
/// the number of threads.
///
/// # Examples
///
/// With a known black level only the slope is fitted; a photosite of the defect map is left
/// out and flagged, and one that only ever shows the black level measures zero:
///
/// ```
/// use hdr::{flags, merge, DefectMap, Intercept, MergeOptions};
/// # use gantry_hal::{BayerFrame, BayerPattern};
/// # // a noiseless series: value = black level 20 DN + rate × exposure, clipped at 10 bits
/// # fn series(rates: &[f64], exposures: &[f64]) -> Vec<BayerFrame> {
/// #     exposures.iter().enumerate().map(|(i, &t)| {
/// #         let data = rates.iter().map(|r| (20.0 + r * t).round().min(1023.0) as u16).collect();
/// #         BayerFrame::new(rates.len(), 1, 10, BayerPattern::Rggb, data, t, i as f64, 25.0, i as u64)
/// #             .unwrap()
/// #     }).collect()
/// # }
///
/// let rates = [100.0, 800.0, 5000.0, 0.0]; // DN/s
/// let frames = series(&rates, &[0.05, 0.1, 0.2, 0.4, 0.8]);
/// let hot = DefectMap::from_mask(4, 1, vec![false, true, false, false]).unwrap();
/// let options = MergeOptions { intercept: Intercept::BlackLevel(20.0), ..MergeOptions::default() };
/// let image = merge(&frames, Some(&hot), &options).unwrap();
///
/// assert!((image.radiance[0] - 100.0).abs() < 1.0 && image.valid[0]);
/// assert!(!image.valid[1] && image.flags[1] & flags::HOT != 0);
/// assert!((image.radiance[2] - 5000.0).abs() < 10.0); // from its two unsaturated samples…
/// assert_eq!(image.count[2], 2);
/// assert!(!image.valid[2] && image.flags[2] & flags::TOO_FEW != 0); // …too few to trust
/// assert_eq!(image.radiance[3], 0.0);
/// ```
pub fn merge<F: Borrow<BayerFrame> + Sync>(
    frames: &[F],
    defects: Option<&DefectMap>,
    opts: &MergeOptions,
) -> HdrResult<HdrImage> {
    let order = check_series(frames, defects, opts)?;
    let first = frames[0].borrow();
    let (width, height) = (first.width, first.height);
    let npx = width * height;
    let data: Vec<&[u16]> = order
        .iter()
        .map(|&k| &frames[k].borrow().data[..])
        .collect();
    let ts: Vec<f64> = order
        .iter()
        .map(|&k| frames[k].borrow().exposure_s)
        .collect();
    let series = Series {
        tt: ts.iter().map(|t| t * t).collect(),
        w: ts.iter().map(|t| 1.0 / t).collect(),
        t: ts.clone(),
    };
    let simd = simd_available();
    let (lo, hi) = (opts.low_dn, opts.high_dn);
    let hot = defects.map(|d| d.mask());
    let shortest = data[0];
    let longest = data[data.len() - 1];

    let mut radiance = vec![0f32; npx];
    let mut std_error = vec![0f32; npx];
    let mut offset = vec![0f32; npx];
    let mut correlation = vec![0f32; npx];
    let mut valid = vec![false; npx];
    let mut count = vec![0u16; npx];
    let mut flag = vec![0u8; npx];

    radiance
        .par_chunks_mut(BLOCK)
        .zip(std_error.par_chunks_mut(BLOCK))
        .zip(offset.par_chunks_mut(BLOCK))
        .zip(correlation.par_chunks_mut(BLOCK))
        .zip(valid.par_chunks_mut(BLOCK))
        .zip(count.par_chunks_mut(BLOCK))
        .zip(flag.par_chunks_mut(BLOCK))
        .enumerate()
        .for_each_init(
            Sums::zero,
            |sums, (bi, ((((((rad, se), off), cor), val), cnt), fl))| {
                let base = bi * BLOCK;
                let len = rad.len();
                sums.clear();
                for (k, d) in data.iter().enumerate() {
                    let (t, w) = (series.t[k], series.w[k]);
                    sums.add(simd, &d[base..base + len], k as u32, (t, w), (lo, hi));
                }
                for j in 0..len {
                    let i = base + j;
                    let mut f = 0u8;
                    if (shortest[i] as f64) > hi {
                        f |= flags::SATURATED;
                    }
                    if (longest[i] as f64) < lo {
                        f |= flags::UNDEREXPOSED;
                    }
                    if hot.is_some_and(|h| h[i]) {
                        f |= flags::HOT;
                        rad[j] = 0.0;
                        se[j] = f32::NAN;
                        off[j] = f32::NAN;
                        cor[j] = f32::NAN;
                        cnt[j] = 0;
                        val[j] = false;
                        fl[j] = f;
                        continue;
                    }
                    let n = sums.mask[j].count_ones() as usize;
                    let fit = fit_pixel(sums, &series, j, opts.intercept);
                    if n < opts.min_valid {
                        f |= flags::TOO_FEW;
                    }
                    if n >= 2
                        && (fit.correlation.is_nan() || fit.correlation < opts.min_correlation)
                    {
                        f |= flags::LOW_CORRELATION;
                    }
                    if !fit.rate.is_finite() {
                        f |= flags::TOO_FEW;
                    }
                    rad[j] = if fit.rate.is_finite() {
                        fit.rate as f32
                    } else {
                        0.0
                    };
                    se[j] = fit.std_error as f32;
                    off[j] = fit.offset as f32;
                    cor[j] = fit.correlation as f32;
                    cnt[j] = n as u16;
                    val[j] = f & flags::INVALIDATING == 0;
                    fl[j] = f;
                }
            },
        );

    let image = HdrImage {
        width,
        height,
        radiance,
        std_error,
        offset,
        correlation,
        valid,
        count,
        flags: flag,
        exposures_s: ts,
        options: opts.clone(),
    };
    tracing::debug!(
        frames = frames.len(),
        valid = image.valid_count(),
        pixels = npx,
        "merged exposure series"
    );
    Ok(image)
}

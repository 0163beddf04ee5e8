//! # hdr — multi-exposure HDR radiance (thesis §3.3)
//!
//! ```
//! use gantry_hal::{BayerFrame, BayerPattern};
//! use hdr::{merge, MergeOptions};
//!
//! // four exposures of a 2 × 2 sensor: value = black level 20 DN + radiance × exposure
//! let radiance: [f64; 4] = [100.0, 500.0, 2000.0, 50.0]; // DN/s
//! let frames: Vec<BayerFrame> = [0.1, 0.2, 0.4, 0.8]
//!     .iter()
//!     .enumerate()
//!     .map(|(i, &t)| {
//!         let data = radiance.iter().map(|r| (20.0 + r * t).min(1023.0) as u16).collect();
//!         BayerFrame::new(2, 2, 10, BayerPattern::Rggb, data, t, i as f64, 25.0, i as u64)
//!             .unwrap()
//!     })
//!     .collect();
//! let hdr = merge(&frames, None, &MergeOptions::default()).unwrap();
//! for (px, r) in radiance.iter().enumerate() {
//!     assert!((hdr.radiance[px] as f64 - r).abs() < 0.01 * r, "{px}");
//! }
//! // the brightest photosite saturates at the longest exposure: 3 samples fitted, not 4
//! assert_eq!(hdr.count[2], 3);
//! ```
//!
//! The scene's dynamic range exceeds the 10-bit sensor of the gantry, so every lamp position is
//! photographed with a series of exposures (thesis §3.3: 18 from 40 µs to 20 s) and each
//! photosite's radiance is the slope of a line fitted through its valid samples. In the order a
//! capture uses them:
//!
//! 1. [`DefectMap::from_dark_frame`]: hot photosites from a 60 s dark frame (raw value > 16 DN),
//!    left out of the whole capture.
//! 2. [`thesis_ladder`] gives the thesis's exposure series; [`plan_exposures`] (adaptive
//!    bracketing, beyond the thesis) chooses a position's exposures from the previous
//!    position's radiance instead ([`BracketOptions`], [`ExposurePlan`]).
//! 3. [`merge()`] fits the lines ([`MergeOptions`]: valid window 10..1000 DN, correlation above
//!    0.998, at least 3 valid exposures; [`Intercept`]: fitted offset or known black level) and
//!    returns an [`HdrImage`]: radiance in DN/s, standard error, correlation, count and
//!    [`flags`] per photosite.
//! 4. [`check_frames`] and [`fit_quality`] tell whether a series agrees with its fit, which it
//!    does not when the lamp dropped out or flickered during it; the remedy is to repeat the
//!    series.
//! 5. [`write_hdr_exr`] stores the image as OpenEXR (`DIR/hdr/NNN.exr`, written atomically) and
//!    [`read_exr`] reads it back as an [`HdrFile`]; [`write_truth_exr`] stores the simulator's
//!    noise-free signal in the same units.
//!
//! All functions report bad input as [`HdrError`]; nothing panics on input or prints.

#![warn(missing_docs)]

mod bracket;
mod consistency;
mod defect;
mod error;
mod exr_io;
mod ladder;
mod merge;

pub use exr_io::{check_exr_size, ExrCompression, MAX_EXR_SAMPLE_BYTES};

pub use bracket::{plan_exposures, plan_for_rates, BracketOptions, ExposurePlan};
pub use consistency::{check_frames, fit_quality, inconsistent_frames, FitQuality, FrameCheck};
pub use defect::{DarkFrameOptions, DefectMap};
pub use error::{HdrError, HdrResult};
pub use exr_io::{
    hdr_path, read_exr, truth_path, write_hdr_exr, write_truth_exr, ExrOptions, HdrFile,
    PositionInfo,
};
pub use ladder::{geometric_ladder, series_time_s, thesis_ladder};
pub use merge::{flags, merge, HdrImage, Intercept, MergeOptions};

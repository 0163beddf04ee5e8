//! # hdr — multi-exposure HDR radiance (seed §3.3)
//!
//! The scene's dynamic range exceeds the 10-bit sensor of the gantry, so every lamp position is
//! photographed with a series of exposures (the seed: 18 from 40 µs to 20 s) and each photosite's
//! radiance is the slope of a line fitted through its valid samples. This crate provides
//!
//! * [`merge()`]: the per-pixel fit (valid window 10..1000 DN, slope = radiance in DN/s, standard
//!   error, correlation, flags for correlation < 0.998 and too few valid exposures);
//! * [`DefectMap`]: hot photosites from a 60 s dark frame (raw value > 16 DN);
//! * [`exr_io`]: OpenEXR files with float channels `radiance`, `valid`, `count` (and the fit
//!   statistics) and the exposure metadata in the header, written atomically, and their reader;
//! * [`bracket`]: adaptive bracketing, choosing a position's exposures from the previous
//!   position's radiance range;
//! * [`consistency`]: per-frame agreement of a series with its fit and the share of badly
//!   fitting pixels (lamp dropout / flicker);
//! * [`ladder`]: the seed's exposure series.
//!
//! All functions report bad input as [`HdrError`]; nothing panics on input or prints.

#![warn(missing_docs)]

pub mod bracket;
pub mod consistency;
pub mod defect;
pub mod error;
pub mod exr_io;
pub mod ladder;
pub mod merge;

pub use bracket::{plan_exposures, plan_for_rates, BracketOptions, ExposurePlan};
pub use consistency::{check_frames, fit_quality, inconsistent_frames, FitQuality, FrameCheck};
pub use defect::{DarkFrameOptions, DefectMap};
pub use error::{HdrError, HdrResult};
pub use exr_io::{
    hdr_path, read_exr, truth_path, write_hdr_exr, write_truth_exr, ExrOptions, HdrFile,
    PositionInfo,
};
pub use ladder::{geometric_ladder, seed_ladder, series_time_s};
pub use merge::{flags, merge, HdrImage, Intercept, MergeOptions};

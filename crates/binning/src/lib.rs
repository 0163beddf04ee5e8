//! # binning — from HDR images of a sphere to a MERL BRDF table
//!
//! The seed's §3.4–3.6: every sphere pixel of every lamp position is one BRDF sample in its own
//! Bayer channel (radiance / irradiance); samples are binned on the MERL grid with the lowest and
//! highest 25% of each bin discarded; the table is validated by re-rendering the sphere.
//!
//! * [`samples`]: BRDF samples and the per-position sample files (the capture checkpoints).
//! * [`accumulate`]: robust binning in bounded memory.
//! * [`geometry`]: what binning needs of the calibration, and the per-pixel sphere geometry.
//! * [`forward`]: per-pixel BRDF samples, the white-reference lamp constant, re-rendering.
//! * [`validate`]: contact sheets of measured and re-rendered images.

#![warn(missing_docs)]

pub mod accumulate;
pub mod error;
pub mod samples;
pub mod validate;

pub use accumulate::{bin_samples, BinnedTable, BinningOptions};
pub use error::{BinningError, Result};
pub use samples::{PositionSamples, Sample, SampleFiles, SampleSource};
pub mod forward;
pub mod geometry;
pub mod inverse;

pub use forward::{position_samples, BinAssignment, ForwardOptions, Rates};
pub use geometry::{RigGeometry, SphereView};

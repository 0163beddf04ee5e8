//! # binning — from HDR images of a sphere to a MERL BRDF table
//!
//! Thesis §3.4–3.6: every sphere pixel of every lamp position is one BRDF sample in its own
//! Bayer channel (radiance / irradiance); samples are binned on the MERL grid with the lowest and
//! highest 25% of each bin discarded; the table is validated by re-rendering the sphere.
//!
//! Robust binning of samples: in each bin the lowest and highest quarter are dropped and the
//! rest averaged, so an outlier (a hot pixel, a specular glint of dust) does not move the value.
//!
//! ```
//! use binning::{bin_samples, BinningOptions, PositionSamples, Sample};
//! let bin = brdf::table::bin_index(10, 20, 30);
//! // Eight samples of the red channel in one bin, one of them an outlier.
//! let values = [0.50f32, 0.51, 0.49, 0.50, 0.52, 0.48, 0.50, 9.0];
//! let position = PositionSamples {
//!     position: 0,
//!     angle_deg: 0.0,
//!     samples: values.iter().map(|&v| Sample::new(0, bin, v)).collect(),
//! };
//! let binned = bin_samples(&[position][..], &BinningOptions::default())?;
//! assert_eq!(binned.counts[bin], 8);
//! assert!((binned.table.get(0, bin) - 0.5).abs() < 0.01);
//! assert!(!binned.table.is_valid(1, bin), "no green sample, no green value");
//! # Ok::<(), binning::BinningError>(())
//! ```
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

pub use accumulate::{bin_samples, BinnedTable, BinningOptions, FIXED_BYTES};
pub use error::{BinningError, Result};
pub use samples::{PositionSamples, Sample, SampleFiles, SampleSource};
pub mod forward;
pub mod geometry;
pub mod inverse;

pub use forward::{position_samples, BinAssignment, ForwardOptions, Rates};
pub use geometry::{RigGeometry, SphereView};

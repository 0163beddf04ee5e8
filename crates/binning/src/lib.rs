//! # binning — from HDR images of a sphere to a MERL BRDF table
//!
//! Thesis §3.4–3.6: every sphere pixel of every lamp position is one BRDF sample in its own
//! Bayer channel (radiance / irradiance); samples are binned on the MERL grid with the lowest and
//! highest 25% of each bin discarded; the table is validated by re-rendering the sphere.
//!
//! ```
//! use binning::{bin_samples, position_samples, rerender, BinAssignment, BinningOptions};
//! use binning::{ForwardOptions, PositionSamples, Rates, RigGeometry, SphereView};
//! # use gantry_hal::{CameraIntrinsics, CameraPose, LampCircle, SphereGeometry};
//! # let rig = gantry_hal::RigGeometry {
//! #     camera: CameraIntrinsics::radial(128, 128, 2000.0, 2000.0, 64.0, 64.0, 0.0, 0.0),
//! #     pose: CameraPose::look_at([0.0, -1.0, 0.0], [0.0; 3], 0.0),
//! #     lamp: LampCircle { centre: [0.0; 3], normal: [0.0, 0.0, 1.0], radius: 0.5, reference: [0.0, -1.0, 0.0] },
//! #     sphere: SphereGeometry { centre: [0.0; 3], radius: 0.0254 },
//! # };
//! // `rig`: a 128 × 128 camera 1 m from a 1-inch sphere, lamp circle of 0.5 m (hidden above)
//! let view = SphereView::new(&rig, |x, y| gantry_hal::BayerPattern::Rggb.channel_at(x, y), 85.0);
//! let truth = brdf::MerlTable::tabulate(&brdf::analytic::Lambert { kd: [0.2, 0.4, 0.6] });
//! let k = [5.0e4; 3]; // lamp constant, DN/s · m² · sr
//! let options = ForwardOptions { subtract_ambient: false, ..ForwardOptions::default() };
//! let positions: Vec<PositionSamples> = (0..3u32).map(|i| {
//!     // stand-in for a merged HDR image: the signal rates the true table gives
//!     let angle = 30.0 * i as f64;
//!     let lamp = rig.lamp_position(angle);
//!     let mut rate = vec![0.0f32; 128 * 128];
//!     let lit = rerender(&view, &truth, &lamp, &k, BinAssignment::NearestNode);
//!     for (p, r) in view.pixels.iter().zip(lit) {
//!         rate[p.index as usize] = if r.is_finite() { r } else { 0.0 };
//!     }
//!     let valid = vec![true; rate.len()];
//!     let samples = position_samples(&view, Rates { rate: &rate, valid: &valid }, &lamp, &k, &options)?;
//!     Ok(PositionSamples { position: i, angle_deg: angle, samples })
//! }).collect::<binning::Result<_>>()?;
//! let binned = bin_samples(&positions[..], &BinningOptions::default())?;
//! assert!(binned.coverage() > 0.0);
//! let measured = (0..brdf::BINS).find(|&b| binned.table.is_valid(2, b)).unwrap();
//! assert!((binned.table.get(2, measured) - truth.get(2, measured)).abs() < 1e-4);
//! # Ok::<(), binning::BinningError>(())
//! ```
//!
//! In the order of the work:
//!
//! 1. [`RigGeometry`] is what binning needs of the calibration (implemented for
//!    [`gantry_hal::RigGeometry`] and everything holding one, such as `calib::Calibration`);
//!    [`SphereView`] traces it once per capture into the [`SpherePixel`]s that see the sample.
//! 2. [`lamp_constant_from_reference`] gives the absolute scale from a diffuse white sphere;
//!    [`ambient_from_lamp_off`] and [`ambient_rate`] the stray-light signal to subtract.
//! 3. [`position_samples`] turns one lamp position's HDR image ([`Rates`]) into BRDF [`Sample`]s
//!    (thesis §3.4), assigned to bins by [`BinAssignment`] ([`ForwardOptions`]); a capture
//!    stores them per position as [`PositionSamples`] files, read back through [`SampleFiles`].
//! 4. [`bin_samples`] bins all samples robustly in bounded memory ([`BinningOptions`]) into a
//!    [`BinnedTable`] (thesis §3.6).
//! 5. [`rerender`] and [`compare`] re-render every position from the table for validation, and
//!    [`contact_sheet`] lays measured and re-rendered images side by side (thesis §3.6).
//! 6. [`fill_table`] is the thesis's alternative, the inverse mapping (thesis §3.5): every bin
//!    evaluated at a chosen point from [`InversePosition`]s ([`InverseOptions`]), giving an
//!    [`InverseTable`].

#![warn(missing_docs)]

mod accumulate;
mod error;
mod samples;
mod validate;

pub use accumulate::{bin_samples, BinnedTable, BinningOptions, FIXED_BYTES};
pub use error::{BinningError, Result};
pub use samples::{PositionSamples, Sample, SampleFiles, SampleSource};
mod forward;
mod geometry;
mod inverse;

pub use forward::{
    ambient_from_lamp_off, ambient_rate, compare, half_diff, lamp_constant_from_reference,
    lighting, merl_bin, rerender, ImageError, Lighting,
};
pub use geometry::{frame_from_normal, ray_sphere, to_local, SpherePixel, V3};
pub use inverse::{
    fill_table, solve_point, BinPoint, Configuration, Construction, Interpolated, InverseOptions,
    InversePosition, InverseTable, PositionChoice, SurfacePoint,
};
pub use validate::{contact_sheet, to_mosaic, Rgb8Image, SheetRow};

pub use forward::{position_samples, BinAssignment, ForwardOptions, Rates};
pub use geometry::{RigGeometry, SphereView};

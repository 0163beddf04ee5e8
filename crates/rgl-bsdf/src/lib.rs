//! # rgl-bsdf — measured materials in the RGL tensor `.bsdf` format
//!
//! Mitsuba 3's `measured` BSDF and pbrt-v4's `measured` material read one measured-material
//! format: the tensor files of Dupuy & Jakob, "An Adaptive Parameterization for Efficient
//! Material Acquisition and Rendering" (ACM TOG 37(6), 2018). This crate writes any material
//! of the toolkit (a MERL table, a neural BRDF, an analytic model, a PCA reconstruction, an
//! edited material) in that format, and reads such files back as a [`brdf::Brdf`].
//!
//! * [`TensorFile`] is the container: named, typed, shaped fields after a small header. Its
//!   parser checks every declared size against the bytes present before allocating anything.
//! * [`write()`] computes the adaptive parameterization from the material: a microfacet
//!   distribution from its back-scattering (the paper's power iteration), the projected area
//!   `σ`, a visible-normal distribution per incident elevation, and `f cos θo` sampled on the
//!   grid that those distributions warp, with luminance tables for importance sampling.
//!   [`WriteOptions`] sets the grid sizes.
//! * [`RglBsdf`] reads a file and evaluates it by the interpolation the renderers use, so a
//!   file converts back to a MERL table, fits, joins a corpus or projects on a model like any
//!   other material. Spectral files are converted to linear sRGB under D65 light (CIE 1931 observer)
//!   ([`rgb_weights`]).
//!
//! The field-by-field layout is documented in `docs/formats.md`.
//!
//! ```
//! use brdf::{Brdf, Spherical};
//! use rgl_bsdf::{RglBsdf, TensorFile, WriteOptions};
//!
//! let material = brdf::load("ggx:alpha=0.25,kd=0.3").unwrap();
//! let bytes = rgl_bsdf::write(material.as_brdf(), &WriteOptions::small()).unwrap().to_bytes();
//! let back = RglBsdf::from_tensor(&TensorFile::parse(&bytes).unwrap()).unwrap();
//! let (wi, wo) = (Spherical::new(0.4, 0.0).to_vector(), Spherical::new(0.5, 3.0).to_vector());
//! let (f, g) = (material.as_brdf().eval(&wi, &wo), back.eval(&wi, &wo));
//! assert!((f[0] - g[0]).abs() < 0.05 * f[0]);
//! ```

#![warn(missing_docs)]

mod error;
mod marginal;
mod material;
mod spectrum;
mod tensor;
mod write;

pub use error::{Result, RglError};
pub use material::{Channels, RglBsdf, RglSpecs};
pub use spectrum::{cie_xyz, d65, rgb_basis, rgb_weights, spectral_wavelengths, xyz_to_srgb};
pub use tensor::{Dtype, Field, TensorFile, MAGIC, MAX_RANK};
pub use write::{write, WriteOptions};

//! # wavelet — wavelet analysis of tabulated isotropic BRDFs (thesis chapter 6, §6.1–6.2)
//!
//! A MERL table channel is transformed, thresholded, gathered with a corpus into one shared
//! basis, and evaluated through a coefficient tree:
//!
//! 1. **Embed.** A [`Cube`] holds one channel (90 × 90 × 180) zero-padded into a 256³ cube
//!    (thesis §6.2); a [`Layout`] names the cube side, the table extent and the filter.
//! 2. **Transform.** [`forward`] and [`inverse`] are the 3D nonstandard wavelet transform of
//!    thesis §6.1, with the [`Wavelet`] filters Haar, CDF 5/3 and Daubechies-4;
//!    [`error_at_equal_counts`] compares them at equal coefficient counts.
//! 3. **Threshold.** [`CoefficientAddress`] locates a coefficient (level, type, offset) and
//!    evaluates its Haar function; [`keep_for_relative_error`] thresholds one component to a
//!    relative-error target.
//! 4. **Share a basis.** [`CommonBasis`] is the Common Wavelet Basis of thesis §6.2, the union of
//!    the significant coefficients of a corpus ([`CommonBasisBuilder`] adds components one at a
//!    time).
//! 5. **Evaluate.** [`CoefficientTree`] is the Common Wavelet Coefficient Tree (thesis §6.2,
//!    appendix A.3): many functions at once, O(log n) nodes per point.
//! 6. **Compress materials.** [`CompressedMaterial`] is a material's log channels on a basis,
//!    the `.wtree` file; [`WaveletBrdf`] evaluates it as a [`brdf::Brdf`]; [`WaveletSpecs`]
//!    resolves the `wavelet:<file.wtree>` material spec.
//!
//! [`BasisJob`] and [`CompressJob`] are the jobs behind `gantry wavelet basis|compress`, each
//! options in, `run()`, a serde report out.
//!
//! # Examples
//!
//! ```
//! use brdf::{Brdf, Vec3};
//! use wavelet::{build_basis, CompressedMaterial, WaveletBrdf};
//!
//! // Two MERL tables, a shared basis for their log channels at 1 % relative error, and one of
//! // them compressed onto it and evaluated through its coefficient tree.
//! let matte = brdf::load("lambert:kd=0.5").unwrap().tabulate();
//! let glossy = brdf::load("ggx:alpha=0.2,kd=0.1").unwrap().tabulate();
//! let basis = build_basis(&[matte.clone(), glossy.clone()], 0.01).unwrap();
//! assert!(basis.len() < 3 * brdf::BINS / 10); // far fewer functions than table values
//! let compressed = CompressedMaterial::compress(basis, &matte).unwrap();
//! assert_eq!(CompressedMaterial::from_bytes(&compressed.to_bytes()).unwrap(), compressed);
//! let tree = WaveletBrdf::new(&compressed, "matte").unwrap();
//! // A constant log channel is kept exactly: the Lambertian value kd/π comes back.
//! let (wi, wo) = (Vec3::new(0.4, 0.2, 0.89).normalize(), Vec3::new(-0.1, 0.3, 0.95).normalize());
//! let f = tree.eval(&wi, &wo);
//! assert!(f.iter().all(|v| (v - 0.5 / std::f64::consts::PI).abs() < 1e-4), "{f:?}");
//! ```

#![warn(missing_docs)]

mod basis;
mod compare;
mod cube;
mod cwb;
mod error;
mod job;
mod material;
mod transform;
mod tree;

pub use basis::{
    coarse_to_fine_scale, haar_basis_value, keep_for_relative_error, keep_largest,
    relative_l2_error, zero_all_but, CoefficientAddress, Thresholded,
};
pub use compare::{error_at_equal_counts, CountError};
pub use cwb::{functions_from_dimension_major, ComponentStats};
pub use material::{
    build_basis, log_channels, register_spec_resolver, MaterialError, WaveletSpecs,
};
pub use transform::{forward_rows, inverse_rows};
pub use tree::TreeStorage;

pub use cube::{Cube, MERL_CUBE_SIDE, MERL_EXTENT};
pub use cwb::{CommonBasis, CommonBasisBuilder, Layout};
pub use error::{Result, WaveletError};
pub use job::{BasisJob, BasisReport, CompressJob, CompressReport};
pub use material::{CompressedMaterial, WaveletBrdf};
pub use transform::{forward, forward_full, inverse, inverse_full, Wavelet};
pub use tree::CoefficientTree;

//! # wavelet — wavelet analysis of tabulated isotropic BRDFs (thesis chapter 6, §6.1–6.2)
//!
//! ```
//! use wavelet::{forward, inverse, CommonBasis, Cube, Layout, Wavelet};
//!
//! // a 16³ cube, transformed and back (the MERL layout is a 256³ cube: `Layout::MERL_HAAR`)
//! let side = 16;
//! let values: Vec<f32> = (0..side * side * side).map(|i| ((i % 13) as f32).sin()).collect();
//! let mut cube = Cube::from_vec(side, values.clone()).unwrap();
//! forward(&mut cube, Wavelet::Haar, 4).unwrap();
//! inverse(&mut cube, Wavelet::Haar, 4).unwrap();
//! assert!(cube.data().iter().zip(&values).all(|(a, b)| (a - b).abs() < 1e-4));
//!
//! // the Common Wavelet Basis of two functions on a 4 × 4 × 8 table, at 1 % relative error
//! let layout = Layout { side, extent: [4, 4, 8], wavelet: Wavelet::Haar };
//! let f: Vec<f32> = (0..128).map(|i| (i as f32 * 0.1).cos()).collect();
//! let g: Vec<f32> = (0..128).map(|i| 1.0 + (i / 32) as f32).collect();
//! let (basis, stats) = CommonBasis::build(layout, &[&f, &g], 0.01).unwrap();
//! assert!(stats.iter().all(|s| s.relative_error <= 0.01));
//! let coefficients = basis.coefficients(&f).unwrap();
//! assert_eq!(coefficients.len(), basis.len());
//! ```
//!
//! * [`cube`]: a MERL table channel (90 × 90 × 180) zero-padded into a 256³ cube.
//! * [`transform`]: the 3D nonstandard wavelet transform, forward and inverse, with Haar,
//!   CDF 5/3 (lifting) and Daubechies-4 (lifting) filters.
//! * [`basis`]: Haar coefficient addressing (level, type, offset), basis-function values, and
//!   thresholding a component to a relative-error target.
//! * [`cwb`]: the Common Wavelet Basis, the union of the significant coefficients of a corpus.
//! * [`tree`]: the Common Wavelet Coefficient Tree, storing per node the coefficient vectors of
//!   many functions, with O(log n) point evaluation.
//! * [`compare`]: error of Haar and smooth wavelets at equal coefficient count.
//! * [`material`]: materials compressed onto a basis (the `.wtree` file), evaluated through
//!   the tree ([`material::WaveletBrdf`]), and the `wavelet:<file.wtree>` material spec.
//! * [`BasisJob`], [`CompressJob`]: the jobs behind `gantry wavelet`, each options in, `run()`,
//!   a serde report out.

#![warn(missing_docs)]

pub mod basis;
pub mod compare;
pub mod cube;
pub mod cwb;
pub mod error;
mod job;
pub mod material;
pub mod transform;
pub mod tree;

pub use cube::{Cube, MERL_CUBE_SIDE, MERL_EXTENT};
pub use cwb::{CommonBasis, CommonBasisBuilder, Layout};
pub use error::{Result, WaveletError};
pub use job::{BasisJob, BasisReport, CompressJob, CompressReport};
pub use material::{CompressedMaterial, WaveletBrdf};
pub use transform::{forward, forward_full, inverse, inverse_full, Wavelet};
pub use tree::CoefficientTree;

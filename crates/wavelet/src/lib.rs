//! # wavelet — wavelet analysis of tabulated isotropic BRDFs (seed chapter 6, §6.1–6.2)
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

#![warn(missing_docs)]

pub mod basis;
pub mod compare;
pub mod cube;
pub mod cwb;
pub mod error;
pub mod material;
pub mod transform;
pub mod tree;

pub use cube::{Cube, MERL_CUBE_SIDE, MERL_EXTENT};
pub use cwb::{CommonBasis, CommonBasisBuilder, Layout};
pub use error::{Result, WaveletError};
pub use material::{CompressedMaterial, WaveletBrdf};
pub use transform::{forward, forward_full, inverse, inverse_full, Wavelet};
pub use tree::CoefficientTree;

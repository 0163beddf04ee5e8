//! # brdf — core types for isotropic reflectance
//!
//! ```
//! use brdf::{Brdf, HalfDiff, MerlTable, Spherical};
//!
//! // name a material by its spec (here an analytic model; `merl:<name>` names a measured one)
//! let ggx = brdf::spec::load("ggx:alpha=0.2,kd=0.1").unwrap();
//! let wi = Spherical::new(0.5, 0.0).to_vector(); // (θ, φ) in radians
//! let wo = Spherical::new(0.5, std::f64::consts::PI).to_vector();
//! let f = ggx.eval(&wi, &wo); // RGB, 1/sr
//! assert!(f.iter().all(|v| *v > 0.0));
//! // reciprocity
//! assert!((ggx.eval(&wo, &wi)[0] - f[0]).abs() < 1e-12);
//! // a dense MERL table of it, evaluated at Rusinkiewicz angles
//! let table = MerlTable::tabulate(&ggx);
//! let hd = HalfDiff::from_directions(&wi, &wo);
//! let t = table.lookup(&hd).unwrap();
//! assert!((t[0] - f[0]).abs() / f[0] < 0.05);
//! ```
//!
//! * [`coords`]: directions in the local shading frame and Rusinkiewicz half/difference angles.
//! * [`Brdf`]: the one interface every reflectance model implements (RGB value in 1/sr).
//! * [`table`]: dense isotropic tables on the MERL grid (90 × 90 × 180 × RGB) with nearest and
//!   trilinear lookup.
//! * [`merl`]: reading and writing MERL `.binary` files.
//! * [`nbrdf`]: neural-BRDF weight files (the shared reference data) and their decoding.
//! * [`analytic`]: analytic models (Lambert, Phong, Ward, Cook-Torrance, GGX, ...), each written
//!   once, generic over the scalar ([`real::Real`]: `f64`, or [`real::Dual`] numbers for exact
//!   parameter gradients).
//! * [`spec`]: the material-spec string syntax every command uses to name a BRDF, extensible
//!   by other crates through registered [`spec::SpecResolver`]s.
//! * [`corpus`]: the log transform of thesis §4.1 and corpora of materials (NBRDF
//!   directories, `.binary` files, spec lists) as named tables or log-space vectors.
//! * [`summary`]: albedo, peak value, reciprocity residual, missing-bin fraction.

#![warn(missing_docs)]
// Channel loops index several arrays at once; iterator zips would obscure them.
#![allow(clippy::needless_range_loop)]

pub mod analytic;
pub mod angles;
pub mod atomic;
pub mod coords;
pub mod corpus;
pub mod error;
pub mod merl;
pub mod metrics;
pub mod nbrdf;
pub mod npy;
pub mod process;
pub mod real;
pub mod spec;
pub mod summary;
pub mod table;

pub use atomic::{create_parent_dir, write_atomic, write_atomic_with};
pub use coords::{AnglePair, HalfDiff, Spherical, Vec3};
pub use error::BrdfError;
pub use nalgebra;
pub use table::MerlTable;

/// An RGB triple (linear, BRDF values in 1/sr).
pub type Rgb = [f64; 3];

/// A bidirectional reflectance distribution function.
///
/// Directions are unit vectors in the local shading frame (normal = +z), both pointing away from
/// the surface: `wi` towards the light, `wo` towards the viewer. Values are in 1/sr, one per RGB
/// channel. Implementations return zero when either direction is below the horizon.
pub trait Brdf: Send + Sync {
    /// BRDF value for the pair (`wi`, `wo`).
    fn eval(&self, wi: &Vec3, wo: &Vec3) -> Rgb;

    /// BRDF value at Rusinkiewicz angles. The default converts to directions; tabulated and
    /// isotropic models override it to avoid the round trip.
    fn eval_half_diff(&self, hd: &HalfDiff) -> Rgb {
        let (wi, wo) = hd.to_directions();
        if wi.z < 0.0 || wo.z < 0.0 {
            return [0.0; 3];
        }
        self.eval(&wi, &wo)
    }

    /// A short human-readable name.
    fn name(&self) -> String;

    /// Whether the model depends only on (θh, θd, φd). Anisotropic models return `false`.
    fn is_isotropic(&self) -> bool {
        true
    }
}

/// A boxed or shared BRDF is a BRDF.
macro_rules! forward_brdf {
    ($($pointer:ident)::+) => {
        impl<T: Brdf + ?Sized> Brdf for $($pointer)::+<T> {
            fn eval(&self, wi: &Vec3, wo: &Vec3) -> Rgb {
                (**self).eval(wi, wo)
            }
            fn eval_half_diff(&self, hd: &HalfDiff) -> Rgb {
                (**self).eval_half_diff(hd)
            }
            fn name(&self) -> String {
                (**self).name()
            }
            fn is_isotropic(&self) -> bool {
                (**self).is_isotropic()
            }
        }
    };
}

forward_brdf!(Box);
forward_brdf!(std::sync::Arc);

/// Default location of the shared reference data, relative to the project root.
pub const DEFAULT_DATA_DIR: &str = "../shared/data";

/// Environment variable that overrides the location of the shared reference data.
pub const DATA_DIR_ENV: &str = "BRDF_DATA_DIR";

/// The directory holding the shared reference data (`nbrdf/merl`, `nbrdf/nielsen`).
///
/// `BRDF_DATA_DIR` wins when set; otherwise `../shared/data` is searched for from the current
/// directory and its ancestors (so tests run from a crate directory find it too), then from the
/// running executable's directory and its ancestors.
pub fn data_dir() -> std::path::PathBuf {
    if let Some(d) = std::env::var_os(DATA_DIR_ENV) {
        return d.into();
    }
    // From the current directory upwards, then from the executable's directory upwards (so an
    // installed `target/release/gantry` finds the data beside its checkout from anywhere).
    let starts = [
        std::env::current_dir().ok(),
        std::env::current_exe()
            .ok()
            .and_then(|p| p.parent().map(|d| d.to_path_buf())),
    ];
    for start in starts.into_iter().flatten() {
        let mut cur = Some(start);
        while let Some(dir) = cur {
            let cand = dir.join(DEFAULT_DATA_DIR);
            if cand.join("nbrdf").is_dir() {
                return cand;
            }
            cur = dir.parent().map(|p| p.to_path_buf());
        }
    }
    DEFAULT_DATA_DIR.into()
}

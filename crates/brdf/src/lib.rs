//! # brdf — core types for isotropic reflectance
//!
//! Everything else in the workspace builds on this crate: a material is named by a spec string,
//! evaluated through one trait, tabulated on the MERL grid, and gathered with others into a
//! corpus in log space for the data-driven models.
//!
//! 1. **Name a material.** [`load`] turns a spec string into a [`Material`]; [`parse`] stops at
//!    the [`MaterialSpec`], whose docs list the syntax (MERL `.binary` files, neural-BRDF
//!    weights such as `merl:<name>`, analytic models such as `ggx:alpha=0.2`). Other crates add
//!    their own forms by registering a [`SpecResolver`].
//! 2. **Evaluate it.** [`Brdf`] is the one interface every reflectance model implements: an RGB
//!    value in 1/sr for a pair of directions in the local shading frame ([`Vec3`], built from
//!    [`Spherical`] angles), or at Rusinkiewicz half/difference angles ([`HalfDiff`]).
//! 3. **Tabulate it.** [`MerlTable`] is the dense isotropic table of the MERL grid
//!    (90 θh × 90 θd × 180 φd × RGB, thesis §3.6) with nearest and trilinear lookup; the bin
//!    arithmetic is [`bin_index`], [`bin_coords`] and [`reference_bin`], and [`merl`] reads and
//!    writes `.binary` files. [`nbrdf`] decodes the neural-BRDF weight files in which the shared
//!    reference measurements come.
//! 4. **Model it analytically.** [`analytic`] holds Lambert, Phong, Ward, Cook-Torrance, GGX,
//!    He-Torrance-Sillion-Greenberg and others (thesis §2.2), each written once, generic over
//!    the scalar [`Real`]: `f64` for values, [`Dual`] numbers for exact parameter gradients.
//! 5. **Gather a corpus.** [`LogTransform`] is the log transform of thesis §4.1 with its floor
//!    [`LOG_FLOOR`]; [`Corpus`] holds materials (neural-BRDF directories, `.binary` files,
//!    specs, stores read by a registered [`StoreReader`]) as log-space vectors, and
//!    [`load_tables`] as named tables.
//! 6. **Check it.** [`summarize`] gives a [`Summary`]: directional albedo
//!    ([`directional_albedo`]), peak value, reciprocity residual, missing-bin fraction;
//!    [`metrics::log_relative_rms`] compares two tables.
//!
//! Around these: [`write_atomic`], the one way the workspace writes a result file;
//! [`parse_csv`] for lists of angles; [`resident_bytes`] and [`cpu_seconds`] for the memory and
//! time reports; [`data_dir`] to find the shared reference data.
//!
//! # Examples
//!
//! ```
//! use brdf::{Brdf, HalfDiff, MerlTable, Spherical};
//!
//! // name a material by its spec (here an analytic model; `merl:<name>` names a measured one)
//! let ggx = brdf::load("ggx:alpha=0.2,kd=0.1").unwrap();
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

#![warn(missing_docs)]
// Channel loops index several arrays at once; iterator zips would obscure them.
#![allow(clippy::needless_range_loop)]

pub mod analytic;
mod angles;
mod atomic;
mod coords;
mod corpus;
mod error;
pub mod merl;
pub mod metrics;
pub mod nbrdf;
pub mod npy;
mod process;
mod real;
mod sample;
mod spec;
mod summary;
mod table;

pub use angles::{parse_csv, AnglesError};
pub use coords::{sphere_pixels, SpherePixel};
pub use corpus::{
    from_log, from_log_clamped, load_tables, log_vector, register_store_reader, sources,
    sources_of, to_log, values_from_log, Corpus, LogTransform, Source, StoreReader, LOG_FLOOR,
    MATERIAL_DIM,
};
pub use error::Result;
pub use process::{cpu_seconds, peak_resident_bytes, resident_bytes};
pub use real::{Dual, Real};
pub use sample::{cosine_hemisphere, cosine_hemisphere_pdf, DirectionSample};
pub use spec::{
    load, parse, register, registered_forms, resolver_error, spec_error, Material, MaterialSpec,
    SpecResolver, BUILT_IN_FORMS,
};
pub use summary::{
    albedo_cells, directional_albedo, reciprocity_residual, summarize, AlbedoSample, Summary,
    SummaryOptions, ALBEDO_CELLS,
};
pub use table::{
    bin_angles, bin_coords, bin_index, grid_coordinates, node_bin_index, phi_diff_index,
    reference_bin, theta_diff_index, theta_half_index, Interpolation, BINS, MERL_SCALE, PHI_D_RES,
    THETA_D_RES, THETA_H_RES,
};

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
///
/// # Examples
///
/// ```
/// use brdf::{Brdf, HalfDiff, Rgb, Vec3};
///
/// /// A grey Lambertian surface of albedo 0.4.
/// struct Matte;
/// impl Brdf for Matte {
///     fn eval(&self, wi: &Vec3, wo: &Vec3) -> Rgb {
///         if wi.z < 0.0 || wo.z < 0.0 {
///             return [0.0; 3];
///         }
///         [0.4 / std::f64::consts::PI; 3]
///     }
///     fn name(&self) -> String {
///         "matte".into()
///     }
/// }
///
/// // the default half/difference evaluation goes through the directions
/// let f = Matte.eval_half_diff(&HalfDiff::isotropic(0.2, 0.3, 1.0));
/// assert!((f[0] - 0.4 / std::f64::consts::PI).abs() < 1e-12);
/// assert_eq!(Matte.eval(&Vec3::z(), &-Vec3::z()), [0.0; 3]);
/// ```
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

    /// Draws an incident direction for the outgoing direction `wo` from three uniform numbers in
    /// `[0, 1)`, with its density in solid angle; `None` when `wo` lies below the horizon or
    /// the draw leaves the upper hemisphere.
    ///
    /// The default draws cosine-weighted directions. Models with a sampler that follows their
    /// own lobes (Lambert, GGX with one or two lobes: visible-normal sampling) override it
    /// together with [`Brdf::pdf`] and say so with [`Brdf::has_importance_sampler`]; a renderer
    /// uses tabulated importance sampling (thesis A.2.4) for the others.
    fn sample(&self, wo: &Vec3, u: [f64; 3]) -> Option<DirectionSample> {
        sample::cosine_sample(wo, u)
    }

    /// Density in solid angle with which [`Brdf::sample`] draws `wi` for the outgoing direction
    /// `wo` (zero where either lies below the horizon).
    fn pdf(&self, wi: &Vec3, wo: &Vec3) -> f64 {
        sample::cosine_pdf(wi, wo)
    }

    /// Whether [`Brdf::sample`] follows the model's own lobes rather than the cosine default.
    fn has_importance_sampler(&self) -> bool {
        false
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
            fn sample(&self, wo: &Vec3, u: [f64; 3]) -> Option<DirectionSample> {
                (**self).sample(wo, u)
            }
            fn pdf(&self, wi: &Vec3, wo: &Vec3) -> f64 {
                (**self).pdf(wi, wo)
            }
            fn has_importance_sampler(&self) -> bool {
                (**self).has_importance_sampler()
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

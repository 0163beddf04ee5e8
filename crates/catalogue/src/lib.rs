//! The catalogue of material forms: which material specs (`merl:`, `.binary`, analytic models,
//! `pca:`, `wavelet:` ...) and which corpus stores a program reads.
//!
//! `brdf` reads its own forms and leaves the others to resolvers that live in the crates that
//! own them (`reduce` owns `pca:`, `wavelet` owns `wavelet:`, `corpus-store` owns the Zarr
//! store). A [`Catalogue`] is the explicit list of those resolvers and store readers; every
//! front end builds the same one with [`Catalogue::workspace`] and [`installs`](Catalogue::install)
//! it at start-up, so the CLI, the Python package and the server accept the same specs and the
//! same `--corpus` inputs (docs/material-spec.md lists them).
//!
//! ```
//! let catalogue = catalogue::Catalogue::workspace();
//! catalogue.install();
//! assert!(catalogue.forms().iter().any(|f| f.starts_with("pca:")));
//! let m = brdf::load("ggx:alpha=0.2").unwrap();
//! assert_eq!(m.as_brdf().name(), "ggx");
//! ```

use brdf::SpecResolver;
use brdf::StoreReader;
use std::path::Path;
use std::sync::Arc;

/// The spec resolvers and store readers a program reads, beyond `brdf`'s built-in forms.
#[derive(Clone, Default)]
pub struct Catalogue {
    resolvers: Vec<Arc<dyn SpecResolver>>,
    stores: Vec<Arc<dyn StoreReader>>,
}

impl std::fmt::Debug for Catalogue {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Catalogue")
            .field("forms", &self.forms())
            .field("stores", &self.store_formats())
            .finish()
    }
}

impl Catalogue {
    /// Only `brdf`'s built-in forms.
    pub fn builtin() -> Catalogue {
        Catalogue::default()
    }

    /// Every form of the workspace: `pca:` (reduce), `wavelet:` (wavelet), `rgl:` and `.bsdf` files (rgl-bsdf) and Zarr corpus
    /// stores (corpus-store), on top of the built-in ones.
    pub fn workspace() -> Catalogue {
        Catalogue::builtin()
            .with_resolver(Arc::new(reduce::PcaSpecs::default()))
            .with_resolver(Arc::new(wavelet::WaveletSpecs))
            .with_resolver(Arc::new(rgl_bsdf::RglSpecs))
            .with_store_reader(Arc::new(corpus_store::ZarrStoreReader))
    }

    /// Adds a spec resolver (one replacing an earlier one of the same prefix).
    pub fn with_resolver(mut self, resolver: Arc<dyn SpecResolver>) -> Catalogue {
        self.resolvers
            .retain(|r| !r.prefix().eq_ignore_ascii_case(resolver.prefix()));
        self.resolvers.push(resolver);
        self
    }

    /// Adds a corpus-store reader (one replacing an earlier one of the same format).
    pub fn with_store_reader(mut self, reader: Arc<dyn StoreReader>) -> Catalogue {
        self.stores.retain(|r| r.format() != reader.format());
        self.stores.push(reader);
        self
    }

    /// Every spec form, as users write it: the built-in ones, then the resolvers'.
    pub fn forms(&self) -> Vec<String> {
        brdf::BUILT_IN_FORMS
            .iter()
            .map(|f| f.to_string())
            .chain(self.resolvers.iter().map(|r| match r.form() {
                "" => format!("{}:...", r.prefix()),
                f => f.to_string(),
            }))
            .collect()
    }

    /// The corpus-store formats read.
    pub fn store_formats(&self) -> Vec<String> {
        self.stores.iter().map(|r| r.format().to_string()).collect()
    }

    /// Makes this catalogue the one `brdf::spec` and `brdf::corpus` read for the rest of the
    /// process (installing again, or another catalogue, replaces entries of the same prefix or
    /// format).
    /// A resolver added with [`with_resolver`](Catalogue::with_resolver) whose prefix is built
    /// in or malformed is skipped with a `tracing` warning.
    pub fn install(&self) {
        for r in &self.resolvers {
            if let Err(e) = brdf::register(r.clone()) {
                tracing::warn!("spec resolver not installed: {e}");
            }
        }
        for s in &self.stores {
            brdf::register_store_reader(s.clone());
        }
    }
}

/// The file formats [`write_material`] writes, by extension.
pub const WRITE_FORMATS: &[&str] = &["binary", "bsdf"];

/// Why a material could not be written.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum WriteError {
    /// The output's extension names no format this program writes.
    #[error("{path}: unknown output format '.{extension}' (written formats: .binary for a MERL table, .bsdf for an RGL tensor file)")]
    UnknownFormat {
        /// The output path.
        path: String,
        /// Its extension.
        extension: String,
    },
    /// Writing the MERL table failed.
    #[error(transparent)]
    Brdf(#[from] brdf::BrdfError),
    /// Writing the `.bsdf` file failed.
    #[error(transparent)]
    Rgl(#[from] rgl_bsdf::RglError),
}

/// What [`write_material`] wrote.
#[derive(Debug, Clone, serde::Serialize)]
pub struct Written {
    /// The output file.
    pub path: String,
    /// Its format: `merl` or `rgl-bsdf`.
    pub format: &'static str,
    /// Its size in bytes.
    pub bytes: u64,
}

impl std::fmt::Display for Written {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "wrote {} ({}, {} bytes)",
            self.path, self.format, self.bytes
        )
    }
}

/// Writes `material` in the format its path names (atomically): `.binary`, a MERL table on
/// the full grid; `.bsdf`, an RGL tensor file ([`rgl_bsdf::write`] with `bsdf` options), which
/// Mitsuba 3's `measured` BSDF and pbrt-v4's `measured` material read. Any other extension is
/// an [`WriteError::UnknownFormat`], before anything is computed.
///
/// # Examples
///
/// ```
/// let dir = tempfile::tempdir().unwrap();
/// let m = brdf::load("lambert:kd=0.3").unwrap();
/// let options = rgl_bsdf::WriteOptions::small();
/// let w = catalogue::write_material(&m, &dir.path().join("m.bsdf"), &options).unwrap();
/// assert_eq!(w.format, "rgl-bsdf");
/// assert!(catalogue::write_material(&m, &dir.path().join("m.exr"), &options).is_err());
/// ```
pub fn write_material(
    material: &brdf::Material,
    path: &Path,
    bsdf: &rgl_bsdf::WriteOptions,
) -> Result<Written, WriteError> {
    let extension = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    let format = match extension.as_str() {
        "binary" => {
            brdf::merl::write(path, &material.tabulate())?;
            "merl"
        }
        "bsdf" => {
            rgl_bsdf::write(material.as_brdf(), bsdf)?.write(path)?;
            "rgl-bsdf"
        }
        _ => {
            return Err(WriteError::UnknownFormat {
                path: path.display().to_string(),
                extension,
            })
        }
    };
    let bytes = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
    tracing::info!(path = %path.display(), format, bytes, "wrote material");
    Ok(Written {
        path: path.display().to_string(),
        format,
        bytes,
    })
}

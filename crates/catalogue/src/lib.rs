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
//! let m = brdf::spec::load("ggx:alpha=0.2").unwrap();
//! assert_eq!(m.as_brdf().name(), "ggx");
//! ```

use brdf::corpus::StoreReader;
use brdf::spec::SpecResolver;
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

    /// Every form of the workspace: `pca:` (reduce), `wavelet:` (wavelet) and Zarr corpus
    /// stores (corpus-store), on top of the built-in ones.
    pub fn workspace() -> Catalogue {
        Catalogue::builtin()
            .with_resolver(Arc::new(reduce::spec::PcaSpecs::default()))
            .with_resolver(Arc::new(wavelet::material::WaveletSpecs))
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
        brdf::spec::BUILT_IN_FORMS
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
            if let Err(e) = brdf::spec::register(r.clone()) {
                tracing::warn!("spec resolver not installed: {e}");
            }
        }
        for s in &self.stores {
            brdf::corpus::register_store_reader(s.clone());
        }
    }
}

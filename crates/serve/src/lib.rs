//! # serve — the material viewer and editor in the browser
//!
//! `gantry serve` runs this crate: a local HTTP server (axum on tokio, bound to 127.0.0.1 by
//! default) with an embedded page and a small JSON API (docs/serve.md). The page browses a
//! corpus with thumbnails and trait scores, shows a lit sphere under a draggable light, an
//! environment-map render refined pass by pass, the incidence-plane cut, a θh × θd slice and
//! the directional albedo, compares two materials with a difference image, and edits a
//! material with one slider per trait (thesis chapter 5), every step checked for physical
//! validity (the check that stops a step is shown), with undo/redo and export as MERL
//! `.binary`, edit spec and PNG.
//!
//! A [`Config`] says what to serve (corpus, model, trait sets, address); [`App`] is the state
//! shared by all requests, and [`serve()`] runs it on a listener through [`router`]. Inside,
//! the [`Library`] holds the materials (corpus, uploads), the [`Editor`] the model, trait spaces
//! and open [`EditSession`]s (thesis §5.2–5.4), and the views ([`PreviewCache`],
//! [`IncidencePlane`], [`Slice`], [`AlbedoCurve`], [`Comparison`]) compute what the page shows.
//!
//! ```
//! use serve::{App, Config};
//! use std::sync::Arc;
//!
//! # tokio::runtime::Runtime::new().unwrap().block_on(async {
//! // A server without corpus or model: the page, the API and uploads.
//! let app = Arc::new(App::new(Config::default()).unwrap());
//! let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
//! let addr = listener.local_addr().unwrap();
//! let server = tokio::spawn(serve::serve(app, listener));
//! // A client: the API answers in JSON.
//! let mut s = tokio::net::TcpStream::connect(addr).await.unwrap();
//! use tokio::io::{AsyncReadExt, AsyncWriteExt};
//! s.write_all(b"GET /api/info HTTP/1.1\r\nHost: localhost\r\nConnection: close\r\n\r\n").await.unwrap();
//! let mut reply = String::new();
//! s.read_to_string(&mut reply).await.unwrap();
//! assert!(reply.starts_with("HTTP/1.1 200") && reply.contains("\"editing\":false"));
//! server.abort();
//! # });
//! ```

#![warn(missing_docs)]

mod api;
mod assets;
mod editor;
mod error;
mod gpu;
mod gpu_api;
mod library;
mod prepare;
mod views;

pub use api::{router, routes};
pub use assets::OPENAPI_JSON;
pub use editor::{EditSession, EditSpec, Editor, SessionState, StepResult, TraitSpace};
pub use library::{upload_stem, Library, Origin, Shared};
pub use prepare::{
    corpus_key, default_cache_dirs, PreparationState, PreparationStatus, EDITING_NEEDS,
};
pub use views::{AlbedoCurve, Comparison, IncidencePlane, Pixels, PreviewCache, Shape, Slice};

pub use error::{Result, ServeError};
pub use gpu::{
    gpu_reduction_error, GpuBasis, GpuBrdf, GpuGrid, GpuReductionError, GPU_BASIS_MAGIC,
};

use std::collections::HashMap;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};

/// Default upload limit: a MERL `.binary` (34,992,012 bytes) with some room.
pub const DEFAULT_UPLOAD_LIMIT: u64 = 40 * 1024 * 1024;

/// What the server serves.
#[derive(Debug, Clone)]
pub struct Config {
    /// Corpus directory (neural-BRDF weights and/or `.binary` files); never written.
    pub corpus: Option<PathBuf>,
    /// Model file (`gantry model build`), needed for editing and trait scores.
    pub model: Option<PathBuf>,
    /// Trait sets (`gantry traits fit`), one per space.
    pub traits: Vec<PathBuf>,
    /// Where models built from the corpus are cached (without `model`); `None`: beside the
    /// corpus ([`default_cache_dirs`]).
    pub cache: Option<PathBuf>,
    /// Lat-long light probe (OpenEXR or Radiance `.hdr`) of the environment view (the shared Venice probe when
    /// found, else a procedural probe).
    pub environment: Option<PathBuf>,
    /// Largest upload accepted, bytes.
    pub upload_limit: u64,
    /// Address to bind.
    pub bind: SocketAddr,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            corpus: None,
            model: None,
            traits: Vec::new(),
            cache: None,
            environment: None,
            upload_limit: DEFAULT_UPLOAD_LIMIT,
            bind: SocketAddr::from(([127, 0, 0, 1], 8080)),
        }
    }
}

/// The application state shared by all requests.
pub struct App {
    /// Settings.
    pub config: Config,
    /// Corpus and uploads.
    pub library: library::Library,
    /// Model, trait spaces and edit sessions (from `--model` and `--traits`, or built from the
    /// corpus on first use: [`App::prepare_editing`]); see [`App::editor`].
    editor: std::sync::OnceLock<editor::Editor>,
    preparation: Mutex<prepare::Preparation>,
    /// Sphere previews by size and light.
    pub previews: views::PreviewCache,
    /// The environment-map view's light probe.
    pub environment: render::EnvironmentMap,
    /// Its name for the page.
    pub environment_name: String,
    thumbnails: Mutex<HashMap<String, Arc<Vec<u8>>>>,
    gpu_basis: std::sync::OnceLock<Arc<gpu::GpuBasis>>,
    /// Environment renders run one at a time on their own single thread, so the editor's
    /// slider steps keep the other cores; a request whose client left before its turn is
    /// dropped without rendering.
    pub(crate) env_gate: tokio::sync::Semaphore,
    pub(crate) env_pool: rayon::ThreadPool,
}

impl App {
    /// Opens the corpus, loads the model and the trait sets, and the light probe.
    pub fn new(config: Config) -> Result<App> {
        let library = library::Library::open(config.corpus.as_deref())?;
        let editor = match &config.model {
            None => {
                if !config.traits.is_empty() {
                    return Err(ServeError::InvalidParameter(
                        "--traits needs --model".into(),
                    ));
                }
                std::sync::OnceLock::new()
            }
            Some(m) => {
                let model = reduce::Model::load(m)?;
                model.require_log_mapping("the editor")?;
                let sets = config
                    .traits
                    .iter()
                    .map(traits::TraitSet::load)
                    .collect::<traits::Result<Vec<_>>>()?;
                std::sync::OnceLock::from(editor::Editor::new(model, sets)?)
            }
        };
        let preparation = prepare::Preparation::new(if editor.get().is_some() {
            PreparationState::Ready
        } else if config.corpus.is_some() {
            PreparationState::Buildable
        } else {
            PreparationState::Unavailable
        });
        let probe = config.environment.clone().or_else(|| {
            let p = brdf::data_dir().join("real/envmap/venice_sunset_1k.exr");
            p.is_file().then_some(p)
        });
        let (environment, environment_name) = match probe {
            Some(p) => (
                render::EnvironmentMap::read(&p)?,
                p.file_name()
                    .map_or("probe".into(), |s| s.to_string_lossy().into_owned()),
            ),
            None => (
                render::EnvironmentMap::procedural_probe(256, 128, 1)?,
                "procedural probe".into(),
            ),
        };
        Ok(App {
            config,
            library,
            editor,
            preparation,
            previews: Default::default(),
            environment,
            environment_name,
            thumbnails: Default::default(),
            gpu_basis: Default::default(),
            env_gate: tokio::sync::Semaphore::new(1),
            env_pool: rayon::ThreadPoolBuilder::new()
                .num_threads(1)
                .thread_name(|_| "environment-render".into())
                .build()
                .map_err(|e| ServeError::Internal(e.to_string()))?,
        })
    }
}

/// Binds the configured address.
pub async fn bind(config: &Config) -> Result<tokio::net::TcpListener> {
    tokio::net::TcpListener::bind(config.bind)
        .await
        .map_err(|source| ServeError::Io {
            what: format!("cannot listen on {}", config.bind),
            source,
        })
}

/// Serves the application on `listener` until the task is dropped or ctrl-c. Without a model,
/// a cached build of the corpus is looked for in the background ([`App::prepare_editing`]).
pub async fn serve(app: Arc<App>, listener: tokio::net::TcpListener) -> Result<()> {
    app.prepare_editing(false);
    let router = api::router(app);
    axum::serve(listener, router)
        .with_graceful_shutdown(async {
            let _ = tokio::signal::ctrl_c().await;
        })
        .await
        .map_err(|source| ServeError::Io {
            what: "server".into(),
            source,
        })
}

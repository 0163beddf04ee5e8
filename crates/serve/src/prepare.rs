//! Editing out of the box: with a corpus but no `--model`, the server builds a model and the
//! default trait sets from the corpus on first use, and caches them beside the corpus under a
//! key of its content, so that a later start on the same corpus edits at once.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use serde::Serialize;

use crate::error::{Result, ServeError};
use crate::App;

/// File written last into a cache entry; an entry without it is incomplete and rebuilt.
const COMPLETE: &str = "complete";

/// Where editing stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum PreparationState {
    /// Editing works.
    Ready,
    /// No model yet; one can be built from the corpus.
    Buildable,
    /// Looking for a cached build, or building.
    Running,
    /// The build failed (see the message); it can be asked again.
    Failed,
    /// No corpus to build from, and no model given.
    Unavailable,
}

/// What the page shows about editing (`/api/info`'s `preparation`).
#[derive(Debug, Clone, Serialize)]
pub struct PreparationStatus {
    /// Where editing stands.
    pub state: PreparationState,
    /// What is being done, or why editing is off.
    pub message: String,
    /// Seconds since the current step began (while running).
    pub elapsed_s: Option<f64>,
    /// The cache entry of this corpus, once known.
    pub cache: Option<PathBuf>,
}

#[derive(Debug)]
pub(crate) struct Preparation {
    state: PreparationState,
    message: String,
    since: Instant,
    cache: Option<PathBuf>,
}

/// The message of a server that cannot edit yet.
pub const EDITING_NEEDS: &str = "editing needs a model and a trait set";

impl Preparation {
    pub(crate) fn new(state: PreparationState) -> Mutex<Preparation> {
        let message = match state {
            PreparationState::Ready => "editing".into(),
            PreparationState::Unavailable => {
                format!("{EDITING_NEEDS}: start the server with --model and --traits")
            }
            _ => format!("{EDITING_NEEDS}: they can be built from the corpus"),
        };
        Mutex::new(Preparation {
            state,
            message,
            since: Instant::now(),
            cache: None,
        })
    }

    fn status(&self) -> PreparationStatus {
        PreparationStatus {
            state: self.state,
            message: self.message.clone(),
            elapsed_s: (self.state == PreparationState::Running)
                .then(|| self.since.elapsed().as_secs_f64()),
            cache: self.cache.clone(),
        }
    }
}

/// 64-bit FNV-1a, streamed.
struct Fnv(u64);

impl Fnv {
    fn new() -> Fnv {
        Fnv(0xcbf2_9ce4_8422_2325)
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= u64::from(b);
            self.0 = self.0.wrapping_mul(0x0100_0000_01b3);
        }
    }
}

fn io_error(what: impl Into<String>, source: std::io::Error) -> ServeError {
    ServeError::Io {
        what: what.into(),
        source,
    }
}

/// The key of a corpus's content: a hash of every file under it (a file corpus: of the file),
/// each with its path relative to the corpus and its bytes, in path order. Any change of a
/// file's name or content gives another key.
pub fn corpus_key(corpus: &Path) -> Result<String> {
    let mut files = Vec::new();
    if corpus.is_dir() {
        let mut stack = vec![corpus.to_path_buf()];
        while let Some(dir) = stack.pop() {
            let entries = std::fs::read_dir(&dir)
                .map_err(|e| io_error(format!("cannot list {}", dir.display()), e))?;
            for entry in entries {
                let entry =
                    entry.map_err(|e| io_error(format!("cannot list {}", dir.display()), e))?;
                let path = entry.path();
                // Links to files count as the files; linked folders are not followed.
                let real_dir = entry.file_type().is_ok_and(|t| t.is_dir());
                if real_dir {
                    stack.push(path);
                } else if path.is_file() {
                    files.push(path);
                }
            }
        }
    } else {
        files.push(corpus.to_path_buf());
    }
    files.sort();
    let mut h = Fnv::new();
    let mut buf = vec![0u8; 1 << 20];
    for path in &files {
        let rel = path.strip_prefix(corpus).unwrap_or(path);
        h.write(rel.to_string_lossy().as_bytes());
        h.write(&[0]);
        let mut f = std::fs::File::open(path)
            .map_err(|e| io_error(format!("cannot read {}", path.display()), e))?;
        let mut len = 0u64;
        loop {
            let n = f
                .read(&mut buf)
                .map_err(|e| io_error(format!("cannot read {}", path.display()), e))?;
            if n == 0 {
                break;
            }
            h.write(&buf[..n]);
            len += n as u64;
        }
        h.write(&len.to_le_bytes());
    }
    Ok(format!("{:016x}", h.0))
}

/// The cache folders of a corpus when none is configured, in the order they are tried:
/// `<corpus>.gantry-cache` beside it, then `gantry` under `$XDG_CACHE_HOME` (or `~/.cache`)
/// for a corpus whose folder cannot be written.
pub fn default_cache_dirs(corpus: &Path) -> Vec<PathBuf> {
    let name = corpus
        .file_name()
        .map_or("corpus".into(), |n| n.to_string_lossy().into_owned());
    let mut dirs = vec![corpus.with_file_name(format!("{name}.gantry-cache"))];
    if let Some(base) = std::env::var_os("XDG_CACHE_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".cache")))
    {
        dirs.push(base.join("gantry"));
    }
    dirs
}

/// A built model and its trait sets, as files of one cache entry.
struct Entry {
    dir: PathBuf,
}

impl Entry {
    fn model(&self) -> PathBuf {
        self.dir.join("model.bin")
    }
    fn set(&self, i: usize) -> PathBuf {
        self.dir.join(format!("traits-{i}.json"))
    }
    fn is_complete(&self) -> bool {
        self.dir.join(COMPLETE).is_file()
    }

    fn load(&self) -> Result<(reduce::Model, Vec<traits::TraitSet>)> {
        let count: usize = std::fs::read_to_string(self.dir.join(COMPLETE))
            .map_err(|e| io_error(format!("cannot read {}", self.dir.display()), e))?
            .trim()
            .parse()
            .map_err(|_| {
                ServeError::InvalidParameter(format!(
                    "bad cache entry {}: remove it to rebuild",
                    self.dir.display()
                ))
            })?;
        let model = reduce::Model::load(self.model())?;
        let sets = (0..count)
            .map(|i| traits::TraitSet::load(self.set(i)))
            .collect::<traits::Result<Vec<_>>>()?;
        Ok((model, sets))
    }

    fn save(&self, sets: &[traits::TraitSet]) -> Result<()> {
        for (i, s) in sets.iter().enumerate() {
            s.save(self.set(i))?;
        }
        Ok(brdf::write_atomic(
            &self.dir.join(COMPLETE),
            sets.len().to_string().as_bytes(),
        )?)
    }
}

impl App {
    /// The editor, once there is one (from `--model`, or built on first use).
    pub fn editor(&self) -> Option<&crate::Editor> {
        self.editor.get()
    }

    /// Where editing stands.
    pub fn preparation(&self) -> PreparationStatus {
        self.lock_preparation().status()
    }

    fn lock_preparation(&self) -> std::sync::MutexGuard<'_, Preparation> {
        self.preparation
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
    }

    fn set_step(&self, state: PreparationState, message: impl Into<String>) {
        let mut p = self.lock_preparation();
        p.state = state;
        p.message = message.into();
        p.since = Instant::now();
    }

    /// Makes editing available without `--model`, in a background thread: finds this corpus's
    /// cached model and trait sets, or, when `build` is set and there are none, builds them
    /// (`reduce::BuildJob`, then [`traits::default_trait_sets`]) and caches them. Returns the
    /// status at once; a call while one runs, or once editing works, changes nothing.
    pub fn prepare_editing(self: &Arc<Self>, build: bool) -> PreparationStatus {
        {
            let mut p = self.lock_preparation();
            match p.state {
                PreparationState::Ready
                | PreparationState::Running
                | PreparationState::Unavailable => return p.status(),
                PreparationState::Buildable | PreparationState::Failed => {
                    p.state = PreparationState::Running;
                    p.message = "looking for a cached model of this corpus".into();
                    p.since = Instant::now();
                }
            }
        }
        let app = self.clone();
        let spawned = std::thread::Builder::new()
            .name("prepare-editing".into())
            .spawn(move || {
                if let Err(e) = app.run_preparation(build) {
                    tracing::warn!("preparing editing failed: {e}");
                    app.set_step(
                        PreparationState::Failed,
                        format!("{EDITING_NEEDS}, and building them failed: {e}"),
                    );
                }
            });
        if let Err(e) = spawned {
            self.set_step(
                PreparationState::Failed,
                format!("{EDITING_NEEDS}: cannot start the build: {e}"),
            );
        }
        self.preparation()
    }

    fn run_preparation(&self, build: bool) -> Result<()> {
        let corpus = self
            .config
            .corpus
            .clone()
            .ok_or_else(|| ServeError::InvalidParameter("no corpus".into()))?;
        let key = corpus_key(&corpus)?;
        let roots = match &self.config.cache {
            Some(dir) => vec![dir.clone()],
            None => default_cache_dirs(&corpus),
        };
        let entries: Vec<Entry> = roots.iter().map(|r| Entry { dir: r.join(&key) }).collect();
        // A complete entry in any root; else the first root that can be written.
        let entry = match entries.iter().position(Entry::is_complete) {
            Some(i) => &entries[i],
            None if !build => &entries[0],
            None => entries
                .iter()
                .find(|e| std::fs::create_dir_all(&e.dir).is_ok())
                .ok_or_else(|| {
                    ServeError::InvalidParameter(format!(
                        "no cache folder can be written (tried {})",
                        roots
                            .iter()
                            .map(|r| r.display().to_string())
                            .collect::<Vec<_>>()
                            .join(", ")
                    ))
                })?,
        };
        self.lock_preparation().cache = Some(entry.dir.clone());
        let (model, sets) = if entry.is_complete() {
            self.set_step(PreparationState::Running, "loading the cached model");
            tracing::info!("editing from the cached model {}", entry.dir.display());
            entry.load()?
        } else if !build {
            self.set_step(
                PreparationState::Buildable,
                format!("{EDITING_NEEDS}: they can be built from the corpus"),
            );
            return Ok(());
        } else {
            self.set_step(
                PreparationState::Running,
                format!(
                    "building the model of the {} materials (PCA and chart)",
                    self.library.corpus_names().len()
                ),
            );
            let job = reduce::BuildJob {
                corpus: vec![corpus.to_string_lossy().into_owned()],
                out: entry.model(),
                components: None,
                chart_dim: reduce::DEFAULT_CHART_DIM,
                mapping: reduce::Mapping::Log.name(),
            };
            let report = job.run()?;
            tracing::info!("{report}");
            let model = reduce::Model::load(entry.model())?;
            self.set_step(
                PreparationState::Running,
                "fitting the trait sets (the thesis's traits and the human ratings)",
            );
            let sets = traits::default_trait_sets(&model, true)?;
            entry.save(&sets)?;
            (model, sets)
        };
        if sets.is_empty() {
            self.set_step(
                PreparationState::Failed,
                format!(
                    "{EDITING_NEEDS}: the model is built, but no trait has enough labelled \
                     materials in this corpus; fit one with gantry traits fit and start with \
                     --model {} --traits",
                    entry.model().display()
                ),
            );
            return Ok(());
        }
        let editor = crate::Editor::new(model, sets)?;
        let _ = self.editor.set(editor);
        self.set_step(PreparationState::Ready, "editing");
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_key_follows_names_and_content() {
        let dir = tempfile::tempdir().unwrap();
        let c = dir.path().join("corpus");
        std::fs::create_dir_all(c.join("sub")).unwrap();
        std::fs::write(c.join("a.json"), b"one").unwrap();
        std::fs::write(c.join("sub/b.json"), b"two").unwrap();
        let k0 = corpus_key(&c).unwrap();
        assert_eq!(k0, corpus_key(&c).unwrap());
        assert_eq!(k0.len(), 16);
        std::fs::write(c.join("a.json"), b"onE").unwrap();
        let k1 = corpus_key(&c).unwrap();
        assert_ne!(k0, k1);
        std::fs::rename(c.join("sub/b.json"), c.join("sub/c.json")).unwrap();
        assert_ne!(k1, corpus_key(&c).unwrap());
        // Moving bytes between files changes the key too.
        std::fs::write(c.join("a.json"), b"on").unwrap();
        std::fs::write(c.join("sub/c.json"), b"Etwo").unwrap();
        assert_ne!(k1, corpus_key(&c).unwrap());
        assert!(corpus_key(&dir.path().join("missing")).is_err());
    }

    #[test]
    fn fnv_matches_its_reference_values() {
        // FNV-1a 64 of "" and "a" (the algorithm's published test vectors).
        let mut h = Fnv::new();
        assert_eq!(h.0, 0xcbf2_9ce4_8422_2325);
        h.write(b"a");
        assert_eq!(h.0, 0xaf63_dc4c_8601_ec8c);
    }

    #[test]
    fn the_default_cache_sits_beside_the_corpus() {
        let dir = tempfile::tempdir().unwrap();
        let c = dir.path().join("merl");
        assert_eq!(
            default_cache_dirs(&c)[0],
            dir.path().join("merl.gantry-cache")
        );
    }
}

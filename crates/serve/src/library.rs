//! The materials the server knows: the corpus, uploads and edit sessions.

use crate::error::{Result, ServeError};
use brdf::Source;
use brdf::{Brdf, MerlTable};
use std::collections::{BTreeMap, VecDeque};
use std::path::Path;
use std::sync::{Arc, Mutex};

/// Longest accepted material name.
pub const MAX_NAME_LEN: usize = 128;
/// Corpus materials kept decoded at once (a `.binary` corpus material is 35 MB).
pub const CACHE_CAPACITY: usize = 24;
/// Uploads kept at once (the oldest is dropped first).
pub const MAX_UPLOADS: usize = 8;

/// Checks that `name` is a plain material name: 1–128 characters from letters, digits, `-`,
/// `_`, `.` and `:`, not starting with `.`, and no `..`. Anything that could name a path
/// (separators, parent references, NUL or other control characters) is refused.
pub fn check_name(name: &str) -> Result<&str> {
    let ok = !name.is_empty()
        && name.len() <= MAX_NAME_LEN
        && !name.starts_with('.')
        && !name.contains("..")
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.' | ':'));
    if ok {
        Ok(name)
    } else {
        Err(ServeError::InvalidName(
            name.chars().take(MAX_NAME_LEN).collect(),
        ))
    }
}

/// Where a material comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Origin {
    /// The corpus directory given with `--corpus`.
    Corpus,
    /// A `.binary` uploaded by a client (kept in memory only).
    Upload,
    /// The current point of an edit session.
    Edit,
}

/// A loaded material, shareable between requests.
pub type Shared = Arc<dyn Brdf>;

/// The materials the server knows: the corpus directory (loaded on first use, never written),
/// uploads kept in memory, and the current state of edit sessions. Every material is reached by
/// a checked name, never by a path from a request.
///
/// # Examples
///
/// ```
/// use brdf::Vec3;
/// use serve::Library;
/// // A corpus directory with one MERL table.
/// let dir = tempfile::tempdir().unwrap();
/// let table = brdf::load("lambert:kd=0.5").unwrap().tabulate();
/// brdf::merl::write(dir.path().join("matte.binary"), &table).unwrap();
/// let library = Library::open(Some(dir.path())).unwrap();
/// assert_eq!(library.corpus_names(), ["matte"]);
/// // Loaded on first use: a Lambertian surface is kd/π everywhere.
/// let matte = library.get("matte").unwrap();
/// let f = matte.eval(&Vec3::new(0.3, 0.0, 0.954).normalize(), &Vec3::z());
/// assert!(f.iter().all(|v| (v - 0.5 / std::f64::consts::PI).abs() < 1e-3));
/// // Names that could reach a path are refused before any lookup.
/// assert!(library.get("../matte").is_err());
/// // Uploads stay in memory under a new name.
/// let name = library.add_upload("my paint.binary", &brdf::merl::to_bytes(&table)).unwrap();
/// assert_eq!(name, "upload-1-mypaint");
/// assert_eq!(library.upload_names(), [name.clone()]);
/// assert!(!library.is_corpus(&name) && library.upload_table(&name).is_some());
/// assert!(library.add_upload("short.binary", b"not a table").is_err());
/// ```
pub struct Library {
    sources: BTreeMap<String, Source>,
    cache: Mutex<VecDeque<(String, Shared)>>,
    uploads: Mutex<VecDeque<(String, Arc<MerlTable>)>>,
    next_upload: std::sync::atomic::AtomicU64,
}

/// The part of an uploaded file's name that names the upload: the last path component
/// without `.binary`, reduced to ASCII letters, digits, `-` and `_`, at most 48 of them (a
/// client's name never reaches a path or the page unescaped).
pub fn upload_stem(file_name: &str) -> String {
    file_name
        .rsplit(['/', '\\'])
        .next()
        .unwrap_or("")
        .trim_end_matches(".binary")
        .chars()
        .filter(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_'))
        .take(48)
        .collect()
}

impl Library {
    /// The materials of a corpus directory (neural-BRDF weights and/or `.binary` files), or an
    /// empty library. Materials whose names are not plain names are left out (logged).
    pub fn open(corpus: Option<&Path>) -> Result<Library> {
        let mut sources = BTreeMap::new();
        if let Some(dir) = corpus {
            if !dir.is_dir() {
                return Err(ServeError::InvalidParameter(format!(
                    "corpus {} is not a directory",
                    dir.display()
                )));
            }
            for s in brdf::sources_of(dir)? {
                let name = s.name();
                if check_name(&name).is_err() {
                    tracing::warn!(%name, "corpus material skipped: not a plain name");
                    continue;
                }
                sources.insert(name, s);
            }
        }
        Ok(Library {
            sources,
            cache: Mutex::new(VecDeque::new()),
            uploads: Mutex::new(VecDeque::new()),
            next_upload: 1.into(),
        })
    }

    /// Names of the corpus materials, sorted.
    pub fn corpus_names(&self) -> Vec<String> {
        self.sources.keys().cloned().collect()
    }

    /// Names of the uploads kept, oldest first.
    pub fn upload_names(&self) -> Vec<String> {
        lock(&self.uploads).iter().map(|(n, _)| n.clone()).collect()
    }

    /// Whether `name` is a corpus material.
    pub fn is_corpus(&self, name: &str) -> bool {
        self.sources.contains_key(name)
    }

    /// A corpus material or an upload by name (decoded on first use, then cached).
    pub fn get(&self, name: &str) -> Result<Shared> {
        check_name(name)?;
        if let Some((_, t)) = lock(&self.uploads).iter().find(|(n, _)| n == name) {
            return Ok(t.clone() as Shared);
        }
        let source = self
            .sources
            .get(name)
            .ok_or_else(|| ServeError::UnknownMaterial(name.into()))?;
        {
            let mut c = lock(&self.cache);
            if let Some(i) = c.iter().position(|(n, _)| n == name) {
                let e = c.remove(i).expect("index in range");
                let b = e.1.clone();
                c.push_back(e);
                return Ok(b);
            }
        }
        let m: Shared = Arc::new(source.load()?);
        let mut c = lock(&self.cache);
        c.push_back((name.to_string(), m.clone()));
        while c.len() > CACHE_CAPACITY {
            c.pop_front();
        }
        Ok(m)
    }

    /// The corpus material's source (for tabulation through the fast decoder).
    pub fn source(&self, name: &str) -> Option<&Source> {
        self.sources.get(name)
    }

    /// An upload: the bytes of a MERL `.binary` file, parsed and checked (size, header,
    /// finite values). It is kept in memory under a new name `upload-N-<stem>` and never
    /// written anywhere.
    pub fn add_upload(&self, file_name: &str, bytes: &[u8]) -> Result<String> {
        let table =
            brdf::merl::parse(bytes, Path::new(file_name)).map_err(ServeError::from_merl)?;
        let stem = upload_stem(file_name);
        let n = self
            .next_upload
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let name = if stem.is_empty() {
            format!("upload-{n}")
        } else {
            format!("upload-{n}-{stem}")
        };
        let mut u = lock(&self.uploads);
        u.push_back((name.clone(), Arc::new(table.with_name(name.clone()))));
        while u.len() > MAX_UPLOADS {
            u.pop_front();
        }
        Ok(name)
    }

    /// The table of an upload.
    pub fn upload_table(&self, name: &str) -> Option<Arc<MerlTable>> {
        lock(&self.uploads)
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, t)| t.clone())
    }
}

/// Locks a mutex, recovering the data if a panicking thread poisoned it.
pub(crate) fn lock<T>(m: &Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_that_could_reach_outside_are_refused() {
        for bad in [
            "",
            "..",
            "../etc/passwd",
            "..%2f..%2fetc",
            "a/b",
            "a\\b",
            "/abs",
            ".hidden",
            "a..b",
            "nul\0",
            "sp ace",
            "new\nline",
            &"x".repeat(MAX_NAME_LEN + 1),
        ] {
            assert!(
                matches!(check_name(bad), Err(ServeError::InvalidName(_))),
                "{bad:?} accepted"
            );
        }
        for good in [
            "blue-acrylic",
            "upload-3-x",
            "edit:12",
            "cherry-235",
            "a.b_c",
        ] {
            assert_eq!(check_name(good).unwrap(), good);
        }
    }

    #[test]
    fn uploads_are_checked_and_kept_in_memory_only() {
        let dir = tempfile::tempdir().unwrap();
        let lib = Library::open(Some(dir.path())).err();
        // An empty directory is not a corpus.
        assert!(lib.is_some());
        let lib = Library::open(None).unwrap();
        let g = brdf::analytic::Lambert {
            kd: [0.5, 0.4, 0.3],
        };
        let t = MerlTable::tabulate(&g);
        let bytes = brdf::merl::to_bytes(&t);
        let name = lib.add_upload("../../evil/x.binary", &bytes).unwrap();
        assert_eq!(name, "upload-1-x");
        let back = lib.upload_table(&name).unwrap();
        assert_eq!(back.raw(), t.raw());
        // Wrong size, bad header, NaN: typed errors with their kinds.
        let e = lib.add_upload("short", &bytes[..1000]).unwrap_err();
        assert_eq!(e.kind(), "wrong-size", "{e}");
        let mut hdr = bytes.clone();
        hdr[0..4].copy_from_slice(&91i32.to_le_bytes());
        assert_eq!(lib.add_upload("h", &hdr).unwrap_err().kind(), "bad-header");
        let mut nan = bytes.clone();
        nan[12 + 8 * 77..12 + 8 * 78].copy_from_slice(&f64::NAN.to_le_bytes());
        let e = lib.add_upload("n", &nan).unwrap_err();
        assert_eq!(e.kind(), "non-finite");
        assert!(e.to_string().contains("NaN"), "{e}");
        // Nothing was written into the (empty) directory.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    }
}

//! Atomic file writes with this crate's error type.

use crate::error::{BrdfError, Result};
use std::path::Path;

pub use atomic_write::write_atomic_with;

/// Writes `bytes` to `path` atomically (see [`write_atomic_with`]): the one way every crate of
/// the workspace writes a result file.
///
/// The writer lives in the `atomic-write` crate, so that crates needing nothing else of `brdf`
/// can use it; this wrapper reports failures as a [`BrdfError`] naming the path.
///
/// # Examples
///
/// ```
/// let path = std::env::temp_dir().join(format!("brdf-doc-{}.txt", std::process::id()));
/// brdf::write_atomic(&path, b"chrome")?;
/// assert_eq!(std::fs::read(&path).unwrap(), b"chrome");
/// # std::fs::remove_file(&path).unwrap();
/// # Ok::<(), brdf::BrdfError>(())
/// ```
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    atomic_write::write_atomic(path, bytes).map_err(|e| BrdfError::io(path, e))
}

/// Creates the folder `path` goes in (and its parents), as a job does before writing its
/// output; nothing to do for a bare file name.
pub fn create_parent_dir(path: &Path) -> Result<()> {
    match path.parent().filter(|d| !d.as_os_str().is_empty()) {
        Some(dir) => std::fs::create_dir_all(dir).map_err(|e| BrdfError::io(dir, e)),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writing_into_a_missing_directory_is_an_error_naming_the_path() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("absent").join("x.bin");
        let err = write_atomic(&path, b"x").unwrap_err();
        assert!(err.to_string().contains("x.bin"), "{err}");
        write_atomic(&dir.path().join("y.bin"), b"y").unwrap();
        assert_eq!(std::fs::read(dir.path().join("y.bin")).unwrap(), b"y");
        // after creating its folder the same write succeeds
        create_parent_dir(&path).unwrap();
        write_atomic(&path, b"x").unwrap();
        create_parent_dir(Path::new("bare.bin")).unwrap();
    }
}

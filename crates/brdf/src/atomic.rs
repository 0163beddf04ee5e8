//! Atomic file writes: the one way every crate of the workspace writes a result file.
//!
//! The writer lives in the `atomic-write` crate (so crates that need nothing else of `brdf`
//! can use it); this module gives it the error type of this crate.

use crate::error::{BrdfError, Result};
use std::path::Path;

pub use atomic_write::write_atomic_with;

/// Writes `bytes` to `path` atomically (see [`write_atomic_with`]).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    atomic_write::write_atomic(path, bytes).map_err(|e| BrdfError::io(path, e))
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
    }
}

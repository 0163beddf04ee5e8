//! Reading and writing MERL `.binary` files.
//!
//! Layout: three little-endian `i32` dimensions (90, 90, 180), then 3 × 1,458,000
//! little-endian `f64`, channel-major (all red, then green, then blue). Stored values are the BRDF
//! divided by the per-channel scale [`MERL_SCALE`](crate::table::MERL_SCALE); negative values
//! mark missing data.

use crate::atomic::write_atomic;
use crate::error::{BrdfError, Result};
use crate::table::{MerlTable, BINS, PHI_D_RES, THETA_D_RES, THETA_H_RES};
use std::path::Path;

/// Size in bytes of a MERL `.binary` file.
pub const FILE_SIZE: u64 = 12 + 3 * BINS as u64 * 8;

/// Reads a MERL `.binary` file.
pub fn read(path: impl AsRef<Path>) -> Result<MerlTable> {
    let path = path.as_ref();
    let bytes = std::fs::read(path).map_err(|e| BrdfError::io(path, e))?;
    let name = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "table".into());
    Ok(parse(&bytes, path)?.with_name(name))
}

/// Parses the bytes of a MERL `.binary` file; `path` only names the source in errors.
pub fn parse(bytes: &[u8], path: &Path) -> Result<MerlTable> {
    if bytes.len() < 12 {
        return Err(BrdfError::Truncated {
            path: path.into(),
            expected: FILE_SIZE,
            found: bytes.len() as u64,
        });
    }
    let dim = |k: usize| i32::from_le_bytes(bytes[4 * k..4 * k + 4].try_into().unwrap_or([0; 4]));
    let dims = [dim(0) as i64, dim(1) as i64, dim(2) as i64];
    if dims != [THETA_H_RES as i64, THETA_D_RES as i64, PHI_D_RES as i64] {
        return Err(BrdfError::BadDimensions {
            path: path.into(),
            dims,
        });
    }
    let found = bytes.len() as u64;
    if found < FILE_SIZE {
        return Err(BrdfError::Truncated {
            path: path.into(),
            expected: FILE_SIZE,
            found,
        });
    }
    if found > FILE_SIZE {
        return Err(BrdfError::TrailingBytes {
            path: path.into(),
            extra: found - FILE_SIZE,
        });
    }
    let raw: Vec<f64> = bytes[12..]
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap_or([0; 8])))
        .collect();
    if let Some(index) = raw.iter().position(|v| !v.is_finite()) {
        return Err(BrdfError::NonFinite {
            path: path.into(),
            index,
        });
    }
    MerlTable::from_raw(raw)
}

/// The bytes of a MERL `.binary` file holding `table`.
pub fn to_bytes(table: &MerlTable) -> Vec<u8> {
    let mut out = Vec::with_capacity(FILE_SIZE as usize);
    for d in [THETA_H_RES, THETA_D_RES, PHI_D_RES] {
        out.extend_from_slice(&(d as i32).to_le_bytes());
    }
    for v in table.raw() {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

/// Writes `table` as a MERL `.binary` file atomically (temporary file in the same directory,
/// then rename), so that a reader never sees a partial file.
pub fn write(path: impl AsRef<Path>, table: &MerlTable) -> Result<()> {
    write_atomic(path.as_ref(), &to_bytes(table))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Brdf;
    use proptest::prelude::*;

    fn sample_table() -> MerlTable {
        let mut t = MerlTable::missing();
        for bin in (0..BINS).step_by(7) {
            for c in 0..3 {
                t.set(c, bin, (bin % 1000) as f64 * 0.013 + c as f64);
            }
        }
        t
    }

    #[test]
    fn write_then_read_is_byte_exact() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.binary");
        let t = sample_table();
        write(&p, &t).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        assert_eq!(bytes.len() as u64, FILE_SIZE);
        let back = read(&p).unwrap();
        assert_eq!(back.raw(), t.raw());
        let p2 = dir.path().join("b.binary");
        write(&p2, &back).unwrap();
        assert_eq!(std::fs::read(&p2).unwrap(), bytes);
        assert_eq!(back.name(), "a");
    }

    #[test]
    fn malformed_files_are_typed_errors() {
        let good = to_bytes(&sample_table());
        let p = Path::new("x.binary");
        assert!(matches!(
            parse(&good[..5], p),
            Err(BrdfError::Truncated { .. })
        ));
        assert!(matches!(
            parse(&good[..good.len() - 3], p),
            Err(BrdfError::Truncated { .. })
        ));
        let mut long = good.clone();
        long.push(0);
        assert!(matches!(
            parse(&long, p),
            Err(BrdfError::TrailingBytes { extra: 1, .. })
        ));
        let mut dims = good.clone();
        dims[0..4].copy_from_slice(&(-5i32).to_le_bytes());
        assert!(matches!(
            parse(&dims, p),
            Err(BrdfError::BadDimensions { .. })
        ));
        let mut huge = good.clone();
        huge[8..12].copy_from_slice(&i32::MAX.to_le_bytes());
        assert!(matches!(
            parse(&huge, p),
            Err(BrdfError::BadDimensions { .. })
        ));
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let mut nan = good.clone();
            nan[12 + 8 * 1234..12 + 8 * 1235].copy_from_slice(&bad.to_le_bytes());
            assert!(matches!(
                parse(&nan, p),
                Err(BrdfError::NonFinite { index: 1234, .. })
            ));
        }
        assert!(matches!(
            read("/nonexistent/dir/x.binary"),
            Err(BrdfError::Io { .. })
        ));
    }

    proptest! {
        #![proptest_config(ProptestConfig {
        rng_seed: proptest::test_runner::RngSeed::Fixed(20261122),
        ..ProptestConfig::with_cases(256)
    })]
        #[test]
        fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..4096)) {
            prop_assert!(parse(&bytes, Path::new("fuzz")).is_err());
        }

        #[test]
        fn valid_header_with_arbitrary_tail_never_panics(tail in proptest::collection::vec(any::<u8>(), 0..4096)) {
            let mut bytes = Vec::new();
            for d in [90i32, 90, 180] { bytes.extend_from_slice(&d.to_le_bytes()); }
            bytes.extend_from_slice(&tail);
            let truncated = matches!(parse(&bytes, Path::new("fuzz")), Err(BrdfError::Truncated { .. }));
            prop_assert!(truncated);
        }
    }
}

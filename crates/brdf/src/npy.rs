//! A minimal reader for NumPy `.npy` files holding little-endian float arrays in C order.

use crate::error::{BrdfError, Result};
use std::path::Path;

/// A dense array read from a `.npy` file, converted to `f32`.
#[derive(Debug, Clone, PartialEq)]
pub struct NpyArray {
    /// Dimensions, outermost first.
    pub shape: Vec<usize>,
    /// Values in C (row-major) order.
    pub data: Vec<f32>,
}

/// Reads a `.npy` file with dtype `<f4` or `<f8`, C order.
pub fn read(path: impl AsRef<Path>) -> Result<NpyArray> {
    let path = path.as_ref();
    let bytes = std::fs::read(path).map_err(|e| BrdfError::io(path, e))?;
    parse(&bytes, path)
}

/// Parses the bytes of a `.npy` file; `path` only names the source in errors.
pub fn parse(bytes: &[u8], path: &Path) -> Result<NpyArray> {
    let err = |reason: &str| BrdfError::Npy {
        path: path.into(),
        reason: reason.into(),
    };
    if bytes.len() < 10 || &bytes[..6] != b"\x93NUMPY" {
        return Err(err("missing \\x93NUMPY magic"));
    }
    let major = bytes[6];
    let (header_len, start) = match major {
        1 => (u16::from_le_bytes([bytes[8], bytes[9]]) as usize, 10usize),
        2 | 3 => {
            if bytes.len() < 12 {
                return Err(err("truncated header length"));
            }
            (
                u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]) as usize,
                12,
            )
        }
        v => return Err(err(&format!("unsupported format version {v}"))),
    };
    let end = start
        .checked_add(header_len)
        .filter(|&e| e <= bytes.len())
        .ok_or_else(|| err("truncated header"))?;
    let header = std::str::from_utf8(&bytes[start..end]).map_err(|_| err("header is not text"))?;
    let descr = dict_value(header, "descr").ok_or_else(|| err("no 'descr' in header"))?;
    let descr = descr.trim().trim_matches(|c| c == '\'' || c == '"');
    let fortran = dict_value(header, "fortran_order").ok_or_else(|| err("no 'fortran_order'"))?;
    if fortran.trim() != "False" {
        return Err(err("Fortran-ordered arrays are not supported"));
    }
    let shape_text = dict_value(header, "shape").ok_or_else(|| err("no 'shape' in header"))?;
    let shape = parse_shape(shape_text).ok_or_else(|| err("unreadable shape"))?;
    let count = shape
        .iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d))
        .ok_or_else(|| err("shape too large"))?;
    let body = &bytes[end..];
    let width = match descr {
        "<f4" => 4,
        "<f8" => 8,
        other => return Err(err(&format!("unsupported dtype {other} (need <f4 or <f8)"))),
    };
    let need = count
        .checked_mul(width)
        .ok_or_else(|| err("shape too large"))?;
    if body.len() != need {
        return Err(err(&format!(
            "data has {} bytes, shape {:?} needs {need}",
            body.len(),
            shape
        )));
    }
    let data: Vec<f32> = if width == 4 {
        body.chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect()
    } else {
        body.chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().unwrap_or([0; 8])) as f32)
            .collect()
    };
    if let Some(index) = data.iter().position(|v| !v.is_finite()) {
        return Err(BrdfError::NonFinite {
            path: path.into(),
            index,
        });
    }
    Ok(NpyArray { shape, data })
}

/// The text of the value of `key` in a Python dict literal (up to the next top-level comma).
fn dict_value<'a>(header: &'a str, key: &str) -> Option<&'a str> {
    let pat_single = format!("'{key}'");
    let pat_double = format!("\"{key}\"");
    let pos = header
        .find(&pat_single)
        .map(|p| p + pat_single.len())
        .or_else(|| header.find(&pat_double).map(|p| p + pat_double.len()))?;
    let rest = header[pos..].trim_start().strip_prefix(':')?;
    let mut depth = 0i32;
    for (i, ch) in rest.char_indices() {
        match ch {
            '(' | '[' => depth += 1,
            ')' | ']' => depth -= 1,
            ',' | '}' if depth == 0 => return Some(&rest[..i]),
            _ => {}
        }
    }
    None
}

fn parse_shape(text: &str) -> Option<Vec<usize>> {
    let inner = text.trim().strip_prefix('(')?.strip_suffix(')')?;
    inner
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(|s| s.parse().ok())
        .collect()
}

/// Serialises a C-ordered `f32` array as `.npy` (version 1.0), as NumPy would.
pub fn to_bytes(shape: &[usize], data: &[f32]) -> Vec<u8> {
    let dims: Vec<String> = shape.iter().map(|d| d.to_string()).collect();
    let shape_txt = if dims.len() == 1 {
        format!("({},)", dims[0])
    } else {
        format!("({})", dims.join(", "))
    };
    let mut header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': {shape_txt}, }}");
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    for v in data {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn round_trip() {
        let data: Vec<f32> = (0..126).map(|i| i as f32 * 0.5 - 3.0).collect();
        let bytes = to_bytes(&[6, 21], &data);
        let a = parse(&bytes, Path::new("t.npy")).unwrap();
        assert_eq!(a.shape, vec![6, 21]);
        assert_eq!(a.data, data);
        let b = parse(&to_bytes(&[3], &data[..3]), Path::new("t.npy")).unwrap();
        assert_eq!(b.shape, vec![3]);
    }

    #[test]
    fn rejects_wrong_sizes_and_types() {
        let data = vec![1.0f32; 6];
        let mut bytes = to_bytes(&[2, 3], &data);
        bytes.pop();
        assert!(parse(&bytes, Path::new("t")).is_err());
        let mut ints = to_bytes(&[2, 3], &data);
        let at = ints.windows(3).position(|w| w == b"<f4").unwrap();
        ints[at + 1] = b'i';
        assert!(parse(&ints, Path::new("t")).is_err());
    }

    proptest! {
        #![proptest_config(ProptestConfig {
            rng_seed: proptest::test_runner::RngSeed::Fixed(20261122),
            ..ProptestConfig::default()
        })]
        #[test]
        fn arbitrary_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
            let _ = parse(&bytes, Path::new("fuzz"));
        }
    }
}

//! The tensor file container: a header of named fields (name, rank, element type, offset,
//! shape), then the fields' data, all little-endian.

use crate::error::{Result, RglError};

/// Magic bytes at the start of every tensor file (`tensor_file` and a NUL).
pub const MAGIC: &[u8; 12] = b"tensor_file\0";

/// The largest rank a field may declare (the `.bsdf` fields have ranks 1 to 5).
pub const MAX_RANK: usize = 8;

/// Element type of a field, with the codes the format uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dtype {
    /// `uint8` (code 1).
    U8,
    /// `int8` (code 2).
    I8,
    /// `uint16` (code 3).
    U16,
    /// `int16` (code 4).
    I16,
    /// `uint32` (code 5).
    U32,
    /// `int32` (code 6).
    I32,
    /// `uint64` (code 7).
    U64,
    /// `int64` (code 8).
    I64,
    /// `float16` (code 9).
    F16,
    /// `float32` (code 10).
    F32,
    /// `float64` (code 11).
    F64,
}

impl Dtype {
    /// The type of a code, if the format defines it.
    pub fn from_code(code: u8) -> Option<Dtype> {
        use Dtype::*;
        Some(match code {
            1 => U8,
            2 => I8,
            3 => U16,
            4 => I16,
            5 => U32,
            6 => I32,
            7 => U64,
            8 => I64,
            9 => F16,
            10 => F32,
            11 => F64,
            _ => return None,
        })
    }

    /// The format's code of this type.
    pub fn code(self) -> u8 {
        use Dtype::*;
        match self {
            U8 => 1,
            I8 => 2,
            U16 => 3,
            I16 => 4,
            U32 => 5,
            I32 => 6,
            U64 => 7,
            I64 => 8,
            F16 => 9,
            F32 => 10,
            F64 => 11,
        }
    }

    /// Bytes per element.
    pub fn size(self) -> usize {
        use Dtype::*;
        match self {
            U8 | I8 => 1,
            U16 | I16 | F16 => 2,
            U32 | I32 | F32 => 4,
            U64 | I64 | F64 => 8,
        }
    }
}

/// One named field of a tensor file.
#[derive(Debug, Clone, PartialEq)]
pub struct Field {
    /// Field name (`"theta_i"`, `"vndf"` ...).
    pub name: String,
    /// Element type.
    pub dtype: Dtype,
    /// Extent of each dimension, slowest first (row-major).
    pub shape: Vec<usize>,
    /// Raw little-endian element data, `shape.product() × dtype.size()` bytes.
    pub data: Vec<u8>,
}

impl Field {
    /// A `float32` field.
    pub fn f32(name: &str, shape: &[usize], values: &[f32]) -> Field {
        debug_assert_eq!(shape.iter().product::<usize>(), values.len());
        Field {
            name: name.into(),
            dtype: Dtype::F32,
            shape: shape.to_vec(),
            data: values.iter().flat_map(|v| v.to_le_bytes()).collect(),
        }
    }

    /// A `uint8` field.
    pub fn u8(name: &str, shape: &[usize], values: &[u8]) -> Field {
        debug_assert_eq!(shape.iter().product::<usize>(), values.len());
        Field {
            name: name.into(),
            dtype: Dtype::U8,
            shape: shape.to_vec(),
            data: values.to_vec(),
        }
    }

    /// Number of elements.
    pub fn len(&self) -> usize {
        self.shape.iter().product()
    }

    /// Whether the field holds no element.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The values of a `float32` field, refused when any is NaN or infinite.
    pub fn to_f32(&self) -> Result<Vec<f32>> {
        if self.dtype != Dtype::F32 {
            return Err(RglError::Field {
                field: self.name.clone(),
                reason: format!("expected float32 elements, found {:?}", self.dtype),
            });
        }
        let values: Vec<f32> = self
            .data
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            return Err(RglError::Field {
                field: self.name.clone(),
                reason: format!("element {i} is {}", values[i]),
            });
        }
        Ok(values)
    }

    /// The bytes of a `uint8` field.
    pub fn to_u8(&self) -> Result<&[u8]> {
        if self.dtype != Dtype::U8 {
            return Err(RglError::Field {
                field: self.name.clone(),
                reason: format!("expected uint8 elements, found {:?}", self.dtype),
            });
        }
        Ok(&self.data)
    }
}

/// A tensor file: named fields of typed, shaped data.
///
/// # Examples
///
/// ```
/// use rgl_bsdf::{Field, TensorFile};
///
/// let mut file = TensorFile::default();
/// file.push(Field::f32("theta_i", &[3], &[0.0, 0.5, 1.0]));
/// file.push(Field::u8("description", &[4], b"test"));
/// let bytes = file.to_bytes();
/// let back = TensorFile::parse(&bytes).unwrap();
/// assert_eq!(back, file);
/// assert_eq!(back.field("theta_i").unwrap().to_f32().unwrap(), vec![0.0, 0.5, 1.0]);
/// // a truncated file is a typed error, not a panic
/// assert!(TensorFile::parse(&bytes[..bytes.len() - 1]).is_err());
/// ```
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TensorFile {
    fields: Vec<Field>,
}

/// Alignment of each field's data in a written file.
const ALIGN: usize = 8;

impl TensorFile {
    /// The fields, in file order.
    pub fn fields(&self) -> &[Field] {
        &self.fields
    }

    /// The field called `name`.
    pub fn field(&self, name: &str) -> Option<&Field> {
        self.fields.iter().find(|f| f.name == name)
    }

    /// The field called `name`, or a [`RglError::MissingField`].
    pub fn require(&self, name: &str) -> Result<&Field> {
        self.field(name)
            .ok_or_else(|| RglError::MissingField(name.into()))
    }

    /// Adds a field (replacing one of the same name).
    pub fn push(&mut self, field: Field) {
        self.fields.retain(|f| f.name != field.name);
        self.fields.push(field);
    }

    /// Parses a tensor file. Every size the header declares is checked against the bytes
    /// present before anything is allocated for it.
    pub fn parse(bytes: &[u8]) -> Result<TensorFile> {
        let mut r = Cursor { bytes, pos: 0 };
        let magic = r.take(12)?;
        if magic != MAGIC {
            return Err(RglError::Header(
                "not a tensor file (bad magic bytes)".into(),
            ));
        }
        let version = r.take(2)?;
        if version != [1, 0] {
            return Err(RglError::Header(format!(
                "unsupported tensor file version {}.{}",
                version[0], version[1]
            )));
        }
        let count = r.u32()? as usize;
        // the smallest field header is 13 bytes (name length, rank, type, offset)
        if count > bytes.len() / 13 {
            return Err(RglError::Header(format!(
                "{count} fields cannot fit in {} bytes",
                bytes.len()
            )));
        }
        let mut fields = Vec::with_capacity(count);
        for _ in 0..count {
            let name_len = r.u16()? as usize;
            let name = std::str::from_utf8(r.take(name_len)?)
                .map_err(|_| RglError::Header("a field name is not UTF-8".into()))?
                .to_string();
            let rank = r.u16()? as usize;
            if rank > MAX_RANK {
                return Err(RglError::Field {
                    field: name,
                    reason: format!("rank {rank} exceeds {MAX_RANK}"),
                });
            }
            let code = r.take(1)?[0];
            let dtype = Dtype::from_code(code).ok_or_else(|| RglError::Field {
                field: name.clone(),
                reason: format!("unknown element type code {code}"),
            })?;
            let offset = r.u64()?;
            let mut shape = Vec::with_capacity(rank);
            let mut elements: u64 = 1;
            for _ in 0..rank {
                let n = r.u64()?;
                elements = elements.checked_mul(n).ok_or_else(|| RglError::Field {
                    field: name.clone(),
                    reason: "shape overflows".into(),
                })?;
                shape.push(n);
            }
            let size = elements
                .checked_mul(dtype.size() as u64)
                .filter(|s| {
                    offset
                        .checked_add(*s)
                        .is_some_and(|end| end <= bytes.len() as u64)
                })
                .ok_or_else(|| RglError::Field {
                    field: name.clone(),
                    reason: format!(
                        "{elements} elements of {dtype:?} at offset {offset} lie past the end of the {}-byte file",
                        bytes.len()
                    ),
                })?;
            if fields.iter().any(|f: &Field| f.name == name) {
                return Err(RglError::Field {
                    field: name,
                    reason: "appears twice".into(),
                });
            }
            let start = offset as usize;
            fields.push(Field {
                name,
                dtype,
                shape: shape.into_iter().map(|n| n as usize).collect(),
                data: bytes[start..start + size as usize].to_vec(),
            });
        }
        Ok(TensorFile { fields })
    }

    /// Reads and parses a tensor file.
    pub fn read(path: impl AsRef<std::path::Path>) -> Result<TensorFile> {
        let path = path.as_ref();
        let bytes = std::fs::read(path).map_err(|source| RglError::Io {
            path: path.display().to_string(),
            source,
        })?;
        TensorFile::parse(&bytes)
    }

    /// The file's bytes: the header, then each field's data aligned to 8 bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        let header: usize = 12
            + 2
            + 4
            + self
                .fields
                .iter()
                .map(|f| 2 + f.name.len() + 2 + 1 + 8 + 8 * f.shape.len())
                .sum::<usize>();
        let mut offsets = Vec::with_capacity(self.fields.len());
        let mut end = header;
        for f in &self.fields {
            end = end.div_ceil(ALIGN) * ALIGN;
            offsets.push(end);
            end += f.data.len();
        }
        let mut out = Vec::with_capacity(end);
        out.extend_from_slice(MAGIC);
        out.extend_from_slice(&[1, 0]);
        out.extend_from_slice(&(self.fields.len() as u32).to_le_bytes());
        for (f, offset) in self.fields.iter().zip(&offsets) {
            out.extend_from_slice(&(f.name.len() as u16).to_le_bytes());
            out.extend_from_slice(f.name.as_bytes());
            out.extend_from_slice(&(f.shape.len() as u16).to_le_bytes());
            out.push(f.dtype.code());
            out.extend_from_slice(&(*offset as u64).to_le_bytes());
            for &n in &f.shape {
                out.extend_from_slice(&(n as u64).to_le_bytes());
            }
        }
        for (f, offset) in self.fields.iter().zip(&offsets) {
            out.resize(*offset, 0);
            out.extend_from_slice(&f.data);
        }
        out
    }

    /// Writes the file atomically (temporary file, then rename).
    pub fn write(&self, path: impl AsRef<std::path::Path>) -> Result<()> {
        let path = path.as_ref();
        atomic_write::write_atomic(path, &self.to_bytes()).map_err(|source| RglError::Io {
            path: path.display().to_string(),
            source,
        })
    }
}

struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8]> {
        let end = self
            .pos
            .checked_add(n)
            .filter(|&e| e <= self.bytes.len())
            .ok_or_else(|| {
                RglError::Header(format!(
                    "truncated header: {n} bytes wanted at offset {} of {}",
                    self.pos,
                    self.bytes.len()
                ))
            })?;
        let s = &self.bytes[self.pos..end];
        self.pos = end;
        Ok(s)
    }
    fn u16(&mut self) -> Result<u16> {
        let b = self.take(2)?;
        Ok(u16::from_le_bytes([b[0], b[1]]))
    }
    fn u32(&mut self) -> Result<u32> {
        let b = self.take(4)?;
        Ok(u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }
    fn u64(&mut self) -> Result<u64> {
        let b = self.take(8)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(b);
        Ok(u64::from_le_bytes(a))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> TensorFile {
        let mut f = TensorFile::default();
        f.push(Field::f32("a", &[2, 3], &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0]));
        f.push(Field::u8("jacobian", &[1], &[1]));
        f.push(Field::f32("b", &[1], &[0.25]));
        f
    }

    #[test]
    fn round_trip_keeps_every_field_and_aligns_the_data() {
        let f = sample();
        let bytes = f.to_bytes();
        assert_eq!(TensorFile::parse(&bytes).unwrap(), f);
        // offsets are multiples of 8
        let parsed = TensorFile::parse(&bytes).unwrap();
        assert_eq!(parsed.field("a").unwrap().shape, vec![2, 3]);
    }

    #[test]
    fn every_truncation_is_an_error() {
        let bytes = sample().to_bytes();
        for n in 0..bytes.len() {
            assert!(TensorFile::parse(&bytes[..n]).is_err(), "length {n}");
        }
    }

    #[test]
    fn absurd_headers_are_refused_without_allocating() {
        let mut bytes = sample().to_bytes();
        // field count far beyond the file
        bytes[14..18].copy_from_slice(&u32::MAX.to_le_bytes());
        assert!(matches!(
            TensorFile::parse(&bytes),
            Err(RglError::Header(_))
        ));
        // a shape of 2^62 elements in the first field
        let mut bytes = sample().to_bytes();
        let shape_at = 18 + 2 + 1 + 2 + 1 + 8;
        bytes[shape_at..shape_at + 8].copy_from_slice(&(1u64 << 62).to_le_bytes());
        assert!(matches!(
            TensorFile::parse(&bytes),
            Err(RglError::Field { .. })
        ));
        // an unknown element type
        let mut bytes = sample().to_bytes();
        bytes[18 + 2 + 1 + 2] = 42;
        assert!(matches!(
            TensorFile::parse(&bytes),
            Err(RglError::Field { .. })
        ));
    }

    #[test]
    fn nan_values_and_wrong_types_are_refused_on_access() {
        let mut f = TensorFile::default();
        f.push(Field::f32("x", &[2], &[1.0, f32::NAN]));
        f.push(Field::u8("y", &[1], &[0]));
        let f = TensorFile::parse(&f.to_bytes()).unwrap();
        assert!(f.field("x").unwrap().to_f32().is_err());
        assert!(f.field("y").unwrap().to_f32().is_err());
        assert!(f.field("x").unwrap().to_u8().is_err());
        assert!(matches!(f.require("z"), Err(RglError::MissingField(_))));
    }
}

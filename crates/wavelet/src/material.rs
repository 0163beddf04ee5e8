//! Materials compressed onto a Common Wavelet Basis, their `.wtree` file and `wavelet:` spec.

use crate::cwb::{CommonBasis, Layout};
use crate::error::WaveletError;
use crate::tree::CoefficientTree;
use brdf::LogTransform;
use brdf::{Brdf, HalfDiff, MerlTable, Rgb, Vec3};
use brdf::{Material, SpecResolver};
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Magic bytes opening a `.wtree` file.
pub const WTREE_MAGIC: &[u8; 8] = b"GWTREE01";

/// The spec prefix of compressed materials: `wavelet:<file.wtree>`.
pub const SPEC_PREFIX: &str = "wavelet";

/// Errors of compressed materials.
#[derive(Debug, thiserror::Error)]
pub enum MaterialError {
    /// A file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        source: std::io::Error,
    },
    /// A malformed `.wtree` file or buffer.
    #[error("{origin}: malformed wavelet material ({reason})")]
    Format {
        /// The file, or `<bytes>` for a buffer.
        origin: String,
        /// What is wrong.
        reason: String,
    },
    /// An error of the basis or the coefficient tree.
    #[error(transparent)]
    Wavelet(#[from] WaveletError),
    /// An error of the `brdf` crate (loading or writing a material).
    #[error(transparent)]
    Brdf(#[from] brdf::BrdfError),
}

/// Result alias of this module.
pub type Result<T, E = MaterialError> = std::result::Result<T, E>;

/// The three log channels `ln(max(f, 0) + ε)` of a MERL table ([`brdf::to_log`]).
pub fn log_channels(table: &MerlTable) -> [Vec<f32>; 3] {
    let v = table.values();
    let n = brdf::BINS;
    [0, 1, 2].map(|c| {
        v[c * n..(c + 1) * n]
            .iter()
            .map(|&x| brdf::to_log(x) as f32)
            .collect()
    })
}

/// Builds the Common Wavelet Basis (Haar, MERL layout) of the log channels of `tables`,
/// keeping the relative L2 error `target` per channel (thesis §6.2).
pub fn build_basis(tables: &[MerlTable], target: f64) -> Result<CommonBasis> {
    let channels: Vec<Vec<f32>> = tables.iter().flat_map(log_channels).collect();
    let refs: Vec<&[f32]> = channels.iter().map(|c| c.as_slice()).collect();
    let (basis, _) = CommonBasis::build(Layout::MERL_HAAR, &refs, target)?;
    Ok(basis)
}

fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ *b as u64).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// A material compressed onto a Common Wavelet Basis: the basis and the coefficients of its
/// three log channels (the content of a `.wtree` file; thesis §6.1–6.2). Registered through
/// [`register_spec_resolver`], the `wavelet:<file.wtree>` spec names one as a material.
///
/// A material is represented by its three log channels `ln(max(f, 0) + ε)`
/// ([`brdf::LOG_FLOOR`], thesis §4.1): the relative-error target of the basis then
/// applies across the whole dynamic range rather than being spent on the specular peak. It is
/// compressed by projecting each channel onto a [`CommonBasis`] and evaluated through the
/// Common Wavelet Coefficient Tree, one traversal giving R, G and B ([`WaveletBrdf`]).
///
/// # The `.wtree` format
///
/// All integers and floats little-endian:
///
/// | bytes | content |
/// |---|---|
/// | 8 | magic `GWTREE01` |
/// | 8 | `u64` length `L` of the basis |
/// | `L` | the basis in the `CWBASIS1` format of [`CommonBasis::to_bytes`] |
/// | 8 | `u64` coefficient count `n` per channel (= the basis length) |
/// | 12 `n` | `f32` coefficients of R, then G, then B (log channels) |
/// | 8 | `u64` FNV-1a 64 hash of every byte before it |
///
/// A reader rejects a wrong magic, a checksum mismatch, lengths that do not add up, a
/// coefficient count other than the basis length and non-finite coefficients.
///
/// # Examples
///
/// ```
/// use brdf::Brdf;
/// use wavelet::{log_channels, CompressedMaterial, WaveletBrdf};
/// use wavelet::{CommonBasis, Layout, Wavelet};
///
/// // a small layout (a 4 × 4 × 8 corner of the MERL grid in a 16³ cube) keeps this fast
/// let layout = Layout { extent: [4, 4, 8], side: 16, wavelet: Wavelet::Haar };
/// let channel = |c: usize| -> Vec<f32> {
///     (0..layout.table_len()).map(|i| ((i % 7) as f32 * 0.1 + c as f32).ln_1p()).collect()
/// };
/// let channels = [channel(0), channel(1), channel(2)];
/// let refs: Vec<&[f32]> = channels.iter().map(|c| c.as_slice()).collect();
/// let (basis, _) = CommonBasis::build(layout, &refs, 0.0).unwrap(); // lossless
/// let m = CompressedMaterial::from_log_channels(basis, &channels).unwrap();
/// let bytes = m.to_bytes();
/// let back = CompressedMaterial::from_bytes(&bytes).unwrap();
/// assert_eq!(back, m);
/// let brdf = WaveletBrdf::new(&back, "demo").unwrap();
/// assert_eq!(brdf.name(), "demo");
/// # let _ = log_channels;
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct CompressedMaterial {
    basis: CommonBasis,
    coefficients: [Vec<f32>; 3],
}

impl CompressedMaterial {
    /// Compresses a MERL table onto `basis` (which must have the MERL layout).
    pub fn compress(basis: CommonBasis, table: &MerlTable) -> Result<Self> {
        Self::from_log_channels(basis, &log_channels(table))
    }

    /// Compresses three log channels (each of the basis layout's table length).
    pub fn from_log_channels(basis: CommonBasis, channels: &[Vec<f32>; 3]) -> Result<Self> {
        let coefficients = [
            basis.coefficients(&channels[0])?,
            basis.coefficients(&channels[1])?,
            basis.coefficients(&channels[2])?,
        ];
        Ok(Self {
            basis,
            coefficients,
        })
    }

    /// The basis.
    pub fn basis(&self) -> &CommonBasis {
        &self.basis
    }

    /// The coefficients of the R, G and B log channels (one per basis function).
    pub fn coefficients(&self) -> &[Vec<f32>; 3] {
        &self.coefficients
    }

    /// The reconstructed log channels on the basis layout's table.
    pub fn log_channels(&self) -> Result<[Vec<f32>; 3]> {
        Ok([
            self.basis.reconstruct(&self.coefficients[0])?,
            self.basis.reconstruct(&self.coefficients[1])?,
            self.basis.reconstruct(&self.coefficients[2])?,
        ])
    }

    /// Serialises to the `.wtree` format.
    pub fn to_bytes(&self) -> Vec<u8> {
        let b = self.basis.to_bytes();
        let mut out = WTREE_MAGIC.to_vec();
        out.extend_from_slice(&(b.len() as u64).to_le_bytes());
        out.extend_from_slice(&b);
        out.extend_from_slice(&(self.basis.len() as u64).to_le_bytes());
        for c in &self.coefficients {
            for v in c {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
        let h = fnv1a(&out);
        out.extend_from_slice(&h.to_le_bytes());
        out
    }

    /// Parses the `.wtree` format.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self> {
        Self::parse(bytes, "<bytes>")
    }

    fn parse(bytes: &[u8], origin: &str) -> Result<Self> {
        let bad = |reason: &str| MaterialError::Format {
            origin: origin.into(),
            reason: reason.into(),
        };
        let u64_at = |b: &[u8], at: usize| -> Option<u64> {
            b.get(at..at.checked_add(8)?)
                .map(|s| u64::from_le_bytes(s.try_into().expect("8 bytes")))
        };
        if bytes.len() < 8 + 8 + 8 + 8 || &bytes[..8] != WTREE_MAGIC {
            return Err(bad("magic"));
        }
        let (body, tail) = bytes.split_at(bytes.len() - 8);
        if u64_at(tail, 0) != Some(fnv1a(body)) {
            return Err(bad("checksum"));
        }
        let blen = u64_at(body, 8).ok_or_else(|| bad("length"))?;
        let bend = usize::try_from(blen)
            .ok()
            .and_then(|l| l.checked_add(16))
            .filter(|e| e.checked_add(8).is_some_and(|x| x <= body.len()))
            .ok_or_else(|| bad("length"))?;
        let basis = CommonBasis::from_bytes(&body[16..bend])?;
        let n = u64_at(body, bend).ok_or_else(|| bad("length"))?;
        let data = &body[bend + 8..];
        if n != basis.len() as u64 || data.len() as u64 != 12 * n {
            return Err(bad("coefficient count"));
        }
        let n = basis.len();
        let channel = |c: usize| -> Vec<f32> {
            data[c * 4 * n..(c + 1) * 4 * n]
                .chunks_exact(4)
                .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                .collect()
        };
        let coefficients = [channel(0), channel(1), channel(2)];
        if coefficients.iter().flatten().any(|v| !v.is_finite()) {
            return Err(bad("non-finite coefficient"));
        }
        Ok(Self {
            basis,
            coefficients,
        })
    }

    /// Writes a `.wtree` file atomically.
    pub fn write(&self, path: impl AsRef<Path>) -> Result<()> {
        brdf::write_atomic(path.as_ref(), &self.to_bytes())?;
        Ok(())
    }

    /// Reads a `.wtree` file.
    pub fn read(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let bytes = std::fs::read(path).map_err(|source| MaterialError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&bytes, &path.display().to_string())
    }
}

/// A compressed material evaluated from its Common Wavelet Coefficient Tree: one tree
/// traversal per lookup gives the three log channels, returned as BRDF values
/// `max(exp(y) − ε, 0)`. The tree is piecewise constant on the MERL bins (Haar basis).
#[derive(Debug)]
pub struct WaveletBrdf {
    name: String,
    tree: CoefficientTree,
}

impl WaveletBrdf {
    /// Builds the coefficient tree of a compressed material.
    pub fn new(material: &CompressedMaterial, name: impl Into<String>) -> Result<Self> {
        let tree = CoefficientTree::new(&material.basis, &material.coefficients)?;
        Ok(Self {
            name: name.into(),
            tree,
        })
    }

    /// Reads a `.wtree` file (the material is named after the file stem).
    pub fn read(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let material = CompressedMaterial::read(path)?;
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "wavelet".into());
        Self::new(&material, name)
    }

    /// The coefficient tree.
    pub fn tree(&self) -> &CoefficientTree {
        &self.tree
    }
}

impl Brdf for WaveletBrdf {
    fn eval(&self, wi: &Vec3, wo: &Vec3) -> Rgb {
        if wi.z < 0.0 || wo.z < 0.0 {
            return [0.0; 3];
        }
        self.eval_half_diff(&HalfDiff::from_directions(wi, wo))
    }

    fn eval_half_diff(&self, hd: &HalfDiff) -> Rgb {
        let mut out = [0.0f32; 3];
        if self
            .tree
            .eval_angles(hd.theta_h, hd.theta_d, hd.phi_d, &mut out)
            .is_err()
        {
            return [0.0; 3];
        }
        out.map(|v| LogTransform::DEFAULT.inverse_clamped(v as f64))
    }

    fn name(&self) -> String {
        self.name.clone()
    }
}

/// The resolver of `wavelet:<file.wtree>` specs (a relative path is relative to the working
/// directory).
#[derive(Debug, Default, Clone, Copy)]
pub struct WaveletSpecs;

impl SpecResolver for WaveletSpecs {
    fn prefix(&self) -> &str {
        SPEC_PREFIX
    }

    fn form(&self) -> &str {
        "wavelet:<file.wtree>"
    }

    fn load(&self, spec: &str, rest: &str) -> brdf::Result<Material> {
        if rest.is_empty() {
            return Err(brdf::spec_error(spec, "expected wavelet:<file.wtree>"));
        }
        let m = WaveletBrdf::read(rest).map_err(|e| brdf::resolver_error(spec, e))?;
        Ok(Material::Resolved(Box::new(m)))
    }
}

/// Registers [`WaveletSpecs`] so that every material spec accepts `wavelet:<file.wtree>`
/// (idempotent).
pub fn register_spec_resolver() {
    brdf::register(Arc::new(WaveletSpecs)).expect("`wavelet` is a valid, free prefix");
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small() -> (Layout, [Vec<f32>; 3]) {
        let layout = Layout {
            extent: [4, 4, 8],
            side: 16,
            wavelet: crate::Wavelet::Haar,
        };
        let ch = |c: usize| -> Vec<f32> {
            (0..layout.table_len())
                .map(|i| ((i * (c + 3)) % 11) as f32 * 0.25 - 1.0)
                .collect()
        };
        (layout, [ch(0), ch(1), ch(2)])
    }

    fn compressed() -> CompressedMaterial {
        let (layout, ch) = small();
        let refs: Vec<&[f32]> = ch.iter().map(|c| c.as_slice()).collect();
        let (basis, _) = CommonBasis::build(layout, &refs, 0.0).unwrap();
        CompressedMaterial::from_log_channels(basis, &ch).unwrap()
    }

    #[test]
    fn lossless_basis_reconstructs_the_channels_and_bytes_round_trip() {
        let (_, ch) = small();
        let m = compressed();
        let back = CompressedMaterial::from_bytes(&m.to_bytes()).unwrap();
        assert_eq!(back, m);
        let rec = back.log_channels().unwrap();
        for (a, b) in rec.iter().zip(&ch) {
            let err = a
                .iter()
                .zip(b)
                .map(|(x, y)| (x - y).abs())
                .fold(0.0f32, f32::max);
            assert!(err < 1e-4, "{err}");
        }
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.wtree");
        m.write(&p).unwrap();
        assert_eq!(CompressedMaterial::read(&p).unwrap(), m);
        assert_eq!(WaveletBrdf::read(&p).unwrap().name(), "m");
    }

    #[test]
    fn bad_inputs_are_typed_errors() {
        let good = compressed().to_bytes();
        let format = |b: &[u8]| {
            matches!(
                CompressedMaterial::from_bytes(b),
                Err(MaterialError::Format { .. })
            )
        };
        assert!(format(&[]), "empty");
        assert!(format(&good[..20]), "short");
        let mut magic = good.clone();
        magic[0] = b'X';
        assert!(format(&magic), "magic");
        let mut flipped = good.clone();
        flipped[40] ^= 1;
        assert!(format(&flipped), "checksum");
        assert!(format(&good[..good.len() - 1]), "truncated");
        // a consistent checksum over inconsistent lengths
        let rehash = |mut b: Vec<u8>| {
            b.truncate(b.len() - 8);
            let h = fnv1a(&b);
            b.extend_from_slice(&h.to_le_bytes());
            b
        };
        let mut long_basis = good.clone();
        long_basis[8..16].copy_from_slice(&u64::MAX.to_le_bytes());
        assert!(format(&rehash(long_basis)), "basis length");
        let mut extra = good[..good.len() - 8].to_vec();
        extra.extend_from_slice(&[0; 4]);
        extra.extend_from_slice(&[0; 8]);
        assert!(format(&rehash(extra)), "coefficient count");
        let mut nan = good.clone();
        let at = good.len() - 12;
        nan[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
        assert!(format(&rehash(nan)), "non-finite");
        assert!(matches!(
            CompressedMaterial::read("/nonexistent/x.wtree"),
            Err(MaterialError::Io { .. })
        ));
        // a table of the wrong layout
        let basis = compressed().basis().clone();
        let t = MerlTable::tabulate(&brdf::analytic::Lambert { kd: [0.5; 3] });
        assert!(matches!(
            CompressedMaterial::compress(basis, &t),
            Err(MaterialError::Wavelet(_))
        ));
    }

    #[test]
    fn wavelet_specs_load_through_the_registry() {
        register_spec_resolver();
        register_spec_resolver();
        assert!(brdf::load("wavelet:").is_err());
        let e = brdf::load("wavelet:/nonexistent/x.wtree").unwrap_err();
        assert!(matches!(e, brdf::BrdfError::Resolver { .. }), "{e}");
        assert!(e.to_string().contains("x.wtree"), "{e}");
    }
}

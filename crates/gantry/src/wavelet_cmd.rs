//! `gantry wavelet basis|compress`: the Common Wavelet Basis of a corpus (seed §6.1–6.2) and
//! materials compressed onto it, which render evaluates through the Common Wavelet Coefficient
//! Tree (one traversal gives R, G and B). Channels are represented in log space,
//! ln(f + 10⁻³), as the model of §4.1 does.
//!
//! A compressed material (`.wtree`) holds its basis and the coefficients of its three channels:
//!
//! ```text
//! magic "GWTREE01" | u64 basis length | basis bytes (wavelet CWBASIS1 format)
//! | u64 n | 3 × n f32 coefficients (R, G, B) | FNV-1a 64 of everything before
//! ```

use anyhow::{bail, Context, Result};
use brdf::{Brdf, HalfDiff, Rgb, Vec3};
use clap::{Args, Subcommand};
use std::path::{Path, PathBuf};
use wavelet::cwb::{CommonBasis, Layout};
use wavelet::tree::CoefficientTree;

/// Subcommands of `gantry wavelet`.
#[derive(Subcommand, Debug)]
pub enum WaveletCommand {
    /// Builds the Common Wavelet Basis (Haar, 256³) of the log RGB channels of a corpus.
    Basis(BasisArgs),
    /// Compresses a material onto a basis (a `.wtree` file that `render` can use).
    Compress(CompressArgs),
}

/// Arguments of `gantry wavelet basis`.
#[derive(Args, Debug)]
pub struct BasisArgs {
    /// Material specs of the corpus (e.g. merl:chrome), or NBRDF directories.
    #[arg(long, num_args = 1.., required = true)]
    corpus: Vec<String>,
    /// Relative L2 error kept per log channel.
    #[arg(long, default_value_t = 0.005)]
    target: f64,
    /// Output basis file.
    #[arg(long)]
    out: PathBuf,
}

/// Arguments of `gantry wavelet compress`.
#[derive(Args, Debug)]
pub struct CompressArgs {
    /// Material spec.
    spec: String,
    /// Basis file from `gantry wavelet basis`.
    #[arg(long)]
    basis: PathBuf,
    /// Output `.wtree` file.
    #[arg(long)]
    out: PathBuf,
}

/// Floor of the log transform: channels are represented as ln(f + LOG_FLOOR), so that the
/// relative-error target of the basis applies across the whole dynamic range rather than being
/// spent on the specular peak.
const LOG_FLOOR: f32 = 1e-3;

fn channels(table: &brdf::MerlTable) -> [Vec<f32>; 3] {
    let v = table.values_f32();
    let n = brdf::table::BINS;
    [0, 1, 2].map(|c| {
        v[c * n..(c + 1) * n]
            .iter()
            .map(|x| (x.max(0.0) + LOG_FLOOR).ln())
            .collect()
    })
}

fn corpus_tables(items: &[String]) -> Result<Vec<brdf::MerlTable>> {
    let mut out = Vec::new();
    for item in items {
        let p = Path::new(item);
        if p.is_dir() {
            for m in brdf::nbrdf::load_dir(p)? {
                out.push(m.tabulate());
            }
        } else {
            out.push(
                brdf::spec::load(item)
                    .with_context(|| format!("cannot load material '{item}'"))?
                    .tabulate(),
            );
        }
    }
    if out.is_empty() {
        bail!("the corpus is empty");
    }
    Ok(out)
}

fn fnv1a(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325u64, |h, b| {
        (h ^ *b as u64).wrapping_mul(0x0000_0100_0000_01b3)
    })
}

/// Serialises a compressed material.
fn wtree_bytes(basis: &CommonBasis, coefficients: &[Vec<f32>; 3]) -> Vec<u8> {
    let b = basis.to_bytes();
    let mut out = b"GWTREE01".to_vec();
    out.extend_from_slice(&(b.len() as u64).to_le_bytes());
    out.extend_from_slice(&b);
    out.extend_from_slice(&(basis.len() as u64).to_le_bytes());
    for c in coefficients {
        for v in c {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    let h = fnv1a(&out);
    out.extend_from_slice(&h.to_le_bytes());
    out
}

/// A material evaluated from its Common Wavelet Coefficient Tree.
pub struct WaveletBrdf {
    name: String,
    tree: CoefficientTree,
}

impl WaveletBrdf {
    /// Reads a `.wtree` file.
    pub fn read(path: &Path) -> Result<Self> {
        let bytes =
            std::fs::read(path).with_context(|| format!("{}: cannot read", path.display()))?;
        let bad =
            |what: &str| anyhow::anyhow!("{}: malformed wavelet material ({what})", path.display());
        if bytes.len() < 8 + 8 + 8 + 8 || &bytes[..8] != b"GWTREE01" {
            return Err(bad("magic"));
        }
        let (body, tail) = bytes.split_at(bytes.len() - 8);
        if fnv1a(body) != u64::from_le_bytes(tail.try_into()?) {
            return Err(bad("checksum"));
        }
        let blen = u64::from_le_bytes(body[8..16].try_into()?) as usize;
        let bend = 16usize
            .checked_add(blen)
            .filter(|e| *e + 8 <= body.len())
            .ok_or_else(|| bad("length"))?;
        let basis = CommonBasis::from_bytes(&body[16..bend])?;
        let n = u64::from_le_bytes(body[bend..bend + 8].try_into()?) as usize;
        let data = &body[bend + 8..];
        if n != basis.len() || data.len() != 3 * 4 * n {
            return Err(bad("coefficient count"));
        }
        let coefficients: Vec<Vec<f32>> = (0..3)
            .map(|c| {
                data[c * 4 * n..(c + 1) * 4 * n]
                    .chunks_exact(4)
                    .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                    .collect()
            })
            .collect();
        if coefficients.iter().flatten().any(|v| !v.is_finite()) {
            return Err(bad("non-finite coefficient"));
        }
        let tree = CoefficientTree::new(&basis, &coefficients)?;
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "wavelet".into());
        Ok(Self { name, tree })
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
        out.map(|v| ((v.exp() - LOG_FLOOR) as f64).max(0.0))
    }
    fn name(&self) -> String {
        self.name.clone()
    }
}

/// Runs a `gantry wavelet` subcommand.
pub fn run(cmd: WaveletCommand) -> Result<()> {
    match cmd {
        WaveletCommand::Basis(a) => {
            let tables = corpus_tables(&a.corpus)?;
            let chans: Vec<Vec<f32>> = tables.iter().flat_map(channels).collect();
            let refs: Vec<&[f32]> = chans.iter().map(|c| c.as_slice()).collect();
            let (basis, _) = CommonBasis::build(Layout::MERL_HAAR, &refs, a.target)?;
            if let Some(dir) = a.out.parent().filter(|d| !d.as_os_str().is_empty()) {
                std::fs::create_dir_all(dir)?;
            }
            basis.write(&a.out)?;
            println!(
                "wrote {}: {} coefficients ({:.2}% of a table) for {} materials",
                a.out.display(),
                basis.len(),
                100.0 * basis.fraction_of_table(),
                tables.len()
            );
        }
        WaveletCommand::Compress(a) => {
            let basis = CommonBasis::read(&a.basis)
                .with_context(|| format!("cannot read basis {}", a.basis.display()))?;
            let table = brdf::spec::load(&a.spec)
                .with_context(|| format!("cannot load material '{}'", a.spec))?
                .tabulate();
            let ch = channels(&table);
            let coefficients = [
                basis.coefficients(&ch[0])?,
                basis.coefficients(&ch[1])?,
                basis.coefficients(&ch[2])?,
            ];
            brdf::write_atomic(&a.out, &wtree_bytes(&basis, &coefficients))?;
            println!(
                "wrote {} ({} coefficients per channel)",
                a.out.display(),
                basis.len()
            );
        }
    }
    Ok(())
}

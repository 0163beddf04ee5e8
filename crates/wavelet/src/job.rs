//! The jobs behind `gantry wavelet basis|compress`.

use std::fmt;
use std::path::PathBuf;

use serde::Serialize;

use crate::cwb::CommonBasis;
use crate::material::{build_basis, CompressedMaterial, Result};

/// Build the Common Wavelet Basis (Haar, 256³) of the log RGB channels of a corpus: the job
/// behind `gantry wavelet basis`.
///
/// Each job is an options value (with the `cli` feature also the command's arguments), a `run`
/// method and a serde report whose `Display` is what the command prints.
///
/// # Examples
///
/// ```
/// use wavelet::{BasisJob, CommonBasis};
///
/// let dir = std::env::temp_dir().join(format!("wavelet-basis-doc-{}", std::process::id()));
/// // a Lambertian surface is constant in every channel: few coefficients describe it
/// let report = BasisJob {
///     corpus: vec!["lambert:kd=0.4".into()],
///     target: 0.01,
///     out: dir.join("basis.cwb"),
/// }
/// .run()
/// .unwrap();
/// assert_eq!(report.materials, 1);
/// assert!(report.coefficients > 0 && report.fraction_of_table < 0.5);
/// let basis = CommonBasis::from_bytes(&std::fs::read(&report.out).unwrap()).unwrap();
/// assert_eq!(basis.len(), report.coefficients);
/// # std::fs::remove_dir_all(&dir).unwrap();
/// ```
#[derive(Debug, Clone)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct BasisJob {
    /// Corpus: material specs, folders of neural-BRDF weights and/or .binary files, or corpus
    /// stores (see `gantry forms`).
    #[cfg_attr(feature = "cli", arg(long, num_args = 1.., required = true))]
    pub corpus: Vec<String>,
    /// Relative L2 error kept per log channel.
    #[cfg_attr(feature = "cli", arg(long, default_value_t = 0.005))]
    pub target: f64,
    /// Output basis file.
    #[cfg_attr(feature = "cli", arg(long))]
    pub out: PathBuf,
}

/// What [`BasisJob::run`] built.
#[derive(Debug, Clone, Serialize)]
pub struct BasisReport {
    /// The basis file.
    pub out: PathBuf,
    /// Wavelet coefficients kept.
    pub coefficients: usize,
    /// Their share of a full table's coefficients.
    pub fraction_of_table: f64,
    /// Materials of the corpus.
    pub materials: usize,
}

impl fmt::Display for BasisReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "wrote {}: {} coefficients ({:.2}% of a table) for {} materials",
            self.out.display(),
            self.coefficients,
            100.0 * self.fraction_of_table,
            self.materials
        )
    }
}

/// Compress a material onto a basis (a `.wtree` file that `render` can use): the job behind
/// `gantry wavelet compress`.
///
/// # Examples
///
/// ```
/// use brdf::Brdf;
/// use wavelet::{BasisJob, CompressJob, WaveletBrdf};
///
/// let dir = std::env::temp_dir().join(format!("wavelet-compress-doc-{}", std::process::id()));
/// let basis = BasisJob { corpus: vec!["lambert:kd=0.4".into()], target: 0.01, out: dir.join("b.cwb") }
///     .run()
///     .unwrap()
///     .out;
/// let report = CompressJob { spec: "lambert:kd=0.2".into(), basis, out: dir.join("m.wtree") }
///     .run()
///     .unwrap();
/// let m = WaveletBrdf::read(&report.out).unwrap();
/// let z = brdf::Vec3::z();
/// // the darker Lambertian surface is close to the span of the basis
/// let expected = 0.2 / std::f64::consts::PI;
/// assert!((m.eval(&z, &z)[0] - expected).abs() < 0.05 * expected);
/// # std::fs::remove_dir_all(&dir).unwrap();
/// ```
#[derive(Debug, Clone)]
#[cfg_attr(feature = "cli", derive(clap::Args))]
pub struct CompressJob {
    /// Material spec.
    pub spec: String,
    /// Basis file from `gantry wavelet basis`.
    #[cfg_attr(feature = "cli", arg(long))]
    pub basis: PathBuf,
    /// Output `.wtree` file.
    #[cfg_attr(feature = "cli", arg(long))]
    pub out: PathBuf,
}

/// What [`CompressJob::run`] wrote.
#[derive(Debug, Clone, Serialize)]
pub struct CompressReport {
    /// The `.wtree` file.
    pub out: PathBuf,
    /// Coefficients per channel.
    pub coefficients: usize,
}

impl fmt::Display for CompressReport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "wrote {} ({} coefficients per channel)",
            self.out.display(),
            self.coefficients
        )
    }
}

impl BasisJob {
    /// Loads the corpus, builds the basis and writes it.
    pub fn run(&self) -> Result<BasisReport> {
        let tables: Vec<brdf::MerlTable> = brdf::load_tables(&self.corpus)?
            .into_iter()
            .map(|(_, t)| t)
            .collect();
        let basis = build_basis(&tables, self.target)?;
        brdf::create_parent_dir(&self.out)?;
        basis.write(&self.out)?;
        Ok(BasisReport {
            out: self.out.clone(),
            coefficients: basis.len(),
            fraction_of_table: basis.fraction_of_table(),
            materials: tables.len(),
        })
    }
}

impl CompressJob {
    /// Tabulates the material, compresses it onto the basis and writes the `.wtree` file.
    pub fn run(&self) -> Result<CompressReport> {
        let basis = CommonBasis::read(&self.basis)?;
        let table = brdf::load(&self.spec)?.tabulate();
        let coefficients = basis.len();
        CompressedMaterial::compress(basis, &table)?.write(&self.out)?;
        Ok(CompressReport {
            out: self.out.clone(),
            coefficients,
        })
    }
}

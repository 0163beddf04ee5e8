//! The reflectance model (PCA of the log-space corpus and an optional chart) and its file.

use std::fs::File;
use std::io::{BufReader, Read, Write};
use std::path::Path;

use nalgebra::{DMatrix, DVector};

use crate::charting::{Chart, ChartingConfig, Charts};
use crate::corpus::{log_vector, to_log, Corpus, LOG_FLOOR};
use crate::encode::{least_absolute, robust_sample, Encoder};
use crate::error::{ReduceError, Result};
use crate::mapping::Mapping;
use crate::pca::Pca;

/// File magic.
pub const MAGIC: &[u8; 8] = b"BRDFMODL";
/// End marker.
pub const END_MARKER: &[u8; 8] = b"ENDMODEL";
/// Current file format version (2 adds the mapping; version 1 files are read as
/// [`Mapping::Log`]).
pub const VERSION: u32 = 2;
/// Default number of stored principal components (the thesis's linear model dimension is 45;
/// 60 keeps room for its Fig. 4-3 sweep).
pub const DEFAULT_COMPONENTS: usize = 60;
/// Default chart dimension (the thesis: under 1 % error at 15).
pub const DEFAULT_CHART_DIM: usize = 15;

/// Linear (PCA) model of log-space BRDFs, with an optional non-linear chart (thesis §4.1,
/// §4.4): what [`build_model`] makes of a corpus and `model.bin` holds.
///
/// [`Model::save`] writes and [`Model::load`] reads the versioned binary file below.
///
/// # File format (version 2, little-endian)
///
/// | field | type |
/// |---|---|
/// | magic | 8 bytes `BRDFMODL` |
/// | version | `u32` = 2 (1: as 2 without the mapping fields, read as `log`) |
/// | log floor | `f64` ([`LOG_FLOOR`](crate::LOG_FLOOR) at build time) |
/// | mapping | `u8` (0 = [`Mapping::Log`], 1 = [`Mapping::CosineLog`]) and its ε as `f64` (0 for `log`) |
/// | `D`, `N`, `K` | 3 × `u64`: vector length, materials, stored components |
/// | names | `N` × (`u32` byte length + UTF-8) |
/// | eigenvalues | `N` × `f64` (all of them, decreasing) |
/// | mean | `D` × `f32` (in the mapping's space) |
/// | basis | `D·K` × `f32`, dimension-major (`basis[d·K + k]`) |
/// | coordinates | `N·K` × `f64`, material-major |
/// | chart flag | `u8` (0 = none, 1 = chart follows) |
/// | chart | σ, eigen floor, posterior broadening, pseudo-inverse tolerance, ridge (5 × `f64`); `d`, `Kc`, `Nc` (3 × `u64`); centres `Nc·Kc`; eigenvectors `Nc·Kc·Kc` (column-major per chart); eigenvalues `Nc·Kc`; maps `Nc·d·(d+1)` (column-major per chart); spectrum `d` — all `f64` |
/// | end marker | 8 bytes `ENDMODEL` |
///
/// The chart lives in the space of the first `Kc ≤ K` PCA coordinates.
///
/// # Examples
///
/// ```
/// use reduce::{build_model, Corpus, Model};
///
/// // a tiny corpus: four materials of 40 log-space values
/// let mut corpus = Corpus::new(40);
/// for i in 0..4 {
///     let values: Vec<f64> = (0..40).map(|d| 0.1 + 0.01 * ((i + 1) * d % 11) as f64).collect();
///     corpus.push_values(format!("m{i}"), &values).unwrap();
/// }
/// let model = build_model(&corpus, 3, None, None).unwrap();
/// // the file round-trips
/// let path = std::env::temp_dir().join(format!("reduce-doc-{}.bin", std::process::id()));
/// model.save(&path).unwrap();
/// let back = Model::load(&path).unwrap();
/// # std::fs::remove_file(&path).unwrap();
/// assert_eq!(back.names, ["m0", "m1", "m2", "m3"]);
/// assert_eq!(back.components(), model.components());
/// assert_eq!(back.pca.basis, model.pca.basis);
/// assert_eq!(back.log_floor, reduce::LOG_FLOOR);
/// ```
#[derive(Debug, Clone)]
pub struct Model {
    /// Names of the corpus materials (row order of `pca.coords`).
    pub names: Vec<String>,
    /// Floor used by the log transform.
    pub log_floor: f64,
    /// The transform of BRDF values the PCA is fitted in ([`Mapping::Log`]: the thesis's).
    pub mapping: Mapping,
    /// PCA: mean, eigenvalues, basis, coordinates.
    pub pca: Pca,
    /// Manifold chart in the space of the first `chart.charts.ambient_dim()` PCA coordinates.
    pub chart: Option<Chart>,
}

/// Relative reconstruction errors of one material at a given number of components.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ReconstructionError {
    /// Number of components used.
    pub k: usize,
    /// `‖y − ỹ‖ / ‖y − m‖`: fraction of the material's deviation from the mean left unexplained.
    pub relative: f64,
    /// `‖y − ỹ‖ / √D`: RMS error in natural-log units (≈ relative error of BRDF values).
    pub rms_log: f64,
}

/// Builds the model of a corpus: PCA with `k` components and, when `chart_dim` is given, a
/// chart of that dimension over the first `chart_coords` PCA coordinates (all when `None`).
///
/// # Examples
///
/// ```
/// use reduce::Corpus;
/// use reduce::build_model;
///
/// // a corpus of log-space vectors (here 8 synthetic materials of 50 values; a MERL corpus is
/// // loaded with `Corpus::load(&["merl:chrome", "merl:pink-felt", ...])`)
/// let mut corpus = Corpus::new(50);
/// let material = |i: usize, d: usize| {
///     let (w1, w2, w3) = (1.0 + i as f64, 1.0 + ((i * i) % 5) as f64, 0.5 + ((3 * i) % 4) as f64);
///     w1 * (1.0 + d as f64) + w2 * (-(d as f64) / 5.0).exp() + w3 * (d % 7) as f64
/// };
/// for i in 0..8 {
///     let values: Vec<f64> = (0..50).map(|d| material(i, d)).collect();
///     corpus.push_values(format!("m{i}"), &values).unwrap();
/// }
/// // PCA in log space (thesis §4.1), at most N − 1 = 7 components
/// let model = build_model(&corpus, 7, None, None).unwrap();
/// let k = model.components();
/// assert!(k >= 2 && k <= 7);
/// let ev = &model.pca.eigenvalues;
/// assert!(ev.windows(2).all(|w| w[0] >= w[1]));
/// // a corpus member is recovered (within 1 %) from its coordinates on all components
/// let x: Vec<f64> = (0..k).map(|c| model.pca.coords[(2, c)]).collect();
/// let back = model.synthesize(&x).unwrap();
/// for d in [0, 17, 49] {
///     let v = material(2, d);
///     assert!((back[d] - v).abs() < 1e-2 * v, "{d}: {} vs {v}", back[d]);
/// }
/// ```
pub fn build_model(
    corpus: &Corpus,
    k: usize,
    chart_dim: Option<usize>,
    chart_coords: Option<usize>,
) -> Result<Model> {
    build_mapped_model(corpus, Mapping::Log, k, chart_dim, chart_coords)
}

/// [`build_model`] in the space of `mapping` (the corpus holds log-space vectors; each is
/// mapped before the PCA).
pub fn build_mapped_model(
    corpus: &Corpus,
    mapping: Mapping,
    k: usize,
    chart_dim: Option<usize>,
    chart_coords: Option<usize>,
) -> Result<Model> {
    let pca = if mapping == Mapping::Log {
        Pca::fit(corpus.data(), corpus.len(), corpus.dim(), k)?
    } else {
        let mut data = corpus.data().to_vec();
        for row in data.chunks_mut(corpus.dim().max(1)) {
            mapping.from_log_in_place(row)?;
        }
        Pca::fit(&data, corpus.len(), corpus.dim(), k)?
    };
    let chart = match chart_dim {
        Some(d) => Some(chart_pca_coords(
            &pca,
            d,
            chart_coords,
            ChartingConfig::default(),
        )?),
        None => None,
    };
    Ok(Model {
        names: corpus.names().to_vec(),
        log_floor: LOG_FLOOR,
        mapping,
        pca,
        chart,
    })
}

/// Charts the corpus in the space of its first `coords` PCA coordinates (default all).
pub fn chart_pca_coords(
    pca: &Pca,
    d: usize,
    coords: Option<usize>,
    config: ChartingConfig,
) -> Result<Chart> {
    let kc = coords.unwrap_or(pca.components).min(pca.components);
    let pts = pca.coords.columns(0, kc).into_owned();
    Charts::fit(&pts, config)?.connect(d)
}

/// Charting reconstruction error of a corpus under the candidate readings of the thesis's
/// "residual error" (Fig. 4-6; see docs/reduce.md). Every training point is mapped forward
/// (2.52) and back (2.54); `r = Σ_i ‖ŷ_i − y_i‖²` is measured in the chart's `Kc` PCA
/// coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChartErrors {
    /// Embedding dimension `d`.
    pub dim: usize,
    /// `sqrt(r / Σ_i ‖y_i − ȳ‖²)` in the `Kc` coordinates (norm ratio, chart only).
    pub relative_in_coords: f64,
    /// `r / Σ_i ‖y_i − ȳ‖²` in the `Kc` coordinates (unexplained variance, chart only).
    pub unexplained_in_coords: f64,
    /// `(r + Σ_{j ≥ Kc} λ_j) / Σ_j λ_j`: fraction of the variance of the centred log corpus
    /// (all `D` values) left unexplained, the PCA truncation to `Kc` coordinates included.
    /// Its PCA counterpart at `k` components is `Σ_{j ≥ k} λ_j / Σ_j λ_j`.
    pub unexplained_total: f64,
    /// `sqrt` of [`ChartErrors::unexplained_total`].
    pub relative_total: f64,
    /// `sqrt(r / Σ_i ‖y_i‖²)` with the uncentred log vectors (chart only).
    pub relative_uncentred: f64,
}

/// [`ChartErrors`] of a chart built on the first `Kc` coordinates of `pca`, whose corpus the
/// chart's centres must be.
pub fn chart_errors(pca: &Pca, chart: &Chart) -> Result<ChartErrors> {
    let kc = chart.charts.ambient_dim();
    let n = chart.charts.len();
    if kc > pca.components || n != pca.coords.nrows() {
        return Err(ReduceError::Dimension {
            what: "chart coordinates within the PCA model",
            expected: pca.components,
            got: kc,
        });
    }
    let rt = chart.round_trip()?;
    let r = rt.residual_norm2();
    let total: f64 = pca.eigenvalues.iter().sum();
    let rest: f64 = pca.eigenvalues.iter().skip(kc).sum();
    let mean2: f64 = pca.mean.iter().map(|&v| (v as f64) * (v as f64)).sum();
    let unexplained_total = (r + rest) / total;
    Ok(ChartErrors {
        dim: chart.dim,
        relative_in_coords: rt.relative_error(),
        unexplained_in_coords: rt.unexplained_fraction(),
        unexplained_total,
        relative_total: unexplained_total.sqrt(),
        relative_uncentred: (r / (total + n as f64 * mean2)).sqrt(),
    })
}

impl Model {
    /// Number of stored components.
    pub fn components(&self) -> usize {
        self.pca.components
    }

    fn check_floor(&self) -> Result<()> {
        if self.log_floor != LOG_FLOOR {
            return Err(ReduceError::MalformedModel(format!(
                "model built with log floor {} but this build uses {LOG_FLOOR}",
                self.log_floor
            )));
        }
        Ok(())
    }

    /// `Ok` for a model in the thesis's log space ([`Mapping::Log`]); a
    /// [`ReduceError::InvalidParameter`] naming `what` otherwise. Code that decodes the PCA
    /// itself (`exp(y) − ε`) calls it first.
    pub fn require_log_mapping(&self, what: &str) -> Result<()> {
        match self.mapping {
            Mapping::Log => Ok(()),
            m => Err(ReduceError::InvalidParameter(format!(
                "{what} needs a model in log space; this one is built with the {} mapping \
                 (rebuild it with `gantry model build --mapping log`)",
                m.name()
            ))),
        }
    }

    /// The vector of a material (BRDF values, 3 × BINS) in the model's space.
    pub fn mapped_vector(&self, values: &[f64]) -> Result<Vec<f32>> {
        self.check_floor()?;
        let mut y = log_vector(values)?;
        self.mapping.from_log_in_place(&mut y)?;
        Ok(y)
    }

    /// Coordinates of a material (BRDF values, 3 × BINS) on the first `k` components.
    pub fn project_values(&self, values: &[f64], k: usize) -> Result<Vec<f64>> {
        let y = self.mapped_vector(values)?;
        self.pca.project(&y, k)
    }

    /// Coordinates of a material (BRDF values) on the first `k` components found by
    /// `encoder`: the projection, or the least-absolute-deviations fit over a seeded sample of
    /// entries started from it ([`Encoder::Robust`]).
    pub fn encode_values(&self, values: &[f64], k: usize, encoder: Encoder) -> Result<Vec<f64>> {
        let y = self.mapped_vector(values)?;
        let x = self.pca.project(&y, k)?;
        match encoder {
            Encoder::Projection => Ok(x),
            Encoder::Robust => {
                let p = &self.pca;
                let kk = p.components;
                let sample = robust_sample(p.dim);
                let u =
                    DMatrix::from_fn(sample.len(), k, |s, c| p.basis[sample[s] * kk + c] as f64);
                let t = DVector::from_fn(sample.len(), |s, _| {
                    (y[sample[s]] - p.mean[sample[s]]) as f64
                });
                Ok(least_absolute(&u, &t, DVector::from_vec(x))
                    .iter()
                    .copied()
                    .collect())
            }
        }
    }

    /// Projects a material onto the first `k` components and returns the reconstructed BRDF
    /// values (1/sr, clamped to ≥ 0), ready for `MerlTable::from_values`.
    pub fn reconstruct_values(&self, values: &[f64], k: usize) -> Result<Vec<f64>> {
        let x = self.project_values(values, k)?;
        self.synthesize(&x)
    }

    /// Projects a table onto the first `k` components and returns the reconstruction.
    pub fn reconstruct(&self, table: &brdf::MerlTable, k: usize) -> Result<brdf::MerlTable> {
        let v = self.reconstruct_values(&table.values(), k)?;
        Ok(brdf::MerlTable::from_values(v)?
            .with_name(format!("{} (PCA {k})", brdf::Brdf::name(table))))
    }

    /// Completes a partly measured table (a capture, a sparse measurement): fits the first `k`
    /// components to the log values of its valid bins only ([`Pca::project_masked`] with
    /// `ridge`) and returns the full reconstruction, which is non-negative and reciprocal where
    /// the corpus is. Bins the table holds are not copied over: the result is the model's
    /// explanation of them.
    pub fn complete(
        &self,
        table: &brdf::MerlTable,
        k: usize,
        ridge: f64,
    ) -> Result<brdf::MerlTable> {
        self.check_floor()?;
        let values = table.values();
        let known: Vec<bool> = (0..values.len())
            .map(|i| table.is_valid(i / brdf::BINS, i % brdf::BINS))
            .collect();
        let mut y: Vec<f32> = values.iter().map(|&v| to_log(v.max(0.0))).collect();
        self.mapping.from_log_in_place(&mut y)?;
        let x = self.pca.project_masked(&y, &known, k, ridge)?;
        let v = self.synthesize(&x)?;
        Ok(brdf::MerlTable::from_values(v)?
            .with_name(format!("{} (completed, PCA {k})", brdf::Brdf::name(table))))
    }

    /// `model reconstruct`: loads the material named by a spec string (`brdf::spec`), encodes
    /// it on the first `k` components and writes the reconstruction as a MERL `.binary` file.
    /// Returns the reconstruction errors at `k` (in the model's space).
    pub fn reconstruct_spec_to_file(
        &self,
        spec: &str,
        k: usize,
        encoder: Encoder,
        out: impl AsRef<Path>,
    ) -> Result<ReconstructionError> {
        let table = brdf::load(spec)?.tabulate();
        let values = table.values();
        let y = self.mapped_vector(&values)?;
        let x = self.encode_values(&values, k, encoder)?;
        let rec = self.pca.reconstruct(&x)?;
        let dev = self.pca.residuals(&y, &[0])?[0].sqrt();
        let r = y
            .iter()
            .zip(&rec)
            .map(|(&a, &b)| (a as f64 - b as f64).powi(2))
            .sum::<f64>()
            .sqrt();
        let err = ReconstructionError {
            k,
            relative: r / dev.max(1e-300),
            rms_log: r / (self.pca.dim as f64).sqrt(),
        };
        let rec = brdf::MerlTable::from_values(self.mapping.to_values(&rec)?)?;
        brdf::merl::write(out.as_ref(), &rec)?;
        Ok(err)
    }

    /// BRDF values (clamped to ≥ 0) of the point with PCA coordinates `x`.
    pub fn synthesize(&self, x: &[f64]) -> Result<Vec<f64>> {
        let y = self.pca.reconstruct(x)?;
        self.mapping.to_values(&y)
    }

    /// Relative reconstruction errors of a material (BRDF values) for each `k` in `ks`, in
    /// the model's space (log units for [`Mapping::Log`]).
    pub fn reconstruction_errors(
        &self,
        values: &[f64],
        ks: &[usize],
    ) -> Result<Vec<ReconstructionError>> {
        let y = self.mapped_vector(values)?;
        let res = self.pca.residuals(&y, ks)?;
        let dev = res[ks.len()].sqrt();
        let sqrt_d = (self.pca.dim as f64).sqrt();
        Ok(ks
            .iter()
            .zip(&res)
            .map(|(&k, r)| ReconstructionError {
                k,
                relative: r.sqrt() / dev,
                rms_log: r.sqrt() / sqrt_d,
            })
            .collect())
    }

    /// Writes the model atomically (temporary file in the same directory, then rename).
    pub fn save(&self, path: impl AsRef<Path>) -> Result<()> {
        let path = path.as_ref();
        brdf::write_atomic_with(path, |w| self.write_to(w)).map_err(|e| ReduceError::io(path, e))
    }

    fn write_to(&self, w: &mut impl Write) -> std::io::Result<()> {
        let p = &self.pca;
        let (n, k) = (self.names.len(), p.components);
        w.write_all(MAGIC)?;
        w.write_all(&VERSION.to_le_bytes())?;
        w.write_all(&self.log_floor.to_le_bytes())?;
        let (tag, eps) = match self.mapping {
            Mapping::Log => (0u8, 0.0),
            Mapping::CosineLog { epsilon } => (1u8, epsilon),
        };
        w.write_all(&[tag])?;
        w.write_all(&eps.to_le_bytes())?;
        for v in [p.dim, n, k] {
            w.write_all(&(v as u64).to_le_bytes())?;
        }
        for name in &self.names {
            w.write_all(&(name.len() as u32).to_le_bytes())?;
            w.write_all(name.as_bytes())?;
        }
        write_f64s(w, p.eigenvalues.iter().copied())?;
        write_f32s(w, &p.mean)?;
        write_f32s(w, &p.basis)?;
        write_f64s(
            w,
            (0..n)
                .flat_map(|i| (0..k).map(move |c| (i, c)))
                .map(|(i, c)| p.coords[(i, c)]),
        )?;
        match &self.chart {
            None => w.write_all(&[0u8])?,
            Some(ch) => {
                w.write_all(&[1u8])?;
                let c = &ch.charts;
                let cfg = c.config;
                write_f64s(
                    w,
                    [
                        c.sigma,
                        cfg.eigen_floor,
                        cfg.posterior_broadening,
                        cfg.pinv_tolerance,
                        cfg.ridge,
                    ]
                    .into_iter(),
                )?;
                for v in [ch.dim, c.ambient_dim(), c.len()] {
                    w.write_all(&(v as u64).to_le_bytes())?;
                }
                let nc = c.len();
                let kc = c.ambient_dim();
                write_f64s(
                    w,
                    (0..nc)
                        .flat_map(|i| (0..kc).map(move |j| (i, j)))
                        .map(|(i, j)| c.centres[(i, j)]),
                )?;
                for v in &c.eigenvectors {
                    write_f64s(w, v.iter().copied())?;
                }
                for v in &c.eigenvalues {
                    write_f64s(w, v.iter().copied())?;
                }
                for g in &ch.maps {
                    write_f64s(w, g.iter().copied())?;
                }
                write_f64s(w, ch.spectrum.iter().copied())?;
            }
        }
        w.write_all(END_MARKER)
    }

    /// Reads a model file, checking magic, version, sizes against the file length and the end
    /// marker; every defect is a [`ReduceError::MalformedModel`].
    pub fn load(path: impl AsRef<Path>) -> Result<Model> {
        let path = path.as_ref();
        let f = File::open(path).map_err(|e| ReduceError::io(path, e))?;
        let len = f.metadata().map_err(|e| ReduceError::io(path, e))?.len();
        let mut r = Reader {
            // a buffer no larger than the file (a small or hostile file costs little)
            inner: BufReader::with_capacity((1 << 20).min(len.max(1) as usize), f),
            remaining: len,
        };
        Model::read_from(&mut r)
    }

    fn read_from<R: Read>(r: &mut Reader<R>) -> Result<Model> {
        let magic = r.bytes(8)?;
        if magic != MAGIC {
            return Err(ReduceError::MalformedModel(
                "not a model file (bad magic)".into(),
            ));
        }
        let version = u32::from_le_bytes(r.array()?);
        if version != VERSION && version != 1 {
            return Err(ReduceError::MalformedModel(format!(
                "unsupported version {version} (expected 1 or {VERSION})"
            )));
        }
        let log_floor = r.f64()?;
        let mapping = if version == 1 {
            Mapping::Log
        } else {
            let tag = r.array::<1>()?[0];
            let eps = r.f64()?;
            match tag {
                0 => Mapping::Log,
                1 if eps.is_finite() && eps > 0.0 => Mapping::CosineLog { epsilon: eps },
                _ => {
                    return Err(ReduceError::MalformedModel(format!(
                        "bad mapping {tag} (ε = {eps})"
                    )))
                }
            }
        };
        let dim = r.count()?;
        let n = r.count()?;
        let k = r.count()?;
        if n < 2 || k == 0 || k >= n || dim == 0 || (log_floor.is_nan() || log_floor <= 0.0) {
            return Err(ReduceError::MalformedModel(format!(
                "inconsistent header: D={dim} N={n} K={k}"
            )));
        }
        let mut names = Vec::with_capacity(n);
        for _ in 0..n {
            let l = u32::from_le_bytes(r.array()?) as usize;
            let b = r.bytes(l)?;
            names.push(
                String::from_utf8(b).map_err(|_| {
                    ReduceError::MalformedModel("material name is not UTF-8".into())
                })?,
            );
        }
        let eigenvalues = r.f64s(n)?;
        let mean = r.f32s(dim)?;
        let basis = r.f32s(
            dim.checked_mul(k)
                .ok_or_else(|| ReduceError::MalformedModel("size overflow".into()))?,
        )?;
        let coords_v = r.f64s(n * k)?;
        let coords = DMatrix::from_row_slice(n, k, &coords_v);
        if eigenvalues.iter().chain(&coords_v).any(|v| !v.is_finite())
            || mean.iter().chain(&basis).any(|v| !v.is_finite())
        {
            return Err(ReduceError::MalformedModel("non-finite values".into()));
        }
        let chart = match r.array::<1>()?[0] {
            0 => None,
            1 => Some(read_chart(r)?),
            f => return Err(ReduceError::MalformedModel(format!("bad chart flag {f}"))),
        };
        if r.bytes(8)? != END_MARKER {
            return Err(ReduceError::MalformedModel("missing end marker".into()));
        }
        if r.remaining != 0 {
            return Err(ReduceError::MalformedModel(format!(
                "{} trailing bytes",
                r.remaining
            )));
        }
        Ok(Model {
            names,
            log_floor,
            mapping,
            pca: Pca {
                dim,
                mean,
                eigenvalues,
                components: k,
                basis,
                coords,
            },
            chart,
        })
    }
}

fn read_chart<R: Read>(r: &mut Reader<R>) -> Result<Chart> {
    let v = r.f64s(5)?;
    let config = ChartingConfig {
        sigma: Some(v[0]),
        eigen_floor: v[1],
        posterior_broadening: v[2],
        pinv_tolerance: v[3],
        ridge: v[4],
    };
    if v.iter().any(|x| !x.is_finite() || *x < 0.0) {
        return Err(ReduceError::MalformedModel("bad chart settings".into()));
    }
    let d = r.count()?;
    let kc = r.count()?;
    let nc = r.count()?;
    if d == 0 || d > kc || nc < d + 2 || (v[0].is_nan() || v[0] <= 0.0) {
        return Err(ReduceError::MalformedModel(format!(
            "inconsistent chart header d={d} K={kc} N={nc}"
        )));
    }
    let centres = DMatrix::from_row_slice(nc, kc, &r.f64s(nc * kc)?);
    let mut eigenvectors = Vec::with_capacity(nc);
    for _ in 0..nc {
        eigenvectors.push(DMatrix::from_column_slice(kc, kc, &r.f64s(kc * kc)?));
    }
    let mut eigenvalues = Vec::with_capacity(nc);
    for _ in 0..nc {
        let e = r.f64s(kc)?;
        if e.iter()
            .any(|&l| (l.is_nan() || l <= 0.0) || !l.is_finite())
        {
            return Err(ReduceError::MalformedModel(
                "chart eigenvalues must be positive".into(),
            ));
        }
        eigenvalues.push(e);
    }
    let mut maps = Vec::with_capacity(nc);
    for _ in 0..nc {
        maps.push(DMatrix::from_column_slice(d, d + 1, &r.f64s(d * (d + 1))?));
    }
    let spectrum = r.f64s(d)?;
    if centres
        .iter()
        .chain(eigenvectors.iter().flat_map(|m| m.iter()))
        .chain(maps.iter().flat_map(|m| m.iter()))
        .any(|v| !v.is_finite())
    {
        return Err(ReduceError::MalformedModel(
            "non-finite chart values".into(),
        ));
    }
    let charts = Charts {
        centres,
        sigma: v[0],
        eigenvectors,
        eigenvalues,
        config,
    };
    Chart::new(charts, d, maps, spectrum)
        .map_err(|e| ReduceError::MalformedModel(format!("chart: {e}")))
}

impl Chart {
    /// Back-projects embedding coordinates to PCA coordinates as a plain vector.
    pub fn backward_vec(&self, x: &[f64]) -> Result<Vec<f64>> {
        Ok(self
            .backward(&DVector::from_column_slice(x))?
            .iter()
            .copied()
            .collect())
    }
}

fn write_f64s(w: &mut impl Write, it: impl Iterator<Item = f64>) -> std::io::Result<()> {
    let mut buf = Vec::with_capacity(1 << 16);
    for v in it {
        buf.extend_from_slice(&v.to_le_bytes());
        if buf.len() >= 1 << 16 {
            w.write_all(&buf)?;
            buf.clear();
        }
    }
    w.write_all(&buf)
}

fn write_f32s(w: &mut impl Write, v: &[f32]) -> std::io::Result<()> {
    let mut buf = Vec::with_capacity(1 << 16);
    for chunk in v.chunks(1 << 14) {
        buf.clear();
        for x in chunk {
            buf.extend_from_slice(&x.to_le_bytes());
        }
        w.write_all(&buf)?;
    }
    Ok(())
}

struct Reader<R> {
    inner: R,
    remaining: u64,
}

impl<R: Read> Reader<R> {
    fn take(&mut self, n: usize) -> Result<()> {
        if n as u64 > self.remaining {
            return Err(ReduceError::MalformedModel(format!(
                "truncated: needs {n} more bytes, {} left",
                self.remaining
            )));
        }
        self.remaining -= n as u64;
        Ok(())
    }

    fn fill(&mut self, buf: &mut [u8]) -> Result<()> {
        self.take(buf.len())?;
        self.inner
            .read_exact(buf)
            .map_err(|e| ReduceError::MalformedModel(format!("read failed: {e}")))
    }

    fn bytes(&mut self, n: usize) -> Result<Vec<u8>> {
        // Size is checked against the file length before allocating.
        if n as u64 > self.remaining {
            return Err(ReduceError::MalformedModel(format!(
                "truncated: needs {n} more bytes, {} left",
                self.remaining
            )));
        }
        let mut b = vec![0u8; n];
        self.fill(&mut b)?;
        Ok(b)
    }

    fn array<const L: usize>(&mut self) -> Result<[u8; L]> {
        let mut b = [0u8; L];
        self.fill(&mut b)?;
        Ok(b)
    }

    fn f64(&mut self) -> Result<f64> {
        Ok(f64::from_le_bytes(self.array()?))
    }

    fn count(&mut self) -> Result<usize> {
        let v = u64::from_le_bytes(self.array()?);
        if v > self.remaining {
            // No count in a valid file exceeds the number of bytes that follow it.
            return Err(ReduceError::MalformedModel(format!("implausible size {v}")));
        }
        Ok(v as usize)
    }

    fn f64s(&mut self, n: usize) -> Result<Vec<f64>> {
        let b = self.bytes(
            n.checked_mul(8)
                .ok_or_else(|| ReduceError::MalformedModel("size overflow".into()))?,
        )?;
        Ok(b.chunks_exact(8)
            .map(|c| f64::from_le_bytes(c.try_into().unwrap()))
            .collect())
    }

    fn f32s(&mut self, n: usize) -> Result<Vec<f32>> {
        let nb = n
            .checked_mul(4)
            .ok_or_else(|| ReduceError::MalformedModel("size overflow".into()))?;
        if nb as u64 > self.remaining {
            return Err(ReduceError::MalformedModel(format!(
                "truncated: needs {nb} more bytes, {} left",
                self.remaining
            )));
        }
        let mut out = Vec::with_capacity(n);
        let mut buf = vec![0u8; 1 << 16];
        let mut left = nb;
        while left > 0 {
            let m = left.min(buf.len());
            self.fill(&mut buf[..m])?;
            out.extend(
                buf[..m]
                    .chunks_exact(4)
                    .map(|c| f32::from_le_bytes(c.try_into().unwrap())),
            );
            left -= m;
        }
        Ok(out)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Four GGX materials on the full MERL grid (a corpus that both mappings can model).
    pub(crate) fn ggx_corpus() -> Corpus {
        let mut c = Corpus::new(brdf::MATERIAL_DIM);
        for (i, (alpha, kd)) in [(0.1, 0.1), (0.3, 0.3), (0.5, 0.05), (0.2, 0.5)]
            .into_iter()
            .enumerate()
        {
            let t = brdf::MerlTable::tabulate(&brdf::analytic::Ggx {
                kd: [kd, 0.2, 0.1],
                ks: [0.1; 3],
                alpha,
                ior: 1.5,
            });
            c.push_values(format!("m{i}"), &t.values()).unwrap();
        }
        c
    }

    fn small_corpus() -> Corpus {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(21);
        let dim = 600;
        let mut c = Corpus::new(dim);
        let lobes: Vec<Vec<f64>> = (0..3)
            .map(|_| (0..dim).map(|_| rng.gen_range(0.0..2.0)).collect())
            .collect();
        for i in 0..12 {
            let w: Vec<f64> = (0..3).map(|_| rng.gen_range(0.1..1.0)).collect();
            // Three lobes plus 20 % multiplicative texture (keeps the log-space spectrum flat).
            let v: Vec<f64> = (0..dim)
                .map(|d| (0..3).map(|c| w[c] * lobes[c][d]).sum::<f64>() * rng.gen_range(0.8..1.2))
                .collect();
            c.push_values(format!("m{i}"), &v).unwrap();
        }
        c
    }

    #[test]
    fn save_load_round_trip_with_chart() {
        let c = small_corpus();
        let m = build_model(&c, 6, Some(2), None).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("model.bin");
        m.save(&p).unwrap();
        let l = Model::load(&p).unwrap();
        assert_eq!(l.names, m.names);
        assert_eq!(l.pca, m.pca);
        let (a, b) = (m.chart.as_ref().unwrap(), l.chart.as_ref().unwrap());
        assert_eq!(a.maps, b.maps);
        // The loaded chart maps points exactly as the original.
        let y = m.pca.coords.row(3).transpose();
        assert_eq!(a.forward(&y).unwrap(), b.forward(&y).unwrap());
        // Only the final file remains (atomic write).
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    /// A corpus member with a few entries gone wrong: the robust encoder finds the member's
    /// own coordinates, the projection is pulled away by the bad entries.
    #[test]
    fn robust_encoding_sees_past_a_few_bad_entries() {
        let c = small_corpus();
        let m = build_model(&c, 11, None, None).unwrap();
        let k = m.components();
        let mut vals = brdf::values_from_log(c.row(4));
        for d in [3, 99, 100, 400, 555] {
            vals[d] = 500.0;
        }
        let own: Vec<f64> = (0..k).map(|j| m.pca.coords[(4, j)]).collect();
        let dist = |x: &[f64]| {
            x.iter()
                .zip(&own)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                .sqrt()
        };
        let scale = own.iter().map(|v| v * v).sum::<f64>().sqrt();
        let robust = m.encode_values(&vals, k, Encoder::Robust).unwrap();
        let projection = m.encode_values(&vals, k, Encoder::Projection).unwrap();
        assert!(dist(&robust) < 1e-3 * scale, "{} of {scale}", dist(&robust));
        assert!(
            dist(&projection) > 0.1 * scale,
            "{} of {scale}",
            dist(&projection)
        );
    }

    /// Version 1 files (no mapping fields) still load, as log-space models.
    #[test]
    fn version_1_files_load_as_log_models() {
        let m = build_model(&small_corpus(), 4, None, None).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.bin");
        m.save(&p).unwrap();
        let b = std::fs::read(&p).unwrap();
        let v1 = [&b[..8], &1u32.to_le_bytes(), &b[12..20], &b[29..]].concat();
        std::fs::write(&p, v1).unwrap();
        let l = Model::load(&p).unwrap();
        assert_eq!(
            (l.mapping, &l.pca, &l.names),
            (Mapping::Log, &m.pca, &m.names)
        );
    }

    /// A model in the cosine mapping decodes through it: a corpus member comes back from all
    /// its components, the file keeps the mapping, and log-only code is told.
    #[test]
    fn cosine_mapped_model_reconstructs_its_members_and_keeps_its_mapping() {
        let c = ggx_corpus();
        let m = build_mapped_model(&c, Mapping::COSINE, 3, None, None).unwrap();
        let vals = brdf::values_from_log(c.row(2));
        let rec = m.reconstruct_values(&vals, 3).unwrap();
        let worst = rec
            .iter()
            .zip(&vals)
            .map(|(a, b)| (a - b).abs() / (b + 0.1))
            .fold(0.0, f64::max);
        assert!(worst < 1e-2, "{worst}");
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.bin");
        m.save(&p).unwrap();
        let l = Model::load(&p).unwrap();
        assert_eq!(l.mapping, Mapping::COSINE);
        assert_eq!(l.reconstruct_values(&vals, 3).unwrap(), rec);
        assert!(l.require_log_mapping("this").is_err());
        assert!(build_model(&c, 3, None, None)
            .unwrap()
            .require_log_mapping("this")
            .is_ok());
    }

    #[test]
    fn malformed_files_are_typed_errors() {
        let c = small_corpus();
        let m = build_model(&c, 4, Some(2), None).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.bin");
        m.save(&p).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        let bad = dir.path().join("bad.bin");
        let cases: Vec<Vec<u8>> = vec![
            bytes[..bytes.len() / 2].to_vec(),
            bytes[..bytes.len() - 1].to_vec(),
            [bytes.clone(), vec![0u8]].concat(),
            {
                let mut b = bytes.clone();
                b[0] = b'X';
                b
            },
            {
                let mut b = bytes.clone();
                b[8] = 99; // version
                b
            },
            {
                let mut b = bytes.clone();
                b[29..37].copy_from_slice(&u64::MAX.to_le_bytes()); // D
                b
            },
            {
                let mut b = bytes.clone();
                b[20] = 7; // mapping
                b
            },
            {
                let mut b = bytes.clone();
                b[20] = 1; // cosine mapping with ε = 0
                b
            },
            Vec::new(),
        ];
        for (i, case) in cases.iter().enumerate() {
            std::fs::write(&bad, case).unwrap();
            match Model::load(&bad) {
                Err(ReduceError::MalformedModel(_)) => {}
                other => panic!("case {i}: expected MalformedModel, got {other:?}"),
            }
        }
    }

    #[test]
    fn reconstruction_of_corpus_member_is_exact_with_all_components() {
        let c = small_corpus();
        let m = build_model(&c, 11, None, None).unwrap();
        let vals: Vec<f64> = c.row(5).iter().map(|&y| crate::from_log(y)).collect();
        let errs = m
            .reconstruction_errors(&vals, &[0, 1, m.components()])
            .unwrap();
        assert!((errs[0].relative - 1.0).abs() < 1e-9);
        assert!(errs[1].relative < 1.0);
        assert!(errs[2].relative < 1e-3, "{:?}", errs[2]);
        let rec = m.reconstruct_values(&vals, m.components()).unwrap();
        let worst = rec
            .iter()
            .zip(&vals)
            .map(|(a, b)| ((a + LOG_FLOOR) / (b + LOG_FLOOR)).ln().abs())
            .fold(0.0, f64::max);
        assert!(
            worst < 1e-3,
            "worst log error {worst}, K = {}, eigenvalues {:?}",
            m.components(),
            m.pca.eigenvalues
        );
        assert!(m.project_values(&vals[1..], 2).is_err());
    }
}

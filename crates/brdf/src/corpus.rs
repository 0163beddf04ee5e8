//! Corpora of materials and the log transform they are analysed in (thesis §4.1).

use crate::error::{BrdfError, Result};
use crate::nbrdf::Nbrdf;
use crate::spec::{self, MaterialSpec};
use crate::table::{MerlTable, BINS};
use std::path::{Path, PathBuf};

/// Floor `ε` added to BRDF values (1/sr) before taking the natural logarithm. `10⁻³ sr⁻¹` is
/// about the value of a Lambertian surface with albedo 0.3 %, darker than any material of the
/// MERL corpus at normal incidence.
pub const LOG_FLOOR: f64 = 1e-3;

/// Length of one material vector on the MERL grid (all bins of the three channels).
pub const MATERIAL_DIM: usize = 3 * BINS;

/// The log transform `y = ln(max(f, 0) + ε)` with its floor `ε` (thesis §4.1).
///
/// Data-driven models of measured BRDFs work on log values `y` rather than on the values `f`
/// (1/sr): a specular peak and a diffuse floor differ by five orders of magnitude, and a linear
/// model fitted to the values would spend itself on the peaks. The floor `ε` keeps zeros and
/// missing bins (negative values in a `.binary` file, treated as 0) finite and limits the weight
/// of the darkest, noisiest values. It is *added* rather than clamped, so the transform is
/// exactly invertible for valid values (`f = exp(y) − ε`).
///
/// Every crate of the workspace uses [`LOG_FLOOR`] = 10⁻³ sr⁻¹ ([`LogTransform::DEFAULT`],
/// and the shorthands [`to_log`], [`from_log`], [`from_log_clamped`]); a model that stores its
/// own floor (the `reduce` model file does) builds its transform with [`LogTransform::new`].
/// The inverse comes in two flavours: [`LogTransform::inverse`] returns negative values for
/// `y < ln ε` (a linear model can produce those, and they flag a physically invalid
/// reconstruction), while [`LogTransform::inverse_clamped`] clamps them to 0 (for rendering
/// and error metrics).
///
/// # Examples
///
/// ```
/// use brdf::LogTransform;
///
/// // the transform and its inverse
/// let y = brdf::to_log(0.25);
/// assert!((brdf::from_log(y) - 0.25).abs() < 1e-12);
/// assert_eq!(brdf::to_log(-1.0), brdf::to_log(0.0)); // missing = 0
/// assert!(LogTransform::DEFAULT.inverse(y.min(0.0) - 10.0) < 0.0);
/// assert_eq!(LogTransform::DEFAULT.inverse_clamped(-20.0), 0.0);
/// // a transform with its own floor
/// let t = LogTransform::new(0.01).unwrap();
/// assert_eq!(t.forward(0.0), 0.01f64.ln());
/// assert!(LogTransform::new(0.0).is_err());
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LogTransform {
    floor: f64,
}

impl Default for LogTransform {
    fn default() -> Self {
        Self::DEFAULT
    }
}

impl LogTransform {
    /// The workspace's transform, floor [`LOG_FLOOR`].
    pub const DEFAULT: LogTransform = LogTransform { floor: LOG_FLOOR };

    /// A transform with another floor (e.g. the one a model file was built with); the floor
    /// must be finite and positive.
    pub fn new(floor: f64) -> Result<Self> {
        if !(floor.is_finite() && floor > 0.0) {
            return Err(BrdfError::Parameter {
                model: "log transform".into(),
                param: "floor".into(),
                value: floor,
                reason: "must be finite and positive".into(),
            });
        }
        Ok(Self { floor })
    }

    /// The floor `ε` (1/sr).
    pub fn floor(&self) -> f64 {
        self.floor
    }

    /// `ln(max(f, 0) + ε)`: negative (missing) values count as 0.
    #[inline]
    pub fn forward(&self, f: f64) -> f64 {
        (f.max(0.0) + self.floor).ln()
    }

    /// `exp(y) − ε`: the exact inverse of [`Self::forward`] for valid values, negative when
    /// `y < ln ε` (physically invalid).
    #[inline]
    pub fn inverse(&self, y: f64) -> f64 {
        y.exp() - self.floor
    }

    /// [`Self::inverse`] clamped at 0.
    #[inline]
    pub fn inverse_clamped(&self, y: f64) -> f64 {
        self.inverse(y).max(0.0)
    }
}

/// [`LogTransform::forward`] with the workspace floor [`LOG_FLOOR`].
#[inline]
pub fn to_log(f: f64) -> f64 {
    LogTransform::DEFAULT.forward(f)
}

/// [`LogTransform::inverse`] with the workspace floor (negative below the floor).
#[inline]
pub fn from_log(y: f64) -> f64 {
    LogTransform::DEFAULT.inverse(y)
}

/// [`LogTransform::inverse_clamped`] with the workspace floor (never negative).
#[inline]
pub fn from_log_clamped(y: f64) -> f64 {
    LogTransform::DEFAULT.inverse_clamped(y)
}

/// Converts BRDF values to a log-space `f32` vector, rejecting NaN and infinities.
pub fn log_vector(values: &[f64]) -> Result<Vec<f32>> {
    if let Some(index) = values.iter().position(|v| !v.is_finite()) {
        return Err(non_finite("BRDF values", index));
    }
    Ok(values.iter().map(|&v| to_log(v) as f32).collect())
}

/// Converts a log-space vector back to BRDF values, clamping invalid (negative) values to 0.
pub fn values_from_log(y: &[f32]) -> Vec<f64> {
    y.iter().map(|&v| from_log_clamped(v as f64)).collect()
}

fn non_finite(what: &str, index: usize) -> BrdfError {
    BrdfError::NonFinite {
        path: what.into(),
        index,
    }
}

/// One material of a corpus, named and not yet decoded.
#[derive(Debug, Clone, PartialEq)]
pub enum Source {
    /// A neural BRDF of a weight directory.
    Nbrdf {
        /// The directory.
        dir: PathBuf,
        /// The material name (file prefix).
        name: String,
    },
    /// A MERL `.binary` file (named by its stem).
    Binary(PathBuf),
    /// Any other material spec (named by the spec as written).
    Spec(String),
    /// Row `index` of a corpus store read by a registered [`StoreReader`] (its vectors are
    /// already in log space, of length `dim`).
    Stored {
        /// The store (a directory).
        store: PathBuf,
        /// Row of the material.
        index: usize,
        /// The material name recorded in the store.
        name: String,
        /// Vector length of the store (3 × bins of its grid).
        dim: usize,
    },
}

impl Source {
    /// The material's name in the corpus.
    pub fn name(&self) -> String {
        match self {
            Source::Nbrdf { name, .. } => name.clone(),
            Source::Binary(p) => p.file_stem().map_or_else(
                || p.display().to_string(),
                |s| s.to_string_lossy().into_owned(),
            ),
            Source::Spec(s) => s.clone(),
            Source::Stored { name, .. } => name.clone(),
        }
    }

    /// Loads the material.
    pub fn load(&self) -> Result<spec::Material> {
        match self {
            Source::Nbrdf { dir, name } => Ok(spec::Material::Nbrdf(Nbrdf::load(dir, name)?)),
            Source::Binary(p) => Ok(spec::Material::Table(crate::merl::read(p)?)),
            Source::Spec(s) => spec::load(s),
            Source::Stored { .. } => Ok(spec::Material::Table(MerlTable::from_values(
                values_from_log(&self.stored_log_row()?),
            )?)),
        }
    }

    /// The log-space vector of a [`Source::Stored`] on the full MERL grid (a store on a
    /// reduced grid has no MERL table: a [`BrdfError::Corpus`] error).
    fn stored_log_row(&self) -> Result<Vec<f32>> {
        let Source::Stored {
            store, index, dim, ..
        } = self
        else {
            return Err(BrdfError::Corpus("not a stored material".into()));
        };
        if *dim != MATERIAL_DIM {
            return Err(BrdfError::Corpus(format!(
                "{}: the store is on a reduced grid ({dim} values per material, not the \
                 {MATERIAL_DIM} of the MERL grid); only commands that take log-space vectors \
                 (e.g. PCA) read it",
                store.display()
            )));
        }
        read_stored(store, *index..*index + 1)
    }

    /// The material on the MERL grid.
    pub fn table(&self) -> Result<MerlTable> {
        match self {
            Source::Binary(p) => crate::merl::read(p),
            other => Ok(other.load()?.tabulate()),
        }
    }

    /// The material on the MERL grid as channel-major `f32` values (1/sr; negative = missing),
    /// through the fast `f32` decoder for neural BRDFs.
    pub fn values_f32(&self) -> Result<Vec<f32>> {
        match self {
            Source::Nbrdf { dir, name } => Ok(Nbrdf::load(dir, name)?.tabulate_f32()),
            Source::Stored { .. } => Ok(self
                .stored_log_row()?
                .iter()
                .map(|&y| from_log_clamped(y as f64) as f32)
                .collect()),
            other => Ok(other.table()?.values_f32()),
        }
    }
}

/// Reads corpus stores: on-disk collections of named log-space vectors in a format owned by
/// another crate (the `corpus-store` crate registers the Zarr store). With a reader
/// registered, [`sources_of`] expands a store directory into [`Source::Stored`] rows and
/// [`Corpus::load`] reads them, so every command that takes a corpus accepts a store.
pub trait StoreReader: Send + Sync {
    /// Whether the directory `path` is a store of this reader.
    fn accepts(&self, path: &Path) -> bool;
    /// Material names (row order) and vector length of the store.
    fn names(&self, path: &Path) -> Result<(Vec<String>, usize)>;
    /// Rows `rows` of the store, row-major log-space `f32` vectors.
    fn log_rows(&self, path: &Path, rows: std::ops::Range<usize>) -> Result<Vec<f32>>;
    /// The store format's name, for listings; registering a second reader of the same name
    /// replaces the first. Defaults to the implementing type's name.
    fn format(&self) -> &str {
        std::any::type_name::<Self>()
    }
}

static STORE_READERS: std::sync::RwLock<Vec<std::sync::Arc<dyn StoreReader>>> =
    std::sync::RwLock::new(Vec::new());

/// Registers a [`StoreReader`] process-wide; a reader of the same [`StoreReader::format`]
/// is replaced (so registration may be repeated). The first reader that accepts a path reads
/// it.
pub fn register_store_reader(reader: std::sync::Arc<dyn StoreReader>) {
    let mut all = STORE_READERS.write().unwrap_or_else(|e| e.into_inner());
    all.retain(|r| r.format() != reader.format());
    all.push(reader);
}

fn store_reader(path: &Path) -> Option<std::sync::Arc<dyn StoreReader>> {
    STORE_READERS
        .read()
        .unwrap_or_else(|e| e.into_inner())
        .iter()
        .find(|r| r.accepts(path))
        .cloned()
}

fn read_stored(store: &Path, rows: std::ops::Range<usize>) -> Result<Vec<f32>> {
    let reader = store_reader(store).ok_or_else(|| {
        BrdfError::Corpus(format!(
            "{}: no corpus-store reader is registered for this directory",
            store.display()
        ))
    })?;
    reader.log_rows(store, rows)
}

impl Source {
    fn stored_dim(&self) -> usize {
        match self {
            Source::Stored { dim, .. } => *dim,
            _ => MATERIAL_DIM,
        }
    }
}

/// The sources of one input: a directory (its neural-BRDF materials, then its `.binary`
/// files) or a material spec. A directory without either is a [`BrdfError::Corpus`] error.
pub fn sources_of(input: impl AsRef<Path>) -> Result<Vec<Source>> {
    let input = input.as_ref();
    if input.is_dir() {
        if let Some(reader) = store_reader(input) {
            let (names, dim) = reader.names(input)?;
            return Ok(names
                .into_iter()
                .enumerate()
                .map(|(index, name)| Source::Stored {
                    store: input.to_path_buf(),
                    index,
                    name,
                    dim,
                })
                .collect());
        }
        let mut out: Vec<Source> = crate::nbrdf::list(input)?
            .into_iter()
            .map(|name| Source::Nbrdf {
                dir: input.to_path_buf(),
                name,
            })
            .collect();
        let mut bins: Vec<PathBuf> = std::fs::read_dir(input)
            .map_err(|e| BrdfError::io(input, e))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|x| x == "binary"))
            .collect();
        bins.sort();
        out.extend(bins.into_iter().map(Source::Binary));
        if out.is_empty() {
            return Err(BrdfError::Corpus(format!(
                "{}: no NBRDF materials or .binary files",
                input.display()
            )));
        }
        return Ok(out);
    }
    let Some(text) = input.to_str() else {
        return Ok(vec![Source::Binary(input.to_path_buf())]);
    };
    Ok(vec![match spec::parse(text)? {
        MaterialSpec::Table(p) => Source::Binary(p),
        MaterialSpec::Nbrdf { dir, name } => Source::Nbrdf { dir, name },
        _ => Source::Spec(text.trim().to_string()),
    }])
}

/// The sources of all inputs, in order (see [`sources_of`]).
///
/// # Examples
///
/// ```
/// use brdf::Source;
///
/// // specs are named, not decoded
/// let s = brdf::sources(&["lambert:kd=0.2", "ggx:alpha=0.3"]).unwrap();
/// assert_eq!(s, [Source::Spec("lambert:kd=0.2".into()), Source::Spec("ggx:alpha=0.3".into())]);
/// assert_eq!(s[1].name(), "ggx:alpha=0.3");
/// ```
pub fn sources<P: AsRef<Path>>(inputs: &[P]) -> Result<Vec<Source>> {
    let mut out = Vec::new();
    for input in inputs {
        out.extend(sources_of(input)?);
    }
    Ok(out)
}

/// Loads every material of `inputs` as a named MERL table. No material at all is an error.
pub fn load_tables<P: AsRef<Path>>(inputs: &[P]) -> Result<Vec<(String, MerlTable)>> {
    let all = sources(inputs)?;
    if all.is_empty() {
        return Err(BrdfError::Corpus("no materials given".into()));
    }
    all.iter()
        .map(|s| {
            let t = s.table()?;
            tracing::debug!(material = %s.name(), "corpus: tabulated");
            Ok((s.name(), t))
        })
        .collect()
}

/// Named materials as log-space vectors of equal length, stored as `f32`, material-major, in
/// one contiguous buffer (96 MERL materials take 1.68 GB).
///
/// A corpus is given as a list of inputs, each a directory (all neural-BRDF materials of it,
/// then all its `.binary` files, each group sorted by name), a corpus store read by a registered
/// [`StoreReader`], or a material spec ([`MaterialSpec`]: `merl:chrome`, a `.binary` path, an
/// analytic model, any registered form). [`sources`] expands the list into named [`Source`]s
/// without decoding anything; [`load_tables`] decodes them as MERL tables and [`Corpus::load`]
/// as vectors in the log space of [`LogTransform`].
///
/// # Examples
///
/// ```
/// use brdf::Corpus;
///
/// // two analytic materials as log-space vectors on the MERL grid
/// let c = Corpus::load(&["lambert:kd=0.2", "ggx:alpha=0.3"]).unwrap();
/// assert_eq!(c.len(), 2);
/// assert_eq!(c.dim(), brdf::MATERIAL_DIM);
/// assert_eq!(c.row(0)[0], brdf::to_log(0.2 / std::f64::consts::PI) as f32);
/// ```
#[derive(Debug, Clone, Default)]
pub struct Corpus {
    names: Vec<String>,
    dim: usize,
    data: Vec<f32>,
}

impl Corpus {
    /// An empty corpus of vectors of length `dim`.
    pub fn new(dim: usize) -> Corpus {
        Corpus {
            names: Vec::new(),
            dim,
            data: Vec::new(),
        }
    }

    /// Appends a material given by its BRDF values (1/sr; negative = missing).
    pub fn push_values(&mut self, name: impl Into<String>, values: &[f64]) -> Result<()> {
        self.check_len(values.len())?;
        let y = log_vector(values)?;
        self.data.extend_from_slice(&y);
        self.names.push(name.into());
        Ok(())
    }

    /// Appends a material given by single-precision BRDF values, converted in place to log
    /// space.
    pub fn push_values_f32(&mut self, name: impl Into<String>, mut values: Vec<f32>) -> Result<()> {
        self.check_len(values.len())?;
        if let Some(index) = values.iter().position(|v| !v.is_finite()) {
            return Err(non_finite("BRDF values", index));
        }
        for v in values.iter_mut() {
            *v = to_log(*v as f64) as f32;
        }
        if self.data.is_empty() {
            self.data = values;
        } else {
            self.data.extend_from_slice(&values);
        }
        self.names.push(name.into());
        Ok(())
    }

    /// Appends a source decoded on the MERL grid (the corpus dimension must be
    /// [`MATERIAL_DIM`]).
    pub fn push_source(&mut self, source: &Source) -> Result<()> {
        if let Source::Stored {
            store, index, dim, ..
        } = source
        {
            self.check_len(*dim)?;
            let row = read_stored(store, *index..*index + 1)?;
            self.push_log(source.name(), &row)?;
            return Ok(());
        }
        self.check_len(MATERIAL_DIM)?;
        match source {
            Source::Binary(p) => self.push_values(source.name(), &crate::merl::read(p)?.values()),
            other => self.push_values_f32(other.name(), other.values_f32()?),
        }?;
        tracing::debug!(material = %source.name(), "corpus: decoded");
        Ok(())
    }

    /// Appends a material given as a log-space vector (as a store holds them).
    pub fn push_log(&mut self, name: impl Into<String>, y: &[f32]) -> Result<()> {
        self.check_len(y.len())?;
        if let Some(index) = y.iter().position(|v| !v.is_finite()) {
            return Err(non_finite("log-space vector", index));
        }
        self.data.extend_from_slice(y);
        self.names.push(name.into());
        Ok(())
    }

    fn check_len(&self, len: usize) -> Result<()> {
        if len != self.dim {
            return Err(BrdfError::Length {
                expected: self.dim,
                found: len,
            });
        }
        Ok(())
    }

    /// Loads every complete material of an NBRDF weight directory (sorted by name), decoding
    /// each on the MERL grid with the `f32` fast path.
    pub fn from_nbrdf_dir(dir: impl AsRef<Path>) -> Result<Corpus> {
        let dir = dir.as_ref();
        let names = crate::nbrdf::list(dir)?;
        let mut c = Corpus::new(MATERIAL_DIM);
        c.data.reserve(names.len() * MATERIAL_DIM);
        for name in names {
            c.push_source(&Source::Nbrdf {
                dir: dir.to_path_buf(),
                name,
            })?;
        }
        Ok(c)
    }

    /// Loads MERL `.binary` files (material name = file stem).
    pub fn from_binary_files<P: AsRef<Path>>(paths: &[P]) -> Result<Corpus> {
        let mut c = Corpus::new(MATERIAL_DIM);
        for p in paths {
            c.push_source(&Source::Binary(p.as_ref().to_path_buf()))?;
        }
        Ok(c)
    }

    /// Loads a corpus from a mix of inputs: directories (all NBRDF materials and all `.binary`
    /// files in them) and material specs (which include `.binary` paths); see [`sources`].
    ///
    /// A corpus store (a directory a registered [`StoreReader`] accepts) contributes its
    /// log-space vectors as stored, read in runs of consecutive rows; a corpus made only of
    /// stores on a reduced grid has that grid's dimension.
    pub fn load<P: AsRef<Path>>(inputs: &[P]) -> Result<Corpus> {
        let all = sources(inputs)?;
        let dim = match all.first() {
            Some(Source::Stored { dim, .. }) => *dim,
            _ => MATERIAL_DIM,
        };
        let mut c = Corpus::new(dim);
        c.data.reserve(all.len() * dim);
        let mut i = 0;
        while i < all.len() {
            if let Source::Stored { store, index, .. } = &all[i] {
                // the run of consecutive rows of the same store
                let mut j = i + 1;
                while let Some(Source::Stored {
                    store: s2,
                    index: i2,
                    ..
                }) = all.get(j)
                {
                    if s2 != store || *i2 != index + (j - i) {
                        break;
                    }
                    j += 1;
                }
                c.check_len(all[i].stored_dim())?;
                let rows = read_stored(store, *index..index + (j - i))?;
                for (k, src) in all[i..j].iter().enumerate() {
                    c.push_log(src.name(), &rows[k * dim..(k + 1) * dim])?;
                }
                i = j;
                continue;
            }
            c.push_source(&all[i])?;
            i += 1;
        }
        Ok(c)
    }

    /// Number of materials.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// Whether the corpus is empty.
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// Vector length `D`.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Material names, in row order.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// All vectors, row-major `N × D`.
    pub fn data(&self) -> &[f32] {
        &self.data
    }

    /// The log-space vector of material `i` (panics when `i >= len()`, like slice indexing).
    pub fn row(&self, i: usize) -> &[f32] {
        &self.data[i * self.dim..(i + 1) * self.dim]
    }

    /// Takes the buffer out (e.g. to convert it to linear values for NMF without a copy).
    pub fn into_parts(self) -> (Vec<String>, usize, Vec<f32>) {
        (self.names, self.dim, self.data)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn log_transform_round_trips_and_takes_its_floor_as_a_parameter() {
        for v in [0.0, 1e-4, 0.3, 17.0, 3000.0] {
            let back = from_log(to_log(v));
            assert!((back - v).abs() <= 1e-12 * (v + LOG_FLOOR), "{v} -> {back}");
        }
        let t = LogTransform::new(0.05).unwrap();
        assert!((t.forward(0.0) - 0.05f64.ln()).abs() < 1e-15);
        assert!((t.inverse(t.forward(2.0)) - 2.0).abs() < 1e-12);
        assert!(t.inverse(0.05f64.ln() - 1.0) < 0.0);
        assert_eq!(t.inverse_clamped(0.05f64.ln() - 1.0), 0.0);
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(LogTransform::new(bad).is_err(), "{bad}");
        }
        assert_eq!(LogTransform::default(), LogTransform::DEFAULT);
        assert!(log_vector(&[1.0, f64::NAN]).is_err());
        assert_eq!(values_from_log(&[-30.0, to_log(1.5) as f32])[0], 0.0);
    }

    #[test]
    fn corpus_checks_lengths() {
        let mut c = Corpus::new(4);
        c.push_values("a", &[0.1, 0.2, 0.3, -1.0]).unwrap();
        c.push_values_f32("b", vec![1.0, 2.0, 3.0, 4.0]).unwrap();
        assert!(c.push_values("c", &[1.0]).is_err());
        assert!(c.push_values_f32("d", vec![f32::INFINITY; 4]).is_err());
        assert_eq!(c.len(), 2);
        assert_eq!(c.row(1)[1], to_log(2.0) as f32);
        assert_eq!(c.names(), ["a", "b"]);
    }

    #[test]
    fn directories_binary_files_and_specs_make_one_corpus() {
        let dir = tempfile::tempdir().unwrap();
        let lambert = crate::analytic::Lambert {
            kd: [0.4, 0.3, 0.2],
        };
        let table = MerlTable::tabulate(&lambert);
        crate::merl::write(dir.path().join("b.binary"), &table).unwrap();
        crate::merl::write(dir.path().join("a.binary"), &table).unwrap();
        let srcs = sources(&[
            dir.path().to_str().unwrap(),
            "lambert:kd=0.4/0.3/0.2",
            dir.path().join("a.binary").to_str().unwrap(),
        ])
        .unwrap();
        let names: Vec<String> = srcs.iter().map(Source::name).collect();
        assert_eq!(names, ["a", "b", "lambert:kd=0.4/0.3/0.2", "a"]);
        let tables = load_tables(&srcs_inputs(&srcs)).unwrap();
        assert_eq!(tables.len(), 4);
        let c = Corpus::load(&srcs_inputs(&srcs)).unwrap();
        // the spec and the files hold the same material
        let max_diff = |a: &[f32], b: &[f32]| {
            a.iter()
                .zip(b)
                .map(|(x, y)| (x - y).abs())
                .fold(0.0f32, f32::max)
        };
        assert!(max_diff(c.row(0), c.row(2)) < 1e-5);
        assert_eq!(c.row(0), c.row(3));
        assert!((c.row(2)[0] - to_log(0.4 / std::f64::consts::PI) as f32).abs() < 1e-6);

        let empty = tempfile::tempdir().unwrap();
        assert!(matches!(
            Corpus::load(&[empty.path()]),
            Err(BrdfError::Corpus(_))
        ));
        assert!(load_tables::<&str>(&[]).is_err());
        assert!(Corpus::load(&["no-such-model:1"]).is_err());
    }

    fn srcs_inputs(srcs: &[Source]) -> Vec<String> {
        srcs.iter()
            .map(|s| match s {
                Source::Binary(p) => p.display().to_string(),
                Source::Spec(s) => s.clone(),
                Source::Nbrdf { dir, name } => format!("nbrdf:{}/{name}", dir.display()),
                Source::Stored { store, .. } => store.display().to_string(),
            })
            .collect()
    }
}

//! # reflectance-py — the toolkit as a Python package (import name `reflectance`)
//!
//! A thin PyO3 layer over the workspace crates: [`brdf`] (material specs, evaluation,
//! tabulation, MERL files, summaries), [`reduce`] (PCA models, the Gram kernel), [`render`]
//! (the thesis's figures and scene files, the importance tables of thesis A.2.4) and
//! [`acquire`] (the capture job on the simulated rig). No reflectance logic lives here: each
//! function converts its arguments, releases the GIL, calls one crate function and converts
//! the result. Errors of the crates become `ValueError` (bad input, bad specs) or `OSError`
//! (files) carrying the crate's message.
//!
//! The extension module is built by maturin (`pip install ./bindings/python`); it cannot be
//! linked into a Rust test binary, so its doctests and tests are Python: see
//! `bindings/python/tests/`, `bindings/python/examples/` and `docs/python.md`. The
//! Python side of the package (`bindings/python/python/reflectance/`) adds the Mitsuba 3 BSDF.
//!
//! ```python
//! import reflectance
//! m = reflectance.load("merl:blue-acrylic")
//! table = m.tabulate()            # numpy (90, 90, 180, 3), 1/sr
//! f = m.eval(0.1, 0.5, 1.0)       # (3,) at (θh, θd, φd)
//! ```

use brdf::{Brdf, HalfDiff, Vec3};
use numpy::ndarray::{ArrayD, IxDyn};
use numpy::{
    IntoPyArray, PyArray1, PyArrayDescrMethods, PyArrayDyn, PyReadonlyArray2, PyReadonlyArrayDyn,
    PyUntypedArray, PyUntypedArrayMethods,
};
use pyo3::exceptions::{PyOSError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;
use std::path::PathBuf;
use std::sync::{Arc, Mutex, Once};

/// Shape of a tabulated material: (θh, θd, φd, RGB).
const TABLE_SHAPE: [usize; 4] = [brdf::THETA_H_RES, brdf::THETA_D_RES, brdf::PHI_D_RES, 3];

fn value_error(e: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(e.to_string())
}

/// Installs the workspace's catalogue of spec forms and corpus stores, as `gantry` does.
fn register_specs() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| catalogue::Catalogue::workspace().install());
}

fn brdf_error(e: brdf::BrdfError) -> PyErr {
    match e {
        brdf::BrdfError::Io { .. } => PyOSError::new_err(e.to_string()),
        other => value_error(other),
    }
}

/// Any array-like as a C-contiguous float64 numpy array.
fn f64_array<'py>(obj: &Bound<'py, PyAny>) -> PyResult<PyReadonlyArrayDyn<'py, f64>> {
    aligned_c(obj, Some("float64"))?.extract::<PyReadonlyArrayDyn<'py, f64>>()
}

/// `obj` as a C-contiguous, aligned numpy array (of `dtype` when given), copied only if it is
/// not one already. Alignment matters: an array unpickled from a byte buffer (as Dask ships
/// scattered data) can start at an odd address, and a slice over it is undefined behaviour.
/// `require` keeps 0-d input 0-d (`ascontiguousarray` would make it 1-d).
fn aligned_c<'py>(obj: &Bound<'py, PyAny>, dtype: Option<&str>) -> PyResult<Bound<'py, PyAny>> {
    let np = obj.py().import("numpy")?;
    let kwargs = PyDict::new(obj.py());
    if let Some(dtype) = dtype {
        kwargs.set_item("dtype", dtype)?;
    }
    kwargs.set_item("requirements", "CA")?;
    np.call_method("require", (obj,), Some(&kwargs))
}

/// A flat row-major vector as a numpy array of the given shape.
fn to_numpy<'py, T: numpy::Element>(
    py: Python<'py>,
    data: Vec<T>,
    shape: Vec<usize>,
) -> PyResult<Bound<'py, PyArrayDyn<T>>> {
    let a = ArrayD::from_shape_vec(IxDyn(&shape), data).map_err(value_error)?;
    Ok(a.into_pyarray(py))
}

/// A table's channel-major values as a row-major (90, 90, 180, 3) vector.
fn table_to_rows(table: &brdf::MerlTable) -> Vec<f64> {
    let values = table.values();
    let bins = brdf::BINS;
    let mut out = vec![0.0; 3 * bins];
    for c in 0..3 {
        for (b, v) in values[c * bins..(c + 1) * bins].iter().enumerate() {
            out[b * 3 + c] = *v;
        }
    }
    out
}

fn table_from_array(obj: &Bound<'_, PyAny>) -> PyResult<brdf::MerlTable> {
    let arr = f64_array(obj)?;
    if arr.shape() != TABLE_SHAPE {
        return Err(value_error(format!(
            "a table has shape (90, 90, 180, 3), not {:?}",
            arr.shape()
        )));
    }
    let rows = arr.as_slice().map_err(value_error)?;
    let bins = brdf::BINS;
    let mut values = vec![0.0; 3 * bins];
    for b in 0..bins {
        for c in 0..3 {
            values[c * bins + b] = rows[b * 3 + c];
        }
    }
    brdf::MerlTable::from_values(values).map_err(brdf_error)
}

fn interpolation(name: Option<&str>) -> PyResult<Option<brdf::Interpolation>> {
    match name {
        None => Ok(None),
        Some("nearest") => Ok(Some(brdf::Interpolation::Nearest)),
        Some("trilinear") => Ok(Some(brdf::Interpolation::Trilinear)),
        Some(other) => Err(value_error(format!(
            "interpolation '{other}': expected 'nearest' or 'trilinear'"
        ))),
    }
}

/// A material: any spec of the toolkit (`merl:<name>`, `nielsen:<name>`, a `.binary` file,
/// an analytic model such as `ggx:alpha=0.2`, `pca:` and `wavelet:` forms), loaded by
/// `reflectance.load`.
#[pyclass(frozen, name = "Material", module = "reflectance")]
struct PyMaterial {
    inner: Arc<brdf::Material>,
    spec: String,
}

impl PyMaterial {
    fn from_material(mut m: brdf::Material, spec: String, interp: Option<&str>) -> PyResult<Self> {
        if let Some(mode) = interpolation(interp)? {
            match &mut m {
                brdf::Material::Table(t) => *t = t.clone().with_interpolation(mode),
                _ => {
                    return Err(value_error(format!(
                        "'{spec}' is not a tabulated material: interpolation does not apply"
                    )))
                }
            }
        }
        Ok(Self {
            inner: Arc::new(m),
            spec,
        })
    }
}

#[pymethods]
impl PyMaterial {
    /// The spec the material was loaded from.
    #[getter]
    fn spec(&self) -> String {
        self.spec.clone()
    }

    /// A short human-readable name.
    #[getter]
    fn name(&self) -> String {
        self.inner.name()
    }

    /// Whether the material depends only on (θh, θd, φd).
    #[getter]
    fn is_isotropic(&self) -> bool {
        self.inner.is_isotropic()
    }

    /// BRDF values (1/sr, RGB) at Rusinkiewicz angles (radians). The three arguments broadcast
    /// against each other; the result has their shape plus a last axis of 3. Tabulated
    /// materials use their interpolation (nearest unless loaded with `interpolation=`).
    fn eval<'py>(
        &self,
        py: Python<'py>,
        theta_h: &Bound<'py, PyAny>,
        theta_d: &Bound<'py, PyAny>,
        phi_d: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let np = py.import("numpy")?;
        let b = np.call_method1("broadcast_arrays", (theta_h, theta_d, phi_d))?;
        let th = f64_array(&b.get_item(0)?)?;
        let td = f64_array(&b.get_item(1)?)?;
        let pd = f64_array(&b.get_item(2)?)?;
        let mut shape = th.shape().to_vec();
        let (th, td, pd) = (
            th.as_slice().map_err(value_error)?,
            td.as_slice().map_err(value_error)?,
            pd.as_slice().map_err(value_error)?,
        );
        let m = &self.inner;
        let out: Vec<f64> = py.allow_threads(|| {
            (0..th.len())
                .into_par_iter()
                .flat_map_iter(|i| m.eval_half_diff(&HalfDiff::isotropic(th[i], td[i], pd[i])))
                .collect()
        });
        shape.push(3);
        to_numpy(py, out, shape)
    }

    /// BRDF values (1/sr, RGB) for direction pairs in the local frame (normal +z): `wi`
    /// towards the light, `wo` towards the viewer, arrays of shape (..., 3) that broadcast.
    fn eval_directions<'py>(
        &self,
        py: Python<'py>,
        wi: &Bound<'py, PyAny>,
        wo: &Bound<'py, PyAny>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let np = py.import("numpy")?;
        let b = np.call_method1("broadcast_arrays", (wi, wo))?;
        let a = f64_array(&b.get_item(0)?)?;
        let o = f64_array(&b.get_item(1)?)?;
        let shape = a.shape().to_vec();
        if shape.last() != Some(&3) {
            return Err(value_error(format!(
                "directions have a last axis of 3, not shape {shape:?}"
            )));
        }
        let (a, o) = (
            a.as_slice().map_err(value_error)?,
            o.as_slice().map_err(value_error)?,
        );
        let m = &self.inner;
        let out: Vec<f64> = py.allow_threads(|| {
            (0..a.len() / 3)
                .into_par_iter()
                .flat_map_iter(|i| {
                    let wi = Vec3::new(a[3 * i], a[3 * i + 1], a[3 * i + 2]);
                    let wo = Vec3::new(o[3 * i], o[3 * i + 1], o[3 * i + 2]);
                    m.eval(&wi, &wo)
                })
                .collect()
        });
        to_numpy(py, out, shape)
    }

    /// The material tabulated on the MERL grid: float64 array (90, 90, 180, 3) in 1/sr indexed
    /// (θh bin, θd bin, φd bin, channel); negative values mark missing bins.
    fn tabulate<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let m = &self.inner;
        let rows = py.allow_threads(|| table_to_rows(&m.tabulate()));
        to_numpy(py, rows, TABLE_SHAPE.to_vec())
    }

    /// Writes the tabulated material as a MERL `.binary` file (atomically).
    fn write_merl(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let m = &self.inner;
        py.allow_threads(|| brdf::merl::write(&path, &m.tabulate()))
            .map_err(brdf_error)
    }

    /// Writes the material as an RGL tensor `.bsdf` file (atomically), which Mitsuba 3's
    /// `measured` BSDF (RGB variants) and pbrt-v4's `measured` material read. `resolution` is
    /// the side of the warped reflectance grid, `theta_i` the number of incident elevations;
    /// `spectral=True` writes a spectral file (pbrt-v4, Mitsuba's spectral variants).
    #[pyo3(signature = (path, resolution = 32, theta_i = 16, spectral = false))]
    fn save_bsdf(
        &self,
        py: Python<'_>,
        path: PathBuf,
        resolution: usize,
        theta_i: usize,
        spectral: bool,
    ) -> PyResult<()> {
        let m = &self.inner;
        let options = rgl_bsdf::WriteOptions {
            resolution,
            vndf_resolution: resolution,
            theta_i,
            spectral,
            description: self.spec.clone(),
            ..Default::default()
        };
        py.allow_threads(|| rgl_bsdf::write(m.as_brdf(), &options).and_then(|f| f.write(&path)))
            .map_err(|e| value_error(e.to_string()))
    }

    /// Directional albedo (RGB) for light at polar angle `theta_i` (radians), by the
    /// quadrature of `brdf::directional_albedo` on `n_u` × `n_phi` cells.
    #[pyo3(signature = (theta_i, n_u=256, n_phi=256))]
    fn albedo(&self, py: Python<'_>, theta_i: f64, n_u: usize, n_phi: usize) -> [f64; 3] {
        let m = &self.inner;
        py.allow_threads(|| brdf::directional_albedo(m.as_ref(), theta_i, n_u.max(1), n_phi.max(1)))
    }

    /// Relative RMS difference between f(ωi, ωo) and f(ωo, ωi) over `n` seeded random pairs.
    #[pyo3(signature = (n=20000, seed=1))]
    fn reciprocity_residual(&self, py: Python<'_>, n: usize, seed: u64) -> f64 {
        let m = &self.inner;
        py.allow_threads(|| brdf::reciprocity_residual(m.as_ref(), n, seed))
    }

    /// The summary of `gantry info --json` as a dict: peak, albedo curve, reciprocity residual,
    /// missing fraction.
    fn summary<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let m = &self.inner;
        let json = py.allow_threads(|| {
            let table = m.tabulate();
            let s = brdf::summarize(m.as_ref(), &table, &brdf::SummaryOptions::default());
            serde_json::to_string(&s)
        });
        py.import("json")?
            .call_method1("loads", (json.map_err(value_error)?,))
    }

    /// Importance-sampling tables of the tabulated material (thesis A.2.4, built by
    /// `render::BrdfImportance`): a dict of `cell` (θr × θi × φdiff cell weights, float32),
    /// `conditional_cdf` (same shape), `marginal_cdf` (θr × (θi + 1), float64), `row_totals`
    /// (θr) and `defensive` (the cosine-sampling fraction); the same density as alias tables
    /// (`render::BrdfImportance::alias_tables`): `marginal_alias` (θr × θi × (threshold, alias)),
    /// `conditional_alias` (θr × θi × φdiff × (threshold, alias)) and
    /// `cell_density` (θr × θi × φdiff, the density within each cell before the defensive
    /// mixture), all float32.
    #[pyo3(signature = (theta_r=90, theta_i=90, phi_diff=180, supersample=2))]
    fn importance_tables<'py>(
        &self,
        py: Python<'py>,
        theta_r: usize,
        theta_i: usize,
        phi_diff: usize,
        supersample: usize,
    ) -> PyResult<Bound<'py, PyDict>> {
        let res = render::ImportanceResolution {
            theta_r: theta_r.max(1),
            theta_i: theta_i.max(1),
            phi_diff: phi_diff.max(1),
            supersample: supersample.max(1),
        };
        let m = &self.inner;
        let t = py.allow_threads(|| {
            let table = m
                .tabulate()
                .with_interpolation(brdf::Interpolation::Trilinear);
            render::BrdfImportance::build(&table, res)
        });
        let (nr, na, nk) = (res.theta_r, res.theta_i, res.phi_diff);
        let d = PyDict::new(py);
        d.set_item(
            "cell",
            to_numpy(py, t.cell_weights().to_vec(), vec![nr, na, nk])?,
        )?;
        d.set_item(
            "conditional_cdf",
            to_numpy(py, t.conditional_cdf().to_vec(), vec![nr, na, nk])?,
        )?;
        d.set_item(
            "marginal_cdf",
            to_numpy(py, t.marginal_cdf(), vec![nr, na + 1])?,
        )?;
        d.set_item(
            "row_totals",
            PyArray1::from_vec(py, t.row_totals().to_vec()),
        )?;
        d.set_item("defensive", t.defensive())?;
        let alias = t.alias_tables();
        d.set_item(
            "marginal_alias",
            to_numpy(py, alias.marginal, vec![nr, na, 2])?,
        )?;
        d.set_item(
            "conditional_alias",
            to_numpy(py, alias.conditional, vec![nr, na, nk, 2])?,
        )?;
        d.set_item(
            "cell_density",
            to_numpy(py, alias.cell_density, vec![nr, na, nk])?,
        )?;
        Ok(d)
    }

    fn __repr__(&self) -> String {
        format!("reflectance.Material({:?})", self.spec)
    }
}

/// Loads a material spec (see docs/material-spec.md). `interpolation` ('nearest' or
/// 'trilinear') sets the lookup of tabulated materials. A bad spec raises ValueError.
#[pyfunction]
#[pyo3(signature = (spec, interpolation=None))]
fn load(py: Python<'_>, spec: &str, interpolation: Option<&str>) -> PyResult<PyMaterial> {
    register_specs();
    let m = py
        .allow_threads(|| brdf::load(spec))
        .map_err(|e| value_error(format!("cannot load material '{spec}': {e}")))?;
    PyMaterial::from_material(m, spec.to_string(), interpolation)
}

/// The material-spec forms this package reads, as users write them (the same list as
/// `gantry forms`).
#[pyfunction]
fn spec_forms() -> Vec<String> {
    register_specs();
    catalogue::Catalogue::workspace().forms()
}

/// A material from a (90, 90, 180, 3) array of BRDF values in 1/sr (negative = missing).
#[pyfunction]
#[pyo3(signature = (table, name=None, interpolation=None))]
fn from_table(
    table: &Bound<'_, PyAny>,
    name: Option<String>,
    interpolation: Option<&str>,
) -> PyResult<PyMaterial> {
    let mut t = table_from_array(table)?;
    let name = name.unwrap_or_else(|| "table".into());
    t = t.with_name(name.clone());
    PyMaterial::from_material(brdf::Material::Table(t), name, interpolation)
}

/// Reads a MERL `.binary` file into a (90, 90, 180, 3) float64 array (1/sr).
#[pyfunction]
fn read_merl<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let rows = py
        .allow_threads(|| brdf::merl::read(&path).map(|t| table_to_rows(&t)))
        .map_err(brdf_error)?;
    to_numpy(py, rows, TABLE_SHAPE.to_vec())
}

/// Writes a (90, 90, 180, 3) array of BRDF values (1/sr) as a MERL `.binary` file (atomically).
#[pyfunction]
fn write_merl(py: Python<'_>, path: PathBuf, table: &Bound<'_, PyAny>) -> PyResult<()> {
    let t = table_from_array(table)?;
    py.allow_threads(|| brdf::merl::write(&path, &t))
        .map_err(brdf_error)
}

/// Rows of a 2-D float array as f32 values: the array itself when C-contiguous float32, a
/// converted copy otherwise.
enum Rows<'py> {
    Borrowed(PyReadonlyArray2<'py, f32>),
    Owned(Vec<f32>),
}

impl Rows<'_> {
    fn slice(&self) -> &[f32] {
        match self {
            Rows::Borrowed(a) => a.as_slice().unwrap_or(&[]),
            Rows::Owned(v) => v,
        }
    }
}

/// `obj` as rows of f32; anything but a 2-D float32/float64 numpy array is a ValueError.
fn rows_f32<'py>(what: &str, obj: &Bound<'py, PyAny>) -> PyResult<(Rows<'py>, usize, usize)> {
    let py = obj.py();
    let arr = obj.downcast::<PyUntypedArray>().map_err(|_| {
        value_error(format!(
            "{what}: expected a numpy array, got {}",
            obj.get_type()
        ))
    })?;
    if arr.ndim() != 2 {
        return Err(value_error(format!(
            "{what}: expected a 2-D array (rows, dim), got {} dimensions",
            arr.ndim()
        )));
    }
    let (m, d) = (arr.shape()[0], arr.shape()[1]);
    let dtype = arr.dtype();
    if dtype.is_equiv_to(&numpy::dtype::<f32>(py)) {
        let a: PyReadonlyArray2<'py, f32> = aligned_c(obj, None)?.extract()?;
        // (`as_slice` also accepts Fortran order, whose slice is not row-major)
        if a.is_c_contiguous() {
            return Ok((Rows::Borrowed(a), m, d));
        }
        let v = a.as_array().iter().copied().collect();
        return Ok((Rows::Owned(v), m, d));
    }
    if dtype.is_equiv_to(&numpy::dtype::<f64>(py)) {
        let a: PyReadonlyArray2<'py, f64> = aligned_c(obj, None)?.extract()?;
        let v: Vec<f32> = a.as_array().iter().map(|&x| x as f32).collect();
        return Ok((Rows::Owned(v), m, d));
    }
    Err(value_error(format!(
        "{what}: expected dtype float32 or float64, got {dtype}"
    )))
}

/// `a · bᵀ` (float64, shape (m, n)) of the rows of `a` (m, d) and `b` (n, d), or `a · aᵀ` when
/// `b` is None, by `reduce::gram`'s SIMD kernel (f32 products within blocks of 1024
/// dimensions, f64 sums). C-contiguous float32 input is read in place; float64 is converted
/// to float32 first. The GIL is released. Bad shapes or dtypes raise ValueError.
#[pyfunction]
#[pyo3(signature = (a, b=None))]
fn gram<'py>(
    py: Python<'py>,
    a: &Bound<'py, PyAny>,
    b: Option<&Bound<'py, PyAny>>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let (ra, m, dim) = rows_f32("a", a)?;
    let g = match b {
        None => {
            let data = ra.slice();
            py.allow_threads(|| reduce::gram_matrix(data, m, dim, None))
        }
        Some(b) => {
            let (rb, n, dim_b) = rows_f32("b", b)?;
            if dim_b != dim {
                return Err(value_error(format!(
                    "a has rows of {dim} values but b of {dim_b}"
                )));
            }
            let (x, y) = (ra.slice(), rb.slice());
            py.allow_threads(|| reduce::cross_gram_matrix(x, m, y, n, dim))
        }
    }
    .map_err(value_error)?;
    let (r, c) = (g.nrows(), g.ncols());
    let rows: Vec<f64> = (0..r)
        .flat_map(|i| (0..c).map(move |j| (i, j)))
        .map(|(i, j)| g[(i, j)])
        .collect();
    to_numpy(py, rows, vec![r, c])
}

/// A PCA model of log-space BRDFs (thesis §4.1; `reduce::Model`): built from a corpus
/// of material specs with `PcaModel.build`, or read from a `gantry model build` file.
#[pyclass(frozen, name = "PcaModel", module = "reflectance.models")]
struct PyModel {
    inner: Arc<reduce::Model>,
    /// The half-precision decoder of `reconstruct(x, fast=True)`, built on first use.
    decoder: std::sync::OnceLock<reduce::Decoder>,
}

fn material_values(obj: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
    if let Ok(m) = obj.downcast::<PyMaterial>() {
        let inner = m.get().inner.clone();
        return Ok(obj.py().allow_threads(|| inner.tabulate().values()));
    }
    if let Ok(spec) = obj.extract::<String>() {
        register_specs();
        let m = brdf::load(&spec)
            .map_err(|e| value_error(format!("cannot load material '{spec}': {e}")))?;
        return Ok(obj.py().allow_threads(|| m.tabulate().values()));
    }
    Ok(table_from_array(obj)?.values())
}

fn values_to_table<'py>(
    py: Python<'py>,
    values: Vec<f64>,
) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let t = brdf::MerlTable::from_values(values).map_err(brdf_error)?;
    to_numpy(py, table_to_rows(&t), TABLE_SHAPE.to_vec())
}

#[pymethods]
impl PyModel {
    /// PCA with `components` components of the materials of `specs` (each tabulated on the
    /// MERL grid and log-transformed, `reduce::build_model`). Each entry is a corpus
    /// input as `gantry model build --corpus` takes it: a material spec, a folder of neural-BRDF
    /// weights and/or `.binary` files, or a corpus store.
    #[staticmethod]
    #[pyo3(signature = (specs, components=reduce::DEFAULT_COMPONENTS))]
    fn build(py: Python<'_>, specs: Vec<String>, components: usize) -> PyResult<PyModel> {
        register_specs();
        let model = py.allow_threads(|| -> Result<reduce::Model, String> {
            let corpus =
                reduce::Corpus::load(&specs).map_err(|e| format!("cannot load the corpus: {e}"))?;
            reduce::build_model(&corpus, components, None, None).map_err(|e| e.to_string())
        });
        Ok(PyModel {
            inner: Arc::new(model.map_err(value_error)?),
            decoder: Default::default(),
        })
    }

    /// Reads a model file (`gantry model build`, `PcaModel.save`).
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<PyModel> {
        let m = py
            .allow_threads(|| reduce::Model::load(&path))
            .map_err(|e| PyOSError::new_err(format!("{}: {e}", path.display())))?;
        Ok(PyModel {
            inner: Arc::new(m),
            decoder: Default::default(),
        })
    }

    /// Writes the model file (atomically).
    fn save(&self, py: Python<'_>, path: PathBuf) -> PyResult<()> {
        let m = &self.inner;
        py.allow_threads(|| m.save(&path))
            .map_err(|e| PyOSError::new_err(format!("{}: {e}", path.display())))
    }

    /// Names (specs) of the corpus materials, in row order.
    #[getter]
    fn names(&self) -> Vec<String> {
        self.inner.names.clone()
    }

    /// Number of stored components.
    #[getter]
    fn components(&self) -> usize {
        self.inner.components()
    }

    /// Eigenvalues of the corpus covariance, largest first.
    #[getter]
    fn eigenvalues<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<f64>> {
        PyArray1::from_vec(py, self.inner.pca.eigenvalues.clone())
    }

    /// Coordinates on the first `k` components (all when None) of a material: a
    /// `Material`, a spec string or a (90, 90, 180, 3) table.
    #[pyo3(signature = (material, k=None))]
    fn project<'py>(
        &self,
        py: Python<'py>,
        material: &Bound<'py, PyAny>,
        k: Option<usize>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let values = material_values(material)?;
        let k = k.unwrap_or(self.inner.components());
        let m = &self.inner;
        let x = py
            .allow_threads(|| m.project_values(&values, k))
            .map_err(value_error)?;
        Ok(PyArray1::from_vec(py, x))
    }

    /// The (90, 90, 180, 3) table of the coordinates `x` (the first len(x) components).
    /// With `fast`, through the model's half-precision decoder (`reduce::Decoder`, built
    /// on the first such call): two to four times faster, within 0.3 % of the exact table.
    #[pyo3(signature = (x, fast=false))]
    fn reconstruct<'py>(
        &self,
        py: Python<'py>,
        x: Vec<f64>,
        fast: bool,
    ) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
        let m = &self.inner;
        let values = py
            .allow_threads(|| -> reduce::Result<Vec<f64>> {
                if !fast {
                    return m.synthesize(&x);
                }
                let decoder = match self.decoder.get() {
                    Some(d) => d,
                    None => {
                        let d = m.decoder(m.components())?;
                        self.decoder.get_or_init(|| d)
                    }
                };
                decoder.decode(&x)
            })
            .map_err(value_error)?;
        values_to_table(py, values)
    }

    fn __repr__(&self) -> String {
        format!(
            "reflectance.models.PcaModel({} materials, {} components)",
            self.inner.names.len(),
            self.inner.components()
        )
    }
}

fn render_material(obj: &Bound<'_, PyAny>) -> PyResult<render::SurfaceMaterial> {
    let loaded: Arc<brdf::Material> = if let Ok(m) = obj.downcast::<PyMaterial>() {
        m.get().inner.clone()
    } else {
        let spec: String = obj
            .extract()
            .map_err(|_| value_error("a material is a reflectance.Material or a spec string"))?;
        register_specs();
        Arc::new(
            brdf::load(&spec)
                .map_err(|e| value_error(format!("cannot load material '{spec}': {e}")))?,
        )
    };
    let py = obj.py();
    Ok(py.allow_threads(|| {
        // as `gantry render`: evaluated as loaded, importance-sampled from its MERL-grid table
        let table = loaded.tabulate();
        let brdf: Arc<dyn Brdf> = loaded;
        render::Material::with_importance_from(brdf, &table, Default::default()).into()
    }))
}

fn image_to_numpy<'py>(
    py: Python<'py>,
    img: &render::Image,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let data: Vec<f32> = img.pixels().iter().flat_map(|p| *p).collect();
    to_numpy(py, data, vec![img.height(), img.width(), 3])
}

fn render_options(spp: u32, seed: u64, integrator: render::Integrator) -> render::RenderOptions {
    render::RenderOptions {
        spp,
        seed,
        integrator,
        ..Default::default()
    }
}

/// `gantry render sphere`: a unit sphere of the material under one point light (irradiance π),
/// direct lighting; returns linear RGB float32 (size, size, 3).
#[pyfunction]
#[pyo3(signature = (material, size=256, spp=16, seed=1))]
fn render_sphere<'py>(
    py: Python<'py>,
    material: &Bound<'py, PyAny>,
    size: usize,
    spp: u32,
    seed: u64,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let m = render_material(material)?;
    let img = py
        .allow_threads(|| {
            let scene = render::sphere_scene(m, size, size)?;
            render::render_scene(
                &scene,
                &render_options(spp, seed, render::Integrator::Direct),
            )
        })
        .map_err(value_error)?;
    image_to_numpy(py, &img)
}

/// `gantry render teapot`: the Utah teapot in the material on a grey ground under a light probe
/// (lat-long OpenEXR or Radiance .hdr; the procedural probe when None), path traced;
/// (3w/4, w, 3) float32.
#[pyfunction]
#[pyo3(signature = (material, width=320, spp=64, seed=1, env=None))]
fn render_teapot<'py>(
    py: Python<'py>,
    material: &Bound<'py, PyAny>,
    width: usize,
    spp: u32,
    seed: u64,
    env: Option<PathBuf>,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let m = render_material(material)?;
    let img = py
        .allow_threads(|| {
            let scene = render::teapot_figure(m, env.as_deref(), width)?;
            render::render_scene(
                &scene,
                &render_options(spp, seed, render::Integrator::PathTracing),
            )
        })
        .map_err(value_error)?;
    image_to_numpy(py, &img)
}

/// `gantry render SCENE.toml`: a scene file (docs/render.md) with its `[render]` defaults;
/// `spp` overrides them. Returns linear RGB float32 (height, width, 3).
#[pyfunction]
#[pyo3(signature = (path, spp=None, seed=1))]
fn render_scene_file<'py>(
    py: Python<'py>,
    path: PathBuf,
    spp: Option<u32>,
    seed: u64,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    register_specs();
    let img = py
        .allow_threads(|| render::render_scene_file(&path, spp, seed, None))
        .map_err(value_error)?;
    image_to_numpy(py, &img)
}

/// A capture's progress callback `progress(stage, done, total)`; an exception it raises is kept
/// in `failure` and re-raised when the job ends.
fn progress_callback(
    progress: Option<Py<PyAny>>,
    failure: &Arc<Mutex<Option<PyErr>>>,
) -> Option<acquire::ProgressFn> {
    progress.map(|cb| {
        let failure = failure.clone();
        let f: acquire::ProgressFn = Arc::new(move |p: &acquire::Progress| {
            Python::with_gil(|py| {
                let stage = format!("{:?}", p.stage).to_lowercase();
                if let Err(e) = cb.call1(py, (stage, p.done, p.total)) {
                    let mut slot = failure.lock().unwrap_or_else(|e| e.into_inner());
                    slot.get_or_insert(e);
                }
            })
        });
        f
    })
}

/// How a capture on the simulated rig runs: calibrated by the simulated operator or with the true
/// geometry, resumed or new, with a progress callback.
fn sim_run_options(
    calibrate: bool,
    resume: bool,
    progress: Option<Py<PyAny>>,
    failure: &Arc<Mutex<Option<PyErr>>>,
) -> acquire::RunOptions {
    acquire::RunOptions {
        calibration: if calibrate {
            acquire::CalibrationSource::Calibrate
        } else {
            acquire::CalibrationSource::TrueGeometry
        },
        resume,
        progress: progress_callback(progress, failure),
        ..Default::default()
    }
}

/// `json.loads` of a serialisable value.
fn to_python<'py, T: serde::Serialize>(py: Python<'py>, value: &T) -> PyResult<Bound<'py, PyAny>> {
    let json = serde_json::to_string(value).map_err(value_error)?;
    py.import("json")?.call_method1("loads", (json,))
}

/// The capture job (`acquire::run`) on the simulated rig: measures `material` at `positions`
/// lamp positions into `directory` (image scale `scale`, seeded), calling
/// `progress(stage, done, total)` as it advances. Returns the report (`report.json`) as a
/// dict. An exception raised by `progress` is re-raised when the job ends.
#[pyfunction]
#[pyo3(signature = (material, directory, positions=3, scale=0.1, seed=1, calibrate=false, resume=false, progress=None))]
#[allow(clippy::too_many_arguments)]
fn capture<'py>(
    py: Python<'py>,
    material: &str,
    directory: PathBuf,
    positions: usize,
    scale: f64,
    seed: u64,
    calibrate: bool,
    resume: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    register_specs();
    let spec = acquire::JobSpec::new(material, positions);
    let setup = acquire::SimSetup {
        seed,
        ..acquire::SimSetup::with_scale(scale)
    };
    let failure: Arc<Mutex<Option<PyErr>>> = Arc::new(Mutex::new(None));
    let options = sim_run_options(calibrate, resume, progress, &failure);
    let outcome = py.allow_threads(|| -> acquire::Result<acquire::Outcome> {
        let mut station = acquire::Station::simulated(&spec, &setup)?;
        acquire::run(&mut station, &spec, &options, &directory)
    });
    if let Some(e) = failure.lock().unwrap_or_else(|e| e.into_inner()).take() {
        return Err(e);
    }
    match outcome.map_err(value_error)? {
        acquire::Outcome::Finished(done) => to_python(py, &done.report),
        other => Err(value_error(format!("the job did not finish: {other:?}"))),
    }
}

/// The fast capture (`fast_capture::run`) on the simulated rig: the lamp positions the model
/// `model` (a `model.bin` path) needs most within `budget` seconds of rig clock (at most
/// `positions`, exposures up to `max_exposure` seconds), captured into `directory`, the table
/// completed from the model's first `components` components. Returns `fast_report.json` as a
/// dict, or with `dry_run=True` the plan (`plan.json`) without capturing.
#[pyfunction]
#[pyo3(name = "fast_capture", signature = (material, directory, model, positions=40, budget=600.0, max_exposure=None, components=45, scale=0.1, seed=1, calibrate=false, resume=false, dry_run=false, progress=None))]
#[allow(clippy::too_many_arguments)]
fn fast_capture_job<'py>(
    py: Python<'py>,
    material: &str,
    directory: PathBuf,
    model: PathBuf,
    positions: usize,
    budget: f64,
    max_exposure: Option<f64>,
    components: usize,
    scale: f64,
    seed: u64,
    calibrate: bool,
    resume: bool,
    dry_run: bool,
    progress: Option<Py<PyAny>>,
) -> PyResult<Bound<'py, PyAny>> {
    register_specs();
    let spec = acquire::JobSpec::new(material, 1);
    let setup = acquire::SimSetup {
        seed,
        ..acquire::SimSetup::with_scale(scale)
    };
    let failure: Arc<Mutex<Option<PyErr>>> = Arc::new(Mutex::new(None));
    let options = ::fast_capture::FastOptions {
        plan: ::fast_capture::PlanOptions {
            max_positions: positions,
            budget_s: budget,
            max_exposure_s: Some(max_exposure.unwrap_or(::fast_capture::DEFAULT_MAX_EXPOSURE_S)),
            components,
            ..Default::default()
        },
        run: sim_run_options(calibrate, resume, progress, &failure),
        dry_run,
        ..Default::default()
    };
    let outcome = py.allow_threads(|| -> Result<::fast_capture::FastOutcome, String> {
        let model = reduce::Model::load(&model).map_err(|e| e.to_string())?;
        let mut station = acquire::Station::simulated(&spec, &setup).map_err(|e| e.to_string())?;
        ::fast_capture::run(&mut station, &spec, &model, &options, &directory)
            .map_err(|e| e.to_string())
    });
    if let Some(e) = failure.lock().unwrap_or_else(|e| e.into_inner()).take() {
        return Err(e);
    }
    match outcome.map_err(value_error)? {
        ::fast_capture::FastOutcome::Finished(report) => to_python(py, &*report),
        ::fast_capture::FastOutcome::Planned(plan) => to_python(py, &*plan),
        other => Err(value_error(format!("the job did not finish: {other:?}"))),
    }
}

/// The native module `reflectance._native`; the Python package re-exports it by topic.
#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<PyMaterial>()?;
    m.add_class::<PyModel>()?;
    m.add_function(wrap_pyfunction!(load, m)?)?;
    m.add_function(wrap_pyfunction!(spec_forms, m)?)?;
    m.add_function(wrap_pyfunction!(from_table, m)?)?;
    m.add_function(wrap_pyfunction!(read_merl, m)?)?;
    m.add_function(wrap_pyfunction!(write_merl, m)?)?;
    m.add_function(wrap_pyfunction!(gram, m)?)?;
    m.add_function(wrap_pyfunction!(render_sphere, m)?)?;
    m.add_function(wrap_pyfunction!(render_teapot, m)?)?;
    m.add_function(wrap_pyfunction!(render_scene_file, m)?)?;
    m.add_function(wrap_pyfunction!(capture, m)?)?;
    m.add_function(wrap_pyfunction!(fast_capture_job, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}

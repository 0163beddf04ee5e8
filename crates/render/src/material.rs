//! Materials: a BRDF plus optional importance tables, per-point blends of two BRDFs, and the
//! "many materials" shader (one shared linear basis in log space + k coefficients each).

use crate::error::{RenderError, Result};
use crate::image::Image;
use crate::importance::{BrdfImportance, ImportanceResolution};
use crate::varying::CoefficientTexture;
use brdf::{Brdf, HalfDiff, Rgb, Vec3};
use std::f64::consts::{FRAC_PI_2, PI};
use std::path::Path;
use std::sync::Arc;

/// A BRDF as used by the renderer.
///
/// # Examples
///
/// ```
/// use brdf::{Brdf, Vec3};
/// use rand::SeedableRng;
/// use render::{ImportanceResolution, Material, PhiSampling, SampleRng};
/// use std::sync::Arc;
///
/// let ggx: Arc<dyn Brdf> = Arc::new(brdf::load("ggx:alpha=0.2,kd=0.1").unwrap());
/// let plain = Material::new(ggx.clone());
/// assert!(plain.importance.is_none()); // the renderer samples it by cosine
/// // Coarse importance tables (thesis A.2.4) keep the example fast.
/// let res = ImportanceResolution { theta_r: 16, theta_i: 16, phi_diff: 32, supersample: 1 };
/// let sampled = Material::with_importance(ggx, res);
/// assert_eq!(sampled.name, plain.name);
/// let tables = sampled.importance.as_ref().unwrap();
/// // The BRDF is reciprocal, and its directional albedo, estimated with the tables, is below 1.
/// let (a, b) = (Vec3::new(0.4, 0.1, 0.9).normalize(), Vec3::new(-0.3, 0.2, 0.93).normalize());
/// assert_eq!(sampled.brdf.eval(&a, &b), sampled.brdf.eval(&b, &a));
/// let wo = Vec3::new(0.5, 0.0, 0.866);
/// let mut rng = SampleRng::seed_from_u64(1);
/// let n = 4000;
/// let mut albedo = 0.0;
/// for _ in 0..n {
///     let (wi, pdf) = tables.sample(&wo, PhiSampling::Inversion, &mut rng).unwrap();
///     let f = sampled.brdf.eval(&wi, &wo);
///     albedo += (f[0] + f[1] + f[2]) / 3.0 * wi.z / pdf / n as f64;
/// }
/// assert!(albedo > 0.1 && albedo < 1.0, "{albedo}");
/// ```
#[derive(Clone)]
pub struct Material {
    /// Name for logs.
    pub name: String,
    /// The reflectance function.
    pub brdf: Arc<dyn Brdf>,
    /// Importance-sampling tables (thesis A.2.4), when built.
    pub importance: Option<Arc<BrdfImportance>>,
}

impl std::fmt::Debug for Material {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Material")
            .field("name", &self.name)
            .field("importance", &self.importance.is_some())
            .finish()
    }
}

impl Material {
    /// A material without importance tables (cosine sampling is used for it).
    pub fn new(brdf: Arc<dyn Brdf>) -> Self {
        Self {
            name: brdf.name(),
            brdf,
            importance: None,
        }
    }

    /// A material with importance tables built from `brdf` itself.
    pub fn with_importance(brdf: Arc<dyn Brdf>, res: ImportanceResolution) -> Self {
        let table = BrdfImportance::build(brdf.as_ref(), res);
        Self {
            name: brdf.name(),
            brdf,
            importance: Some(Arc::new(table)),
        }
    }

    /// A material evaluated with `brdf` but importance-sampled with tables built from
    /// `tabulated` (e.g. the MERL table of an NBRDF).
    pub fn with_importance_from(
        brdf: Arc<dyn Brdf>,
        tabulated: &dyn Brdf,
        res: ImportanceResolution,
    ) -> Self {
        Self {
            name: brdf.name(),
            brdf,
            importance: Some(Arc::new(BrdfImportance::build(tabulated, res))),
        }
    }
}

/// A scalar field in [0, 1] over the surface that blends two materials.
#[derive(Debug, Clone)]
pub enum Mask {
    /// The same weight everywhere.
    Constant(f64),
    /// Fractal value noise of the world position (`scale` features per unit, seeded).
    Noise {
        /// Spatial frequency.
        scale: f64,
        /// Seed of the lattice hash.
        seed: u64,
        /// Values below `threshold` map to 0, above `threshold + softness` to 1.
        threshold: f64,
        /// Width of the transition.
        softness: f64,
    },
    /// 3D checkerboard of the world position.
    Checker {
        /// Squares per unit.
        scale: f64,
    },
    /// An image looked up by the surface's texture coordinates (luminance of the pixel).
    Texture(Arc<Image>),
}

impl Mask {
    /// Weight of the second material at `point` with texture coordinates `uv`.
    pub fn weight(&self, point: &Vec3, uv: [f64; 2]) -> f64 {
        let w = match self {
            Mask::Constant(c) => *c,
            Mask::Noise {
                scale,
                seed,
                threshold,
                softness,
            } => {
                let n = fbm(&(point * *scale), *seed);
                ((n - threshold) / softness.max(1e-9)).clamp(0.0, 1.0)
            }
            Mask::Checker { scale } => {
                let s = point * *scale;
                let k = s.x.floor() as i64 + s.y.floor() as i64 + s.z.floor() as i64;
                (k.rem_euclid(2)) as f64
            }
            Mask::Texture(img) => {
                let x = ((uv[0].rem_euclid(1.0)) * img.width() as f64) as usize;
                let y = ((1.0 - uv[1].rem_euclid(1.0)) * img.height() as f64) as usize;
                let p = img.get(x.min(img.width() - 1), y.min(img.height() - 1));
                (0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]) as f64
            }
        };
        if w.is_finite() {
            w.clamp(0.0, 1.0)
        } else {
            0.0
        }
    }
}

fn hash(x: i64, y: i64, z: i64, seed: u64) -> f64 {
    let mut h = seed ^ 0x9E37_79B9_7F4A_7C15;
    for v in [x, y, z] {
        h ^= v as u64;
        h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
        h ^= h >> 31;
    }
    (h >> 11) as f64 / (1u64 << 53) as f64
}

fn value_noise(p: &Vec3, seed: u64) -> f64 {
    let f = p.map(f64::floor);
    let t = (p - f).map(|t| t * t * (3.0 - 2.0 * t));
    let (x, y, z) = (f.x as i64, f.y as i64, f.z as i64);
    let mut acc = 0.0;
    for dz in 0..2 {
        for dy in 0..2 {
            for dx in 0..2 {
                let w = (if dx == 1 { t.x } else { 1.0 - t.x })
                    * (if dy == 1 { t.y } else { 1.0 - t.y })
                    * (if dz == 1 { t.z } else { 1.0 - t.z });
                acc += w * hash(x + dx, y + dy, z + dz, seed);
            }
        }
    }
    acc
}

/// Four-octave fractal value noise in [0, 1].
pub fn fbm(p: &Vec3, seed: u64) -> f64 {
    let mut amp = 0.5;
    let mut freq = 1.0;
    let mut acc = 0.0;
    let mut norm = 0.0;
    for o in 0..4 {
        acc += amp * value_noise(&(p * freq), seed.wrapping_add(o));
        norm += amp;
        amp *= 0.5;
        freq *= 2.03;
    }
    acc / norm
}

/// What a surface is made of.
#[derive(Debug, Clone)]
pub enum SurfaceMaterial {
    /// One BRDF everywhere.
    Single(Material),
    /// `(1 − m) · a + m · b` with the mask value `m` at each point (the thesis's rust teapot).
    Blend {
        /// Material where the mask is 0.
        a: Material,
        /// Material where the mask is 1.
        b: Material,
        /// The blend weight field.
        mask: Mask,
    },
    /// A different BRDF at every point (thesis §7.2.2): the coefficients of the shared
    /// log-space `basis` sampled from `texture` at the hit's texture coordinates
    /// ([`CoefficientTexture::sample`]), evaluated like a [`BasisBrdf`] with them. Directions
    /// are sampled as for a [`Material`] without importance tables (the BRDF's default,
    /// cosine-weighted, sampler). Build it with [`SurfaceMaterial::varying`], which checks that
    /// the basis has the texture's coefficients.
    Varying {
        /// The shared linear model.
        basis: Arc<LinearBasis>,
        /// Per-texel coefficients (at most `basis.components()` of them; fewer use the first
        /// components only, like a truncated [`BasisBrdf`]).
        texture: Arc<CoefficientTexture>,
    },
}

impl SurfaceMaterial {
    /// A spatially varying material; an error when the texture holds more coefficients than
    /// the basis has components.
    pub fn varying(basis: Arc<LinearBasis>, texture: Arc<CoefficientTexture>) -> Result<Self> {
        if texture.components() > basis.components() {
            return Err(RenderError::InvalidArgument(format!(
                "a texture of {} coefficients for a {}-component basis",
                texture.components(),
                basis.components()
            )));
        }
        Ok(SurfaceMaterial::Varying { basis, texture })
    }
}

impl From<Material> for SurfaceMaterial {
    fn from(m: Material) -> Self {
        SurfaceMaterial::Single(m)
    }
}

/// A grid of (θh, θd, φd) bins laid out like the MERL table (θh quadratic, φd over [0, π)).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BasisGrid {
    /// θh bins.
    pub theta_h: usize,
    /// θd bins.
    pub theta_d: usize,
    /// φd bins.
    pub phi_d: usize,
}

impl BasisGrid {
    /// The MERL grid, 90 × 90 × 180.
    pub const MERL: BasisGrid = BasisGrid {
        theta_h: 90,
        theta_d: 90,
        phi_d: 180,
    };

    /// Number of bins.
    pub fn bins(&self) -> usize {
        self.theta_h * self.theta_d * self.phi_d
    }

    /// Bin of Rusinkiewicz angles (nearest-lower bin, MERL convention), `None` below the horizon.
    pub fn bin(&self, hd: &HalfDiff) -> Option<usize> {
        if !(hd.theta_h.is_finite() && hd.theta_d.is_finite() && hd.phi_d.is_finite()) {
            return None;
        }
        let th = hd.theta_h.clamp(0.0, FRAC_PI_2);
        let i = (((th / FRAC_PI_2).sqrt()) * self.theta_h as f64) as usize;
        let j = (hd.theta_d.clamp(0.0, FRAC_PI_2) / FRAC_PI_2 * self.theta_d as f64) as usize;
        let pd = hd.phi_d.rem_euclid(PI);
        let k = (pd / PI * self.phi_d as f64) as usize;
        let (i, j, k) = (
            i.min(self.theta_h - 1),
            j.min(self.theta_d - 1),
            k.min(self.phi_d - 1),
        );
        Some(k + self.phi_d * (j + self.theta_d * i))
    }

    /// Grid angles `(θh, θd, φd)` of bin `(i, j, k)`.
    pub fn angles(&self, i: usize, j: usize, k: usize) -> (f64, f64, f64) {
        let t = i as f64 / self.theta_h as f64;
        (
            t * t * FRAC_PI_2,
            j as f64 / self.theta_d as f64 * FRAC_PI_2,
            k as f64 / self.phi_d as f64 * PI,
        )
    }
}

/// A shared linear model of log-BRDFs: `f = exp(mean + Σ_j c_j · component_j) − offset`
/// per bin and channel (the thesis's chapter 4 model; appendix A's second rendering method).
#[derive(Debug, Clone)]
pub struct LinearBasis {
    grid: BasisGrid,
    k: usize,
    offset: f64,
    /// `[bin][channel][1 + k]`: the mean then the k component values, contiguous per lookup.
    data: Vec<f32>,
}

impl LinearBasis {
    /// Builds the basis from channel-major vectors of length `3 · grid.bins()` (the layout
    /// of `MerlTable::values`): the mean log-BRDF and `k` components. `offset` is subtracted
    /// after the exponential (use it when the model was fitted to `log(f + offset)`).
    pub fn new(
        grid: BasisGrid,
        mean: &[f32],
        components: &[Vec<f32>],
        offset: f64,
    ) -> Result<Self> {
        let n = 3 * grid.bins();
        if grid.bins() == 0 || mean.len() != n || components.iter().any(|c| c.len() != n) {
            return Err(RenderError::InvalidArgument(format!(
                "linear basis vectors must have 3 × {} values",
                grid.bins()
            )));
        }
        if !offset.is_finite()
            || mean.iter().any(|x| !x.is_finite())
            || components.iter().flatten().any(|x| !x.is_finite())
        {
            return Err(RenderError::InvalidArgument(
                "linear basis has non-finite values".into(),
            ));
        }
        let k = components.len();
        let bins = grid.bins();
        let mut data = vec![0f32; n * (k + 1)];
        for b in 0..bins {
            for c in 0..3 {
                let base = (b * 3 + c) * (k + 1);
                data[base] = mean[c * bins + b];
                for (j, comp) in components.iter().enumerate() {
                    data[base + 1 + j] = comp[c * bins + b];
                }
            }
        }
        Ok(Self {
            grid,
            k,
            offset,
            data,
        })
    }

    /// Builds the basis from a dimension-major matrix `basis[d · stored + j]` (component `j` at
    /// dimension `d`, dimensions channel-major as in `MerlTable::values`), keeping the first
    /// `keep` of the `stored` components. This is the layout of the `reduce` crate's PCA
    /// (`Pca::basis`, `Pca::mean`, offset = the model's `log_floor`).
    pub fn from_dimension_major(
        grid: BasisGrid,
        mean: &[f32],
        basis: &[f32],
        stored: usize,
        keep: usize,
        offset: f64,
    ) -> Result<Self> {
        let n = 3 * grid.bins();
        if grid.bins() == 0 || mean.len() != n || basis.len() != n * stored || keep > stored {
            return Err(RenderError::InvalidArgument(format!(
                "dimension-major basis: {} mean values and {} basis values for {} dimensions × {stored} components (keep {keep})",
                mean.len(),
                basis.len(),
                n
            )));
        }
        if !offset.is_finite()
            || mean.iter().any(|x| !x.is_finite())
            || basis.iter().any(|x| !x.is_finite())
        {
            return Err(RenderError::InvalidArgument(
                "linear basis has non-finite values".into(),
            ));
        }
        let bins = grid.bins();
        let k = keep;
        let mut data = vec![0f32; n * (k + 1)];
        for b in 0..bins {
            for c in 0..3 {
                let d = c * bins + b;
                let base = (b * 3 + c) * (k + 1);
                data[base] = mean[d];
                data[base + 1..base + 1 + k].copy_from_slice(&basis[d * stored..d * stored + k]);
            }
        }
        Ok(Self {
            grid,
            k,
            offset,
            data,
        })
    }

    /// Number of components.
    pub fn components(&self) -> usize {
        self.k
    }

    /// The grid.
    pub fn grid(&self) -> BasisGrid {
        self.grid
    }

    /// Bytes held by the basis.
    pub fn memory_bytes(&self) -> usize {
        self.data.len() * std::mem::size_of::<f32>()
    }

    /// BRDF value for the coefficients (only the first `coefficients.len()` components are
    /// used, so truncated reconstructions are free). Negative results clamp to 0.
    pub fn eval(&self, coefficients: &[f32], hd: &HalfDiff) -> Rgb {
        let Some(bin) = self.grid.bin(hd) else {
            return [0.0; 3];
        };
        let m = coefficients.len().min(self.k);
        let mut out = [0.0; 3];
        for (c, o) in out.iter_mut().enumerate() {
            let row = &self.data[(bin * 3 + c) * (self.k + 1)..][..self.k + 1];
            let mut y = row[0];
            for j in 0..m {
                y += coefficients[j] * row[1 + j];
            }
            *o = ((y as f64).exp() - self.offset).max(0.0);
        }
        out
    }
}

/// One material of the many-materials shader: k coefficients against a shared basis.
#[derive(Debug, Clone)]
pub struct BasisBrdf {
    basis: Arc<LinearBasis>,
    coefficients: Box<[f32]>,
    name: String,
}

impl BasisBrdf {
    /// A material with the given coefficients (extra coefficients beyond the basis size are
    /// an error; fewer mean a truncated reconstruction).
    pub fn new(basis: Arc<LinearBasis>, coefficients: &[f64], name: &str) -> Result<Self> {
        if coefficients.len() > basis.components() {
            return Err(RenderError::InvalidArgument(format!(
                "{} coefficients for a {}-component basis",
                coefficients.len(),
                basis.components()
            )));
        }
        if coefficients.iter().any(|c| !c.is_finite()) {
            return Err(RenderError::InvalidArgument(
                "non-finite basis coefficient".into(),
            ));
        }
        Ok(Self {
            basis,
            coefficients: coefficients.iter().map(|&c| c as f32).collect(),
            name: name.to_string(),
        })
    }

    /// A material with `f32` coefficients as stored (no checks beyond the basis size: extra
    /// coefficients are ignored by [`LinearBasis::eval`]) and no name: one shading point of a
    /// [`SurfaceMaterial::Varying`].
    pub(crate) fn from_f32(basis: Arc<LinearBasis>, coefficients: Box<[f32]>) -> Self {
        Self {
            basis,
            coefficients,
            name: String::new(),
        }
    }

    /// Bytes owned by this material (the coefficients; the basis is shared).
    pub fn own_memory_bytes(&self) -> usize {
        self.coefficients.len() * std::mem::size_of::<f32>() + self.name.len()
    }

    /// The shared basis.
    pub fn basis(&self) -> &Arc<LinearBasis> {
        &self.basis
    }
}

impl Brdf for BasisBrdf {
    fn eval(&self, wi: &Vec3, wo: &Vec3) -> Rgb {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return [0.0; 3];
        }
        self.eval_half_diff(&HalfDiff::from_directions(wi, wo))
    }

    fn eval_half_diff(&self, hd: &HalfDiff) -> Rgb {
        self.basis.eval(&self.coefficients, hd)
    }

    fn name(&self) -> String {
        self.name.clone()
    }
}

/// Resolves the material kinds of the scene format that live in other crates.
///
/// The default methods handle material spec strings through `brdf::spec`; PCA models
/// (`model` + `coefficients`) and wavelet trees are plugged in by implementing
/// [`MaterialResolver::linear_basis`] and [`MaterialResolver::wavelet`].
pub trait MaterialResolver: Send + Sync {
    /// A BRDF from a material spec string (`path.binary`, `nbrdf:<dir>/<name>`, `lambert:kd=…`).
    fn spec(&self, spec: &str) -> Result<Arc<dyn Brdf>>;

    /// A tabulated version of `brdf` to build importance tables from, when evaluating `brdf`
    /// 1.5 M times would be slow (NBRDFs). `None` = build from `brdf` directly.
    fn tabulated(&self, _spec: &str, _brdf: &Arc<dyn Brdf>) -> Result<Option<Arc<dyn Brdf>>> {
        Ok(None)
    }

    /// The shared linear basis stored in a model file (e.g. `model.bin` of the `reduce` crate).
    fn linear_basis(&self, model: &Path) -> Result<Arc<LinearBasis>> {
        Err(RenderError::Scene(format!(
            "no resolver for linear model {}",
            model.display()
        )))
    }

    /// Coordinates of the materials named by `specs` (material spec strings) on the first `k`
    /// components (all when `None`) of the linear model stored in `model`: projections in log
    /// space, the nodes of a spatially varying material's process path (`from`/`to`).
    fn project(&self, model: &Path, specs: &[&str], k: Option<usize>) -> Result<Vec<Vec<f64>>> {
        let _ = (specs, k);
        Err(RenderError::Scene(format!(
            "no resolver for projections on linear model {}",
            model.display()
        )))
    }

    /// A BRDF from a compressed wavelet material file (`wavelet = "file.wtree"`). The default
    /// resolves the material spec `wavelet:<file>` through [`MaterialResolver::spec`], so a
    /// program that registered `wavelet::register_spec_resolver` needs nothing more.
    /// A compressed material carries its own coefficients: `coefficients` must be `None`.
    fn wavelet(&self, tree: &Path, coefficients: Option<&[f64]>) -> Result<Arc<dyn Brdf>> {
        if coefficients.is_some() {
            return Err(RenderError::Scene(format!(
                "{}: a compressed material carries its own coefficients; drop `coefficients`",
                tree.display()
            )));
        }
        self.spec(&format!("wavelet:{}", tree.display()))
    }
}

/// The Lambertian BRDF `kd / π` (the one of `brdf::analytic`, re-exported here because simple
/// scenes and the furnace test use it).
pub use brdf::analytic::Lambert;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn basis_reconstructs_exponential_of_linear_combination() {
        let grid = BasisGrid {
            theta_h: 4,
            theta_d: 3,
            phi_d: 5,
        };
        let n = 3 * grid.bins();
        let mean: Vec<f32> = (0..n).map(|i| (i % 7) as f32 * 0.1 - 1.0).collect();
        let c1: Vec<f32> = (0..n).map(|i| (i % 3) as f32 * 0.2).collect();
        let c2: Vec<f32> = (0..n).map(|i| ((i * 5) % 11) as f32 * -0.05).collect();
        let basis =
            Arc::new(LinearBasis::new(grid, &mean, &[c1.clone(), c2.clone()], 0.001).unwrap());
        let m = BasisBrdf::new(basis.clone(), &[0.7, -1.3], "m").unwrap();
        let hd = HalfDiff::isotropic(0.3, 0.5, 2.0);
        let bin = grid.bin(&hd).unwrap();
        let f = m.eval_half_diff(&hd);
        for (c, fc) in f.iter().enumerate() {
            let idx = c * grid.bins() + bin;
            let y = mean[idx] + 0.7 * c1[idx] - 1.3 * c2[idx];
            let want = (y as f64).exp() - 0.001;
            assert!(
                (fc - want).abs() < 1e-5 * want.abs().max(1.0),
                "{fc} {want}"
            );
        }
        // the dimension-major constructor (reduce's layout) builds the same model
        let mut dm = vec![0f32; n * 3];
        for d in 0..n {
            dm[d * 3] = c1[d];
            dm[d * 3 + 1] = c2[d];
            dm[d * 3 + 2] = 9.0;
        }
        let other =
            Arc::new(LinearBasis::from_dimension_major(grid, &mean, &dm, 3, 2, 0.001).unwrap());
        let m2 = BasisBrdf::new(other, &[0.7, -1.3], "m2").unwrap();
        assert_eq!(m2.eval_half_diff(&hd), f);
        assert!(LinearBasis::from_dimension_major(grid, &mean, &dm, 3, 4, 0.0).is_err());
        assert!(BasisBrdf::new(basis.clone(), &[0.0; 3], "x").is_err());
        assert!(LinearBasis::new(grid, &mean[1..], &[], 0.0).is_err());
    }
}

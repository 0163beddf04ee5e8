//! Spatially varying data-driven materials (thesis §7.2.2, fig. 5-8): "render each point in a
//! scene with a potentially different BRDF". Every texel of a [`CoefficientTexture`] holds the
//! k coefficients of a material in a shared log-space linear model ([`crate::LinearBasis`]),
//! `f = exp(mean + Σ_j c_j · U_j) − floor`; a [`ProcessPath`] maps a scalar per texel (how far
//! a process such as rusting has gone, [`rust_selector`]) to coefficients.

use crate::error::{RenderError, Result};
use crate::material::fbm;
use brdf::Vec3;
use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;
use std::path::{Path, PathBuf};

/// Most values (`width · height · k`) a texture may hold: 2²⁸ `f32` (1 GiB).
const MAX_TEXTURE_VALUES: usize = 1 << 28;

/// A `width × height` grid of texels, each holding `k` coefficients of a shared linear model,
/// looked up by surface texture coordinates with bilinear filtering.
///
/// # Conventions (reproduced exactly by a GPU sampler)
///
/// * Storage is row-major and texel-major: coefficient `j` of texel `(x, y)` is
///   `data[(y · width + x) · k + j]`.
/// * Row 0 lies at v = 0 (no image flip): texel `(x, y)` has its centre at
///   `((x + 0.5) / width, (y + 0.5) / height)`. An image used as a selector keeps its row order,
///   so its top row is texture row 0, at v = 0.
/// * u wraps (period 1), v is clamped to the texel-centre range: with
///   `s = rem_euclid(u, 1) · width − 0.5` and `t = clamp(v · height − 0.5, 0, height − 1)`,
///   `x0 = floor(s)`, `y0 = floor(t)`, `fx = s − x0`, `fy = t − y0`, the columns
///   `x0 mod width` and `(x0 + 1) mod width` and the rows `y0` and `min(y0 + 1, height − 1)`,
///   the sample is
///   `top = c(x0, y0) + (c(x1, y0) − c(x0, y0)) · fx`,
///   `bottom = c(x0, y1) + (c(x1, y1) − c(x0, y1)) · fx`,
///   `value = top + (bottom − top) · fy`, computed in `f64` and rounded to `f32`.
///   This is WebGL's `LINEAR` filtering with `REPEAT` in s and `CLAMP_TO_EDGE` in t, the rows
///   uploaded in order (row 0 first); hardware filtering rounds the weights to a few bits, so a
///   GPU agrees to that precision. At texel centres the sample is the texel exactly, and a
///   constant texture samples to its value exactly.
///
/// # Examples
///
/// ```
/// use render::CoefficientTexture;
///
/// // 2 × 1 texels of one coefficient: 0 on the left, 1 on the right
/// let t = CoefficientTexture::new(2, 1, 1, vec![0.0, 1.0]).unwrap();
/// assert_eq!(t.sample([0.25, 0.5]), [0.0]); // texel centre
/// assert_eq!(t.sample([0.5, 0.5]), [0.5]); // halfway between the centres
/// assert_eq!(t.sample([0.0, 0.9]), [0.5]); // the u seam blends the last and first columns
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct CoefficientTexture {
    width: usize,
    height: usize,
    k: usize,
    data: Vec<f32>,
}

impl CoefficientTexture {
    /// A texture from its texel-major values (`data[(y · width + x) · k + j]`). Sizes must be
    /// positive, `data` must hold exactly `width · height · k` finite values.
    pub fn new(width: usize, height: usize, k: usize, data: Vec<f32>) -> Result<Self> {
        let n = checked_size(width, height, k)?;
        if data.len() != n {
            return Err(RenderError::InvalidArgument(format!(
                "a {width} × {height} texture of {k} coefficients needs {n} values, got {}",
                data.len()
            )));
        }
        if let Some(i) = data.iter().position(|v| !v.is_finite()) {
            return Err(RenderError::InvalidArgument(format!(
                "texture value {i} (texel {}, coefficient {}) is not finite",
                i / k,
                i % k
            )));
        }
        Ok(Self {
            width,
            height,
            k,
            data,
        })
    }

    /// A texture with the same coefficients in every texel.
    pub fn constant(width: usize, height: usize, coefficients: &[f32]) -> Result<Self> {
        let n = checked_size(width, height, coefficients.len())?;
        let data = coefficients.iter().copied().cycle().take(n).collect();
        Self::new(width, height, coefficients.len(), data)
    }

    /// The texture whose texel `i` (row-major, `i = y · width + x`) holds `path.at(selector[i])`:
    /// a per-texel position along a process path, e.g. from [`rust_selector`] or an image.
    /// Selector values are clamped to [0, 1]; non-finite values are an error.
    pub fn from_selector(
        path: &ProcessPath,
        width: usize,
        height: usize,
        selector: &[f32],
    ) -> Result<Self> {
        let k = path.components();
        let n = checked_size(width, height, k)?;
        if selector.len() != width * height {
            return Err(RenderError::InvalidArgument(format!(
                "a {width} × {height} selector needs {} values, got {}",
                width * height,
                selector.len()
            )));
        }
        if let Some(i) = selector.iter().position(|v| !v.is_finite()) {
            return Err(RenderError::InvalidArgument(format!(
                "selector value {i} is not finite"
            )));
        }
        let mut data = Vec::with_capacity(n);
        for &t in selector {
            data.extend(path.at(t as f64).iter().map(|&c| c as f32));
        }
        Self::new(width, height, k, data)
    }

    /// Texels per row.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Rows.
    pub fn height(&self) -> usize {
        self.height
    }

    /// Coefficients per texel (k).
    pub fn components(&self) -> usize {
        self.k
    }

    /// All values, texel-major (`data[(y · width + x) · k + j]`).
    pub fn data(&self) -> &[f32] {
        &self.data
    }

    /// The coefficients of texel `(x, y)`, `None` outside the texture.
    pub fn texel(&self, x: usize, y: usize) -> Option<&[f32]> {
        (x < self.width && y < self.height)
            .then(|| &self.data[(y * self.width + x) * self.k..][..self.k])
    }

    /// Bilinearly filtered coefficients at texture coordinates `uv` (the formula is in the
    /// type's documentation). Non-finite coordinates read texel (0, 0).
    pub fn sample(&self, uv: [f64; 2]) -> Vec<f32> {
        let mut out = vec![0.0; self.k];
        self.sample_into(uv, &mut out);
        out
    }

    /// [`CoefficientTexture::sample`] into `out` (its first `k` values; extra values are left
    /// alone, missing ones are not written).
    pub fn sample_into(&self, uv: [f64; 2], out: &mut [f32]) {
        let (w, h) = (self.width, self.height);
        let [u, v] = if uv.iter().all(|c| c.is_finite()) {
            uv
        } else {
            [0.5 / w as f64, 0.5 / h as f64]
        };
        let s = u.rem_euclid(1.0) * w as f64 - 0.5;
        let t = (v * h as f64 - 0.5).clamp(0.0, (h - 1) as f64);
        let (xf, yf) = (s.floor(), t.floor());
        let (fx, fy) = (s - xf, t - yf);
        let x0 = (xf as i64).rem_euclid(w as i64) as usize;
        let x1 = (x0 + 1) % w;
        let y0 = (yf as usize).min(h - 1);
        let y1 = (y0 + 1).min(h - 1);
        let k = self.k;
        let at = |x: usize, y: usize| &self.data[(y * w + x) * k..][..k];
        let (c00, c10, c01, c11) = (at(x0, y0), at(x1, y0), at(x0, y1), at(x1, y1));
        for (j, o) in out.iter_mut().take(k).enumerate() {
            let (a, b) = (c00[j] as f64, c10[j] as f64);
            let top = a + (b - a) * fx;
            let (a, b) = (c01[j] as f64, c11[j] as f64);
            let bottom = a + (b - a) * fx;
            *o = (top + (bottom - top) * fy) as f32;
        }
    }

    /// Bytes held by the texture's values.
    pub fn memory_bytes(&self) -> usize {
        self.data.len() * std::mem::size_of::<f32>()
    }
}

fn checked_size(width: usize, height: usize, k: usize) -> Result<usize> {
    if width == 0 || height == 0 || k == 0 {
        return Err(RenderError::InvalidArgument(format!(
            "a coefficient texture needs positive sizes, got {width} × {height} × {k}"
        )));
    }
    width
        .checked_mul(height)
        .and_then(|n| n.checked_mul(k))
        .filter(|&n| n <= MAX_TEXTURE_VALUES)
        .ok_or_else(|| {
            RenderError::InvalidArgument(format!(
                "a {width} × {height} texture of {k} coefficients is larger than \
                 {MAX_TEXTURE_VALUES} values"
            ))
        })
}

/// A process in coefficient space (clean → rusted, new → worn): ordered coefficient vectors,
/// the nodes, visited piecewise linearly at equal parameter spacing (node `i` of `n` at
/// `t = i / (n − 1)`).
///
/// The JSON form ([`ProcessPath::read`], [`ProcessPath::to_json`]) is
/// `{"nodes": [[c_1, c_2, …], [c_1, c_2, …], …]}`.
///
/// # Examples
///
/// ```
/// use render::ProcessPath;
///
/// let p = ProcessPath::new(vec![vec![0.0, 2.0], vec![1.0, 4.0], vec![3.0, 4.0]]).unwrap();
/// assert_eq!(p.at(0.0), [0.0, 2.0]);
/// assert_eq!(p.at(0.25), [0.5, 3.0]); // halfway along the first segment
/// assert_eq!(p.at(1.0), [3.0, 4.0]);
/// assert!(ProcessPath::from_json(r#"{"nodes": [[1.0]]}"#).is_err()); // one node
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct ProcessPath {
    nodes: Vec<Vec<f64>>,
}

#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct PathFile {
    nodes: Vec<Vec<f64>>,
}

impl ProcessPath {
    /// A path through `nodes`: at least two, all of the same positive length, finite.
    pub fn new(nodes: Vec<Vec<f64>>) -> Result<Self> {
        if nodes.len() < 2 {
            return Err(RenderError::InvalidArgument(format!(
                "a process path needs at least 2 nodes, got {}",
                nodes.len()
            )));
        }
        let k = nodes[0].len();
        if k == 0 {
            return Err(RenderError::InvalidArgument(
                "process path nodes have no coefficients".into(),
            ));
        }
        if let Some(i) = nodes.iter().position(|n| n.len() != k) {
            return Err(RenderError::InvalidArgument(format!(
                "process path node {i} has {} coefficients, node 0 has {k}",
                nodes[i].len()
            )));
        }
        if let Some(i) = nodes.iter().position(|n| n.iter().any(|c| !c.is_finite())) {
            return Err(RenderError::InvalidArgument(format!(
                "process path node {i} has a non-finite coefficient"
            )));
        }
        Ok(Self { nodes })
    }

    /// Parses the JSON form `{"nodes": [[…], …]}`; malformed text or nodes are a
    /// [`RenderError::ProcessPath`] error (with an empty path).
    pub fn from_json(text: &str) -> Result<Self> {
        Self::parse(text, Path::new(""))
    }

    /// Reads the JSON form from a file: an unreadable file is a [`RenderError::Io`] error,
    /// malformed JSON or nodes a [`RenderError::ProcessPath`] error.
    pub fn read(path: &Path) -> Result<Self> {
        let text = std::fs::read_to_string(path).map_err(|e| RenderError::io(path, e))?;
        Self::parse(&text, path)
    }

    fn parse(text: &str, path: &Path) -> Result<Self> {
        let err = |message: String| RenderError::ProcessPath {
            path: PathBuf::from(path),
            message,
        };
        let file: PathFile = serde_json::from_str(text).map_err(|e| err(e.to_string()))?;
        Self::new(file.nodes).map_err(|e| match e {
            RenderError::InvalidArgument(m) => err(m),
            other => other,
        })
    }

    /// The JSON form.
    pub fn to_json(&self) -> String {
        let file = PathFile {
            nodes: self.nodes.clone(),
        };
        serde_json::to_string(&file).unwrap_or_default()
    }

    /// Writes the JSON form, atomically.
    pub fn write(&self, path: &Path) -> Result<()> {
        let json = self.to_json();
        brdf::write_atomic_with(path, |w| std::io::Write::write_all(w, json.as_bytes()))
            .map_err(|e| RenderError::io(path, e))
    }

    /// The same path on the first `k` coefficients of each node (a truncated reconstruction);
    /// `k` must be between 1 and [`ProcessPath::components`].
    pub fn truncated(&self, k: usize) -> Result<Self> {
        if k == 0 || k > self.components() {
            return Err(RenderError::InvalidArgument(format!(
                "k = {k}: the path has {} coefficients per node",
                self.components()
            )));
        }
        Ok(Self {
            nodes: self.nodes.iter().map(|n| n[..k].to_vec()).collect(),
        })
    }

    /// The nodes, in order.
    pub fn nodes(&self) -> &[Vec<f64>] {
        &self.nodes
    }

    /// Coefficients per node (k).
    pub fn components(&self) -> usize {
        self.nodes[0].len()
    }

    /// The coefficients at `t`: node `i` at `t = i / (n − 1)`, linear in between
    /// (`a + (b − a) · f`). `t` is clamped to [0, 1]; NaN reads node 0. The end points return
    /// the first and last nodes exactly.
    pub fn at(&self, t: f64) -> Vec<f64> {
        let n = self.nodes.len();
        let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
        if t >= 1.0 {
            return self.nodes[n - 1].clone();
        }
        let s = t * (n - 1) as f64;
        let i = (s.floor() as usize).min(n - 2);
        let f = s - i as f64;
        let (a, b) = (&self.nodes[i], &self.nodes[i + 1]);
        a.iter().zip(b).map(|(a, b)| a + (b - a) * f).collect()
    }
}

/// The rust teapot's rust-amount field over the texture: `width × height` values in [0, 1],
/// row-major (`i = y · width + x`), for texel centres `u = (x + 0.5) / width`,
/// `v = (y + 0.5) / height`. 0 is clean, 1 fully rusted.
///
/// Fractal noise ([`fbm`], seeded) of the texel's point on a cylinder, so the field wraps in u
/// (as [`CoefficientTexture`] does) and is not stretched on the figure teapot
/// ([`crate::figure_teapot_mesh`]: u around the teapot, v down it):
/// `p = (R cos 2πu, R sin 2πu, L v)` with `R = 1.5`, `L = 2.8`, the noise
/// `n = fbm(p, seed) + 0.12 (v − 0.5)` (rust gathers lower down), and the value
/// `smoothstep(clamp((n − 0.56) / 0.06, 0, 1))`, i.e. coarse blotches with soft edges covering
/// about a third of the surface. Deterministic: equal arguments give equal fields.
///
/// # Examples
///
/// ```
/// let s = render::rust_selector(256, 128, 7);
/// assert_eq!(s.len(), 256 * 128);
/// assert!(s.iter().all(|v| (0.0..=1.0).contains(v)));
/// let rusted = s.iter().filter(|&&v| v > 0.5).count() as f64 / s.len() as f64;
/// assert!(rusted > 0.1 && rusted < 0.7, "{rusted}");
/// assert_eq!(s, render::rust_selector(256, 128, 7));
/// ```
pub fn rust_selector(width: usize, height: usize, seed: u64) -> Vec<f32> {
    const RADIUS: f64 = 1.5;
    const LENGTH: f64 = 2.8;
    const THRESHOLD: f64 = 0.56;
    const SOFTNESS: f64 = 0.06;
    let mut out = Vec::with_capacity(width.saturating_mul(height));
    for y in 0..height {
        let v = (y as f64 + 0.5) / height as f64;
        for x in 0..width {
            let u = (x as f64 + 0.5) / width as f64;
            let (s, c) = (TAU * u).sin_cos();
            let p = Vec3::new(RADIUS * c, RADIUS * s, LENGTH * v);
            let n = fbm(&p, seed) + 0.12 * (v - 0.5);
            let x = ((n - THRESHOLD) / SOFTNESS).clamp(0.0, 1.0);
            out.push((x * x * (3.0 - 2.0 * x)) as f32);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn from_selector_places_path_points_per_texel() {
        let p = ProcessPath::new(vec![vec![0.0, 10.0], vec![1.0, 20.0]]).unwrap();
        let t = CoefficientTexture::from_selector(&p, 2, 2, &[0.0, 1.0, 0.5, 2.0]).unwrap();
        assert_eq!(t.texel(0, 0).unwrap(), [0.0, 10.0]);
        assert_eq!(t.texel(1, 0).unwrap(), [1.0, 20.0]);
        assert_eq!(t.texel(0, 1).unwrap(), [0.5, 15.0]);
        assert_eq!(t.texel(1, 1).unwrap(), [1.0, 20.0]); // clamped
        assert!(t.texel(2, 0).is_none());
        assert!(CoefficientTexture::from_selector(&p, 2, 2, &[0.0; 3]).is_err());
        assert!(CoefficientTexture::from_selector(&p, 2, 2, &[0.0, 0.0, f32::NAN, 0.0]).is_err());
        assert!(CoefficientTexture::from_selector(&p, 0, 2, &[]).is_err());
        assert!(CoefficientTexture::from_selector(&p, usize::MAX, 2, &[]).is_err());
    }

    #[test]
    fn path_json_round_trips() {
        let p = ProcessPath::new(vec![vec![0.5, -1.0], vec![2.0, 3.0], vec![0.0, 0.0]]).unwrap();
        assert_eq!(ProcessPath::from_json(&p.to_json()).unwrap(), p);
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("p.json");
        p.write(&f).unwrap();
        assert_eq!(ProcessPath::read(&f).unwrap(), p);
    }
}

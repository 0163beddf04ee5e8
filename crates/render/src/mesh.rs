//! Triangle meshes: the built-in Utah teapot (tessellated from its Bézier patches) and a small
//! Wavefront OBJ reader.

use crate::error::{RenderError, Result};
use brdf::Vec3;
use std::f64::consts::TAU;
use std::path::Path;

/// An indexed triangle mesh.
#[derive(Debug, Clone, Default)]
pub struct Mesh {
    /// Vertex positions.
    pub positions: Vec<Vec3>,
    /// Per-vertex shading normals (empty = flat shading).
    pub normals: Vec<Vec3>,
    /// Per-vertex texture coordinates (empty = none).
    pub uvs: Vec<[f64; 2]>,
    /// Triangles as vertex indices.
    pub triangles: Vec<[u32; 3]>,
}

/// A similarity transform: scale, then rotation about +y, then translation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Transform {
    /// Uniform scale factor.
    pub scale: f64,
    /// Rotation about the world +y axis, degrees.
    pub rotate_y_degrees: f64,
    /// Translation.
    pub translate: Vec3,
}

impl Default for Transform {
    fn default() -> Self {
        Self {
            scale: 1.0,
            rotate_y_degrees: 0.0,
            translate: Vec3::zeros(),
        }
    }
}

impl Transform {
    /// Applies the transform to a point.
    pub fn point(&self, p: &Vec3) -> Vec3 {
        self.direction(p) * self.scale + self.translate
    }

    /// Applies the rotation to a direction (normals are unaffected by uniform scale).
    pub fn direction(&self, d: &Vec3) -> Vec3 {
        let (s, c) = self.rotate_y_degrees.to_radians().sin_cos();
        Vec3::new(c * d.x + s * d.z, d.y, -s * d.x + c * d.z)
    }
}

impl Mesh {
    /// Returns a transformed copy.
    pub fn transformed(&self, t: &Transform) -> Mesh {
        Mesh {
            positions: self.positions.iter().map(|p| t.point(p)).collect(),
            normals: self.normals.iter().map(|n| t.direction(n)).collect(),
            uvs: self.uvs.clone(),
            triangles: self.triangles.clone(),
        }
    }

    /// Axis-aligned bounds (min, max); zeros for an empty mesh.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        if self.positions.is_empty() {
            return (Vec3::zeros(), Vec3::zeros());
        }
        let mut lo = Vec3::repeat(f64::INFINITY);
        let mut hi = Vec3::repeat(f64::NEG_INFINITY);
        for p in &self.positions {
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        (lo, hi)
    }

    /// Total surface area.
    pub fn area(&self) -> f64 {
        self.triangles
            .iter()
            .map(|t| {
                let p = t.map(|i| self.positions[i as usize]);
                0.5 * (p[1] - p[0]).cross(&(p[2] - p[0])).norm()
            })
            .sum()
    }

    /// Replaces the shading normals by smooth per-vertex normals: the area-weighted mean of
    /// the normals of the triangles around each vertex (a vertex no triangle touches, or whose
    /// triangles cancel, gets +y).
    pub fn smooth_normals(&mut self) {
        let mut normals = vec![Vec3::zeros(); self.positions.len()];
        for t in &self.triangles {
            let p = t.map(|i| self.positions[i as usize]);
            // the cross product's length is twice the area: area weighting for free
            let n = (p[1] - p[0]).cross(&(p[2] - p[0]));
            for &i in t {
                normals[i as usize] += n;
            }
        }
        self.normals = normals
            .into_iter()
            .map(|n| {
                let l = n.norm();
                if l > 0.0 && l.is_finite() {
                    n / l
                } else {
                    Vec3::y()
                }
            })
            .collect();
    }

    /// Texture coordinates from a cylinder about the vertical axis through `(centre_x,
    /// centre_z)`: `u = 0.5 + atan2(z, x) / 2π` (around, as on the figure teapot) and
    /// `v = (y_max − y) / (y_max − y_min)` (0 at the top, 1 at the bottom).
    ///
    /// A triangle that straddles the seam (its u values spread over more than half a turn)
    /// gets copies of its low-u vertices with u + 1, so that a texture that wraps in u (as
    /// [`crate::CoefficientTexture`] does) is read continuously across it; vertices on the
    /// axis take u = 0.5.
    pub fn cylindrical_uvs(&mut self, centre_x: f64, centre_z: f64) {
        let (lo, hi) = self.bounds();
        let height = (hi.y - lo.y).max(f64::MIN_POSITIVE);
        self.uvs = self
            .positions
            .iter()
            .map(|p| {
                let (x, z) = (p.x - centre_x, p.z - centre_z);
                let u = if x.hypot(z) > 1e-12 {
                    0.5 + z.atan2(x) / TAU
                } else {
                    0.5
                };
                [u, (hi.y - p.y) / height]
            })
            .collect();
        let mut copies: std::collections::HashMap<u32, u32> = Default::default();
        for t in 0..self.triangles.len() {
            let tri = self.triangles[t];
            let us = tri.map(|i| self.uvs[i as usize][0]);
            let (min, max) = us
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &u| {
                    (a.min(u), b.max(u))
                });
            if max - min <= 0.5 {
                continue;
            }
            let mut fixed = tri;
            for (k, &i) in tri.iter().enumerate() {
                if self.uvs[i as usize][0] >= 0.5 {
                    continue;
                }
                let copy = *copies.entry(i).or_insert_with(|| {
                    let [u, v] = self.uvs[i as usize];
                    self.positions.push(self.positions[i as usize]);
                    if !self.normals.is_empty() {
                        self.normals.push(self.normals[i as usize]);
                    }
                    self.uvs.push([u + 1.0, v]);
                    (self.positions.len() - 1) as u32
                });
                fixed[k] = copy;
            }
            self.triangles[t] = fixed;
        }
    }

    /// Checks indices and finiteness.
    pub fn validate(&self) -> Result<()> {
        let n = self.positions.len();
        if self
            .positions
            .iter()
            .any(|p| !p.iter().all(|x| x.is_finite()))
        {
            return Err(RenderError::InvalidArgument(
                "mesh has non-finite vertex positions".into(),
            ));
        }
        if !self.normals.is_empty() && self.normals.len() != n {
            return Err(RenderError::InvalidArgument(
                "mesh normal count differs from vertex count".into(),
            ));
        }
        if !self.uvs.is_empty() && self.uvs.len() != n {
            return Err(RenderError::InvalidArgument(
                "mesh uv count differs from vertex count".into(),
            ));
        }
        if self.triangles.iter().flatten().any(|&i| i as usize >= n) {
            return Err(RenderError::InvalidArgument(
                "mesh triangle index out of range".into(),
            ));
        }
        Ok(())
    }
}

const TEAPOT_DATA: &str = include_str!("data/teapot.txt");

/// The 32 bicubic Bézier patches of the Utah teapot: control points (z up, as published).
pub fn teapot_patches() -> Vec<[Vec3; 16]> {
    let mut patches: Vec<[u32; 16]> = Vec::new();
    let mut points: Vec<Vec3> = Vec::new();
    let mut section = "";
    for line in TEAPOT_DATA.lines() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        if line.starts_with("patches") || line.starts_with("points") {
            section = if line.starts_with("patches") {
                "patches"
            } else {
                "points"
            };
            continue;
        }
        let nums = line.split(',').map(str::trim);
        if section == "patches" {
            let mut idx = [0u32; 16];
            for (slot, s) in idx.iter_mut().zip(nums) {
                *slot = s.parse::<u32>().unwrap_or(1) - 1;
            }
            patches.push(idx);
        } else {
            let v: Vec<f64> = nums.map(|s| s.parse::<f64>().unwrap_or(0.0)).collect();
            points.push(Vec3::new(v[0], v[1], v[2]));
        }
    }
    patches
        .iter()
        .map(|idx| idx.map(|i| points[i as usize]))
        .collect()
}

fn bernstein(t: f64) -> [f64; 4] {
    let s = 1.0 - t;
    [s * s * s, 3.0 * s * s * t, 3.0 * s * t * t, t * t * t]
}

fn bernstein_derivative(t: f64) -> [f64; 4] {
    let s = 1.0 - t;
    [
        -3.0 * s * s,
        3.0 * s * s - 6.0 * s * t,
        6.0 * s * t - 3.0 * t * t,
        3.0 * t * t,
    ]
}

/// Tessellates the Utah teapot into `32 · 2 · n²` triangles (degenerate ones dropped), y up,
/// resting on y = 0, about 3.15 units tall (unit scale as published) with analytic normals.
/// Texture coordinates are the patch parameters.
pub fn utah_teapot(n: usize) -> Mesh {
    let n = n.max(1);
    let mut mesh = Mesh::default();
    let to_y_up = |v: &Vec3| Vec3::new(v.x, v.z, -v.y);
    for cp in teapot_patches() {
        let base = mesh.positions.len() as u32;
        for i in 0..=n {
            let u = i as f64 / n as f64;
            let (bu, du) = (bernstein(u), bernstein_derivative(u));
            for j in 0..=n {
                let v = j as f64 / n as f64;
                let (bv, dv) = (bernstein(v), bernstein_derivative(v));
                let mut p = Vec3::zeros();
                let mut pu = Vec3::zeros();
                let mut pv = Vec3::zeros();
                for a in 0..4 {
                    for b in 0..4 {
                        let c = cp[a * 4 + b];
                        p += c * (bu[a] * bv[b]);
                        pu += c * (du[a] * bv[b]);
                        pv += c * (bu[a] * dv[b]);
                    }
                }
                let nrm = pu.cross(&pv);
                let nrm = if nrm.norm() > 1e-9 {
                    to_y_up(&nrm.normalize())
                } else {
                    Vec3::zeros() // fixed up from faces below
                };
                mesh.positions.push(to_y_up(&p));
                mesh.normals.push(nrm);
                mesh.uvs.push([u, v]);
            }
        }
        let stride = (n + 1) as u32;
        for i in 0..n as u32 {
            for j in 0..n as u32 {
                let a = base + i * stride + j;
                let b = a + stride;
                for tri in [[a, b, b + 1], [a, b + 1, a + 1]] {
                    let p = tri.map(|k| mesh.positions[k as usize]);
                    if (p[1] - p[0]).cross(&(p[2] - p[0])).norm() > 1e-12 {
                        mesh.triangles.push(tri);
                    }
                }
            }
        }
    }
    // vertices where the patch parameterisation degenerates get the face normal
    let mut acc = vec![Vec3::zeros(); mesh.positions.len()];
    for t in &mesh.triangles {
        let p = t.map(|k| mesh.positions[k as usize]);
        let fnrm = (p[1] - p[0]).cross(&(p[2] - p[0]));
        for &k in t {
            acc[k as usize] += fnrm;
        }
    }
    for (nrm, a) in mesh.normals.iter_mut().zip(acc) {
        if nrm.norm() < 0.5 {
            // unused pole vertices keep an arbitrary unit normal
            *nrm = if a.norm() > 0.0 {
                a.normalize()
            } else {
                Vec3::y()
            };
        }
    }
    mesh
}

/// Height of the untransformed Utah teapot ([`utah_teapot`]).
const TEAPOT_HEIGHT: f64 = 3.15;

/// The Utah teapot of [`utah_teapot`] with texture coordinates that run around it instead of
/// across each patch: `u = 0.5 + atan2(z, x) / 2π` (the azimuth about the teapot's +y axis,
/// as on a sphere: u = 0.5 towards +x, the spout, and the seam u = 0 ≡ 1 towards −x, through
/// the handle) and `v = 1 − y / 3.15` (0 at the top of the knob, 1 at the base). Positions,
/// normals and triangles are those of [`utah_teapot`].
///
/// Every patch keeps its own vertices, and within a patch u is continuous: a patch that
/// straddles the seam has u values just below 0 or just above 1 on one side, which a texture
/// that wraps in u (as [`crate::CoefficientTexture`] does) reads as the same place. Vertices
/// on the axis (the knob's tip, the base's centre) take the azimuth of their neighbour along
/// the patch. Texture features keep their shape on the body; the handle and the spout, which
/// span little azimuth, see the texture stretched along their length.
pub fn utah_teapot_wrapped(n: usize) -> Mesh {
    let n = n.max(1);
    let mut mesh = utah_teapot(n);
    let side = n + 1;
    let per_patch = side * side;
    let azimuth = |p: &Vec3| (p.x.hypot(p.z) > 1e-9).then(|| p.z.atan2(p.x));
    let mut uvs = Vec::with_capacity(mesh.positions.len());
    for patch in mesh.positions.chunks(per_patch) {
        let own: Vec<Option<f64>> = patch.iter().map(azimuth).collect();
        // the patch's circular mean azimuth, to unwrap its vertices around
        let (s, c) = own
            .iter()
            .flatten()
            .fold((0.0, 0.0), |(s, c), a| (s + a.sin(), c + a.cos()));
        let reference = s.atan2(c);
        for (k, p) in patch.iter().enumerate() {
            let (i, j) = (k / side, k % side);
            // an axis vertex borrows the azimuth of the nearest vertex along its column
            let a = own[k]
                .or_else(|| {
                    (1..side).find_map(|d| {
                        let up = (i + d < side).then(|| own[(i + d) * side + j]).flatten();
                        let down = (d <= i).then(|| own[(i - d) * side + j]).flatten();
                        up.or(down)
                    })
                })
                .unwrap_or(reference);
            let a = a + TAU * ((reference - a) / TAU).round();
            let v = (1.0 - p.y / TEAPOT_HEIGHT).clamp(0.0, 1.0);
            uvs.push([0.5 + a / TAU, v]);
        }
    }
    mesh.uvs = uvs;
    mesh
}

/// Reads a Wavefront OBJ file (`v`, `vn`, `vt`, `f` with polygons fanned into triangles).
pub fn read_obj(path: &Path) -> Result<Mesh> {
    let text = std::fs::read_to_string(path).map_err(|e| RenderError::io(path, e))?;
    parse_obj(&text, path)
}

/// Parses OBJ text (`path` only names errors).
pub fn parse_obj(text: &str, path: &Path) -> Result<Mesh> {
    let err = |line: usize, message: String| RenderError::Obj {
        path: path.to_path_buf(),
        line,
        message,
    };
    let mut pos: Vec<Vec3> = Vec::new();
    let mut nrm: Vec<Vec3> = Vec::new();
    let mut tex: Vec<[f64; 2]> = Vec::new();
    // unique (v, vt, vn) triples become mesh vertices
    let mut map: std::collections::HashMap<(usize, Option<usize>, Option<usize>), u32> =
        Default::default();
    let mut mesh = Mesh::default();
    let mut any_normals = true;
    let mut any_uvs = true;
    let mut vertex_keys: Vec<(usize, Option<usize>, Option<usize>)> = Vec::new();
    for (ln, raw) in text.lines().enumerate() {
        let ln = ln + 1;
        let line = raw.split('#').next().unwrap_or("").trim();
        let mut it = line.split_whitespace();
        let Some(tag) = it.next() else { continue };
        let floats = |it: std::str::SplitWhitespace, k: usize| -> Result<Vec<f64>> {
            let v: std::result::Result<Vec<f64>, _> = it.take(k).map(str::parse::<f64>).collect();
            let v = v.map_err(|e| err(ln, format!("bad number: {e}")))?;
            if v.len() < k || v.iter().any(|x| !x.is_finite()) {
                return Err(err(ln, format!("expected {k} finite numbers")));
            }
            Ok(v)
        };
        match tag {
            "v" => {
                let v = floats(it, 3)?;
                pos.push(Vec3::new(v[0], v[1], v[2]));
            }
            "vn" => {
                let v = floats(it, 3)?;
                nrm.push(Vec3::new(v[0], v[1], v[2]));
            }
            "vt" => {
                let v = floats(it, 2)?;
                tex.push([v[0], v[1]]);
            }
            "f" => {
                let mut face = Vec::new();
                for tok in it {
                    let mut parts = tok.split('/');
                    let resolve = |s: Option<&str>, n: usize| -> Result<Option<usize>> {
                        match s {
                            None | Some("") => Ok(None),
                            Some(s) => {
                                let i: i64 =
                                    s.parse().map_err(|_| err(ln, format!("bad index `{s}`")))?;
                                let idx = if i > 0 { i - 1 } else { n as i64 + i };
                                if idx < 0 || idx as usize >= n {
                                    return Err(err(ln, format!("index {i} out of range")));
                                }
                                Ok(Some(idx as usize))
                            }
                        }
                    };
                    let v = resolve(parts.next(), pos.len())?
                        .ok_or_else(|| err(ln, "face vertex without position".into()))?;
                    let t = resolve(parts.next(), tex.len())?;
                    let n = resolve(parts.next(), nrm.len())?;
                    any_normals &= n.is_some();
                    any_uvs &= t.is_some();
                    let key = (v, t, n);
                    let id = *map.entry(key).or_insert_with(|| {
                        vertex_keys.push(key);
                        (vertex_keys.len() - 1) as u32
                    });
                    face.push(id);
                }
                if face.len() < 3 {
                    return Err(err(ln, "face with fewer than 3 vertices".into()));
                }
                for k in 1..face.len() - 1 {
                    mesh.triangles.push([face[0], face[k], face[k + 1]]);
                }
            }
            _ => {}
        }
    }
    for &(v, t, n) in &vertex_keys {
        mesh.positions.push(pos[v]);
        if any_normals {
            mesh.normals
                .push(n.map(|i| nrm[i]).unwrap_or_else(Vec3::zeros));
        }
        if any_uvs {
            mesh.uvs.push(t.map(|i| tex[i]).unwrap_or([0.0; 2]));
        }
    }
    if mesh.triangles.is_empty() {
        return Err(err(0, "no faces".into()));
    }
    mesh.validate()?;
    Ok(mesh)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn teapot_has_published_size_and_closed_shape() {
        let patches = teapot_patches();
        assert_eq!(patches.len(), 32);
        let m = utah_teapot(8);
        let (lo, hi) = m.bounds();
        // height 3.15, spout tip at x = 3.525 (rim handle at x = -3.0)
        assert!(
            (hi.y - 3.15).abs() < 1e-9 && lo.y.abs() < 1e-9,
            "{lo:?} {hi:?}"
        );
        assert!(hi.x > 3.3 && hi.x <= 3.525 + 1e-9 && lo.x >= -3.0 - 1e-9);
        // finer tessellation converges in area
        let a8 = m.area();
        let a32 = utah_teapot(32).area();
        assert!((a8 - a32).abs() / a32 < 0.01, "{a8} vs {a32}");
        assert!(m.normals.iter().all(|n| (n.norm() - 1.0).abs() < 1e-6));
    }

    #[test]
    fn wrapped_teapot_uvs_are_continuous_and_go_around() {
        let n = 6;
        let m = utah_teapot_wrapped(n);
        let patch = utah_teapot(n);
        assert_eq!(m.positions, patch.positions);
        assert_eq!(m.triangles, patch.triangles);
        m.validate().unwrap();
        // no triangle spans the seam: u is continuous within every patch
        for t in &m.triangles {
            let u = t.map(|i| m.uvs[i as usize][0]);
            let span = u.iter().cloned().fold(f64::MIN, f64::max)
                - u.iter().cloned().fold(f64::MAX, f64::min);
            assert!(span < 0.3, "{t:?} {u:?}");
        }
        // vertices shared by neighbouring patches read the same place of a u-wrapping texture
        let mut checked = 0;
        for a in 0..m.positions.len() {
            for b in a + 1..m.positions.len() {
                let (pa, pb) = (m.positions[a], m.positions[b]);
                if (pa - pb).norm() < 1e-9 && pa.x.hypot(pa.z) > 1e-6 {
                    // distance on the circle u mod 1
                    let du = (m.uvs[a][0] - m.uvs[b][0]).rem_euclid(1.0);
                    assert!(
                        du.min(1.0 - du) < 1e-9,
                        "{pa:?}: {:?} {:?}",
                        m.uvs[a],
                        m.uvs[b]
                    );
                    assert!((m.uvs[a][1] - m.uvs[b][1]).abs() < 1e-12);
                    checked += 1;
                }
            }
        }
        assert!(checked > 100, "{checked}");
        // u runs once around the body: towards +z u = 0.75, towards −z 0.25
        let near = |dir: Vec3| {
            let (i, _) = m
                .positions
                .iter()
                .enumerate()
                .filter(|(_, p)| (p.y - 1.5).abs() < 0.3)
                .max_by(|(_, p), (_, q)| p.dot(&dir).total_cmp(&q.dot(&dir)))
                .unwrap();
            m.uvs[i]
        };
        assert!((near(-Vec3::z())[0].rem_euclid(1.0) - 0.25).abs() < 0.05);
        assert!((near(Vec3::z())[0].rem_euclid(1.0) - 0.75).abs() < 0.05);
        let (top, bottom) = (
            m.uvs.iter().map(|t| t[1]).fold(1.0, f64::min),
            m.uvs.iter().map(|t| t[1]).fold(0.0, f64::max),
        );
        assert!(top < 1e-9 && (bottom - 1.0).abs() < 1e-9);
    }

    #[test]
    fn obj_parses_quads_and_rejects_bad_indices() {
        let ok = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1 4//1\n";
        let m = parse_obj(ok, Path::new("t.obj")).unwrap();
        assert_eq!(m.triangles.len(), 2);
        assert!((m.area() - 1.0).abs() < 1e-12);
        assert!(parse_obj("v 0 0 0\nf 1 2 3\n", Path::new("b.obj")).is_err());
        assert!(parse_obj("v 0 0 nan\n", Path::new("c.obj")).is_err());
    }

    /// A closed octahedron with vertices on the axes (outward winding).
    fn octahedron() -> Mesh {
        let positions = vec![
            Vec3::x(),
            -Vec3::x(),
            Vec3::y(),
            -Vec3::y(),
            Vec3::z(),
            -Vec3::z(),
        ];
        let mut triangles = Vec::new();
        for &(a, b) in &[(0u32, 4u32), (4, 1), (1, 5), (5, 0)] {
            triangles.push([b, a, 2]);
            triangles.push([a, b, 3]);
        }
        Mesh {
            positions,
            triangles,
            ..Default::default()
        }
    }

    #[test]
    fn smooth_normals_of_a_symmetric_closed_mesh_point_along_the_vertices() {
        let mut m = octahedron();
        // the winding is outward: every face normal points away from the centre
        for t in &m.triangles {
            let p = t.map(|i| m.positions[i as usize]);
            let n = (p[1] - p[0]).cross(&(p[2] - p[0]));
            assert!(n.dot(&(p[0] + p[1] + p[2])) > 0.0, "{t:?}");
        }
        m.smooth_normals();
        for (p, n) in m.positions.iter().zip(&m.normals) {
            assert!((p - n).norm() < 1e-12, "{p:?} {n:?}");
        }
    }

    #[test]
    fn cylindrical_uvs_split_the_seam_and_keep_the_surface() {
        let mut m = utah_teapot(6);
        m.uvs.clear();
        let (area, before) = (m.area(), m.positions.len());
        m.cylindrical_uvs(0.0, 0.0);
        m.validate().unwrap();
        assert!(m.positions.len() > before, "the teapot straddles the seam");
        assert!((m.area() - area).abs() < 1e-9 * area);
        for t in &m.triangles {
            let u = t.map(|i| m.uvs[i as usize][0]);
            let spread = u.iter().cloned().fold(f64::NEG_INFINITY, f64::max)
                - u.iter().cloned().fold(f64::INFINITY, f64::min);
            assert!(spread <= 0.5, "{u:?}");
        }
        for (p, [u, v]) in m.positions.iter().zip(&m.uvs) {
            assert!((0.0..=1.0).contains(v) && (0.0..1.5).contains(u));
            if p.x.hypot(p.z) > 1e-9 {
                // u is the azimuth, up to whole turns
                let a = (u - 0.5) * TAU;
                assert!((a.cos() - p.x / p.x.hypot(p.z)).abs() < 1e-9);
                assert!((a.sin() - p.z / p.x.hypot(p.z)).abs() < 1e-9);
            }
        }
    }
}

//! Neural-BRDF weight files (Sztrajman et al. 2021): the form in which the shared reference
//! measurements are distributed.
//!
//! A material `NAME` is six little-endian float32 `.npy` files: `NAME_fc1.npy` (6 × H),
//! `NAME_b1.npy` (H), `NAME_fc2.npy` (H × H), `NAME_b2.npy` (H), `NAME_fc3.npy` (H × 3) and
//! `NAME_b3.npy` (3), with H = 21 in the shared data. Kernels are input-major:
//! `out[j] = b[j] + Σ_i in[i] · fc[i][j]`. One BRDF value at (θh, θd, φd), φh = 0, is
//!
//! ```text
//! x  = (sin θh, 0, cos θh, sin θd cos φd, sin θd sin φd, cos θd)
//! a1 = relu(x · fc1 + b1);  a2 = relu(a1 · fc2 + b2);  f = exp(a2 · fc3 + b3) − 1
//! ```
//!
//! in 1/sr with the MERL colour scaling applied. Negative outputs (where the original measurement
//! had no data) are clamped to zero.

use crate::coords::{HalfDiff, Vec3};
use crate::error::{BrdfError, Result};
use crate::npy;
use crate::table::{bin_angles, MerlTable, BINS, PHI_D_RES, THETA_D_RES};
use crate::{Brdf, Rgb};
use rayon::prelude::*;
use std::path::{Path, PathBuf};

/// Hidden width handled by the vectorised tabulation path (the shared files use 21).
const FAST_WIDTH: usize = 24;

/// The weights of one neural BRDF.
#[derive(Debug, Clone, PartialEq)]
pub struct Nbrdf {
    name: String,
    hidden: usize,
    fc1: Vec<f32>,
    b1: Vec<f32>,
    fc2: Vec<f32>,
    b2: Vec<f32>,
    fc3: Vec<f32>,
    b3: Vec<f32>,
}

/// MERL materials embedded in this crate as neural-BRDF weights (a few kilobytes each), so that
/// `merl:<name>` of these works on a machine without the shared data (see `data/NOTICE.md` for
/// their source and licence).
pub const EMBEDDED_MERL: [&str; 3] = ["blue-acrylic", "pink-felt", "chrome"];

macro_rules! embedded_material {
    ($name:literal) => {
        (
            $name,
            [
                include_bytes!(concat!("../data/merl/", $name, "_fc1.npy")).as_slice(),
                include_bytes!(concat!("../data/merl/", $name, "_b1.npy")).as_slice(),
                include_bytes!(concat!("../data/merl/", $name, "_fc2.npy")).as_slice(),
                include_bytes!(concat!("../data/merl/", $name, "_b2.npy")).as_slice(),
                include_bytes!(concat!("../data/merl/", $name, "_fc3.npy")).as_slice(),
                include_bytes!(concat!("../data/merl/", $name, "_b3.npy")).as_slice(),
            ],
        )
    };
}

static EMBEDDED_FILES: [(&str, [&[u8]; 6]); 3] = [
    embedded_material!("blue-acrylic"),
    embedded_material!("pink-felt"),
    embedded_material!("chrome"),
];

/// Suffixes of the six weight files, in network order.
pub const FILE_SUFFIXES: [&str; 6] = ["fc1", "b1", "fc2", "b2", "fc3", "b3"];

fn file_of(dir: &Path, name: &str, suffix: &str) -> PathBuf {
    dir.join(format!("{name}_{suffix}.npy"))
}

impl Nbrdf {
    /// Loads material `name` from the six `.npy` files in `dir`.
    pub fn load(dir: impl AsRef<Path>, name: &str) -> Result<Self> {
        let dir = dir.as_ref();
        let arrays: Vec<npy::NpyArray> = FILE_SUFFIXES
            .iter()
            .map(|s| npy::read(file_of(dir, name, s)))
            .collect::<Result<_>>()?;
        Self::from_arrays(name, arrays, |s| {
            format!("{}", file_of(dir, name, s).display())
        })
    }

    /// The material `name` of the MERL set embedded in this crate ([`EMBEDDED_MERL`]), if it
    /// is one of them: a default sample that works without the shared data.
    pub fn embedded(name: &str) -> Option<Result<Self>> {
        let (_, files) = EMBEDDED_FILES.iter().find(|(n, _)| *n == name)?;
        let parsed = FILE_SUFFIXES
            .iter()
            .zip(files.iter())
            .map(|(s, bytes)| npy::parse(bytes, Path::new(&format!("embedded:{name}_{s}.npy"))))
            .collect::<Result<Vec<_>>>();
        Some(parsed.and_then(|arrays| {
            Self::from_arrays(name, arrays, |s| format!("embedded:{name}_{s}.npy"))
        }))
    }

    /// Builds a network from its six arrays in [`FILE_SUFFIXES`] order, checking their shapes;
    /// `what` names the file of a suffix in errors.
    fn from_arrays(
        name: &str,
        arrays: Vec<npy::NpyArray>,
        what: impl Fn(&str) -> String,
    ) -> Result<Self> {
        let [fc1, b1, fc2, b2, fc3, b3]: [npy::NpyArray; 6] =
            arrays.try_into().map_err(|_| BrdfError::Spec {
                spec: name.into(),
                reason: "weight files missing".into(),
            })?;
        let hidden = fc1.shape.get(1).copied().unwrap_or(0);
        let check = |a: &npy::NpyArray, s: &str, expected: Vec<usize>| {
            if a.shape != expected {
                Err(BrdfError::Shape {
                    what: what(s),
                    expected,
                    found: a.shape.clone(),
                })
            } else {
                Ok(())
            }
        };
        check(&fc1, "fc1", vec![6, hidden])?;
        if hidden == 0 {
            return Err(BrdfError::Shape {
                what: what("fc1"),
                expected: vec![6, 21],
                found: fc1.shape,
            });
        }
        check(&b1, "b1", vec![hidden])?;
        check(&fc2, "fc2", vec![hidden, hidden])?;
        check(&b2, "b2", vec![hidden])?;
        check(&fc3, "fc3", vec![hidden, 3])?;
        check(&b3, "b3", vec![3])?;
        Ok(Self {
            name: name.into(),
            hidden,
            fc1: fc1.data,
            b1: b1.data,
            fc2: fc2.data,
            b2: b2.data,
            fc3: fc3.data,
            b3: b3.data,
        })
    }

    /// Material name.
    pub fn material_name(&self) -> &str {
        &self.name
    }

    /// Width of the hidden layers.
    pub fn hidden_width(&self) -> usize {
        self.hidden
    }

    /// Evaluates the network at (θh, θd, φd) with φh = 0, straight from the definition, in double
    /// precision. Negative outputs are clamped to zero.
    pub fn eval_angles(&self, theta_h: f64, theta_d: f64, phi_d: f64) -> [f64; 3] {
        let h = self.hidden;
        let (sd, cd) = theta_d.sin_cos();
        let (sp, cp) = phi_d.sin_cos();
        let x = [theta_h.sin(), 0.0, theta_h.cos(), sd * cp, sd * sp, cd];
        let layer = |input: &[f64], w: &[f32], b: &[f32], width: usize| -> Vec<f64> {
            let mut out: Vec<f64> = b.iter().map(|&v| v as f64).collect();
            for (i, xi) in input.iter().enumerate() {
                for (j, o) in out.iter_mut().enumerate() {
                    *o += xi * w[i * width + j] as f64;
                }
            }
            out
        };
        let relu = |v: Vec<f64>| -> Vec<f64> { v.into_iter().map(|x| x.max(0.0)).collect() };
        let a1 = relu(layer(&x, &self.fc1, &self.b1, h));
        let a2 = relu(layer(&a1, &self.fc2, &self.b2, h));
        let out = layer(&a2, &self.fc3, &self.b3, 3);
        [0, 1, 2].map(|c| out[c].exp_m1().max(0.0))
    }

    /// Tabulates onto the MERL grid as `f32` BRDF values in 1/sr, 3 × [`BINS`] channel-major,
    /// in parallel over θh.
    pub fn tabulate_f32(&self) -> Vec<f32> {
        let mut out = vec![0.0f32; 3 * BINS];
        let plane = THETA_D_RES * PHI_D_RES;
        let (r, rest) = out.split_at_mut(BINS);
        let (g, b) = rest.split_at_mut(BINS);
        if self.hidden > FAST_WIDTH {
            r.par_chunks_mut(plane)
                .zip(g.par_chunks_mut(plane))
                .zip(b.par_chunks_mut(plane))
                .enumerate()
                .for_each(|(ih, ((r, g), b))| {
                    for k in 0..plane {
                        let (th, td, pd) = bin_angles(ih, k / PHI_D_RES, k % PHI_D_RES);
                        let v = self.eval_angles(th, td, pd);
                        (r[k], g[k], b[k]) = (v[0] as f32, v[1] as f32, v[2] as f32);
                    }
                });
            return out;
        }
        let fast = FastNet::new(self);
        // First-layer contribution of the difference vector, shared by every θh.
        let diff_part: Vec<[f32; FAST_WIDTH]> = (0..plane)
            .map(|k| {
                let (_, td, pd) = bin_angles(0, k / PHI_D_RES, k % PHI_D_RES);
                let (sd, cd) = td.sin_cos();
                let (sp, cp) = pd.sin_cos();
                let x = [(sd * cp) as f32, (sd * sp) as f32, cd as f32];
                let mut acc = [0.0f32; FAST_WIDTH];
                for (i, xi) in x.iter().enumerate() {
                    for (a, w) in acc.iter_mut().zip(&fast.w1[3 + i]) {
                        *a += xi * w;
                    }
                }
                acc
            })
            .collect();
        r.par_chunks_mut(plane)
            .zip(g.par_chunks_mut(plane))
            .zip(b.par_chunks_mut(plane))
            .enumerate()
            .for_each(|(ih, ((r, g), b))| {
                let (th, _, _) = bin_angles(ih, 0, 0);
                let (st, ct) = (th.sin() as f32, th.cos() as f32);
                let mut half_part = fast.b1;
                for ((a, w0), w2) in half_part.iter_mut().zip(&fast.w1[0]).zip(&fast.w1[2]) {
                    *a += st * w0 + ct * w2;
                }
                for (k, d) in diff_part.iter().enumerate() {
                    let v = fast.eval_from_first_layer(&half_part, d);
                    (r[k], g[k], b[k]) = (v[0], v[1], v[2]);
                }
            });
        out
    }

    /// Tabulates onto the MERL grid as a [`MerlTable`].
    pub fn tabulate(&self) -> MerlTable {
        let values = self.tabulate_f32();
        MerlTable::from_values_f32(&values)
            .unwrap_or_else(|_| MerlTable::missing())
            .with_name(self.name.clone())
    }
}

/// Weights padded to [`FAST_WIDTH`] so that the inner loops vectorise.
struct FastNet {
    w1: [[f32; FAST_WIDTH]; 6],
    b1: [f32; FAST_WIDTH],
    w2: Vec<[f32; FAST_WIDTH]>,
    b2: [f32; FAST_WIDTH],
    w3: Vec<[f32; 3]>,
    b3: [f32; 3],
}

impl FastNet {
    fn new(n: &Nbrdf) -> Self {
        let h = n.hidden;
        let mut w1 = [[0.0; FAST_WIDTH]; 6];
        for (i, row) in w1.iter_mut().enumerate() {
            row[..h].copy_from_slice(&n.fc1[i * h..(i + 1) * h]);
        }
        let mut b1 = [0.0; FAST_WIDTH];
        b1[..h].copy_from_slice(&n.b1);
        let w2 = (0..h)
            .map(|i| {
                let mut row = [0.0; FAST_WIDTH];
                row[..h].copy_from_slice(&n.fc2[i * h..(i + 1) * h]);
                row
            })
            .collect();
        let mut b2 = [0.0; FAST_WIDTH];
        b2[..h].copy_from_slice(&n.b2);
        let w3 = (0..h)
            .map(|i| [n.fc3[3 * i], n.fc3[3 * i + 1], n.fc3[3 * i + 2]])
            .collect();
        Self {
            w1,
            b1,
            w2,
            b2,
            w3,
            b3: [n.b3[0], n.b3[1], n.b3[2]],
        }
    }

    #[inline]
    fn eval_from_first_layer(
        &self,
        half: &[f32; FAST_WIDTH],
        diff: &[f32; FAST_WIDTH],
    ) -> [f32; 3] {
        let mut a1 = [0.0f32; FAST_WIDTH];
        for ((a, h), d) in a1.iter_mut().zip(half).zip(diff) {
            *a = (h + d).max(0.0);
        }
        let mut a2 = self.b2;
        for (x, row) in a1.iter().zip(&self.w2) {
            for (a, w) in a2.iter_mut().zip(row) {
                *a += x * w;
            }
        }
        let mut out = self.b3;
        for (x, w) in a2.iter().zip(&self.w3) {
            let x = x.max(0.0);
            out[0] += x * w[0];
            out[1] += x * w[1];
            out[2] += x * w[2];
        }
        out.map(|v| v.exp_m1().max(0.0))
    }
}

impl Brdf for Nbrdf {
    fn eval(&self, wi: &Vec3, wo: &Vec3) -> Rgb {
        if wi.z < 0.0 || wo.z < 0.0 {
            return [0.0; 3];
        }
        self.eval_half_diff(&HalfDiff::from_directions(wi, wo))
    }

    fn eval_half_diff(&self, hd: &HalfDiff) -> Rgb {
        self.eval_angles(hd.theta_h, hd.theta_d, hd.phi_d)
    }

    fn name(&self) -> String {
        self.name.clone()
    }
}

/// The sets of shared neural-BRDF weights under `data_dir()/nbrdf` (96 MERL, 8 Nielsen).
pub const SHARED_SETS: [&str; 2] = ["merl", "nielsen"];

/// Every shared material as `(set, folder, name)`, set by set in [`SHARED_SETS`] order and
/// sorted by name within a set (the data directory is [`crate::data_dir`]).
pub fn shared_materials() -> Result<Vec<(&'static str, std::path::PathBuf, String)>> {
    let root = crate::data_dir().join("nbrdf");
    let mut all = Vec::new();
    for set in SHARED_SETS {
        let dir = root.join(set);
        for name in list(&dir)? {
            all.push((set, dir.clone(), name));
        }
    }
    Ok(all)
}

/// The MERL table of one of [`shared_materials`]: `(set, folder, name)`.
pub fn shared_table(material: &(&str, std::path::PathBuf, String)) -> Result<crate::MerlTable> {
    let (_, dir, name) = material;
    Ok(Nbrdf::load(dir, name)?.tabulate())
}

/// Names of the complete materials (all six weight files present) in `dir`, sorted.
pub fn list(dir: impl AsRef<Path>) -> Result<Vec<String>> {
    let dir = dir.as_ref();
    let entries = std::fs::read_dir(dir).map_err(|e| BrdfError::io(dir, e))?;
    let mut names = Vec::new();
    for e in entries {
        let e = e.map_err(|e| BrdfError::io(dir, e))?;
        let fname = e.file_name().to_string_lossy().into_owned();
        if let Some(name) = fname.strip_suffix("_fc1.npy") {
            if FILE_SUFFIXES
                .iter()
                .all(|s| file_of(dir, name, s).is_file())
            {
                names.push(name.to_string());
            }
        }
    }
    names.sort();
    Ok(names)
}

/// Loads every complete material of `dir` (see [`list`]), sorted by name.
pub fn load_dir(dir: impl AsRef<Path>) -> Result<Vec<Nbrdf>> {
    let dir = dir.as_ref();
    list(dir)?.iter().map(|n| Nbrdf::load(dir, n)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn shared_material(name: &str) -> Option<Nbrdf> {
        let dir = crate::data_dir().join("nbrdf/merl");
        if !dir.is_dir() {
            return None;
        }
        Some(Nbrdf::load(&dir, name).expect("shared material loads"))
    }

    #[test]
    fn fast_tabulation_matches_direct_evaluation() {
        let Some(n) = shared_material("blue-acrylic") else {
            panic!("shared data not found: set BRDF_DATA_DIR");
        };
        assert_eq!(n.hidden_width(), 21);
        let t = n.tabulate_f32();
        for &(i, j, k) in &[
            (0, 0, 0),
            (1, 2, 3),
            (10, 45, 90),
            (89, 89, 179),
            (60, 30, 120),
        ] {
            let (th, td, pd) = bin_angles(i, j, k);
            let direct = n.eval_angles(th, td, pd);
            let bin = crate::table::bin_index(i, j, k);
            for c in 0..3 {
                let fast = t[c * BINS + bin] as f64;
                // Single against double precision: the exponent amplifies rounding a little.
                assert!(
                    (fast - direct[c]).abs() <= 1e-4 * direct[c].abs().max(1e-3),
                    "({i},{j},{k}) ch {c}: fast {fast} direct {}",
                    direct[c]
                );
            }
        }
        assert!(t.iter().all(|v| *v >= 0.0 && v.is_finite()));
    }

    #[test]
    fn listing_finds_all_shared_materials() {
        let dir = crate::data_dir().join("nbrdf");
        let merl = list(dir.join("merl")).unwrap();
        let nielsen = list(dir.join("nielsen")).unwrap();
        assert_eq!(merl.len(), 96);
        assert_eq!(nielsen.len(), 8);
        assert!(merl.iter().any(|n| n == "chrome"));
    }

    #[test]
    fn broken_weight_files_are_errors() {
        let tmp = tempfile::tempdir().unwrap();
        let src = crate::data_dir().join("nbrdf/merl");
        for s in FILE_SUFFIXES {
            std::fs::copy(file_of(&src, "pink-felt", s), file_of(tmp.path(), "m", s)).unwrap();
        }
        assert!(Nbrdf::load(tmp.path(), "m").is_ok());
        // Wrong shape: swap fc2 for fc3.
        std::fs::copy(
            file_of(&src, "pink-felt", "fc3"),
            file_of(tmp.path(), "m", "fc2"),
        )
        .unwrap();
        assert!(matches!(
            Nbrdf::load(tmp.path(), "m"),
            Err(BrdfError::Shape { .. })
        ));
        // Missing file.
        std::fs::remove_file(file_of(tmp.path(), "m", "b3")).unwrap();
        assert!(matches!(
            Nbrdf::load(tmp.path(), "m"),
            Err(BrdfError::Io { .. })
        ));
        assert!(list(tmp.path()).unwrap().is_empty());
    }
}

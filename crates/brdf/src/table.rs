//! Dense isotropic BRDF tables on the MERL grid (90 θh × 90 θd × 180 φd × RGB).

use crate::coords::{HalfDiff, Vec3};
use crate::error::{BrdfError, Result};
use crate::{Brdf, Rgb};
use rayon::prelude::*;
use std::f64::consts::{FRAC_PI_2, PI};

/// Number of θh bins.
pub const THETA_H_RES: usize = 90;
/// Number of θd bins.
pub const THETA_D_RES: usize = 90;
/// Number of φd bins (over `[0, π)`).
pub const PHI_D_RES: usize = 180;
/// Bins per channel: 90 · 90 · 180 = 1,458,000.
pub const BINS: usize = THETA_H_RES * THETA_D_RES * PHI_D_RES;
/// Per-channel factors converting stored MERL values to BRDF values in 1/sr.
pub const MERL_SCALE: [f64; 3] = [1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0];

/// Flat bin index of grid indices (θh, θd, φd).
#[inline]
pub fn bin_index(i_th: usize, i_td: usize, i_pd: usize) -> usize {
    i_pd + PHI_D_RES * (i_td + THETA_D_RES * i_th)
}

/// Grid indices (θh, θd, φd) of a flat bin index.
#[inline]
pub fn bin_coords(bin: usize) -> (usize, usize, usize) {
    let i_pd = bin % PHI_D_RES;
    let rest = bin / PHI_D_RES;
    (rest / THETA_D_RES, rest % THETA_D_RES, i_pd)
}

/// Angles (θh, θd, φd) of the grid point with the given indices.
#[inline]
pub fn bin_angles(i_th: usize, i_td: usize, i_pd: usize) -> (f64, f64, f64) {
    let u = i_th as f64 / THETA_H_RES as f64;
    (
        u * u * FRAC_PI_2,
        i_td as f64 / THETA_D_RES as f64 * FRAC_PI_2,
        i_pd as f64 / PHI_D_RES as f64 * PI,
    )
}

/// θh bin index with the MERL reference reader's arithmetic.
#[inline]
pub fn theta_half_index(theta_half: f64) -> usize {
    if theta_half.is_nan() || theta_half <= 0.0 {
        return 0;
    }
    let theta_half_deg = (theta_half / (PI / 2.0)) * THETA_H_RES as f64;
    let temp = (theta_half_deg * THETA_H_RES as f64).sqrt();
    (temp as i64).clamp(0, THETA_H_RES as i64 - 1) as usize
}

/// θd bin index with the MERL reference reader's arithmetic.
#[inline]
pub fn theta_diff_index(theta_diff: f64) -> usize {
    if theta_diff.is_nan() {
        return 0;
    }
    let tmp = (theta_diff / (PI * 0.5) * THETA_D_RES as f64) as i64;
    tmp.clamp(0, THETA_D_RES as i64 - 1) as usize
}

/// φd bin index with the MERL reference reader's arithmetic, after folding by reciprocity.
///
/// The reference reader receives φd in `(-π, π]` and adds π to negative values; angles in
/// `[π, 2π)` (this crate's convention) are brought to the same place by subtracting π.
#[inline]
pub fn phi_diff_index(phi_diff: f64) -> usize {
    if phi_diff.is_nan() {
        return 0;
    }
    let mut p = phi_diff;
    if p >= PI {
        p -= PI;
    }
    if p < 0.0 {
        p += PI;
    }
    let tmp = (p / PI * (2 * PHI_D_RES) as f64 / 2.0) as i64;
    tmp.clamp(0, PHI_D_RES as i64 - 1) as usize
}

/// The bin whose grid node ([`bin_angles`]) lies nearest to (θh, θd, φd), measured in the grid's
/// own parametrisation: √θh, θd, and φd folded by reciprocity into `[0, π)` (periodic, so angles
/// just below π belong to node 0).
///
/// [`MerlTable::tabulate`] stores the BRDF *at* the grid nodes, while the reference reader's
/// indexing ([`theta_half_index`] etc.) assigns the whole cell `[i, i+1)` to node `i`. Averaging
/// measured samples by the reference indexing therefore estimates the BRDF half a cell away from
/// the node; averaging them by this function estimates it at the node. Non-finite angles give node 0.
#[inline]
pub fn node_bin_index(theta_half: f64, theta_diff: f64, phi_diff: f64) -> usize {
    let [uh, ud, up] = grid_coordinates(theta_half, theta_diff, phi_diff);
    let i = (uh.round() as usize).min(THETA_H_RES - 1);
    let j = (ud.round() as usize).min(THETA_D_RES - 1);
    let k = (up.round() as usize) % PHI_D_RES;
    bin_index(i, j, k)
}

/// Continuous coordinates of the angles on the MERL grid, in units of one bin: √(θh/(π/2))·90,
/// θd/(π/2)·90 and φd folded into [0, π) by reciprocity, /π·180. Node (i, j, k) sits at
/// coordinates (i, j, k). Negative angles count as 0, non-finite ones as 0.
#[inline]
pub fn grid_coordinates(theta_half: f64, theta_diff: f64, phi_diff: f64) -> [f64; 3] {
    let finite_or_zero = |x: f64| if x.is_finite() { x.max(0.0) } else { 0.0 };
    let p = if phi_diff.is_finite() {
        phi_diff.rem_euclid(PI)
    } else {
        0.0
    };
    [
        (finite_or_zero(theta_half) / FRAC_PI_2).sqrt() * THETA_H_RES as f64,
        finite_or_zero(theta_diff) / FRAC_PI_2 * THETA_D_RES as f64,
        p / PI * PHI_D_RES as f64,
    ]
}

/// Rodrigues rotation of `v` about unit `axis` by `angle`, written as the MERL reader does.
fn rotate_vector(v: &Vec3, axis: &Vec3, angle: f64) -> Vec3 {
    let (sin_ang, cos_ang) = (angle.sin(), angle.cos());
    let mut out = v * cos_ang;
    let temp = axis.dot(v) * (1.0 - cos_ang);
    out += axis * temp;
    let cross = axis.cross(v);
    out + cross * sin_ang
}

/// The MERL bin of a direction pair, as the MERL reference reader (and
/// [`MerlTable::lookup_reference`], the nearest lookup of [`crate::Brdf::eval`]) selects it.
pub fn reference_bin(wi: &Vec3, wo: &Vec3) -> usize {
    let (th, _, td, pd) = reference_half_diff(wi, wo);
    bin_index(
        theta_half_index(th),
        theta_diff_index(td),
        phi_diff_index(pd),
    )
}

/// Half/difference angles (θh, φh, θd, φd) computed with exactly the arithmetic of the MERL
/// reference reader (`acos` polar angles, Rodrigues rotations, φ in `(-π, π]`); the bin they
/// select is [`reference_bin`].
pub fn reference_half_diff(wi: &Vec3, wo: &Vec3) -> (f64, f64, f64, f64) {
    let sum = wi + wo;
    let norm = sum.norm();
    let half = if norm > 0.0 { sum / norm } else { Vec3::z() };
    let theta_half = half.z.clamp(-1.0, 1.0).acos();
    let phi_half = half.y.atan2(half.x);
    let normal = Vec3::z();
    let bi_normal = Vec3::y();
    let temp = rotate_vector(wi, &normal, -phi_half);
    let diff = rotate_vector(&temp, &bi_normal, -theta_half);
    let theta_diff = diff.z.clamp(-1.0, 1.0).acos();
    let phi_diff = diff.y.atan2(diff.x);
    (theta_half, phi_half, theta_diff, phi_diff)
}

/// How a table is looked up between grid points.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Interpolation {
    /// The bin that contains the query (the MERL reference reader's behaviour).
    #[default]
    Nearest,
    /// Trilinear interpolation between grid points in (√θh, θd, φd) index space; φd wraps
    /// around by reciprocity; missing corners are left out and the weights renormalised.
    Trilinear,
}

/// A tabulated isotropic BRDF on the MERL grid (90 θh × 90 θd × 180 φd × RGB; thesis §3.6).
///
/// Conventions are those of the MERL BRDF database:
///
/// * θh bins follow a square-root mapping: index `floor(sqrt(θh / (π/2)) · 90)`; grid point `i`
///   sits at θh = (i/90)² · π/2, which concentrates resolution near the specular peak.
/// * θd: index `floor(θd / (π/2) · 90)`, grid point θd = j/90 · π/2.
/// * φd is folded by reciprocity into `[0, π)`: index `floor(φd / π · 180)`, grid point
///   φd = k/180 · π.
/// * Flat bin index = `φd_idx + 180 · (θd_idx + 90 · θh_idx)` ([`bin_index`]); values are stored
///   channel-major.
/// * Values are kept in *file units* (BRDF divided by the per-channel [`MERL_SCALE`]), so that
///   a table read from a `.binary` file ([`crate::merl`]) writes back byte for byte. Negative
///   values mark missing data.
///
/// # Examples
///
/// ```
/// use brdf::{bin_index, Brdf, HalfDiff, MerlTable, BINS};
///
/// // a constant table: every bin 0.1 sr⁻¹ in each channel, one bin missing in red
/// let mut table = MerlTable::from_values(vec![0.1; 3 * BINS]).unwrap();
/// let bin = bin_index(10, 20, 30);
/// table.set(0, bin, -1.0);
/// assert!(!table.is_valid(0, bin) && table.bin_rgb(bin).is_none());
/// assert!((table.missing_fraction() - 1.0 / (3 * BINS) as f64).abs() < 1e-15);
/// // values survive the round trip through file units
/// assert!((table.get(1, bin) - 0.1).abs() < 1e-12);
/// let hd = HalfDiff::isotropic(0.3, 0.4, 1.0);
/// assert!((table.lookup(&hd).unwrap()[2] - 0.1).abs() < 1e-12);
/// assert!((table.eval_half_diff(&hd)[2] - 0.1).abs() < 1e-12);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct MerlTable {
    raw: Vec<f64>,
    name: String,
    interpolation: Interpolation,
}

impl MerlTable {
    /// A table whose every value is missing.
    pub fn missing() -> Self {
        Self {
            raw: vec![-1.0; 3 * BINS],
            name: "table".into(),
            interpolation: Interpolation::Nearest,
        }
    }

    /// A table from values in file units (BRDF / MERL scale), 3 × [`BINS`], channel-major.
    pub fn from_raw(raw: Vec<f64>) -> Result<Self> {
        if raw.len() != 3 * BINS {
            return Err(BrdfError::Length {
                expected: 3 * BINS,
                found: raw.len(),
            });
        }
        if let Some(index) = raw.iter().position(|v| !v.is_finite()) {
            return Err(BrdfError::NonFinite {
                path: "table".into(),
                index,
            });
        }
        Ok(Self {
            raw,
            ..Self::missing_empty()
        })
    }

    fn missing_empty() -> Self {
        Self {
            raw: Vec::new(),
            name: "table".into(),
            interpolation: Interpolation::Nearest,
        }
    }

    /// A table from BRDF values in 1/sr, 3 × [`BINS`], channel-major; negative = missing.
    pub fn from_values(values: Vec<f64>) -> Result<Self> {
        let mut raw = values;
        if raw.len() != 3 * BINS {
            return Err(BrdfError::Length {
                expected: 3 * BINS,
                found: raw.len(),
            });
        }
        for (c, chunk) in raw.chunks_mut(BINS).enumerate() {
            for v in chunk {
                *v /= MERL_SCALE[c];
            }
        }
        Self::from_raw(raw)
    }

    /// A table from single-precision BRDF values in 1/sr (3 × [`BINS`], channel-major).
    pub fn from_values_f32(values: &[f32]) -> Result<Self> {
        Self::from_values(values.iter().map(|&v| v as f64).collect())
    }

    /// Tabulates any BRDF at the grid points (θh, θd, φd) with φh = 0, in parallel.
    pub fn tabulate(brdf: &dyn Brdf) -> Self {
        let mut raw = vec![0.0; 3 * BINS];
        let (r, rest) = raw.split_at_mut(BINS);
        let (g, b) = rest.split_at_mut(BINS);
        let plane = THETA_D_RES * PHI_D_RES;
        r.par_chunks_mut(plane)
            .zip(g.par_chunks_mut(plane))
            .zip(b.par_chunks_mut(plane))
            .enumerate()
            .for_each(|(i_th, ((r, g), b))| {
                for i_td in 0..THETA_D_RES {
                    for i_pd in 0..PHI_D_RES {
                        let (th, td, pd) = bin_angles(i_th, i_td, i_pd);
                        let v = brdf.eval_half_diff(&HalfDiff::isotropic(th, td, pd));
                        let k = i_pd + PHI_D_RES * i_td;
                        r[k] = finite_or_zero(v[0]) / MERL_SCALE[0];
                        g[k] = finite_or_zero(v[1]) / MERL_SCALE[1];
                        b[k] = finite_or_zero(v[2]) / MERL_SCALE[2];
                    }
                }
            });
        Self {
            raw,
            name: brdf.name(),
            interpolation: Interpolation::Nearest,
        }
    }

    /// Sets the name reported by [`Brdf::name`].
    pub fn with_name(mut self, name: impl Into<String>) -> Self {
        self.name = name.into();
        self
    }

    /// Chooses the lookup used by [`Brdf::eval`].
    pub fn with_interpolation(mut self, interpolation: Interpolation) -> Self {
        self.interpolation = interpolation;
        self
    }

    /// The lookup used by [`Brdf::eval`].
    pub fn interpolation(&self) -> Interpolation {
        self.interpolation
    }

    /// Values in file units (BRDF / MERL scale), channel-major.
    pub fn raw(&self) -> &[f64] {
        &self.raw
    }

    /// Mutable values in file units.
    pub fn raw_mut(&mut self) -> &mut [f64] {
        &mut self.raw
    }

    /// BRDF value (1/sr) of a channel at a flat bin; negative when missing.
    #[inline]
    pub fn get(&self, channel: usize, bin: usize) -> f64 {
        self.raw[channel * BINS + bin] * MERL_SCALE[channel]
    }

    /// Sets the BRDF value (1/sr) of a channel at a flat bin; a negative value marks it missing.
    #[inline]
    pub fn set(&mut self, channel: usize, bin: usize, value: f64) {
        self.raw[channel * BINS + bin] = value / MERL_SCALE[channel];
    }

    /// Whether the channel has data at the bin.
    #[inline]
    pub fn is_valid(&self, channel: usize, bin: usize) -> bool {
        self.raw[channel * BINS + bin] >= 0.0
    }

    /// RGB value at a flat bin, `None` if any channel is missing there.
    pub fn bin_rgb(&self, bin: usize) -> Option<Rgb> {
        let v = [self.get(0, bin), self.get(1, bin), self.get(2, bin)];
        (v[0] >= 0.0 && v[1] >= 0.0 && v[2] >= 0.0).then_some(v)
    }

    /// All BRDF values in 1/sr, channel-major (negative = missing).
    pub fn values(&self) -> Vec<f64> {
        self.raw
            .chunks(BINS)
            .enumerate()
            .flat_map(|(c, ch)| ch.iter().map(move |v| v * MERL_SCALE[c]))
            .collect()
    }

    /// All BRDF values in 1/sr as `f32`, channel-major (negative = missing).
    pub fn values_f32(&self) -> Vec<f32> {
        self.values().into_iter().map(|v| v as f32).collect()
    }

    /// Fraction of (channel, bin) values that are missing.
    pub fn missing_fraction(&self) -> f64 {
        self.raw.iter().filter(|v| **v < 0.0).count() as f64 / self.raw.len() as f64
    }

    /// Largest BRDF value per channel over valid bins.
    pub fn peak(&self) -> Rgb {
        let mut p = [0.0f64; 3];
        for (c, pc) in p.iter_mut().enumerate() {
            *pc = (0..BINS)
                .map(|b| self.get(c, b))
                .fold(0.0, |a: f64, v| a.max(v));
        }
        p
    }

    /// Nearest-bin lookup at Rusinkiewicz angles; `None` where a channel is missing.
    pub fn lookup_nearest(&self, hd: &HalfDiff) -> Option<Rgb> {
        let bin = bin_index(
            theta_half_index(hd.theta_h),
            theta_diff_index(hd.theta_d),
            phi_diff_index(hd.phi_d),
        );
        self.bin_rgb(bin)
    }

    /// Nearest-bin lookup for a direction pair with the MERL reference reader's arithmetic.
    /// Returns the stored values even below the horizon, as the reference does.
    pub fn lookup_reference(&self, wi: &Vec3, wo: &Vec3) -> Option<Rgb> {
        self.bin_rgb(reference_bin(wi, wo))
    }

    /// Trilinear lookup at Rusinkiewicz angles; `None` where no surrounding grid point has data.
    pub fn lookup_trilinear(&self, hd: &HalfDiff) -> Option<Rgb> {
        let uh = ((hd.theta_h.max(0.0) / FRAC_PI_2).sqrt() * THETA_H_RES as f64)
            .clamp(0.0, (THETA_H_RES - 1) as f64);
        let ud = (hd.theta_d / FRAC_PI_2 * THETA_D_RES as f64).clamp(0.0, (THETA_D_RES - 1) as f64);
        let up = crate::coords::fold_phi_d(hd.phi_d) / PI * PHI_D_RES as f64;
        if !(uh.is_finite() && ud.is_finite() && up.is_finite()) {
            return None;
        }
        let (h0, fh) = split(uh, THETA_H_RES);
        let (d0, fd) = split(ud, THETA_D_RES);
        let p0 = (up.floor() as usize).min(PHI_D_RES - 1);
        let fp = up - p0 as f64;
        let p1 = (p0 + 1) % PHI_D_RES;
        let h1 = (h0 + 1).min(THETA_H_RES - 1);
        let d1 = (d0 + 1).min(THETA_D_RES - 1);
        let mut out = [0.0; 3];
        for (c, o) in out.iter_mut().enumerate() {
            let mut acc = 0.0;
            let mut wsum = 0.0;
            for (ih, wh) in [(h0, 1.0 - fh), (h1, fh)] {
                for (id, wd) in [(d0, 1.0 - fd), (d1, fd)] {
                    for (ip, wp) in [(p0, 1.0 - fp), (p1, fp)] {
                        let w = wh * wd * wp;
                        if w <= 0.0 {
                            continue;
                        }
                        let v = self.get(c, bin_index(ih, id, ip));
                        if v >= 0.0 {
                            acc += w * v;
                            wsum += w;
                        }
                    }
                }
            }
            if wsum <= 0.0 {
                return None;
            }
            *o = acc / wsum;
        }
        Some(out)
    }

    /// Evaluates many Rusinkiewicz angle triples in parallel with the table's interpolation;
    /// missing values come back as zero.
    pub fn eval_batch(&self, points: &[HalfDiff]) -> Vec<Rgb> {
        points
            .par_iter()
            .map(|hd| self.lookup(hd).unwrap_or([0.0; 3]))
            .collect()
    }

    /// Lookup with the table's interpolation mode.
    pub fn lookup(&self, hd: &HalfDiff) -> Option<Rgb> {
        match self.interpolation {
            Interpolation::Nearest => self.lookup_nearest(hd),
            Interpolation::Trilinear => self.lookup_trilinear(hd),
        }
    }
}

fn split(u: f64, res: usize) -> (usize, f64) {
    let i = (u.floor() as usize).min(res - 1);
    (i, u - i as f64)
}

fn finite_or_zero(v: f64) -> f64 {
    if v.is_finite() {
        v
    } else {
        0.0
    }
}

impl Brdf for MerlTable {
    fn eval(&self, wi: &Vec3, wo: &Vec3) -> Rgb {
        if wi.z < 0.0 || wo.z < 0.0 {
            return [0.0; 3];
        }
        match self.interpolation {
            Interpolation::Nearest => self.lookup_reference(wi, wo),
            Interpolation::Trilinear => self.lookup_trilinear(&HalfDiff::from_directions(wi, wo)),
        }
        .unwrap_or([0.0; 3])
    }

    fn eval_half_diff(&self, hd: &HalfDiff) -> Rgb {
        self.lookup(hd).unwrap_or([0.0; 3])
    }

    fn name(&self) -> String {
        self.name.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::coords::AnglePair;
    use rand::{Rng, SeedableRng};

    fn ramp_table() -> MerlTable {
        let mut t = MerlTable::missing();
        for bin in 0..BINS {
            let (h, d, p) = bin_coords(bin);
            for c in 0..3 {
                t.set(c, bin, (h * 3 + d * 5 + p + c) as f64 * 1e-3);
            }
        }
        t
    }

    #[test]
    fn node_bin_index_finds_the_node_within_half_a_cell() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for _ in 0..20_000 {
            let (i, j, k) = (
                rng.gen_range(0..THETA_H_RES),
                rng.gen_range(0..THETA_D_RES),
                rng.gen_range(0..PHI_D_RES),
            );
            let (th, td, pd) = bin_angles(i, j, k);
            assert_eq!(node_bin_index(th, td, pd), bin_index(i, j, k));
            // Move by up to 0.49 cells along each axis of the grid's parametrisation.
            let (a, b, c): (f64, f64, f64) = (
                rng.gen_range(-0.49..0.49),
                rng.gen_range(-0.49..0.49),
                rng.gen_range(-0.49..0.49),
            );
            let uh = (i as f64 + a).max(0.0) / THETA_H_RES as f64;
            let th2 = uh * uh * FRAC_PI_2;
            let td2 = ((j as f64 + b).max(0.0) / THETA_D_RES as f64) * FRAC_PI_2;
            // φd may leave [0, π): reciprocity brings it back (φd + π is the same configuration).
            let pd2 = (k as f64 + c) / PHI_D_RES as f64 * PI + if rng.gen() { PI } else { 0.0 };
            assert_eq!(node_bin_index(th2, td2, pd2), bin_index(i, j, k));
        }
        assert_eq!(node_bin_index(f64::NAN, f64::INFINITY, f64::NAN), 0);
        assert_eq!(
            node_bin_index(FRAC_PI_2, FRAC_PI_2, PI - 1e-9),
            bin_index(THETA_H_RES - 1, THETA_D_RES - 1, 0)
        );
    }

    #[test]
    fn bin_index_round_trip() {
        for bin in [0, 1, 179, 180, 16199, 16200, BINS - 1] {
            let (h, d, p) = bin_coords(bin);
            assert_eq!(bin_index(h, d, p), bin);
        }
        assert_eq!(bin_index(89, 89, 179), BINS - 1);
    }

    #[test]
    fn grid_angles_fall_in_their_bins_away_from_edges() {
        // A point halfway between grid points i and i+1 must index bin i.
        for i in 0..THETA_H_RES - 1 {
            let u = (i as f64 + 0.5) / 90.0;
            assert_eq!(theta_half_index(u * u * FRAC_PI_2), i);
        }
        for j in 0..THETA_D_RES {
            assert_eq!(theta_diff_index((j as f64 + 0.5) / 90.0 * FRAC_PI_2), j);
        }
        for k in 0..PHI_D_RES {
            let p = (k as f64 + 0.5) / 180.0 * PI;
            assert_eq!(phi_diff_index(p), k);
            // Reciprocity: φd + π lands in the same bin, and so does φd - π.
            assert_eq!(phi_diff_index(p + PI), k);
            assert_eq!(phi_diff_index(p - PI), k);
        }
        // Out-of-range values clamp.
        assert_eq!(theta_half_index(-1.0), 0);
        assert_eq!(theta_half_index(10.0), 89);
        assert_eq!(theta_diff_index(10.0), 89);
        assert_eq!(theta_diff_index(-1.0), 0);
    }

    #[test]
    fn reference_and_rusinkiewicz_lookups_agree() {
        let t = ramp_table();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut disagree = 0;
        let n = 20_000;
        for _ in 0..n {
            let pair = AnglePair::new(
                rng.gen_range(0.0..FRAC_PI_2),
                rng.gen_range(0.0..std::f64::consts::TAU),
                rng.gen_range(0.0..FRAC_PI_2),
                rng.gen_range(0.0..std::f64::consts::TAU),
            );
            let (wi, wo) = pair.to_vectors();
            let a = t.lookup_reference(&wi, &wo).unwrap();
            let b = t.lookup_nearest(&pair.to_half_diff()).unwrap();
            if a != b {
                disagree += 1;
            }
        }
        // The two computations differ only by rounding, which can move a point across a bin edge.
        assert!(disagree * 1000 < n, "{disagree} of {n} lookups disagree");
    }

    #[test]
    fn trilinear_reproduces_grid_points_and_linear_functions() {
        let t = ramp_table().with_interpolation(Interpolation::Trilinear);
        for (h, d, p) in [(0, 0, 0), (10, 20, 30), (45, 89, 179), (89, 5, 90)] {
            let (th, td, pd) = bin_angles(h, d, p);
            let v = t
                .lookup_trilinear(&HalfDiff::isotropic(th, td, pd))
                .unwrap();
            let bin = bin_index(h, d, p);
            for (c, vc) in v.iter().enumerate() {
                assert!((vc - t.get(c, bin)).abs() < 1e-9, "{h} {d} {p}");
            }
        }
        // Halfway between two θd grid points (no wrap, no clamp) the ramp is linear.
        let (th, td0, pd) = bin_angles(30, 40, 20);
        let (_, td1, _) = bin_angles(30, 41, 20);
        let v = t
            .lookup_trilinear(&HalfDiff::isotropic(th, 0.5 * (td0 + td1), pd))
            .unwrap();
        let expect = 0.5 * (t.get(0, bin_index(30, 40, 20)) + t.get(0, bin_index(30, 41, 20)));
        assert!((v[0] - expect).abs() < 1e-9);
    }

    #[test]
    fn trilinear_skips_missing_corners() {
        let mut t = ramp_table();
        let bin = bin_index(10, 10, 10);
        t.set(1, bin, -1.0);
        let (th, td, pd) = bin_angles(10, 10, 10);
        let v = t.lookup_trilinear(&HalfDiff::isotropic(th, td, pd));
        // The only corner with weight is missing in green, so the lookup reports no data.
        assert!(v.is_none());
        assert!(t.lookup_nearest(&HalfDiff::isotropic(th, td, pd)).is_none());
        assert!(!t.is_valid(1, bin) && t.is_valid(0, bin));
        assert!((t.missing_fraction() - 1.0 / (3.0 * BINS as f64)).abs() < 1e-15);
    }

    #[test]
    fn values_round_trip_through_file_units() {
        let t = ramp_table();
        let back = MerlTable::from_values(t.values()).unwrap();
        for (a, b) in t.raw().iter().zip(back.raw()) {
            assert!((a - b).abs() <= 1e-12 * a.abs().max(1.0));
        }
        assert!(matches!(
            MerlTable::from_values(vec![0.0; 5]),
            Err(BrdfError::Length { .. })
        ));
        let mut bad = vec![0.0; 3 * BINS];
        bad[17] = f64::NAN;
        assert!(matches!(
            MerlTable::from_raw(bad),
            Err(BrdfError::NonFinite { index: 17, .. })
        ));
    }

    #[test]
    fn batch_evaluation_matches_single_lookups() {
        let t = ramp_table();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let pts: Vec<HalfDiff> = (0..1000)
            .map(|_| {
                HalfDiff::isotropic(
                    rng.gen_range(0.0..FRAC_PI_2),
                    rng.gen_range(0.0..FRAC_PI_2),
                    rng.gen_range(0.0..std::f64::consts::TAU),
                )
            })
            .collect();
        let batch = t.eval_batch(&pts);
        for (p, v) in pts.iter().zip(&batch) {
            assert_eq!(*v, t.lookup_nearest(p).unwrap());
        }
    }
}

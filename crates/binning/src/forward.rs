//! Forward BRDF computation (thesis §3.4), absolute scale from a white reference, and the
//! re-rendering used for validation (§3.6).

use crate::error::{BinningError, Result};
use crate::geometry::{frame_from_normal, to_local, SpherePixel, SphereView, V3};
use crate::samples::Sample;
use brdf::HalfDiff;
use brdf::{
    bin_index, node_bin_index, phi_diff_index, theta_diff_index, theta_half_index, MerlTable,
};
use rayon::prelude::*;

/// Ambient signal rate per channel (DN/s) from two exposures taken with the lamp off, of
/// `long_s` and `short_s` seconds: the mean over clean sphere pixels of the DN difference divided
/// by the exposure difference. The black level cancels in the difference, and averaging over
/// thousands of pixels measures an ambient signal far below any single pixel's noise: stray light
/// of a few electrons per second, which the HDR merge rightly marks invalid per pixel, still biases
/// a dark material's table by several percent if it is not subtracted. `clean[i]` is false for
/// pixels to leave out (hot pixels).
pub fn ambient_from_lamp_off(
    view: &SphereView,
    long: &[u16],
    long_s: f64,
    short: &[u16],
    short_s: f64,
    clean: &dyn Fn(usize) -> bool,
) -> Result<[f64; 3]> {
    let n = view.width * view.height;
    if long.len() != n || short.len() != n {
        return Err(BinningError::Parameter(format!(
            "lamp-off frames of {} and {} pixels for a {}x{} view",
            long.len(),
            short.len(),
            view.width,
            view.height
        )));
    }
    let dt = long_s - short_s;
    if !(dt > 0.0 && dt.is_finite() && short_s >= 0.0) {
        return Err(BinningError::Parameter(format!(
            "lamp-off exposures {long_s} s and {short_s} s: the first must be the longer"
        )));
    }
    let mut sum = [0f64; 3];
    let mut count = [0usize; 3];
    for p in &view.pixels {
        let i = p.index as usize;
        if !clean(i) {
            continue;
        }
        let c = p.channel as usize;
        sum[c] += long[i] as f64 - short[i] as f64;
        count[c] += 1;
    }
    let mut out = [0f64; 3];
    for c in 0..3 {
        if count[c] < MIN_AMBIENT_PIXELS {
            return Err(BinningError::Parameter(format!(
                "only {} clean sphere pixels in channel {c} for the ambient estimate",
                count[c]
            )));
        }
        out[c] = sum[c] / count[c] as f64 / dt;
    }
    Ok(out)
}

/// Options of the forward computation.
#[derive(Debug, Clone)]
pub struct ForwardOptions {
    /// Pixels lit at more than this angle from the normal are not used (degrees).
    pub max_incidence_deg: f64,
    /// Subtract the ambient signal (stray light of the room plus dark signal), estimated per
    /// image and channel from the sphere pixels the lamp does not reach, before dividing by the
    /// irradiance.
    pub subtract_ambient: bool,
    /// A measured ambient rate per channel (DN/s; e.g. from lamp-off exposures, see
    /// [`ambient_from_lamp_off`]) to subtract instead of the shadowed-side estimate. The shadowed
    /// side is dark enough to fall below the HDR valid window for dark materials, where the
    /// estimate would be 0 and the ambient signal a bias of the table.
    pub measured_ambient: Option<[f64; 3]>,
    /// Which bin a sample's (θh, θd, φd) goes to.
    pub assignment: BinAssignment,
}

impl Default for ForwardOptions {
    fn default() -> Self {
        Self {
            max_incidence_deg: 87.0,
            subtract_ambient: true,
            measured_ambient: None,
            assignment: BinAssignment::NearestNode,
        }
    }
}

/// How samples are assigned to MERL bins.
///
/// A table value is read as the BRDF *at* its grid node (the angles of
/// [`brdf::bin_angles`], which is where [`MerlTable::tabulate`] evaluates a model). The
/// reference reader's integer truncation gives node `i` the whole cell `[i, i+1)` of the grid's
/// parametrisation, so the average of that cell's samples is the BRDF about half a cell *above*
/// the node. For a steep BRDF (a mirror-like highlight falls by orders of magnitude across a few
/// θh cells) this shift is a visible bias; assigning each sample to its nearest node centres the
/// samples on the node instead.
///
/// # Examples
///
/// Samples at a grid node's own angles, and a little above them, go to that node's bin under
/// [`BinAssignment::NearestNode`]; the reference reader sends the one below it to the bin
/// below:
///
/// ```
/// use binning::BinAssignment;
/// use brdf::{bin_angles, bin_index, HalfDiff};
///
/// let node = bin_index(40, 30, 100);
/// let (theta_h, theta_d, phi_d) = bin_angles(40, 30, 100);
/// let at = |dh: f64| HalfDiff { theta_h: theta_h + dh, phi_h: 0.0, theta_d, phi_d };
/// for dh in [0.0, 1e-3, -1e-3] {
///     assert_eq!(BinAssignment::NearestNode.bin(&at(dh)), node);
/// }
/// assert_eq!(BinAssignment::ReferenceReader.bin(&at(1e-3)), node);
/// assert_eq!(BinAssignment::ReferenceReader.bin(&at(-1e-3)), bin_index(39, 30, 100));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum BinAssignment {
    /// The nearest grid node ([`brdf::node_bin_index`]): the default.
    #[default]
    NearestNode,
    /// The MERL reference reader's truncation ([`brdf::theta_half_index`] etc.).
    ReferenceReader,
}

impl BinAssignment {
    /// The flat MERL bin of Rusinkiewicz angles under this assignment.
    #[inline]
    pub fn bin(self, hd: &HalfDiff) -> usize {
        match self {
            Self::NearestNode => node_bin_index(hd.theta_h, hd.theta_d, hd.phi_d),
            Self::ReferenceReader => merl_bin(hd),
        }
    }
}

/// Fewest self-shadowed pixels per channel for an ambient estimate.
const MIN_AMBIENT_PIXELS: usize = 32;

/// Ambient signal rate per channel: the median rate of valid sphere pixels facing away from the
/// lamp (cos θi < −0.1), which receive only stray light; zero for a channel with too few of them
/// (lamp beside the camera).
pub fn ambient_rate(view: &SphereView, rates: Rates<'_>, lamp: &V3) -> Result<[f64; 3]> {
    rates.check(view)?;
    let mut per: [Vec<f32>; 3] = Default::default();
    for p in &view.pixels {
        let i = p.index as usize;
        if rates.valid[i] && lighting(p, lamp).cos_i < -0.1 {
            per[p.channel as usize].push(rates.rate[i]);
        }
    }
    Ok(per.map(|mut v| {
        if v.len() < MIN_AMBIENT_PIXELS {
            return 0.0;
        }
        v.sort_by(|a, b| a.total_cmp(b));
        v[v.len() / 2] as f64
    }))
}

/// HDR signal rates of one image: `rate[i]` in DN/s and `valid[i]` for flat pixel index `i`.
#[derive(Debug, Clone, Copy)]
pub struct Rates<'a> {
    /// Signal rate per pixel, DN/s.
    pub rate: &'a [f32],
    /// Whether the pixel's rate is trustworthy.
    pub valid: &'a [bool],
}

impl Rates<'_> {
    fn check(&self, view: &SphereView) -> Result<()> {
        let n = view.width * view.height;
        if self.rate.len() != n || self.valid.len() != n {
            return Err(BinningError::Dimensions(format!(
                "image has {} rates and {} flags, sensor has {n} pixels",
                self.rate.len(),
                self.valid.len()
            )));
        }
        Ok(())
    }
}

/// Illumination geometry of one sphere pixel for one lamp position.
#[derive(Debug, Clone, Copy)]
pub struct Lighting {
    /// Unit direction from the surface point to the lamp.
    pub to_lamp: V3,
    /// Squared distance to the lamp, m².
    pub dist2: f64,
    /// Cosine of the incidence angle.
    pub cos_i: f64,
}

/// Lighting of pixel `p` by a lamp at `lamp`.
#[inline]
pub fn lighting(p: &SpherePixel, lamp: &V3) -> Lighting {
    let l = lamp - p.point;
    let dist2 = l.norm_squared();
    let to_lamp = l / dist2.sqrt();
    Lighting {
        to_lamp,
        dist2,
        cos_i: p.normal.dot(&to_lamp),
    }
}

/// Rusinkiewicz angles of a sphere pixel's (light, view) pair in its local frame.
#[inline]
pub fn half_diff(p: &SpherePixel, to_lamp: &V3) -> HalfDiff {
    let (t, b) = frame_from_normal(&p.normal);
    let wi = to_local(to_lamp, &t, &b, &p.normal);
    let wo = to_local(&p.to_camera, &t, &b, &p.normal);
    HalfDiff::from_directions(&wi, &wo)
}

/// Flat MERL bin of Rusinkiewicz angles (the reference reader's indexing).
#[inline]
pub fn merl_bin(hd: &HalfDiff) -> usize {
    bin_index(
        theta_half_index(hd.theta_h),
        theta_diff_index(hd.theta_d),
        phi_diff_index(hd.phi_d),
    )
}

fn check_constant(k: &[f64; 3]) -> Result<()> {
    if k.iter().all(|v| v.is_finite() && *v > 0.0) {
        Ok(())
    } else {
        Err(BinningError::Parameter(format!(
            "lamp constant {k:?} must be finite and positive"
        )))
    }
}

/// BRDF samples of one lamp position (thesis §3.4): every valid sphere pixel lit by the lamp gives
/// one value in its own Bayer channel.
///
/// Radiometry: a pixel's HDR signal rate (DN/s) is `k_c · L` for scene radiance L, with `k_c`
/// the camera's response in its Bayer channel c. The lamp, of radiant intensity `I_c`, gives the
/// surface point irradiance `E = I_c cos θi / d²` (inverse square and foreshortening). So the
/// BRDF is
///
/// ```text
/// f = L / E = rate · d² / (K_c · cos θi),    K_c = k_c · I_c
/// ```
///
/// Only the product `K_c` (the *lamp constant*, DN/s · m² · sr) matters; it is measured from a
/// sphere of known diffuse albedo ρ, whose BRDF is ρ/π.
///
/// [`lamp_constant_from_reference`] measures `K_c`; [`rerender`] is the inverse computation,
/// used to validate a table (thesis §3.6).
///
/// # Examples
///
/// Signal rates rendered from a Lambertian table of albedo 0.6, plus an ambient floor of
/// 2 DN/s that the job measured with the lamp off, give back ρ/π in every sample:
///
/// ```
/// use binning::{position_samples, rerender, BinAssignment, ForwardOptions, Rates, RigGeometry, SphereView};
/// # use gantry_hal::{CameraIntrinsics, CameraPose, LampCircle, SphereGeometry};
/// # // a 128 × 128 camera 1 m from a 1-inch sphere; the lamp circle (0.5 m) starts beside it
/// # let rig = gantry_hal::RigGeometry {
/// #     camera: CameraIntrinsics::radial(128, 128, 2000.0, 2000.0, 64.0, 64.0, 0.0, 0.0),
/// #     pose: CameraPose::look_at([0.0, -1.0, 0.0], [0.0; 3], 0.0),
/// #     lamp: LampCircle { centre: [0.0; 3], normal: [0.0, 0.0, 1.0], radius: 0.5, reference: [0.0, -1.0, 0.0] },
/// #     sphere: SphereGeometry { centre: [0.0; 3], radius: 0.0254 },
/// # };
/// let view = SphereView::new(&rig, |x, y| gantry_hal::BayerPattern::Rggb.channel_at(x, y), 85.0);
/// let lambert = brdf::MerlTable::tabulate(&brdf::analytic::Lambert { kd: [0.6; 3] });
/// let (lamp, k) = (rig.lamp_position(20.0), [5.0e4, 6.0e4, 4.0e4]);
///
/// let mut rate = vec![2.0f32; 128 * 128];
/// let lit = rerender(&view, &lambert, &lamp, &k, BinAssignment::NearestNode);
/// for (p, r) in view.pixels.iter().zip(&lit) {
///     if r.is_finite() {
///         rate[p.index as usize] += r;
///     }
/// }
/// let valid = vec![true; rate.len()];
/// let options = ForwardOptions { measured_ambient: Some([2.0; 3]), ..ForwardOptions::default() };
/// let samples = position_samples(&view, Rates { rate: &rate, valid: &valid }, &lamp, &k, &options)
///     .unwrap();
/// assert!(samples.len() > 1000);
/// let rho_over_pi = 0.6 / std::f32::consts::PI;
/// assert!(samples.iter().all(|s| (s.value / rho_over_pi - 1.0).abs() < 1e-3));
/// ```
pub fn position_samples(
    view: &SphereView,
    rates: Rates<'_>,
    lamp: &V3,
    lamp_constant: &[f64; 3],
    opts: &ForwardOptions,
) -> Result<Vec<Sample>> {
    rates.check(view)?;
    check_constant(lamp_constant)?;
    let cos_max = opts.max_incidence_deg.to_radians().cos();
    let ambient = match (opts.subtract_ambient, opts.measured_ambient) {
        (false, _) => [0.0; 3],
        (true, Some(a)) => {
            if !a.iter().all(|v| v.is_finite()) {
                return Err(BinningError::Parameter(format!(
                    "measured ambient rate {a:?} must be finite"
                )));
            }
            a
        }
        (true, None) => ambient_rate(view, rates, lamp)?,
    };
    Ok(view
        .pixels
        .par_iter()
        .filter_map(|p| {
            let i = p.index as usize;
            if !rates.valid[i] {
                return None;
            }
            let l = lighting(p, lamp);
            if l.cos_i < cos_max.max(1e-6) {
                return None;
            }
            let c = p.channel as usize;
            let signal = rates.rate[i] as f64 - ambient[c];
            let f = signal * l.dist2 / (lamp_constant[c] * l.cos_i);
            let bin = opts.assignment.bin(&half_diff(p, &l.to_lamp));
            Some(Sample::new(c, bin, f as f32))
        })
        .collect())
}

/// Lamp constant K_c per channel from images of a diffuse reference sphere of albedo `albedo`:
/// the median over well-lit pixels (θi < 60°) of `rate · d² · π / (ρ_c · cos θi)`.
pub fn lamp_constant_from_reference(
    view: &SphereView,
    images: &[(Rates<'_>, V3)],
    albedo: [f64; 3],
) -> Result<[f64; 3]> {
    if albedo.iter().any(|a| !(a.is_finite() && *a > 0.0)) {
        return Err(BinningError::Parameter(format!(
            "reference albedo {albedo:?} must be positive"
        )));
    }
    let mut per_channel: [Vec<f64>; 3] = Default::default();
    for (rates, lamp) in images {
        let ambient = ambient_rate(view, *rates, lamp)?;
        for p in &view.pixels {
            let i = p.index as usize;
            let l = lighting(p, lamp);
            if !rates.valid[i] || l.cos_i < 0.5 || rates.rate[i] <= 0.0 {
                continue;
            }
            let c = p.channel as usize;
            let signal = rates.rate[i] as f64 - ambient[c];
            per_channel[c].push(signal * l.dist2 * std::f64::consts::PI / (albedo[c] * l.cos_i));
        }
    }
    let mut out = [0.0; 3];
    for c in 0..3 {
        let v = &mut per_channel[c];
        if v.is_empty() {
            return Err(BinningError::Dimensions(format!(
                "no usable reference pixels in channel {c}"
            )));
        }
        v.sort_by(|a, b| a.total_cmp(b));
        out[c] = v[v.len() / 2];
    }
    Ok(out)
}

/// The signal rate every sphere pixel would have under a lamp at `lamp` if the sphere reflected
/// with `table` (the value of the bin the pixel's samples were assigned to, by `assignment`):
/// `K_c · f · cos θi / d²`. Pixels with missing table data or unlit get NaN. Returned in the order
/// of `view.pixels`.
pub fn rerender(
    view: &SphereView,
    table: &MerlTable,
    lamp: &V3,
    lamp_constant: &[f64; 3],
    assignment: BinAssignment,
) -> Vec<f32> {
    view.pixels
        .par_iter()
        .map(|p| {
            let l = lighting(p, lamp);
            if l.cos_i <= 0.0 {
                return f32::NAN;
            }
            let c = p.channel as usize;
            let bin = assignment.bin(&half_diff(p, &l.to_lamp));
            if !table.is_valid(c, bin) {
                return f32::NAN;
            }
            (lamp_constant[c] * table.get(c, bin) * l.cos_i / l.dist2) as f32
        })
        .collect()
}

/// Agreement of a re-rendered image with the measured one.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
pub struct ImageError {
    /// Pixels compared.
    pub pixels: usize,
    /// Median of |ln(rendered / measured)|.
    pub median_abs_log: f64,
    /// Relative RMS error, √(Σ(r − m)² / Σm²).
    pub relative_rms: f64,
}

/// Compares re-rendered rates (in `view.pixels` order) with the measured image over pixels that
/// are valid, lit and positive in both.
pub fn compare(view: &SphereView, rendered: &[f32], measured: Rates<'_>) -> Result<ImageError> {
    measured.check(view)?;
    if rendered.len() != view.pixels.len() {
        return Err(BinningError::Dimensions(format!(
            "{} rendered values for {} sphere pixels",
            rendered.len(),
            view.pixels.len()
        )));
    }
    let mut logs = Vec::new();
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for (p, &r) in view.pixels.iter().zip(rendered) {
        let i = p.index as usize;
        let m = measured.rate[i];
        if !measured.valid[i] || !r.is_finite() || r <= 0.0 || m <= 0.0 {
            continue;
        }
        logs.push(((r / m) as f64).ln().abs());
        num += (r as f64 - m as f64).powi(2);
        den += (m as f64).powi(2);
    }
    if logs.is_empty() {
        return Ok(ImageError::default());
    }
    logs.sort_by(|a, b| a.total_cmp(b));
    Ok(ImageError {
        pixels: logs.len(),
        median_abs_log: logs[logs.len() / 2],
        relative_rms: (num / den).sqrt(),
    })
}

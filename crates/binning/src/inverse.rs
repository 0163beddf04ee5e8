//! The thesis's alternative BRDF computation (§3.5): the *inverse mapping*.

use crate::error::{BinningError, Result};
use crate::forward::{ambient_rate, lighting, Rates};
use crate::geometry::{frame_from_normal, RigGeometry, SphereView, V3};
use brdf::HalfDiff;
use brdf::{bin_coords, MerlTable, BINS, PHI_D_RES, THETA_D_RES, THETA_H_RES};
use rayon::prelude::*;
use std::f64::consts::{FRAC_PI_2, PI};

/// How the surface point of a requested configuration is constructed for one lamp position.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Construction {
    /// The thesis's construction (§3.5): intersection of the θi circle (about the lamp direction)
    /// and the θr circle (about the view direction); θi and θr are exact, θd comes from the lamp
    /// position.
    Circles,
    /// θh and φd exact: the normal at θh from the half vector, at the azimuth giving φd; θd
    /// comes from the lamp position. The default: it stays well conditioned at the specular
    /// peak, where the circles are nearly tangent.
    #[default]
    HalfVector,
}

/// Which lamp position(s) serve a bin.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PositionChoice {
    /// The position whose lamp–point–camera angle is closest to 2θd (the thesis's choice).
    Nearest,
    /// Linear interpolation in the lamp–point–camera angle between the two bracketing positions.
    #[default]
    Interpolate,
}

/// Which point of a MERL bin is evaluated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum BinPoint {
    /// The bin's grid point (its lower corner in index space), where
    /// [`brdf::MerlTable::tabulate`] evaluates a model.
    #[default]
    GridPoint,
    /// The bin's centre in index space (√θh, θd, φd).
    CellCentre,
}

/// What is interpolated between the photosites around the sub-pixel location.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Interpolated {
    /// The signal rate (radiance), divided afterwards by the irradiance of the surface point
    /// itself.
    Radiance,
    /// Each photosite's own BRDF value (its rate divided by its own irradiance, as in forward
    /// binning); all four photosites must be lit within the incidence limit. Near the
    /// silhouette and the shadow line the irradiance changes much faster across a pixel than
    /// the BRDF does.
    #[default]
    Reflectance,
}

/// Options of the inverse mapping.
#[derive(Debug, Clone)]
pub struct InverseOptions {
    /// Points lit at more than this angle from the normal are not used (degrees); as
    /// [`crate::ForwardOptions::max_incidence_deg`].
    pub max_incidence_deg: f64,
    /// Points seen at more than this angle from the normal are not used (degrees); the limit the
    /// [`SphereView`] was traced with (85° in `gantry capture`).
    pub max_view_deg: f64,
    /// Subtract the per-image, per-channel ambient rate (see [`crate::ambient_rate`]).
    pub subtract_ambient: bool,
    /// Also measure each bin with lamp and camera swapped (φd + π) and average.
    pub reciprocity: bool,
    /// Point construction.
    pub construction: Construction,
    /// Position choice.
    pub choice: PositionChoice,
    /// Largest gap in lamp–point–camera angle (degrees) between two bracketing positions that
    /// is interpolated; a position alone is used only if it is within half this angle.
    pub max_bracket_deg: f64,
    /// Which point of each bin is evaluated.
    pub bin_point: BinPoint,
    /// What is interpolated between photosites.
    pub interpolate: Interpolated,
}

impl Default for InverseOptions {
    fn default() -> Self {
        Self {
            max_incidence_deg: 87.0,
            max_view_deg: 85.0,
            subtract_ambient: true,
            reciprocity: true,
            construction: Construction::default(),
            choice: PositionChoice::default(),
            max_bracket_deg: 3.0,
            bin_point: BinPoint::default(),
            interpolate: Interpolated::default(),
        }
    }
}

impl InverseOptions {
    fn check(&self) -> Result<()> {
        let angle_ok = |a: f64| a.is_finite() && a > 0.0 && a <= 90.0;
        if !angle_ok(self.max_incidence_deg) || !angle_ok(self.max_view_deg) {
            return Err(BinningError::Parameter(format!(
                "angle limits ({}°, {}°) must lie in (0°, 90°]",
                self.max_incidence_deg, self.max_view_deg
            )));
        }
        if !(self.max_bracket_deg.is_finite() && self.max_bracket_deg > 0.0) {
            return Err(BinningError::Parameter(format!(
                "max_bracket_deg {} must be positive",
                self.max_bracket_deg
            )));
        }
        Ok(())
    }
}

/// One captured lamp position in the compact form the inverse mapping reads: the rates of the
/// sphere pixels only.
#[derive(Debug, Clone)]
pub struct InversePosition {
    /// Turntable angle, degrees.
    pub angle_deg: f64,
    /// Lamp position at that angle.
    pub lamp: V3,
    /// Signal rate (DN/s) of each pixel of the [`SphereView`], in its order; NaN where invalid.
    pub rate: Vec<f32>,
    /// Ambient rate per channel that is subtracted (zero when not subtracted).
    pub ambient: [f64; 3],
}

impl InversePosition {
    /// Keeps the sphere pixels of one HDR image (full sensor `rates`) taken with the turntable at
    /// `angle_deg`, and estimates its ambient rate if `opts.subtract_ambient`.
    pub fn new(
        geometry: &dyn RigGeometry,
        view: &SphereView,
        angle_deg: f64,
        rates: Rates<'_>,
        opts: &InverseOptions,
    ) -> Result<Self> {
        if !angle_deg.is_finite() {
            return Err(BinningError::Parameter(format!(
                "turntable angle {angle_deg} is not finite"
            )));
        }
        let n = view.width * view.height;
        if rates.rate.len() != n || rates.valid.len() != n {
            return Err(BinningError::Dimensions(format!(
                "image has {} rates and {} flags, sensor has {n} pixels",
                rates.rate.len(),
                rates.valid.len()
            )));
        }
        let lamp = geometry.lamp_position(angle_deg);
        if !lamp.iter().all(|v| v.is_finite()) {
            return Err(BinningError::Parameter(format!(
                "lamp position at {angle_deg}° is not finite"
            )));
        }
        let ambient = if opts.subtract_ambient {
            ambient_rate(view, rates, &lamp)?
        } else {
            [0.0; 3]
        };
        let rate = view
            .pixels
            .iter()
            .map(|p| {
                let i = p.index as usize;
                let r = rates.rate[i];
                if rates.valid[i] && r.is_finite() {
                    r
                } else {
                    f32::NAN
                }
            })
            .collect();
        Ok(Self {
            angle_deg,
            lamp,
            rate,
            ambient,
        })
    }
}

/// Bit of [`InverseTable::flags`]: the bin's own configuration (lamp as ωi) gave a value.
pub const FLAG_DIRECT: u8 = 1;
/// Bit of [`InverseTable::flags`]: the swapped configuration (φd + π) gave a value.
pub const FLAG_SWAPPED: u8 = 2;
/// Bit of [`InverseTable::flags`]: at least one value was interpolated between two positions.
pub const FLAG_INTERPOLATED: u8 = 4;

/// The result of the inverse mapping.
#[derive(Debug, Clone)]
pub struct InverseTable {
    /// The table; bins no position reaches are missing (negative).
    pub table: MerlTable,
    /// Number of configurations (0–2: direct and swapped) averaged per key
    /// (`channel · BINS + bin`).
    pub counts: Vec<u8>,
    /// Per bin, the `FLAG_*` bits of the configurations used (any channel).
    pub flags: Vec<u8>,
}

impl InverseTable {
    /// Fraction of (channel, bin) keys with a value.
    pub fn coverage(&self) -> f64 {
        self.counts.iter().filter(|c| **c > 0).count() as f64 / self.counts.len() as f64
    }
}

/// Unit normal of the point where the circle of normals at `theta_i` from `to_lamp` meets the
/// circle at `theta_o` from `to_camera`, for distant lamp and camera (directions fixed).
/// `handedness` picks one of the two intersections: the sign of `n · (to_lamp × to_camera)`
/// (zero: the coplanar solution). `None` when the circles do not meet.
pub fn distant_circle_intersection(
    to_lamp: &V3,
    to_camera: &V3,
    theta_i: f64,
    theta_o: f64,
    handedness: f64,
) -> Option<V3> {
    let g = to_lamp.dot(to_camera);
    let det = 1.0 - g * g;
    if det < 1e-14 {
        return None;
    }
    let (ci, co) = (theta_i.cos(), theta_o.cos());
    let a = (ci - co * g) / det;
    let b = (co - ci * g) / det;
    let m = to_lamp * a + to_camera * b;
    let rem = 1.0 - m.norm_squared();
    if rem < -1e-9 {
        return None;
    }
    let c = (rem.max(0.0) / det).sqrt();
    let c = if handedness < 0.0 { -c } else { c };
    let n = m + to_lamp.cross(to_camera) * c;
    Some(n.normalize())
}

/// Unit normal at `theta_h` from the half vector of (`to_lamp`, `to_camera`) at the azimuth that
/// makes the pair's φd equal `phi_d` (Rusinkiewicz angles with the lamp as ωi), for distant lamp
/// and camera. `None` when the two directions are (anti)parallel.
pub fn distant_half_vector_normal(
    to_lamp: &V3,
    to_camera: &V3,
    theta_h: f64,
    phi_d: f64,
) -> Option<V3> {
    let s = to_lamp + to_camera;
    if s.norm_squared() < 1e-20 {
        return None;
    }
    let h = s.normalize();
    let perp = to_lamp - h * to_lamp.dot(&h);
    if perp.norm_squared() < 1e-20 {
        return None;
    }
    let e1 = perp.normalize();
    let e2 = h.cross(&e1);
    let x = e1 * phi_d.cos() - e2 * phi_d.sin();
    Some(h * theta_h.cos() - x * theta_h.sin())
}

/// A requested configuration: which angles must hold at the surface point.
#[derive(Debug, Clone, Copy)]
pub struct Configuration {
    /// Incidence angle (lamp), radians.
    pub theta_i: f64,
    /// Exitance angle (camera), radians.
    pub theta_o: f64,
    /// Sign of `n · (ωi × ωo)`: which of the two mirror-image solutions.
    pub handedness: f64,
    /// Half-vector angle, radians.
    pub theta_h: f64,
    /// Difference angle, radians; the lamp–point–camera angle is 2θd.
    pub theta_d: f64,
    /// Difference azimuth, radians.
    pub phi_d: f64,
}

impl Configuration {
    /// The configuration of Rusinkiewicz angles (θh, θd, φd), lamp as ωi.
    pub fn from_half_diff(theta_h: f64, theta_d: f64, phi_d: f64) -> Self {
        let (wi, wo) = HalfDiff::isotropic(theta_h, theta_d, phi_d).to_directions();
        let cross_z = wi.x * wo.y - wi.y * wo.x;
        Self {
            theta_i: wi.z.clamp(-1.0, 1.0).acos(),
            theta_o: wo.z.clamp(-1.0, 1.0).acos(),
            handedness: if cross_z.abs() < 1e-12 {
                0.0
            } else {
                cross_z.signum()
            },
            theta_h,
            theta_d,
            phi_d,
        }
    }
}

/// A surface point solving a configuration for one lamp position.
#[derive(Debug, Clone, Copy)]
pub struct SurfacePoint {
    /// The point on the sphere.
    pub point: V3,
    /// Its outward unit normal.
    pub normal: V3,
    /// The lamp–point–camera angle there (radians): 2θd of what is actually observed.
    pub gamma: f64,
}

/// The surface point observing `config` with the lamp at `lamp` and the camera centre at
/// `camera`, for the exact finite-distance geometry: the distant-source solution (directions
/// seen from the sphere centre) refined by Newton's method on the angles seen from the point
/// itself. `None` when there is no solution or the iteration does not converge.
pub fn solve_point(
    construction: Construction,
    config: &Configuration,
    sphere_centre: &V3,
    sphere_radius: f64,
    lamp: &V3,
    camera: &V3,
) -> Option<SurfacePoint> {
    let dirs = |n: &V3| -> Option<(V3, V3)> {
        let p = sphere_centre + n * sphere_radius;
        let l = lamp - p;
        let c = camera - p;
        let (ln, cn) = (l.norm(), c.norm());
        (ln > 0.0 && cn > 0.0).then(|| (l / ln, c / cn))
    };
    let (u0, v0) = dirs(&V3::zeros())?;
    let (ci, co) = (config.theta_i.cos(), config.theta_o.cos());
    if construction == Construction::Circles {
        // The circles can only meet if the lamp–point–camera angle, which differs from the one
        // seen from the centre by at most the parallax, lies in [|θi − θo|, θi + θo].
        let parallax = (sphere_radius / (lamp - sphere_centre).norm())
            .min(1.0)
            .asin()
            + (sphere_radius / (camera - sphere_centre).norm())
                .min(1.0)
                .asin();
        let gamma0 = u0.dot(&v0).clamp(-1.0, 1.0).acos();
        let lo = (config.theta_i - config.theta_o).abs();
        let hi = (config.theta_i + config.theta_o).min(2.0 * PI - config.theta_i - config.theta_o);
        if gamma0 + parallax < lo || gamma0 - parallax > hi {
            return None;
        }
    }
    let n0 = match construction {
        // Started at the distant solution, or at the circles' closest approach if the circles
        // seen from the centre do not meet.
        Construction::Circles => {
            distant_circle_intersection(&u0, &v0, config.theta_i, config.theta_o, config.handedness)
                .or_else(|| circles_closest_approach(&u0, &v0, ci, co, config.handedness))?
        }
        Construction::HalfVector => {
            distant_half_vector_normal(&u0, &v0, config.theta_h, config.phi_d)?
        }
    };
    let residual = |n: &V3| -> Option<[f64; 2]> {
        let (u, v) = dirs(n)?;
        match construction {
            Construction::Circles => Some([n.dot(&u) - ci, n.dot(&v) - co]),
            Construction::HalfVector => {
                let g = distant_half_vector_normal(&u, &v, config.theta_h, config.phi_d)?;
                let (t, b) = frame_from_normal(n);
                let d = n - g;
                Some([d.dot(&t), d.dot(&b)])
            }
        }
    };
    // Fixed-point iteration on the directions seen from the point: cheap, and it contracts by
    // about R / distance when the construction is well conditioned. Newton's method takes over
    // where it does not settle (near the circles' tangency).
    let distant = |n: &V3| -> Option<V3> {
        let (u, v) = dirs(n)?;
        match construction {
            Construction::Circles => distant_circle_intersection(
                &u,
                &v,
                config.theta_i,
                config.theta_o,
                config.handedness,
            ),
            Construction::HalfVector => {
                distant_half_vector_normal(&u, &v, config.theta_h, config.phi_d)
            }
        }
    };
    let mut fixed = None;
    let mut n = n0;
    for _ in 0..16 {
        let Some(next) = distant(&n) else {
            break;
        };
        let step = (next - n).norm();
        n = next;
        if step < 1e-14 {
            fixed = Some(n);
            break;
        }
    }
    let n = match fixed {
        Some(n) => n,
        None => newton_on_sphere(&n0, residual)?,
    };
    let (u, v) = dirs(&n)?;
    if construction == Construction::Circles && config.handedness != 0.0 {
        let side = n.dot(&u.cross(&v));
        if side * config.handedness < -1e-9 {
            return None;
        }
    }
    Some(SurfacePoint {
        point: sphere_centre + n * sphere_radius,
        normal: n,
        gamma: u.dot(&v).clamp(-1.0, 1.0).acos(),
    })
}

/// The coplanar normal between the two circles when they do not meet (a start for Newton).
fn circles_closest_approach(u: &V3, v: &V3, ci: f64, co: f64, handedness: f64) -> Option<V3> {
    let g = u.dot(v);
    let det = 1.0 - g * g;
    if det < 1e-14 {
        return None;
    }
    let m = u * ((ci - co * g) / det) + v * ((co - ci * g) / det);
    let w = u.cross(v) * (if handedness < 0.0 { -1e-3 } else { 1e-3 });
    let n = m + w;
    (n.norm_squared() > 1e-20).then(|| n.normalize())
}

/// Newton's method for a unit vector `n` with `residual(n) = 0` (two equations), stepping in
/// the tangent plane with a central-difference Jacobian and a backtracking line search.
fn newton_on_sphere(n0: &V3, residual: impl Fn(&V3) -> Option<[f64; 2]>) -> Option<V3> {
    const H: f64 = 1e-7;
    let norm = |r: &[f64; 2]| r[0].hypot(r[1]);
    let mut n = *n0;
    let mut r = residual(&n)?;
    for _ in 0..10 {
        if norm(&r) < 1e-14 {
            return Some(n);
        }
        let (t, b) = frame_from_normal(&n);
        let column = |e: &V3| -> Option<[f64; 2]> {
            let p = residual(&(n + e * H).normalize())?;
            let m = residual(&(n - e * H).normalize())?;
            Some([(p[0] - m[0]) / (2.0 * H), (p[1] - m[1]) / (2.0 * H)])
        };
        let (ja, jb) = (column(&t)?, column(&b)?);
        let det = ja[0] * jb[1] - jb[0] * ja[1];
        if det.is_nan() || det.abs() <= 1e-300 {
            break;
        }
        let mut da = -(jb[1] * r[0] - jb[0] * r[1]) / det;
        let mut db = -(-ja[1] * r[0] + ja[0] * r[1]) / det;
        let len = da.hypot(db);
        if !len.is_finite() {
            return None;
        }
        if len > 0.2 {
            da *= 0.2 / len;
            db *= 0.2 / len;
        }
        let mut step = 1.0;
        let mut accepted = false;
        for _ in 0..8 {
            let cand = (n + (t * da + b * db) * step).normalize();
            if let Some(rc) = residual(&cand) {
                if norm(&rc) < norm(&r) {
                    n = cand;
                    r = rc;
                    accepted = true;
                    break;
                }
            }
            step *= 0.5;
        }
        if !accepted {
            break;
        }
    }
    (norm(&r) < 1e-11).then_some(n)
}

/// Flat-index → slot in `view.pixels` (u32::MAX: not a sphere pixel), and the channel of each
/// of the four Bayer offsets (x mod 2, y mod 2).
struct Lattice {
    width: usize,
    height: usize,
    slot: Vec<u32>,
    offsets_of_channel: [Vec<(usize, usize)>; 3],
}

impl Lattice {
    fn new(view: &SphereView) -> Result<Self> {
        let n = view.width * view.height;
        let mut slot = vec![u32::MAX; n];
        let mut channel_of: [Option<u8>; 4] = [None; 4];
        for (k, p) in view.pixels.iter().enumerate() {
            let i = p.index as usize;
            if i >= n || p.channel > 2 {
                return Err(BinningError::Dimensions(format!(
                    "sphere pixel {i} (channel {}) outside the {}×{} sensor",
                    p.channel, view.width, view.height
                )));
            }
            slot[i] = k as u32;
            let (x, y) = (i % view.width, i / view.width);
            let o = (y % 2) * 2 + x % 2;
            match channel_of[o] {
                None => channel_of[o] = Some(p.channel),
                Some(c) if c != p.channel => {
                    return Err(BinningError::Parameter(
                        "the colour filter array is not a 2×2 pattern".into(),
                    ))
                }
                _ => {}
            }
        }
        let mut offsets_of_channel: [Vec<(usize, usize)>; 3] = Default::default();
        for (o, c) in channel_of.iter().enumerate() {
            let Some(c) = c else {
                return Err(BinningError::Dimensions(
                    "too few sphere pixels to read the colour filter array".into(),
                ));
            };
            offsets_of_channel[*c as usize].push((o % 2, o / 2));
        }
        if offsets_of_channel.iter().any(|v| v.is_empty()) {
            return Err(BinningError::Parameter(
                "the colour filter array lacks a channel".into(),
            ));
        }
        Ok(Self {
            width: view.width,
            height: view.height,
            slot,
            offsets_of_channel,
        })
    }

    /// Bilinear interpolation at pixel coordinates (`x`, `y`) of `value(slot)` (slot in
    /// `view.pixels`) on the sub-lattices of channel `c`; `None` unless all four photosites of
    /// every sub-lattice are sphere pixels with a value.
    fn sample(
        &self,
        c: usize,
        x: f64,
        y: f64,
        value: impl Fn(usize) -> Option<f64>,
    ) -> Option<f64> {
        let mut sum = 0.0;
        let offsets = &self.offsets_of_channel[c];
        for &(ox, oy) in offsets {
            let gx = (x - ox as f64) / 2.0;
            let gy = (y - oy as f64) / 2.0;
            let (ix, iy) = (gx.floor(), gy.floor());
            let (fx, fy) = (gx - ix, gy - iy);
            let x0 = ox as i64 + 2 * ix as i64;
            let y0 = oy as i64 + 2 * iy as i64;
            if x0 < 0 || y0 < 0 || x0 + 2 >= self.width as i64 || y0 + 2 >= self.height as i64 {
                return None;
            }
            let (x0, y0) = (x0 as usize, y0 as usize);
            let at = |xx: usize, yy: usize| -> Option<f64> {
                let s = self.slot[yy * self.width + xx];
                if s == u32::MAX {
                    return None;
                }
                value(s as usize)
            };
            let r00 = at(x0, y0)?;
            let r10 = at(x0 + 2, y0)?;
            let r01 = at(x0, y0 + 2)?;
            let r11 = at(x0 + 2, y0 + 2)?;
            sum += (1.0 - fy) * ((1.0 - fx) * r00 + fx * r10) + fy * ((1.0 - fx) * r01 + fx * r11);
        }
        Some(sum / offsets.len() as f64)
    }
}

/// Everything the per-bin work reads.
struct Mapper<'a> {
    geometry: &'a dyn RigGeometry,
    view: &'a SphereView,
    positions: &'a [InversePosition],
    lamp_constant: [f64; 3],
    opts: &'a InverseOptions,
    lattice: Lattice,
    camera: V3,
    sphere_centre: V3,
    sphere_radius: f64,
    /// Position indices in increasing order of the lamp–centre–camera angle.
    order: Vec<usize>,
    /// Those angles (radians), sorted.
    beta: Vec<f64>,
    /// Largest difference between the angle seen from the centre and from a surface point, plus
    /// the bracket limit (radians).
    window: f64,
    cos_max_incidence: f64,
    cos_max_view: f64,
}

/// A BRDF value per channel found at one position (None where a channel could not be read).
type Reading = [Option<f64>; 3];

impl Mapper<'_> {
    /// The surface point of `config` for the position of sorted index `j`.
    fn solve(&self, config: &Configuration, j: usize) -> Option<SurfacePoint> {
        let pos = &self.positions[self.order[j]];
        solve_point(
            self.opts.construction,
            config,
            &self.sphere_centre,
            self.sphere_radius,
            &pos.lamp,
            &self.camera,
        )
    }

    /// The BRDF per channel at surface point `sp` in the image of sorted position `j`.
    fn read(&self, sp: &SurfacePoint, j: usize) -> Option<Reading> {
        let pos = &self.positions[self.order[j]];
        let l = pos.lamp - sp.point;
        let d2 = l.norm_squared();
        let to_lamp = l / d2.sqrt();
        let to_camera = (self.camera - sp.point).normalize();
        let cos_i = sp.normal.dot(&to_lamp);
        let cos_o = sp.normal.dot(&to_camera);
        if cos_i < self.cos_max_incidence.max(1e-6) || cos_o < self.cos_max_view.max(1e-6) {
            return None;
        }
        let [x, y] = self.geometry.project(&sp.point)?;
        if !(x.is_finite() && y.is_finite()) {
            return None;
        }
        let mut out = [None; 3];
        for (c, o) in out.iter_mut().enumerate() {
            let rate = |s: usize| {
                let r = pos.rate[s];
                r.is_finite().then_some(r as f64 - pos.ambient[c])
            };
            *o = match self.opts.interpolate {
                Interpolated::Radiance => self
                    .lattice
                    .sample(c, x, y, rate)
                    .map(|r| r * d2 / (self.lamp_constant[c] * cos_i)),
                Interpolated::Reflectance => self.lattice.sample(c, x, y, |s| {
                    let l = lighting(&self.view.pixels[s], &pos.lamp);
                    if l.cos_i < self.cos_max_incidence.max(1e-6) {
                        return None;
                    }
                    rate(s).map(|r| r * l.dist2 / (self.lamp_constant[c] * l.cos_i))
                }),
            };
        }
        out.iter().any(Option::is_some).then_some(out)
    }

    /// Values of one configuration, and whether they were interpolated.
    fn configuration(&self, config: &Configuration) -> Option<(Reading, bool)> {
        let target = 2.0 * config.theta_d;
        let n = self.beta.len();
        if target < self.beta[0] - self.window || target > self.beta[n - 1] + self.window {
            return None;
        }
        let in_window = |j: usize| (self.beta[j] - target).abs() <= self.window;
        let k0 = self.beta.partition_point(|b| *b < target).min(n - 1);
        let k0 = if k0 > 0 && (self.beta[k0 - 1] - target).abs() < (self.beta[k0] - target).abs() {
            k0 - 1
        } else {
            k0
        };
        // Started at the nearest position with a solution (outwards from k0 within the window;
        // for the circles, positions where they cannot meet are rejected cheaply).
        let start = (0..n)
            .map(|d| [k0.checked_sub(d), Some(k0 + d).filter(|j| *j < n && d > 0)])
            .take_while(|pair| pair.iter().flatten().any(|j| in_window(*j)))
            .flatten()
            .flatten()
            .filter(|j| in_window(*j))
            .find_map(|j| self.solve(config, j).map(|sp| (j, sp)));
        let (mut j, mut sp) = start?;
        // The parallax seen at the start position is nearly the same at its neighbours: jump to
        // the position whose centre angle corrected by it is nearest the target.
        let corrected = target - (sp.gamma - self.beta[j]);
        let k1 = self.beta.partition_point(|b| *b < corrected).min(n - 1);
        let k1 = if k1 > 0
            && (self.beta[k1 - 1] - corrected).abs() < (self.beta[k1] - corrected).abs()
        {
            k1 - 1
        } else {
            k1
        };
        if k1 != j && in_window(k1) {
            if let Some(s1) = self.solve(config, k1) {
                (j, sp) = (k1, s1);
            }
        }
        let mut bracket = None;
        if sp.gamma != target {
            let up = sp.gamma < target;
            let mut next = j;
            loop {
                next = if up { next + 1 } else { next.wrapping_sub(1) };
                if next >= n || !in_window(next) {
                    break;
                }
                // A position without a solution is stepped over (the bracket check below
                // then refuses a bracket that is too wide).
                let Some(sn) = self.solve(config, next) else {
                    continue;
                };
                if (sn.gamma >= target) == up {
                    bracket = Some((next, sn));
                    break;
                }
                (j, sp) = (next, sn);
            }
        }
        let max_bracket = self.opts.max_bracket_deg.to_radians();
        let near = |s: &SurfacePoint| (s.gamma - target).abs() <= 0.5 * max_bracket;
        match bracket {
            Some((jb, sb)) if (sb.gamma - sp.gamma).abs() <= max_bracket => {
                let w = (target - sp.gamma) / (sb.gamma - sp.gamma);
                let ra = self.read(&sp, j);
                let rb = self.read(&sb, jb);
                if self.opts.choice == PositionChoice::Nearest {
                    return if w <= 0.5 { ra } else { rb }.map(|r| (r, false));
                }
                let mut out = [None; 3];
                let mut interpolated = false;
                for c in 0..3 {
                    let a = ra.and_then(|r| r[c]);
                    let b = rb.and_then(|r| r[c]);
                    out[c] = match (a, b) {
                        (Some(a), Some(b)) => {
                            interpolated = true;
                            Some(a + w * (b - a))
                        }
                        (Some(a), None) if w <= 0.5 => Some(a),
                        (None, Some(b)) if w > 0.5 => Some(b),
                        _ => None,
                    };
                }
                out.iter()
                    .any(Option::is_some)
                    .then_some((out, interpolated))
            }
            _ if sp.gamma == target || near(&sp) => self.read(&sp, j).map(|r| (r, false)),
            _ => None,
        }
    }

    /// The requested angles of `bin`.
    fn bin_angles(&self, bin: usize) -> (f64, f64, f64) {
        let (i, j, k) = bin_coords(bin);
        let off = match self.opts.bin_point {
            BinPoint::GridPoint => 0.0,
            BinPoint::CellCentre => 0.5,
        };
        let u = (i as f64 + off) / THETA_H_RES as f64;
        (
            u * u * FRAC_PI_2,
            (j as f64 + off) / THETA_D_RES as f64 * FRAC_PI_2,
            (k as f64 + off) / PHI_D_RES as f64 * PI,
        )
    }

    /// Values (per channel, mean over configurations), counts and flags of one bin.
    fn bin(&self, bin: usize) -> ([f64; 3], [u8; 3], u8) {
        let (th, td, pd) = self.bin_angles(bin);
        let mut sum = [0.0; 3];
        let mut count = [0u8; 3];
        let mut flags = 0u8;
        let orientations: &[(f64, u8)] = if self.opts.reciprocity {
            &[(0.0, FLAG_DIRECT), (PI, FLAG_SWAPPED)]
        } else {
            &[(0.0, FLAG_DIRECT)]
        };
        for &(shift, flag) in orientations {
            let config = Configuration::from_half_diff(th, td, pd + shift);
            if config.theta_i > self.opts.max_incidence_deg.to_radians()
                || config.theta_o > self.opts.max_view_deg.to_radians()
            {
                continue;
            }
            let Some((reading, interpolated)) = self.configuration(&config) else {
                continue;
            };
            for c in 0..3 {
                if let Some(v) = reading[c] {
                    sum[c] += v;
                    count[c] += 1;
                }
            }
            flags |= flag;
            if interpolated {
                flags |= FLAG_INTERPOLATED;
            }
        }
        let mut value = [-1.0; 3];
        for c in 0..3 {
            if count[c] > 0 {
                let v = sum[c] / count[c] as f64;
                if v >= 0.0 {
                    value[c] = v;
                } else {
                    count[c] = 0;
                }
            }
        }
        (value, count, flags)
    }
}

/// The thesis's inverse mapping (§3.5): every MERL bin evaluated at its [`BinPoint`] from the
/// captured `positions` (any order), the rig `geometry`, the traced `view` the positions were
/// built with, and the lamp constant K_c. Bins no position reaches stay missing.
///
/// Forward binning (§3.4, [`crate::position_samples`]) turns every pixel into a sample at whatever angles
/// the pixel happens to see and averages the samples falling into a MERL bin. The inverse mapping
/// starts from the bin instead: for the bin's angles it finds the lamp position and the
/// (sub-pixel) image location that observe exactly that configuration, and interpolates the
/// radiance there. Every bin is thus evaluated at one chosen point of the bin (its grid point by
/// default, the point [`brdf::MerlTable::tabulate`] uses), not averaged over the bin.
///
/// # Geometry
///
/// Camera centre C, lamp position L_k (one per image) and the sphere (centre S, radius R) are
/// fixed per image. A surface point P with normal n sees the lamp at θi = ∠(n, L_k − P) and the
/// camera at θr = ∠(n, C − P). All points with the same θr lie on a circle on the sphere centred
/// on the segment S–C, and all points with the same θi on a circle centred on S–L_k; a
/// configuration with given (θi, θr) is an intersection of the two circles ([`Construction::Circles`],
/// the thesis's construction). The remaining angle, ∠(L_k − P, C − P) = 2θd, is fixed by the lamp
/// position up to the parallax of the sphere, so it is discrete: the capture is a one-parameter
/// family of lamp angles.
///
/// For a distant lamp and camera the intersection has a closed form (the normal is a combination
/// of the two unit directions and their cross product). Lamp and camera are at finite distance,
/// so the directions depend on P itself: the closed form is applied again with the directions
/// seen from the current P until P stops moving (a fixed point that contracts by about
/// R / distance ≈ 0.05 per step); where it does not settle (near the tangency of the circles)
/// Newton's method on the two angle equations takes over.
///
/// [`Construction::HalfVector`] is a variant that keeps θh and φd exact instead: the normal is
/// placed at θh from the half vector of the (lamp, camera) directions seen from P, at the azimuth
/// that gives φd; θd is again what the lamp position gives. It is offered because near the
/// specular direction the circle construction is ill-conditioned (see `docs/inverse-mapping.md`).
///
/// # Choice of lamp position
///
/// For each construction and lamp position the solution P_k has an exact angle
/// γ_k = ∠(L_k − P_k, C − P_k); the requested bin needs γ = 2θd. The positions are walked in
/// order of their lamp–sphere-centre–camera angle from the one nearest to 2θd until γ_k brackets
/// 2θd. With [`PositionChoice::Interpolate`] (default) the BRDF values found at the two
/// bracketing positions are interpolated linearly in γ; with [`PositionChoice::Nearest`] the
/// position with the closer γ is used (the thesis's choice). See the docs for the comparison.
///
/// # Radiance and BRDF
///
/// The image location is the projection of P (sub-pixel). Images are raw Bayer mosaics, so
/// channel c is interpolated bilinearly on the sub-lattice(s) of photosites of that channel (two
/// sub-lattices for green, averaged); all four photosites must be valid sphere pixels. The
/// irradiance model is that of [`crate::position_samples`], `f = (rate − ambient) · d² / (K_c · cos θi)`.
/// With [`Interpolated::Radiance`] the rate is interpolated and divided by the irradiance of P;
/// with [`Interpolated::Reflectance`] (default) each photosite's rate is first divided by its own
/// irradiance and the BRDF values are interpolated, which stays exact for a Lambertian sphere
/// near the silhouette, where one pixel spans many degrees.
///
/// By reciprocity the bin's configuration can also be measured with lamp and camera swapped
/// (φd + π); both are used by default and averaged.
///
/// # Examples
///
/// Images of a Lambertian sphere of albedo 0.6 at every 30° of the turntable: every bin the
/// mapping reaches holds ρ/π.
///
/// ```
/// use binning::{fill_table, rerender, BinAssignment, InverseOptions, InversePosition, Rates, SphereView};
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
/// let k = [5.0e4; 3];
/// let options = InverseOptions { subtract_ambient: false, reciprocity: false, ..InverseOptions::default() };
/// let positions: Vec<InversePosition> = (0..4).map(|i| {
///     let angle = 30.0 * i as f64;
///     let lamp = rig.lamp.position(angle);
///     let mut rate = vec![f32::NAN; 128 * 128];
///     let lit = rerender(&view, &lambert, &lamp, &k, BinAssignment::NearestNode);
///     for (p, r) in view.pixels.iter().zip(lit) {
///         rate[p.index as usize] = r;
///     }
///     let valid: Vec<bool> = rate.iter().map(|r| r.is_finite()).collect();
///     InversePosition::new(&rig, &view, angle, Rates { rate: &rate, valid: &valid }, &options)
/// }).collect::<Result<_, _>>().unwrap();
///
/// let inverse = fill_table(&rig, &view, &positions, &k, &options).unwrap();
/// assert!(inverse.coverage() > 0.01, "{}", inverse.coverage());
/// let rho_over_pi = 0.6 / std::f64::consts::PI;
/// let filled = (0..brdf::BINS).filter(|&b| inverse.table.is_valid(0, b));
/// assert!(filled.into_iter().all(|b| (inverse.table.get(0, b) / rho_over_pi - 1.0).abs() < 0.01));
/// ```
pub fn fill_table(
    geometry: &dyn RigGeometry,
    view: &SphereView,
    positions: &[InversePosition],
    lamp_constant: &[f64; 3],
    opts: &InverseOptions,
) -> Result<InverseTable> {
    opts.check()?;
    if !lamp_constant.iter().all(|k| k.is_finite() && *k > 0.0) {
        return Err(BinningError::Parameter(format!(
            "lamp constant {lamp_constant:?} must be finite and positive"
        )));
    }
    if positions.is_empty() {
        return Err(BinningError::Parameter("no lamp positions".into()));
    }
    if (view.width, view.height) != geometry.sensor_size() {
        return Err(BinningError::Dimensions(format!(
            "sphere view is {}×{}, the geometry's sensor {:?}",
            view.width,
            view.height,
            geometry.sensor_size()
        )));
    }
    for (k, p) in positions.iter().enumerate() {
        if p.rate.len() != view.pixels.len() {
            return Err(BinningError::Dimensions(format!(
                "position {k} holds {} sphere pixels, the view {}",
                p.rate.len(),
                view.pixels.len()
            )));
        }
        if !(p.lamp.iter().all(|v| v.is_finite()) && p.ambient.iter().all(|v| v.is_finite())) {
            return Err(BinningError::Parameter(format!(
                "position {k} has a non-finite lamp position or ambient rate"
            )));
        }
    }
    let (sphere_centre, sphere_radius) = geometry.sphere();
    if !(sphere_radius.is_finite()
        && sphere_radius > 0.0
        && sphere_centre.iter().all(|v| v.is_finite()))
    {
        return Err(BinningError::Parameter(format!(
            "sphere radius {sphere_radius} / centre {sphere_centre:?}"
        )));
    }
    let (w, h) = geometry.sensor_size();
    let (camera, _) = geometry.pixel_ray(w as f64 / 2.0, h as f64 / 2.0);
    let cam_dist = (camera - sphere_centre).norm();
    if !(cam_dist.is_finite() && cam_dist > sphere_radius) {
        return Err(BinningError::Parameter(
            "the camera centre is not outside the sphere".into(),
        ));
    }
    let mut parallax: f64 = 0.0;
    let mut by_angle = Vec::with_capacity(positions.len());
    for (k, p) in positions.iter().enumerate() {
        let to_lamp = p.lamp - sphere_centre;
        let d = to_lamp.norm();
        if d <= sphere_radius * 1.0001 {
            return Err(BinningError::Parameter(format!(
                "lamp of position {k} is not outside the sphere"
            )));
        }
        let beta = (to_lamp / d)
            .dot(&((camera - sphere_centre) / cam_dist))
            .clamp(-1.0, 1.0)
            .acos();
        parallax = parallax.max((sphere_radius / d).asin() + (sphere_radius / cam_dist).asin());
        by_angle.push((beta, k));
    }
    by_angle.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let mapper = Mapper {
        geometry,
        view,
        positions,
        lamp_constant: *lamp_constant,
        opts,
        lattice: Lattice::new(view)?,
        camera,
        sphere_centre,
        sphere_radius,
        order: by_angle.iter().map(|b| b.1).collect(),
        beta: by_angle.iter().map(|b| b.0).collect(),
        window: 2.0 * parallax + opts.max_bracket_deg.to_radians(),
        cos_max_incidence: opts.max_incidence_deg.to_radians().cos(),
        cos_max_view: opts.max_view_deg.to_radians().cos(),
    };
    let results: Vec<([f64; 3], [u8; 3], u8)> = (0..BINS)
        .into_par_iter()
        .with_min_len(512)
        .map(|b| mapper.bin(b))
        .collect();
    let mut values = vec![-1.0; 3 * BINS];
    let mut counts = vec![0u8; 3 * BINS];
    let mut flags = vec![0u8; BINS];
    for (b, (v, n, f)) in results.into_iter().enumerate() {
        for c in 0..3 {
            values[c * BINS + b] = v[c];
            counts[c * BINS + b] = n[c];
        }
        flags[b] = f;
    }
    let table = MerlTable::from_values(values)?;
    let out = InverseTable {
        table,
        counts,
        flags,
    };
    tracing::info!(
        positions = positions.len(),
        coverage = out.coverage(),
        "inverse mapping done"
    );
    Ok(out)
}

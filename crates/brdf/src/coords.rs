//! Directions in the local shading frame and Rusinkiewicz half/difference angles.

use nalgebra::Vector3;
use std::f64::consts::{PI, TAU};

/// A 3-vector of `f64` in the local shading frame.
pub type Vec3 = Vector3<f64>;

/// Polar angle of a (not necessarily unit) vector, accurate near the pole.
///
/// `atan2(|xy|, z)` keeps full precision where `acos(z)` loses half of the digits.
#[inline]
pub fn polar_angle(v: &Vec3) -> f64 {
    (v.x * v.x + v.y * v.y).sqrt().atan2(v.z)
}

/// Azimuth of a vector in `[0, 2π)`.
#[inline]
pub fn azimuth(v: &Vec3) -> f64 {
    let p = v.y.atan2(v.x);
    if p < 0.0 {
        p + TAU
    } else {
        p
    }
}

/// A direction given by polar angle `theta` and azimuth `phi`.
///
/// Directions live in the local shading frame, whose surface normal is +z; a direction is a unit
/// vector pointing away from the surface. Angles are in radians: θ is measured from +z, φ
/// counter-clockwise from +x.
///
/// # Examples
///
/// ```
/// use brdf::Spherical;
///
/// let v = Spherical::new(0.3, 1.2).to_vector();
/// assert!((v.norm() - 1.0).abs() < 1e-12);
/// assert!((v.z - 0.3f64.cos()).abs() < 1e-12);
/// let back = Spherical::from_vector(&v);
/// assert!((back.theta - 0.3).abs() < 1e-12 && (back.phi - 1.2).abs() < 1e-12);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spherical {
    /// Polar angle from the normal, radians.
    pub theta: f64,
    /// Azimuth from +x, radians.
    pub phi: f64,
}

impl Spherical {
    /// Creates a spherical direction.
    pub fn new(theta: f64, phi: f64) -> Self {
        Self { theta, phi }
    }

    /// The unit vector of this direction.
    pub fn to_vector(self) -> Vec3 {
        let (st, ct) = self.theta.sin_cos();
        let (sp, cp) = self.phi.sin_cos();
        Vec3::new(st * cp, st * sp, ct)
    }

    /// Spherical angles of a vector (normalisation is not required); φ in `[0, 2π)`.
    pub fn from_vector(v: &Vec3) -> Self {
        Self {
            theta: polar_angle(v),
            phi: azimuth(v),
        }
    }
}

/// Rusinkiewicz half/difference angles of a direction pair.
///
/// The coordinates (θh, φh, θd, φd) describe a pair (ωi, ωo) by its half vector
/// h = normalize(ωi + ωo), with polar angles θh, φh, and its difference vector d, which is ωi
/// expressed in a frame whose pole is h, with polar angles θd, φd. An isotropic BRDF depends on
/// (θh, θd, φd) only; swapping ωi and ωo maps φd to φd + π, so by reciprocity a table may fold φd
/// into [0, π) (as [`MerlTable`](crate::MerlTable) does).
///
/// # Examples
///
/// ```
/// use brdf::{HalfDiff, Spherical};
/// use std::f64::consts::PI;
///
/// let wi = Spherical::new(0.6, 0.2).to_vector();
/// let wo = Spherical::new(0.3, 2.5).to_vector();
/// let hd = HalfDiff::from_directions(&wi, &wo);
/// // the directions come back from the angles
/// let (wi2, wo2) = hd.to_directions();
/// assert!((wi2 - wi).norm() < 1e-9 && (wo2 - wo).norm() < 1e-9);
/// // swapping the directions turns φd by π and keeps θh, θd
/// let swapped = HalfDiff::from_directions(&wo, &wi);
/// assert!((swapped.theta_h - hd.theta_h).abs() < 1e-9);
/// assert!((swapped.theta_d - hd.theta_d).abs() < 1e-9);
/// assert!(((swapped.phi_d - hd.phi_d).rem_euclid(2.0 * PI) - PI).abs() < 1e-9);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HalfDiff {
    /// Polar angle of the half vector, `[0, π/2]` for directions above the surface.
    pub theta_h: f64,
    /// Azimuth of the half vector, `[0, 2π)`.
    pub phi_h: f64,
    /// Polar angle of the incoming direction about the half vector, `[0, π/2]`.
    pub theta_d: f64,
    /// Azimuth of the incoming direction about the half vector, `[0, 2π)`.
    pub phi_d: f64,
}

/// Rotates `v` about +z by `-phi`.
#[inline]
fn rotate_z_neg(v: &Vec3, phi: f64) -> Vec3 {
    let (s, c) = phi.sin_cos();
    Vec3::new(v.x * c + v.y * s, -v.x * s + v.y * c, v.z)
}

/// Rotates `v` about +y by `-theta`.
#[inline]
fn rotate_y_neg(v: &Vec3, theta: f64) -> Vec3 {
    let (s, c) = theta.sin_cos();
    Vec3::new(v.x * c - v.z * s, v.y, v.x * s + v.z * c)
}

/// Rotates `v` about +z by `phi`.
#[inline]
fn rotate_z(v: &Vec3, phi: f64) -> Vec3 {
    rotate_z_neg(v, -phi)
}

/// Rotates `v` about +y by `theta`.
#[inline]
fn rotate_y(v: &Vec3, theta: f64) -> Vec3 {
    rotate_y_neg(v, -theta)
}

impl HalfDiff {
    /// Creates half/difference angles with the half-vector azimuth set to zero (the isotropic case).
    pub fn isotropic(theta_h: f64, theta_d: f64, phi_d: f64) -> Self {
        Self {
            theta_h,
            phi_h: 0.0,
            theta_d,
            phi_d,
        }
    }

    /// Half/difference angles of the pair (`wi`, `wo`). Inputs need not be normalised.
    ///
    /// When `wi = -wo` the half vector is undefined; the normal is used then, so the result is
    /// always finite for finite input.
    pub fn from_directions(wi: &Vec3, wo: &Vec3) -> Self {
        let wi = normalize_or_z(wi);
        let wo = normalize_or_z(wo);
        let sum = wi + wo;
        let h = if sum.norm_squared() > 1e-24 {
            sum.normalize()
        } else {
            Vec3::z()
        };
        let theta_h = polar_angle(&h);
        let phi_h = azimuth(&h);
        let d = rotate_y_neg(&rotate_z_neg(&wi, phi_h), theta_h);
        Self {
            theta_h,
            phi_h,
            theta_d: polar_angle(&d),
            phi_d: azimuth(&d),
        }
    }

    /// The direction pair (ωi, ωo) with these half/difference angles, as unit vectors.
    pub fn to_directions(&self) -> (Vec3, Vec3) {
        let d = Spherical::new(self.theta_d, self.phi_d).to_vector();
        let o = Vec3::new(-d.x, -d.y, d.z);
        let to_world = |v: &Vec3| rotate_z(&rotate_y(v, self.theta_h), self.phi_h);
        (to_world(&d), to_world(&o))
    }

    /// The same pair with ωi and ωo swapped: φd advances by π.
    pub fn swapped(&self) -> Self {
        Self {
            phi_d: (self.phi_d + PI).rem_euclid(TAU),
            ..*self
        }
    }

    /// True when both directions of the pair lie on or above the surface.
    pub fn above_horizon(&self) -> bool {
        let (wi, wo) = self.to_directions();
        wi.z >= -1e-12 && wo.z >= -1e-12
    }
}

/// A pair of directions given by their spherical angles (θi, φi, θo, φo).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AnglePair {
    /// Incoming (light) direction.
    pub incoming: Spherical,
    /// Outgoing (view) direction.
    pub outgoing: Spherical,
}

impl AnglePair {
    /// Creates a pair from (θi, φi, θo, φo).
    pub fn new(theta_i: f64, phi_i: f64, theta_o: f64, phi_o: f64) -> Self {
        Self {
            incoming: Spherical::new(theta_i, phi_i),
            outgoing: Spherical::new(theta_o, phi_o),
        }
    }

    /// Unit vectors (ωi, ωo).
    pub fn to_vectors(&self) -> (Vec3, Vec3) {
        (self.incoming.to_vector(), self.outgoing.to_vector())
    }

    /// Spherical angles of a vector pair.
    pub fn from_vectors(wi: &Vec3, wo: &Vec3) -> Self {
        Self {
            incoming: Spherical::from_vector(wi),
            outgoing: Spherical::from_vector(wo),
        }
    }

    /// Rusinkiewicz angles of this pair.
    pub fn to_half_diff(&self) -> HalfDiff {
        let (wi, wo) = self.to_vectors();
        HalfDiff::from_directions(&wi, &wo)
    }

    /// Spherical angles of the pair with the given Rusinkiewicz angles.
    pub fn from_half_diff(hd: &HalfDiff) -> Self {
        let (wi, wo) = hd.to_directions();
        Self::from_vectors(&wi, &wo)
    }
}

fn normalize_or_z(v: &Vec3) -> Vec3 {
    let n = v.norm();
    if n > 0.0 && n.is_finite() {
        v / n
    } else {
        Vec3::z()
    }
}

/// Mirror reflection of `w` about the normal +z.
#[inline]
pub fn reflect_z(w: &Vec3) -> Vec3 {
    Vec3::new(-w.x, -w.y, w.z)
}

/// Folds φd into `[0, π)` using reciprocity (φd and φd + π describe the same configuration
/// for an isotropic, reciprocal BRDF).
#[inline]
pub fn fold_phi_d(phi_d: f64) -> f64 {
    let p = phi_d.rem_euclid(PI);
    if p >= PI {
        0.0
    } else {
        p
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;
    use std::f64::consts::FRAC_PI_2;

    fn angle_between(a: &Vec3, b: &Vec3) -> f64 {
        a.cross(b).norm().atan2(a.dot(b))
    }

    proptest! {
        #![proptest_config(ProptestConfig {
            rng_seed: proptest::test_runner::RngSeed::Fixed(20261122),
            ..ProptestConfig::default()
        })]
        #[test]
        fn direction_round_trip(ti in 0.0..=FRAC_PI_2, pi_ in 0.0..TAU, to in 0.0..=FRAC_PI_2, po in 0.0..TAU) {
            let pair = AnglePair::new(ti, pi_, to, po);
            let (wi, wo) = pair.to_vectors();
            let hd = pair.to_half_diff();
            prop_assert!(hd.theta_h.is_finite() && hd.theta_d.is_finite() && hd.phi_d.is_finite() && hd.phi_h.is_finite());
            let (wi2, wo2) = hd.to_directions();
            // The pair is undefined only when wi = -wo, which needs both at grazing.
            if (wi + wo).norm() > 1e-6 {
                prop_assert!(angle_between(&wi, &wi2) < 1e-9, "wi {} vs {}", wi, wi2);
                prop_assert!(angle_between(&wo, &wo2) < 1e-9, "wo {} vs {}", wo, wo2);
            }
        }

        #[test]
        fn half_diff_round_trip(th in 0.01..FRAC_PI_2, ph in 0.0..TAU, td in 0.01..FRAC_PI_2, pd in 0.0..TAU) {
            let hd = HalfDiff { theta_h: th, phi_h: ph, theta_d: td, phi_d: pd };
            let (wi, wo) = hd.to_directions();
            let back = HalfDiff::from_directions(&wi, &wo);
            let dphi = |a: f64, b: f64| { let d = (a - b).rem_euclid(TAU); d.min(TAU - d) };
            prop_assert!((back.theta_h - th).abs() < 1e-9);
            prop_assert!((back.theta_d - td).abs() < 1e-9);
            prop_assert!(dphi(back.phi_h, ph) < 1e-9);
            prop_assert!(dphi(back.phi_d, pd) < 1e-9);
        }

        #[test]
        fn swapping_directions_adds_pi_to_phi_d(ti in 0.0..=FRAC_PI_2, pi_ in 0.0..TAU, to in 0.0..=FRAC_PI_2, po in 0.0..TAU) {
            let (wi, wo) = AnglePair::new(ti, pi_, to, po).to_vectors();
            prop_assume!((wi + wo).norm() > 1e-6 && angle_between(&wi, &wo) > 1e-6);
            let a = HalfDiff::from_directions(&wi, &wo);
            let b = HalfDiff::from_directions(&wo, &wi);
            prop_assert!((a.theta_h - b.theta_h).abs() < 1e-9);
            prop_assert!((a.theta_d - b.theta_d).abs() < 1e-9);
            let d = (b.phi_d - a.phi_d - PI).rem_euclid(TAU);
            prop_assert!(d.min(TAU - d) < 1e-9, "phi_d {} -> {}", a.phi_d, b.phi_d);
            let s = a.swapped();
            let d2 = (s.phi_d - b.phi_d).rem_euclid(TAU);
            prop_assert!(d2.min(TAU - d2) < 1e-9);
        }
    }

    #[test]
    fn normal_incidence_and_grazing_are_finite() {
        let cases = [
            (Vec3::z(), Vec3::z()),
            (Vec3::x(), Vec3::z()),
            (Vec3::x(), -Vec3::x()),
            (Vec3::x(), Vec3::x()),
            (Vec3::new(1.0, 0.0, 1e-300), Vec3::new(-1.0, 0.0, 1e-300)),
            (Vec3::zeros(), Vec3::z()),
        ];
        for (wi, wo) in cases {
            let hd = HalfDiff::from_directions(&wi, &wo);
            for v in [hd.theta_h, hd.phi_h, hd.theta_d, hd.phi_d] {
                assert!(v.is_finite(), "{wi} {wo} -> {hd:?}");
            }
            let (a, b) = hd.to_directions();
            assert!(a.iter().chain(b.iter()).all(|v| v.is_finite()));
        }
        // Normal incidence and retro-reflection: θh = θd = 0.
        let hd = HalfDiff::from_directions(&Vec3::z(), &Vec3::z());
        assert!(hd.theta_h.abs() < 1e-15 && hd.theta_d.abs() < 1e-15);
        // Both directions at grazing, mirror configuration: θh = 0, θd = π/2.
        let hd = HalfDiff::from_directions(&Vec3::x(), &-Vec3::x());
        assert!((hd.theta_d - FRAC_PI_2).abs() < 1e-12 && hd.theta_h.abs() < 1e-12);
    }

    #[test]
    fn fold_phi_d_range() {
        for p in [-7.0, -PI, 0.0, 1.0, PI, 4.0, TAU, 100.0] {
            let f = fold_phi_d(p);
            assert!((0.0..PI).contains(&f), "{p} -> {f}");
            let k = ((p - f) / PI).round();
            assert!((p - f - k * PI).abs() < 1e-9);
        }
    }
}

/// One pixel of an orthographic image of the unit sphere seen from +z (the figure the sphere
/// renders of several crates use), with a shading frame at its surface point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpherePixel {
    /// Row-major pixel index (`row * size + col`; row 0 at the top, +y).
    pub index: usize,
    /// Outward unit normal at the pixel's surface point (world frame, view along −z).
    pub normal: Vec3,
    tangent: Vec3,
    bitangent: Vec3,
}

impl SpherePixel {
    /// A world-frame direction expressed in the pixel's local shading frame (normal along +z).
    /// The tangent's orientation is arbitrary, which isotropic BRDFs do not see.
    pub fn to_local(&self, w: &Vec3) -> Vec3 {
        Vec3::new(
            w.dot(&self.tangent),
            w.dot(&self.bitangent),
            w.dot(&self.normal),
        )
    }
}

/// The pixels of a `size × size` orthographic image that fall on the unit sphere (pixel centres
/// strictly inside the disc), in row-major order.
///
/// ```
/// use brdf::sphere_pixels;
/// use brdf::Vec3;
/// let px: Vec<_> = sphere_pixels(64).collect();
/// // About π/4 of the square is covered.
/// let covered = px.len() as f64 / (64.0 * 64.0);
/// assert!((covered - std::f64::consts::FRAC_PI_4).abs() < 0.01);
/// // The view direction is +z in world space and lies above every pixel's surface.
/// assert!(px.iter().all(|p| p.to_local(&Vec3::z()).z > 0.0));
/// ```
pub fn sphere_pixels(size: usize) -> impl Iterator<Item = SpherePixel> {
    (0..size * size).filter_map(move |index| {
        let (row, col) = (index / size, index % size);
        let x = (col as f64 + 0.5) / size as f64 * 2.0 - 1.0;
        let y = 1.0 - (row as f64 + 0.5) / size as f64 * 2.0;
        let r2 = x * x + y * y;
        if r2 >= 1.0 {
            return None;
        }
        let normal = Vec3::new(x, y, (1.0 - r2).sqrt());
        let helper = if normal.x.abs() < 0.9 {
            Vec3::x()
        } else {
            Vec3::y()
        };
        let tangent = helper.cross(&normal).normalize();
        let bitangent = normal.cross(&tangent);
        Some(SpherePixel {
            index,
            normal,
            tangent,
            bitangent,
        })
    })
}

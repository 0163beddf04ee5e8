//! Direction sampling: the elementary hemisphere samplers and the exact samplers of the analytic
//! microfacet models (visible normals of the GGX distribution).
//!
//! Directions are in the local shading frame (normal +z). A BRDF's sampler draws the incident
//! direction `wi` for a given outgoing direction `wo`; densities are in solid angle.

use crate::coords::Vec3;
use std::f64::consts::{FRAC_1_PI, TAU};

/// An incident direction drawn by a BRDF's sampler, with its density in solid angle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DirectionSample {
    /// The incident direction (unit, above the horizon).
    pub wi: Vec3,
    /// Density of the sampler at `wi`, in 1/sr (the same value [`crate::Brdf::pdf`] returns).
    pub pdf: f64,
}

/// Cosine-weighted direction on the upper hemisphere from two uniform numbers in `[0, 1)`;
/// density [`cosine_hemisphere_pdf`] = cos θ / π.
///
/// ```
/// let w = brdf::cosine_hemisphere(0.3, 0.7);
/// assert!((w.norm() - 1.0).abs() < 1e-12 && w.z > 0.0);
/// assert!((brdf::cosine_hemisphere_pdf(&w) - w.z / std::f64::consts::PI).abs() < 1e-15);
/// ```
pub fn cosine_hemisphere(u1: f64, u2: f64) -> Vec3 {
    let r = u1.sqrt();
    let phi = TAU * u2;
    let z = (1.0 - u1).max(0.0).sqrt();
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Density of [`cosine_hemisphere`] in solid angle (zero below the horizon).
#[inline]
pub fn cosine_hemisphere_pdf(w: &Vec3) -> f64 {
    if w.z > 0.0 {
        w.z * FRAC_1_PI
    } else {
        0.0
    }
}

/// Cosine-weighted sampling as a BRDF sampler: `None` when `wo` lies below the horizon.
pub(crate) fn cosine_sample(wo: &Vec3, u: [f64; 3]) -> Option<DirectionSample> {
    if wo.z <= 0.0 {
        return None;
    }
    let wi = cosine_hemisphere(u[0], u[1]);
    let pdf = cosine_hemisphere_pdf(&wi);
    (pdf > 0.0).then_some(DirectionSample { wi, pdf })
}

/// The density of [`cosine_sample`] (zero where either direction lies below the horizon).
pub(crate) fn cosine_pdf(wi: &Vec3, wo: &Vec3) -> f64 {
    if wo.z <= 0.0 {
        return 0.0;
    }
    cosine_hemisphere_pdf(wi)
}

/// A GGX (Trowbridge-Reitz) microfacet normal drawn from the distribution of normals visible
/// from `wo` (Heitz 2018, "Sampling the GGX Distribution of Visible Normals"): the view is
/// stretched to the α = 1 configuration, a point is drawn on the projected hemisphere (a disk
/// whose lower half is squeezed by the view's inclination) and the normal is unstretched.
/// `wo` must lie above the horizon.
pub(crate) fn ggx_visible_normal(alpha: f64, wo: &Vec3, u1: f64, u2: f64) -> Vec3 {
    let v = Vec3::new(alpha * wo.x, alpha * wo.y, wo.z).normalize();
    let len2 = v.x * v.x + v.y * v.y;
    let t1 = if len2 > 0.0 {
        Vec3::new(-v.y, v.x, 0.0) / len2.sqrt()
    } else {
        Vec3::new(1.0, 0.0, 0.0)
    };
    let t2 = v.cross(&t1);
    let r = u1.sqrt();
    let phi = TAU * u2;
    let p1 = r * phi.cos();
    let s = 0.5 * (1.0 + v.z);
    let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
    let p3 = (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
    let n = t1 * p1 + t2 * p2 + v * p3;
    Vec3::new(alpha * n.x, alpha * n.y, n.z.max(1e-12)).normalize()
}

/// Mirror reflection of `wo` about the unit normal `h`.
#[inline]
pub(crate) fn reflect(wo: &Vec3, h: &Vec3) -> Vec3 {
    h * (2.0 * wo.dot(h)) - wo
}

/// The unit half vector of a direction pair, `None` when the two are opposite.
#[inline]
pub(crate) fn half_vector(wi: &Vec3, wo: &Vec3) -> Option<Vec3> {
    let h = wi + wo;
    let n = h.norm();
    (n > 1e-12).then(|| h / n)
}

/// Picks a component of a discrete mixture with non-negative weights `w` (not necessarily
/// normalised) from the uniform number `u`; zero-weight components are never picked unless all
/// weights are zero (then the first).
pub(crate) fn pick_component(w: &[f64], u: f64) -> usize {
    let total: f64 = w.iter().sum();
    let target = u * total;
    let mut acc = 0.0;
    let mut last = 0;
    for (k, &wk) in w.iter().enumerate() {
        if wk > 0.0 {
            acc += wk;
            last = k;
            if target < acc {
                return k;
            }
        }
    }
    last
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn visible_normals_face_the_view_and_reflect_to_unit_directions() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for alpha in [0.01, 0.2, 1.0, 3.0] {
            for _ in 0..2000 {
                let t: f64 = rng.gen_range(0.0..1.5);
                let p: f64 = rng.gen_range(0.0..TAU);
                let wo = Vec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos());
                let h = ggx_visible_normal(alpha, &wo, rng.gen(), rng.gen());
                assert!((h.norm() - 1.0).abs() < 1e-9);
                assert!(h.z > 0.0, "α={alpha}: {h:?}");
                assert!(
                    wo.dot(&h) >= -1e-9,
                    "α={alpha}: back-facing normal {h:?} for {wo:?}"
                );
                assert!((reflect(&wo, &h).norm() - 1.0).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn components_are_picked_in_proportion_to_their_weights() {
        let w = [0.0, 1.0, 3.0, 0.0];
        let mut count = [0usize; 4];
        let n = 40_000;
        for i in 0..n {
            count[pick_component(&w, (i as f64 + 0.5) / n as f64)] += 1;
        }
        assert_eq!(count[0] + count[3], 0);
        assert!(
            (count[2] as f64 / n as f64 - 0.75).abs() < 1e-3,
            "{count:?}"
        );
        assert_eq!(pick_component(&[0.0, 0.0], 0.5), 0);
        assert_eq!(pick_component(&[0.0, 2.0], 1.0 - f64::EPSILON), 1);
    }
}

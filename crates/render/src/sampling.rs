//! Shading frames and the elementary direction samplers (thesis appendix A.2.2 – A.2.3).

use brdf::Vec3;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use std::f64::consts::{PI, TAU};

/// The random number generator used everywhere in the renderer (seeded, reproducible).
pub type SampleRng = ChaCha8Rng;

/// An orthonormal frame whose third axis is a surface normal.
#[derive(Debug, Clone, Copy)]
pub struct Frame {
    /// First tangent.
    pub tangent: Vec3,
    /// Second tangent.
    pub bitangent: Vec3,
    /// The normal (local +z).
    pub normal: Vec3,
}

impl Frame {
    /// A frame around the unit normal `n` (tangents chosen without branches on a cut).
    pub fn from_normal(n: &Vec3) -> Self {
        let sign = if n.z >= 0.0 { 1.0 } else { -1.0 };
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let tangent = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let bitangent = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Self {
            tangent,
            bitangent,
            normal: *n,
        }
    }

    /// World direction expressed in this frame.
    #[inline]
    pub fn to_local(&self, v: &Vec3) -> Vec3 {
        Vec3::new(
            v.dot(&self.tangent),
            v.dot(&self.bitangent),
            v.dot(&self.normal),
        )
    }

    /// Local direction expressed in world coordinates.
    #[inline]
    pub fn to_world(&self, v: &Vec3) -> Vec3 {
        self.tangent * v.x + self.bitangent * v.y + self.normal * v.z
    }
}

pub use brdf::{cosine_hemisphere, cosine_hemisphere_pdf};

/// Uniform direction on the upper hemisphere; pdf `1 / 2π` (thesis A.2.3).
pub fn uniform_hemisphere(u1: f64, u2: f64) -> Vec3 {
    let z = u1;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = TAU * u2;
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// Density of [`uniform_hemisphere`] in solid angle.
#[inline]
pub fn uniform_hemisphere_pdf(w: &Vec3) -> f64 {
    if w.z > 0.0 {
        0.5 / PI
    } else {
        0.0
    }
}

/// Veach's power heuristic (β = 2) weight of a strategy with density `pdf_a` against `pdf_b`.
#[inline]
pub fn power_heuristic(pdf_a: f64, pdf_b: f64) -> f64 {
    let a = pdf_a * pdf_a;
    let b = pdf_b * pdf_b;
    if a + b > 0.0 && (a + b).is_finite() {
        a / (a + b)
    } else if pdf_a.is_infinite() {
        1.0
    } else {
        0.0
    }
}

/// A uniform number in `[0, 1)`.
#[inline]
pub fn uniform(rng: &mut SampleRng) -> f64 {
    rng.gen::<f64>()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_is_orthonormal() {
        for n in [
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(0.0, 0.0, -1.0),
            Vec3::new(1.0, 2.0, -3.0).normalize(),
            Vec3::new(-0.3, 0.1, 0.2).normalize(),
        ] {
            let f = Frame::from_normal(&n);
            assert!((f.tangent.norm() - 1.0).abs() < 1e-12);
            assert!((f.bitangent.norm() - 1.0).abs() < 1e-12);
            assert!(f.tangent.dot(&f.bitangent).abs() < 1e-12);
            assert!(f.tangent.dot(&n).abs() < 1e-12);
            let v = Vec3::new(0.3, -0.5, 0.7);
            assert!((f.to_world(&f.to_local(&v)) - v).norm() < 1e-12);
            assert!((f.to_local(&n) - Vec3::z()).norm() < 1e-12);
        }
    }
}

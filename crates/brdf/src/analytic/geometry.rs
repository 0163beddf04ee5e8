//! The geometric quantities of a direction pair that the analytic models read.
//!
//! [`PairGeometry`] names them once. [`Pair`] computes them from the two directions when a model
//! asks (what [`crate::Brdf::eval`] uses); [`Geom`] holds them precomputed, for callers that
//! evaluate many models or parameter vectors at the same pairs (the `fit` crate's solver). A
//! [`Geom`] is filled from a [`Pair`], so both give the same values.

use crate::coords::{polar_angle, reflect_z, Vec3};

/// The quantities of a direction pair (ωi, ωo), both above the horizon, that the analytic models
/// use. `h` is the half vector (ωi + ωo)/|ωi + ωo|.
pub trait PairGeometry {
    /// cos θi · cos θo.
    fn zz(&self) -> f64;
    /// √(cos θi cos θo).
    fn sqrt_zz(&self) -> f64;
    /// ωi,x ωo,x (the Lafortune x product).
    fn xx(&self) -> f64;
    /// ωi,y ωo,y (the Lafortune y product).
    fn yy(&self) -> f64;
    /// Cosine of the angle between ωo and the mirror direction of ωi, clamped at 0.
    fn mirror(&self) -> f64;
    /// cos θh (at least 10⁻¹²).
    fn h_z(&self) -> f64;
    /// cos⁴ θh.
    fn h_z4(&self) -> f64;
    /// tan² θh.
    fn tan2_h(&self) -> f64;
    /// cos² φh: the share of h's tangential part along the tangent x (1 when h is the normal).
    fn cos2_phi_h(&self) -> f64;
    /// tan² θi.
    fn tan2_i(&self) -> f64;
    /// tan² θo.
    fn tan2_o(&self) -> f64;
    /// ωi · h = cos θd, clamped to `[10⁻¹², 1]`.
    fn cos_d(&self) -> f64;
    /// The V-cavity shadowing-masking term of Cook-Torrance.
    fn v_cavity(&self) -> f64;
    /// cos Δφ · sin α · tan β of Oren-Nayar (α, β the larger and smaller polar angle).
    fn oren_nayar(&self) -> f64;
    /// Ashikhmin-Shirley's specular denominator ωi·h · max(cos θi, cos θo).
    fn as_denominator(&self) -> f64;
    /// Ashikhmin-Shirley's diffuse angular factor (1 − (1 − cos θi/2)⁵)(1 − (1 − cos θo/2)⁵).
    fn as_diffuse(&self) -> f64;
    /// (1 − ωi·h)⁵, Schlick's grazing factor.
    fn schlick5(&self) -> f64;
    /// cot θi (infinite at normal incidence).
    fn cot_i(&self) -> f64;
    /// cot θo.
    fn cot_o(&self) -> f64;
    /// z component of ωi + ωo.
    fn v_z(&self) -> f64;
    /// Squared tangential length of ωi + ωo.
    fn v_xy2(&self) -> f64;
    /// |ωi + ωo|².
    fn v2(&self) -> f64;
}

/// tan² of the polar angle of cosine `z`.
pub(crate) fn tan2(z: f64) -> f64 {
    let c2 = (z * z).max(1e-300);
    ((1.0 - c2) / c2).max(0.0)
}

/// Cotangent of the polar angle of cosine `z` (infinite at the normal).
pub(crate) fn cot(z: f64) -> f64 {
    let sin = (1.0 - z * z).max(0.0).sqrt();
    if sin > 0.0 {
        z / sin
    } else {
        f64::INFINITY
    }
}

/// (1 − c)⁵ for c clamped to `[0, 1]`: the weight of Schlick's Fresnel approximation.
pub(crate) fn schlick_weight(cos: f64) -> f64 {
    (1.0 - cos.clamp(0.0, 1.0)).powi(5)
}

/// A direction pair whose quantities are computed when asked.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pair {
    wi: Vec3,
    wo: Vec3,
    h: Vec3,
}

impl Pair {
    /// The pair (`wi`, `wo`) of unit directions (the half vector is computed here).
    pub fn new(wi: &Vec3, wo: &Vec3) -> Pair {
        let s = wi + wo;
        let n = s.norm();
        let h = if n > 0.0 { s / n } else { Vec3::z() };
        Pair {
            wi: *wi,
            wo: *wo,
            h,
        }
    }
}

impl PairGeometry for Pair {
    fn zz(&self) -> f64 {
        self.wi.z * self.wo.z
    }
    fn sqrt_zz(&self) -> f64 {
        self.zz().sqrt()
    }
    fn xx(&self) -> f64 {
        self.wi.x * self.wo.x
    }
    fn yy(&self) -> f64 {
        self.wi.y * self.wo.y
    }
    fn mirror(&self) -> f64 {
        reflect_z(&self.wi).dot(&self.wo).max(0.0)
    }
    fn h_z(&self) -> f64 {
        self.h.z.max(1e-12)
    }
    fn h_z4(&self) -> f64 {
        let c2 = self.h_z() * self.h_z();
        c2 * c2
    }
    fn tan2_h(&self) -> f64 {
        tan2(self.h_z())
    }
    fn cos2_phi_h(&self) -> f64 {
        let x2 = self.h.x * self.h.x;
        let t = x2 + self.h.y * self.h.y;
        if t > 0.0 {
            x2 / t
        } else {
            1.0
        }
    }
    fn tan2_i(&self) -> f64 {
        tan2(self.wi.z)
    }
    fn tan2_o(&self) -> f64 {
        tan2(self.wo.z)
    }
    fn cos_d(&self) -> f64 {
        self.wi.dot(&self.h).clamp(1e-12, 1.0)
    }
    fn v_cavity(&self) -> f64 {
        let hz = self.h_z();
        let oh = self.wo.dot(&self.h).max(1e-12);
        (2.0 * hz * self.wo.z / oh)
            .min(2.0 * hz * self.wi.z / oh)
            .min(1.0)
    }
    fn oren_nayar(&self) -> f64 {
        let (wi, wo) = (&self.wi, &self.wo);
        let (ti, to) = (polar_angle(wi), polar_angle(wo));
        let (alpha, beta) = (ti.max(to), ti.min(to));
        let pi_ = (wi.x * wi.x + wi.y * wi.y).sqrt();
        let po = (wo.x * wo.x + wo.y * wo.y).sqrt();
        let cos_dphi = if pi_ > 1e-12 && po > 1e-12 {
            ((wi.x * wo.x + wi.y * wo.y) / (pi_ * po)).max(0.0)
        } else {
            0.0
        };
        cos_dphi * alpha.sin() * beta.tan()
    }
    fn as_denominator(&self) -> f64 {
        self.cos_d() * self.wi.z.max(self.wo.z)
    }
    fn as_diffuse(&self) -> f64 {
        let f = |z: f64| 1.0 - (1.0 - z / 2.0).powi(5);
        f(self.wi.z) * f(self.wo.z)
    }
    fn schlick5(&self) -> f64 {
        schlick_weight(self.cos_d())
    }
    fn cot_i(&self) -> f64 {
        cot(self.wi.z)
    }
    fn cot_o(&self) -> f64 {
        cot(self.wo.z)
    }
    fn v_z(&self) -> f64 {
        self.wi.z + self.wo.z
    }
    fn v_xy2(&self) -> f64 {
        let (x, y) = (self.wi.x + self.wo.x, self.wi.y + self.wo.y);
        x * x + y * y
    }
    fn v2(&self) -> f64 {
        (self.wi + self.wo).norm_squared()
    }
}

/// Declares [`Geom`] with one field per [`PairGeometry`] quantity, filled from a [`Pair`].
macro_rules! cached_geometry {
    ($($field:ident),* $(,)?) => {
        /// A direction pair with every [`PairGeometry`] quantity computed once (by [`Pair`]).
        #[derive(Debug, Clone, Copy, PartialEq)]
        pub struct Geom {
            $($field: f64,)*
        }

        impl Geom {
            /// The quantities of `pair`.
            pub fn of(pair: &Pair) -> Geom {
                Geom { $($field: pair.$field(),)* }
            }
        }

        impl PairGeometry for Geom {
            $(
                #[inline]
                fn $field(&self) -> f64 {
                    self.$field
                }
            )*
        }
    };
}

cached_geometry!(
    zz,
    sqrt_zz,
    xx,
    yy,
    mirror,
    h_z,
    h_z4,
    tan2_h,
    cos2_phi_h,
    tan2_i,
    tan2_o,
    cos_d,
    v_cavity,
    oren_nayar,
    as_denominator,
    as_diffuse,
    schlick5,
    cot_i,
    cot_o,
    v_z,
    v_xy2,
    v2,
);

impl Geom {
    /// The geometry of a pair of unit directions, `None` when either lies at or below the horizon
    /// (cos θ ≤ 10⁻⁹).
    pub fn new(wi: &Vec3, wo: &Vec3) -> Option<Geom> {
        if wi.z <= 1e-9 || wo.z <= 1e-9 {
            return None;
        }
        Some(Geom::of(&Pair::new(wi, wo)))
    }
}

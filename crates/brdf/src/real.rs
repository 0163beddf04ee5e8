//! Scalars for the analytic models: `f64` and forward-mode dual numbers.

use std::ops::{Add, Div, Mul, Neg, Sub};

/// The scalar operations the model formulas use.
///
/// The analytic models of [`crate::analytic`] are written once, generic over `Real`, and
/// evaluated either on `f64` (values) or on [`Dual`] numbers (values with exact parameter
/// gradients, by forward-mode automatic differentiation, as the `fit` crate's solver needs
/// them).
pub trait Real:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + Add<f64, Output = Self>
    + Sub<f64, Output = Self>
    + Mul<f64, Output = Self>
    + Div<f64, Output = Self>
{
    /// A constant (zero derivative).
    fn cst(x: f64) -> Self;
    /// The value, without derivatives.
    fn val(self) -> f64;
    /// eˣ.
    fn exp(self) -> Self;
    /// ln x.
    fn ln(self) -> Self;
    /// √x.
    fn sqrt(self) -> Self;
    /// `self` raised to the constant power `p`.
    fn powc(self, p: f64) -> Self;
    /// The complementary error function erfc x.
    fn erfc(self) -> Self;
    /// Whether `self` is exactly the constant 0 (zero value and, for [`Dual`] numbers, zero
    /// derivatives): a term it multiplies adds nothing.
    fn is_zero(self) -> bool;
    /// `self` raised to the variable power `p`, for `self` ≥ 0 (at 0 the value of `0ᵖ`, held
    /// constant).
    fn powf(self, p: Self) -> Self {
        if self.val() <= 0.0 {
            Self::cst(self.val().powf(p.val()))
        } else {
            (p * self.ln()).exp()
        }
    }
    /// 1 / (1 + e⁻ˣ).
    fn sigmoid(self) -> Self {
        let e = (-self).exp();
        Self::cst(1.0) / (e + 1.0)
    }
}

impl Real for f64 {
    #[inline]
    fn cst(x: f64) -> Self {
        x
    }
    #[inline]
    fn val(self) -> f64 {
        self
    }
    #[inline]
    fn exp(self) -> Self {
        f64::exp(self)
    }
    #[inline]
    fn ln(self) -> Self {
        f64::ln(self)
    }
    #[inline]
    fn sqrt(self) -> Self {
        f64::sqrt(self)
    }
    #[inline]
    fn powc(self, p: f64) -> Self {
        self.powf(p)
    }
    #[inline]
    fn erfc(self) -> Self {
        libm::erfc(self)
    }
    #[inline]
    fn powf(self, p: Self) -> Self {
        f64::powf(self, p)
    }
    #[inline]
    fn is_zero(self) -> bool {
        self == 0.0
    }
}

/// A value with its gradient with respect to `N` parameters (forward-mode automatic
/// differentiation; see [`Real`]).
///
/// # Examples
///
/// ```
/// use brdf::{Dual, Real};
///
/// // d/dx and d/dy of x · exp(y) at (2, 0)
/// let x = Dual::<2>::var(2.0, 0);
/// let y = Dual::<2>::var(0.0, 1);
/// let f = x * y.exp();
/// assert_eq!(f.val(), 2.0);
/// assert_eq!(f.d, [1.0, 2.0]);
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Dual<const N: usize> {
    /// Value.
    pub v: f64,
    /// Partial derivatives.
    pub d: [f64; N],
}

impl<const N: usize> Dual<N> {
    /// The `i`-th independent variable with value `v` (derivative 1 along `i`).
    pub fn var(v: f64, i: usize) -> Self {
        let mut d = [0.0; N];
        if i < N {
            d[i] = 1.0;
        }
        Self { v, d }
    }

    #[inline]
    fn chain(self, v: f64, dv: f64) -> Self {
        let mut d = self.d;
        for x in &mut d {
            *x *= dv;
        }
        Self { v, d }
    }
}

impl<const N: usize> Add for Dual<N> {
    type Output = Self;
    #[inline]
    fn add(mut self, o: Self) -> Self {
        self.v += o.v;
        for i in 0..N {
            self.d[i] += o.d[i];
        }
        self
    }
}

impl<const N: usize> Sub for Dual<N> {
    type Output = Self;
    #[inline]
    fn sub(mut self, o: Self) -> Self {
        self.v -= o.v;
        for i in 0..N {
            self.d[i] -= o.d[i];
        }
        self
    }
}

impl<const N: usize> Mul for Dual<N> {
    type Output = Self;
    #[inline]
    fn mul(self, o: Self) -> Self {
        let mut d = [0.0; N];
        for i in 0..N {
            d[i] = self.d[i] * o.v + o.d[i] * self.v;
        }
        Self { v: self.v * o.v, d }
    }
}

impl<const N: usize> Div for Dual<N> {
    type Output = Self;
    #[inline]
    fn div(self, o: Self) -> Self {
        let inv = 1.0 / o.v;
        let v = self.v * inv;
        let mut d = [0.0; N];
        for i in 0..N {
            d[i] = (self.d[i] - v * o.d[i]) * inv;
        }
        Self { v, d }
    }
}

impl<const N: usize> Neg for Dual<N> {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        self.chain(-self.v, -1.0)
    }
}

impl<const N: usize> Add<f64> for Dual<N> {
    type Output = Self;
    #[inline]
    fn add(mut self, o: f64) -> Self {
        self.v += o;
        self
    }
}

impl<const N: usize> Sub<f64> for Dual<N> {
    type Output = Self;
    #[inline]
    fn sub(mut self, o: f64) -> Self {
        self.v -= o;
        self
    }
}

impl<const N: usize> Mul<f64> for Dual<N> {
    type Output = Self;
    #[inline]
    fn mul(self, o: f64) -> Self {
        self.chain(self.v * o, o)
    }
}

impl<const N: usize> Div<f64> for Dual<N> {
    type Output = Self;
    #[inline]
    fn div(self, o: f64) -> Self {
        self * (1.0 / o)
    }
}

impl<const N: usize> Real for Dual<N> {
    #[inline]
    fn cst(x: f64) -> Self {
        Self { v: x, d: [0.0; N] }
    }
    #[inline]
    fn val(self) -> f64 {
        self.v
    }
    #[inline]
    fn exp(self) -> Self {
        let e = self.v.exp();
        self.chain(e, e)
    }
    #[inline]
    fn ln(self) -> Self {
        self.chain(self.v.ln(), 1.0 / self.v)
    }
    #[inline]
    fn sqrt(self) -> Self {
        let s = self.v.sqrt();
        self.chain(s, if s > 0.0 { 0.5 / s } else { 0.0 })
    }
    #[inline]
    fn powc(self, p: f64) -> Self {
        let v = self.v.powf(p);
        let dv = if self.v != 0.0 { p * v / self.v } else { 0.0 };
        self.chain(v, dv)
    }
    #[inline]
    fn erfc(self) -> Self {
        let d = -std::f64::consts::FRAC_2_SQRT_PI * (-self.v * self.v).exp();
        self.chain(libm::erfc(self.v), d)
    }
    #[inline]
    fn is_zero(self) -> bool {
        self.v == 0.0 && self.d.iter().all(|d| *d == 0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derivatives_match_calculus() {
        let x = Dual::<2>::var(0.7, 0);
        let y = Dual::<2>::var(1.3, 1);
        let f =
            (x * y).exp() / (y.sqrt() + x.ln()) - x.powc(2.5) * 3.0 + y.sigmoid() + (x * y).erfc();
        let g = |x: f64, y: f64| {
            (x * y).exp() / (y.sqrt() + x.ln()) - x.powf(2.5) * 3.0
                + 1.0 / (1.0 + (-y).exp())
                + libm::erfc(x * y)
        };
        let h = 1e-6;
        let dx = (g(0.7 + h, 1.3) - g(0.7 - h, 1.3)) / (2.0 * h);
        let dy = (g(0.7, 1.3 + h) - g(0.7, 1.3 - h)) / (2.0 * h);
        assert!((f.v - g(0.7, 1.3)).abs() < 1e-12);
        assert!(
            (f.d[0] - dx).abs() < 1e-6 * dx.abs().max(1.0),
            "{} {dx}",
            f.d[0]
        );
        assert!(
            (f.d[1] - dy).abs() < 1e-6 * dy.abs().max(1.0),
            "{} {dy}",
            f.d[1]
        );
    }

    #[test]
    fn variable_powers_and_zero_constants() {
        let x = Dual::<2>::var(1.7, 0);
        let n = Dual::<2>::var(3.2, 1);
        let f = x.powf(n);
        let v = 1.7f64.powf(3.2);
        assert!((f.v - v).abs() < 1e-12 * v);
        assert!((f.d[0] - 3.2 * 1.7f64.powf(2.2)).abs() < 1e-12 * v);
        assert!((f.d[1] - v * 1.7f64.ln()).abs() < 1e-12 * v);
        assert_eq!(Dual::<2>::cst(0.0).powf(n), Dual::cst(0.0));
        assert!(Dual::<2>::cst(0.0).is_zero() && 0.0f64.is_zero());
        assert!(!Dual::<2>::var(0.0, 1).is_zero() && !Dual::<2>::cst(1.0).is_zero());
    }
}

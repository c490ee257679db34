//! Forward-mode automatic differentiation with `N` directional derivatives.
//!
//! A [`Dual`] carries a value and its gradient with respect to `N` seeded inputs;
//! every operation applies the chain rule exactly (no truncation error), so the
//! plant's Jacobian comes from one evaluation of the same equations on `Dual<7>`.

use crate::scalar::{Scalar, Sign};
use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

/// A value with `N` partial derivatives: `v + sum_i d[i] * eps_i`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Dual<const N: usize> {
    /// The value.
    pub v: f64,
    /// The partial derivatives.
    pub d: [f64; N],
}

impl<const N: usize> Dual<N> {
    /// The `i`-th independent variable with value `v` (derivative 1 in slot `i`).
    pub fn var(v: f64, i: usize) -> Self {
        let mut d = [0.0; N];
        d[i] = 1.0;
        Dual { v, d }
    }

    /// A constant.
    pub fn constant(v: f64) -> Self {
        Dual { v, d: [0.0; N] }
    }

    /// Chain rule: `g(self)` where `g(v) = gv` and `g'(v) = dg`.
    #[inline(always)]
    fn chain(&self, gv: f64, dg: f64) -> Self {
        let mut d = self.d;
        for x in d.iter_mut() {
            *x *= dg;
        }
        Dual { v: gv, d }
    }
}

impl<const N: usize> Add for Dual<N> {
    type Output = Self;
    #[inline(always)]
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
    #[inline(always)]
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
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        let mut d = [0.0; N];
        for (i, di) in d.iter_mut().enumerate() {
            *di = self.d[i] * o.v + self.v * o.d[i];
        }
        Dual { v: self.v * o.v, d }
    }
}
impl<const N: usize> Div for Dual<N> {
    type Output = Self;
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        let q = self.v / o.v;
        let mut d = [0.0; N];
        for (i, di) in d.iter_mut().enumerate() {
            *di = (self.d[i] - q * o.d[i]) / o.v;
        }
        Dual { v: q, d }
    }
}
impl<const N: usize> Neg for Dual<N> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        self.chain(-self.v, -1.0)
    }
}
impl<const N: usize> Add<f64> for Dual<N> {
    type Output = Self;
    #[inline(always)]
    fn add(mut self, o: f64) -> Self {
        self.v += o;
        self
    }
}
impl<const N: usize> Sub<f64> for Dual<N> {
    type Output = Self;
    #[inline(always)]
    fn sub(mut self, o: f64) -> Self {
        self.v -= o;
        self
    }
}
impl<const N: usize> Mul<f64> for Dual<N> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: f64) -> Self {
        self.chain(self.v * o, o)
    }
}
impl<const N: usize> Div<f64> for Dual<N> {
    type Output = Self;
    #[inline(always)]
    fn div(self, o: f64) -> Self {
        self.chain(self.v / o, 1.0 / o)
    }
}
impl<const N: usize> AddAssign for Dual<N> {
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}
impl<const N: usize> SubAssign for Dual<N> {
    fn sub_assign(&mut self, o: Self) {
        *self = *self - o;
    }
}
impl<const N: usize> MulAssign for Dual<N> {
    fn mul_assign(&mut self, o: Self) {
        *self = *self * o;
    }
}

impl<const N: usize> Scalar for Dual<N> {
    fn cst(c: f64) -> Self {
        Self::constant(c)
    }
    fn value(&self) -> f64 {
        self.v
    }
    fn sin(&self) -> Self {
        let (s, c) = self.v.sin_cos();
        self.chain(s, c)
    }
    fn cos(&self) -> Self {
        let (s, c) = self.v.sin_cos();
        self.chain(c, -s)
    }
    fn tanh(&self) -> Self {
        let t = self.v.tanh();
        self.chain(t, 1.0 - t * t)
    }
    fn atan(&self) -> Self {
        self.chain(self.v.atan(), 1.0 / (1.0 + self.v * self.v))
    }
    fn sqrt(&self) -> Self {
        let r = self.v.sqrt();
        self.chain(r, 0.5 / r)
    }
    fn exp(&self) -> Self {
        let e = self.v.exp();
        self.chain(e, e)
    }
    fn ln(&self) -> Self {
        self.chain(self.v.ln(), 1.0 / self.v)
    }
    fn tan(&self) -> Self {
        let t = self.v.tan();
        self.chain(t, 1.0 + t * t)
    }
    fn abs(&self) -> Self {
        // Derivative of |x| taken as sign(x) (0 at 0: the subgradient midpoint).
        let s = if self.v > 0.0 {
            1.0
        } else if self.v < 0.0 {
            -1.0
        } else {
            0.0
        };
        self.chain(self.v.abs(), s)
    }
    fn sigmoid(&self) -> Self {
        let s = 1.0 / (1.0 + (-self.v).exp());
        self.chain(s, s * (1.0 - s))
    }
    fn sign(&self) -> Sign {
        self.v.sign()
    }
    fn hull(&self, _other: &Self) -> Self {
        *self
    }
    /// A NaN in either operand's value gives that operand (the default would keep
    /// `self`, dropping a NaN `other`).
    fn smin(&self, other: &Self) -> Self {
        if other.v.is_nan() || (!self.v.is_nan() && other.v < self.v) {
            *other
        } else {
            *self
        }
    }
    /// As [`Dual::smin`].
    fn smax(&self, other: &Self) -> Self {
        if other.v.is_nan() || (!self.v.is_nan() && other.v > self.v) {
            *other
        } else {
            *self
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// f(x, y) = atan(x / y) * tanh(x) + sqrt(x*x + y) * sin(y) - cos(x)*exp(y)
    fn f<S: Scalar>(x: S, y: S) -> S {
        (x.clone() / y.clone()).atan() * x.tanh() + (x.sqr() + y.clone()).sqrt() * y.sin()
            - x.cos() * y.exp()
            + x.sigmoid()
            + (x.clone() - 3.0).abs() * y.powi(3)
    }

    proptest::proptest! {
        #[test]
        fn dual_gradient_matches_central_differences(x in 0.2f64..2.5, y in 0.3f64..2.0) {
            let g = f(Dual::<2>::var(x, 0), Dual::<2>::var(y, 1));
            let h = 1e-6;
            let fx = (f(x + h, y) - f(x - h, y)) / (2.0 * h);
            let fy = (f(x, y + h) - f(x, y - h)) / (2.0 * h);
            proptest::prop_assert!((g.v - f(x, y)).abs() < 1e-14 * (1.0 + f(x, y).abs()));
            proptest::prop_assert!((g.d[0] - fx).abs() < 1e-7 * (1.0 + fx.abs()), "{} vs {}", g.d[0], fx);
            proptest::prop_assert!((g.d[1] - fy).abs() < 1e-7 * (1.0 + fy.abs()), "{} vs {}", g.d[1], fy);
        }
    }

    #[test]
    fn ln_tan_min_max_sgn_derivatives() {
        let x = Dual::<1>::var(0.7, 0);
        assert!((x.ln().d[0] - 1.0 / 0.7).abs() < 1e-15);
        let t = 0.7f64.tan();
        assert!((x.tan().d[0] - (1.0 + t * t)).abs() < 1e-14);
        let c = Dual::<1>::constant(2.0);
        assert_eq!(x.smin(&c).d[0], 1.0);
        assert_eq!(x.smax(&c).d[0], 0.0);
        assert_eq!(x.sgn().v, 1.0);
        assert_eq!(x.sgn().d[0], 0.0);
    }

    #[test]
    fn clamp_passes_derivative_inside_and_zero_outside() {
        let x = Dual::<1>::var(0.185, 0);
        assert_eq!(x.clamp_to(0.181, 0.193).d[0], 1.0);
        let y = Dual::<1>::var(0.2, 0);
        assert_eq!(y.clamp_to(0.181, 0.193).d[0], 0.0);
        assert_eq!(y.clamp_to(0.181, 0.193).v, 0.193);
    }
}

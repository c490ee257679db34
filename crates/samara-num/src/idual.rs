//! Forward-mode dual numbers over intervals: a value set and an enclosure of the gradient
//! over that set, for the mean-value form `f(x) in f(c) + Df(X) (x - c)` (Moore, 1966;
//! the Jacobian enclosures of Lohner's method).

// Numeric kernels index several arrays by one index; the explicit forms mirror the formulas.
#![allow(clippy::assign_op_pattern, clippy::needless_range_loop)]

use crate::interval::{mul_finite, Interval};
use crate::scalar::{Scalar, Sign};
use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

/// An interval value with `N` interval partial derivatives. Evaluated on a box seeded with
/// [`IDual::var`], every component of the result encloses the corresponding function
/// value or partial derivative at every point of the box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct IDual<const N: usize> {
    /// Enclosure of the value.
    pub v: Interval,
    /// Enclosures of the partial derivatives.
    pub d: [Interval; N],
}

const Z: Interval = Interval { lo: 0.0, hi: 0.0 };

impl<const N: usize> IDual<N> {
    /// The `i`-th independent variable ranging over `v`.
    pub fn var(v: Interval, i: usize) -> Self {
        let mut d = [Z; N];
        d[i] = Interval::point(1.0);
        IDual { v, d }
    }

    /// A constant set (zero derivative).
    pub fn constant(v: Interval) -> Self {
        IDual { v, d: [Z; N] }
    }

    #[inline]
    fn chain(&self, v: Interval, dv: Interval) -> Self {
        let mut d = self.d;
        for x in d.iter_mut() {
            *x = *x * dv;
        }
        IDual { v, d }
    }
}

impl<const N: usize> Add for IDual<N> {
    type Output = Self;
    #[inline(always)]
    fn add(mut self, o: Self) -> Self {
        self.v = self.v + o.v;
        for i in 0..N {
            self.d[i] = self.d[i] + o.d[i];
        }
        self
    }
}
impl<const N: usize> Sub for IDual<N> {
    type Output = Self;
    #[inline(always)]
    fn sub(mut self, o: Self) -> Self {
        self.v = self.v - o.v;
        for i in 0..N {
            self.d[i] = self.d[i] - o.d[i];
        }
        self
    }
}
impl<const N: usize> IDual<N> {
    /// Whether every end of the value and of the derivatives is finite.
    #[inline]
    fn is_finite(&self) -> bool {
        self.d
            .iter()
            .fold(self.v.is_finite(), |f, x| f & x.is_finite())
    }
}

impl<const N: usize> Mul for IDual<N> {
    type Output = Self;
    /// The product rule; the ends' finiteness is checked once for the `2 N + 1` interval
    /// products, which then take `mul_finite` (the same floats as [`Interval`]'s `*`).
    #[inline]
    fn mul(self, o: Self) -> Self {
        let mut d = [Z; N];
        if self.is_finite() & o.is_finite() {
            for i in 0..N {
                d[i] = mul_finite(self.d[i], o.v) + mul_finite(self.v, o.d[i]);
            }
            return IDual {
                v: mul_finite(self.v, o.v),
                d,
            };
        }
        for i in 0..N {
            d[i] = self.d[i] * o.v + self.v * o.d[i];
        }
        IDual { v: self.v * o.v, d }
    }
}
impl<const N: usize> Div for IDual<N> {
    type Output = Self;
    fn div(self, o: Self) -> Self {
        let v = self.v / o.v;
        let mut d = [Z; N];
        for i in 0..N {
            d[i] = (self.d[i] - v * o.d[i]) / o.v;
        }
        IDual { v, d }
    }
}
impl<const N: usize> Neg for IDual<N> {
    type Output = Self;
    #[inline(always)]
    fn neg(mut self) -> Self {
        self.v = -self.v;
        for x in self.d.iter_mut() {
            *x = -*x;
        }
        self
    }
}
impl<const N: usize> Add<f64> for IDual<N> {
    type Output = Self;
    #[inline(always)]
    fn add(mut self, o: f64) -> Self {
        self.v = self.v + o;
        self
    }
}
impl<const N: usize> Sub<f64> for IDual<N> {
    type Output = Self;
    #[inline(always)]
    fn sub(mut self, o: f64) -> Self {
        self.v = self.v - o;
        self
    }
}
impl<const N: usize> Mul<f64> for IDual<N> {
    type Output = Self;
    #[inline(always)]
    fn mul(mut self, o: f64) -> Self {
        self.v = self.v * o;
        for x in self.d.iter_mut() {
            *x = *x * o;
        }
        self
    }
}
impl<const N: usize> Div<f64> for IDual<N> {
    type Output = Self;
    #[inline(always)]
    fn div(mut self, o: f64) -> Self {
        self.v = self.v / o;
        for x in self.d.iter_mut() {
            *x = *x / o;
        }
        self
    }
}
impl<const N: usize> AddAssign for IDual<N> {
    #[inline(always)]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}
impl<const N: usize> SubAssign for IDual<N> {
    #[inline(always)]
    fn sub_assign(&mut self, o: Self) {
        *self = *self - o;
    }
}
impl<const N: usize> MulAssign for IDual<N> {
    fn mul_assign(&mut self, o: Self) {
        *self = *self * o;
    }
}

impl<const N: usize> Scalar for IDual<N> {
    fn cst(c: f64) -> Self {
        IDual::constant(Interval::point(c))
    }
    fn value(&self) -> f64 {
        self.v.value()
    }
    fn sin(&self) -> Self {
        self.chain(self.v.sin(), self.v.cos())
    }
    fn cos(&self) -> Self {
        self.chain(self.v.cos(), -self.v.sin())
    }
    fn tanh(&self) -> Self {
        let t = self.v.tanh();
        self.chain(t, -t.sqr() + 1.0)
    }
    fn atan(&self) -> Self {
        self.chain(self.v.atan(), Interval::point(1.0) / (self.v.sqr() + 1.0))
    }
    fn sqrt(&self) -> Self {
        let r = self.v.sqrt();
        self.chain(r, Interval::point(0.5) / r)
    }
    fn exp(&self) -> Self {
        let e = self.v.exp();
        self.chain(e, e)
    }
    fn ln(&self) -> Self {
        self.chain(self.v.ln(), Interval::point(1.0) / self.v)
    }
    fn tan(&self) -> Self {
        let t = self.v.tan();
        self.chain(t, t.sqr() + 1.0)
    }
    fn abs(&self) -> Self {
        match self.v.sign() {
            Sign::Positive | Sign::NonNegative | Sign::Zero => *self,
            Sign::Negative | Sign::NonPositive => -*self,
            // Clarke's generalised derivative of |x| at 0 is [-1, 1].
            Sign::Mixed => self.chain(self.v.abs(), Interval::new(-1.0, 1.0)),
        }
    }
    fn sqr(&self) -> Self {
        self.chain(self.v.sqr(), self.v * 2.0)
    }
    fn sign(&self) -> Sign {
        self.v.sign()
    }
    fn hull(&self, o: &Self) -> Self {
        let mut d = [Z; N];
        for i in 0..N {
            d[i] = self.d[i].hull(&o.d[i]);
        }
        IDual {
            v: self.v.hull(&o.v),
            d,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derivatives_enclose_point_derivatives() {
        // f(x, y) = atan(y / x) * sqrt(x^2 + y^2) + exp(x) sin(y), over a box.
        let bx = Interval::new(0.9, 1.1);
        let by = Interval::new(-0.3, 0.1);
        let x = IDual::<2>::var(bx, 0);
        let y = IDual::<2>::var(by, 1);
        let f = (y / x).atan() * (x.sqr() + y.sqr()).sqrt() + x.exp() * y.sin() - x.ln() * y.tan()
            + x.smin(&y) * x.smax(&(y * 2.0));
        for i in 0..=10 {
            for j in 0..=10 {
                let (px, py) = (0.9 + 0.02 * i as f64, -0.3 + 0.04 * j as f64);
                let dx = crate::Dual::<2>::var(px, 0);
                let dy = crate::Dual::<2>::var(py, 1);
                let g = (dy / dx).atan() * (dx.sqr() + dy.sqr()).sqrt() + dx.exp() * dy.sin()
                    - dx.ln() * dy.tan()
                    + dx.smin(&dy) * dx.smax(&(dy * 2.0));
                assert!(f.v.contains(g.v));
                assert!(f.d[0].contains(g.d[0]) && f.d[1].contains(g.d[1]));
            }
        }
    }
}

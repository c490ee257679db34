//! Truncated Taylor series in one variable (time) with coefficients in any [`Scalar`]:
//! Taylor-mode automatic differentiation by the classical recurrences (Moore, 1966;
//! Griewank & Walther, *Evaluating Derivatives*, ch. 13). Running the plant's right-hand
//! side on `Series<Interval, K>` yields the solution's Taylor coefficients; on
//! `Series<IDual<N>, K>` also their Jacobians over a box; on `Series<Tm, K>` (coefficients
//! that are not `Copy`) Taylor models of them in the initial-state parameters.
//!
//! A series is only meaningful where the function is analytic. Branches (`abs`, the
//! hull of two pieces, `relu`) are taken only when the constant coefficient decides them
//! strictly; otherwise the series is marked `bad` and every coefficient built from it is
//! unusable. Validated integrators treat a bad series as "no Taylor expansion here".

// Numeric kernels index several arrays by one index; the explicit forms mirror the formulas.
#![allow(clippy::assign_op_pattern, clippy::needless_range_loop)]

use crate::scalar::{Scalar, Sign};
use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

/// `sum_i c[i] t^i`, the first `n` coefficients valid (`n <= K`).
#[derive(Clone, Copy, Debug)]
pub struct Series<S: Scalar, const K: usize> {
    /// Coefficients (normalised: `c[i] = x^(i)(0) / i!`).
    pub c: [S; K],
    /// Number of valid coefficients.
    pub n: usize,
    /// Set when a non-analytic branch was undecided: the series is unusable.
    pub bad: bool,
    /// Whether only `c[0]` can be nonzero (a constant): products with it cost O(K).
    pub konst: bool,
}

impl<S: Scalar, const K: usize> Series<S, K> {
    /// A variable with constant term `v` and no higher terms known yet (`n = 1`).
    pub fn var(v: S) -> Self {
        let mut c: [S; K] = std::array::from_fn(|_| S::cst(0.0));
        c[0] = v;
        Series {
            c,
            n: 1,
            bad: false,
            konst: false,
        }
    }

    /// A constant (all higher coefficients zero, valid to any order).
    pub fn constant(v: S) -> Self {
        let mut c: [S; K] = std::array::from_fn(|_| S::cst(0.0));
        c[0] = v;
        Series {
            c,
            n: K,
            bad: false,
            konst: true,
        }
    }

    fn zero_like(n: usize, bad: bool) -> Self {
        Series {
            c: std::array::from_fn(|_| S::cst(0.0)),
            n,
            bad,
            konst: false,
        }
    }

    fn zip(self, o: Self, f: impl Fn(S, S) -> S) -> Self {
        let n = self.n.min(o.n);
        let mut r = Self::zero_like(n, self.bad || o.bad);
        if self.konst && o.konst {
            r.c[0] = f(self.c[0].clone(), o.c[0].clone());
            r.konst = true;
            return r;
        }
        for i in 0..n {
            r.c[i] = f(self.c[i].clone(), o.c[i].clone());
        }
        r
    }

    fn map(mut self, f: impl Fn(S) -> S) -> Self {
        if self.konst {
            self.c[0] = f(self.c[0].clone());
            return self;
        }
        for i in 0..self.n {
            self.c[i] = f(self.c[i].clone());
        }
        self
    }
}

/// The order at which the sum `sum_{j in lo..=i} a_j b_{i-j}` ends: the smallest
/// [`Scalar::trunc_order`] of its operands (a sum of Taylor models keeps the smallest
/// order of its terms, and so does a product).
#[inline]
fn conv_cap<S: Scalar>(a: &[S], b: &[S], lo: usize, i: usize) -> u32 {
    (lo..=i)
        .map(|j| a[j].trunc_order().min(b[i - j].trunc_order()))
        .min()
        .unwrap_or(u32::MAX)
}

/// `sum_{j=1}^{i} (j / i) a_j b_{i-j}`, the convolution of the recurrences of
/// `exp`, `sin`/`cos` and `tanh` (coefficient `i >= 1`). Shared with the incremental
/// expansion (`samara_system::taylor`) so that both sum in the same order. Each product
/// is truncated at the order the sum ends at ([`Scalar::mul_capped`]): under the joint
/// degree of (parameters, time) the later coefficients have lower orders, and a product
/// of two early ones at their full order would be computed only to be truncated by the
/// sum (Flow*'s truncation of the products themselves; Chen, Abraham &
/// Sankaranarayanan, CAV 2013).
#[inline]
pub fn dconv<S: Scalar>(a: &[S], b: &[S], i: usize) -> S {
    let cap = conv_cap(a, b, 1, i);
    let mut acc = a[1].mul_capped(&b[i - 1], cap) * (1.0 / i as f64);
    for j in 2..=i {
        acc += a[j].mul_capped(&b[i - j], cap) * (j as f64 / i as f64);
    }
    acc
}

/// Coefficient `i` of the product of the series `a` and `b`,
/// `a_0 b_i + sum_{j=1}^{i} a_j b_{i-j}`, in the order shared with the incremental
/// expansion, each product truncated at the order the sum ends at (as [`dconv`]);
/// summed by [`Scalar::conv_capped`].
#[inline]
pub fn conv<S: Scalar>(a: &[S], b: &[S], i: usize) -> S {
    let cap = conv_cap(a, b, 0, i);
    S::conv_capped(a, b, 0, i, cap)
}

impl<S: Scalar, const K: usize> Add for Series<S, K> {
    type Output = Self;
    fn add(self, o: Self) -> Self {
        self.zip(o, |a, b| a + b)
    }
}
impl<S: Scalar, const K: usize> Sub for Series<S, K> {
    type Output = Self;
    fn sub(self, o: Self) -> Self {
        self.zip(o, |a, b| a - b)
    }
}
impl<S: Scalar, const K: usize> Mul for Series<S, K> {
    type Output = Self;
    fn mul(self, o: Self) -> Self {
        let n = self.n.min(o.n);
        let mut r = Self::zero_like(n, self.bad || o.bad);
        if self.konst || o.konst {
            let (k, other) = if self.konst {
                (self.c[0].clone(), o)
            } else {
                (o.c[0].clone(), self)
            };
            r.konst = other.konst;
            let m = if other.konst { 1 } else { n };
            for i in 0..m {
                r.c[i] = other.c[i].mul_by_ref(&k);
            }
            return r;
        }
        for i in 0..n {
            r.c[i] = conv(&self.c, &o.c, i);
        }
        r
    }
}
impl<S: Scalar, const K: usize> Div for Series<S, K> {
    type Output = Self;
    fn div(self, o: Self) -> Self {
        let n = self.n.min(o.n);
        let mut r = Self::zero_like(n, self.bad || o.bad);
        if o.konst {
            r.konst = self.konst;
            let m = if self.konst { 1 } else { n };
            for i in 0..m {
                r.c[i] = self.c[i].clone() / o.c[0].clone();
            }
            return r;
        }
        for i in 0..n {
            let mut acc = self.c[i].clone();
            for j in 1..=i {
                acc -= o.c[j].mul_by_ref(&r.c[i - j]);
            }
            r.c[i] = acc / o.c[0].clone();
        }
        r
    }
}
impl<S: Scalar, const K: usize> Neg for Series<S, K> {
    type Output = Self;
    fn neg(self) -> Self {
        self.map(|a| -a)
    }
}
impl<S: Scalar, const K: usize> Add<f64> for Series<S, K> {
    type Output = Self;
    fn add(mut self, o: f64) -> Self {
        self.c[0] = self.c[0].clone() + o;
        self
    }
}
impl<S: Scalar, const K: usize> Sub<f64> for Series<S, K> {
    type Output = Self;
    fn sub(mut self, o: f64) -> Self {
        self.c[0] = self.c[0].clone() - o;
        self
    }
}
impl<S: Scalar, const K: usize> Mul<f64> for Series<S, K> {
    type Output = Self;
    fn mul(self, o: f64) -> Self {
        self.map(|a| a * o)
    }
}
impl<S: Scalar, const K: usize> Div<f64> for Series<S, K> {
    type Output = Self;
    fn div(self, o: f64) -> Self {
        self.map(|a| a / o)
    }
}
impl<S: Scalar, const K: usize> AddAssign for Series<S, K> {
    fn add_assign(&mut self, o: Self) {
        *self = self.clone() + o;
    }
}
impl<S: Scalar, const K: usize> SubAssign for Series<S, K> {
    fn sub_assign(&mut self, o: Self) {
        *self = self.clone() - o;
    }
}
impl<S: Scalar, const K: usize> MulAssign for Series<S, K> {
    fn mul_assign(&mut self, o: Self) {
        *self = self.clone() * o;
    }
}

impl<S: Scalar, const K: usize> Scalar for Series<S, K> {
    fn cst(c: f64) -> Self {
        Series::constant(S::cst(c))
    }
    fn value(&self) -> f64 {
        self.c[0].value()
    }
    fn sin(&self) -> Self {
        self.sin_cos().0
    }
    fn cos(&self) -> Self {
        self.sin_cos().1
    }
    fn sin_cos(&self) -> (Self, Self) {
        if self.konst {
            let (a, b) = self.c[0].sin_cos();
            let (mut s, mut c) = (self.clone(), self.clone());
            s.c[0] = a;
            c.c[0] = b;
            return (s, c);
        }
        let mut s = Self::zero_like(self.n, self.bad);
        let mut c = Self::zero_like(self.n, self.bad);
        let (s0, c0) = self.c[0].sin_cos();
        s.c[0] = s0;
        c.c[0] = c0;
        for i in 1..self.n {
            s.c[i] = dconv(&self.c, &c.c, i);
            c.c[i] = -dconv(&self.c, &s.c, i);
        }
        (s, c)
    }
    fn tanh(&self) -> Self {
        if self.konst {
            let mut r = self.clone();
            r.c[0] = self.c[0].tanh();
            return r;
        }
        let mut t = Self::zero_like(self.n, self.bad);
        let mut w = Self::zero_like(self.n, self.bad); // 1 - t^2
        t.c[0] = self.c[0].tanh();
        w.c[0] = -t.c[0].sqr() + 1.0;
        for i in 1..self.n {
            t.c[i] = dconv(&self.c, &w.c, i);
            w.c[i] = -conv(&t.c, &t.c, i);
        }
        t
    }
    fn atan(&self) -> Self {
        if self.konst {
            let mut r = self.clone();
            r.c[0] = self.c[0].atan();
            return r;
        }
        // u' = a' / (1 + a^2).
        let q = self.sqr() + 1.0;
        let mut u = Self::zero_like(self.n, self.bad);
        u.c[0] = self.c[0].atan();
        let mut d: [S; K] = std::array::from_fn(|_| S::cst(0.0));
        for i in 1..self.n {
            // d_{i-1} = (a'_{i-1} - sum_{j=1}^{i-1} q_j d_{i-1-j}) / q_0, a'_k = (k+1) a_{k+1}.
            let k = i - 1;
            let mut acc = self.c[k + 1].clone() * (k as f64 + 1.0);
            for j in 1..=k {
                acc -= q.c[j].mul_by_ref(&d[k - j]);
            }
            d[k] = acc / q.c[0].clone();
            u.c[i] = d[k].clone() / i as f64;
        }
        u
    }
    /// The product with itself, its constant term by `S::sqr` (a square of one quantity:
    /// intervals and Taylor models know it is `>= 0`, a product of two copies does not).
    fn sqr(&self) -> Self {
        let mut r = self.mul_by_ref(self);
        r.c[0] = self.c[0].sqr();
        r
    }
    fn sqrt(&self) -> Self {
        if self.konst {
            let mut r = self.clone();
            r.c[0] = self.c[0].sqrt();
            return r;
        }
        let mut r = Self::zero_like(self.n, self.bad);
        r.c[0] = self.c[0].sqrt();
        let two_r0 = r.c[0].clone() * 2.0;
        for i in 1..self.n {
            let mut acc = self.c[i].clone();
            for j in 1..i {
                acc -= r.c[j].mul_by_ref(&r.c[i - j]);
            }
            r.c[i] = acc / two_r0.clone();
        }
        r
    }
    fn exp(&self) -> Self {
        if self.konst {
            let mut r = self.clone();
            r.c[0] = self.c[0].exp();
            return r;
        }
        let mut e = Self::zero_like(self.n, self.bad);
        e.c[0] = self.c[0].exp();
        for i in 1..self.n {
            e.c[i] = dconv(&self.c, &e.c, i);
        }
        e
    }
    fn ln(&self) -> Self {
        if self.konst {
            let mut r = self.clone();
            r.c[0] = self.c[0].ln();
            return r;
        }
        // a u' = a': i u_i a_0 = i a_i - sum_{j=1}^{i-1} j u_j a_{i-j}.
        let mut u = Self::zero_like(self.n, self.bad);
        u.c[0] = self.c[0].ln();
        for i in 1..self.n {
            let mut acc = self.c[i].clone();
            for j in 1..i {
                acc -= u.c[j].mul_by_ref(&self.c[i - j]) * (j as f64 / i as f64);
            }
            u.c[i] = acc / self.c[0].clone();
        }
        u
    }
    fn abs(&self) -> Self {
        match self.c[0].sign().strict() {
            Sign::Positive => self.clone(),
            Sign::Negative => -self.clone(),
            _ => Series {
                bad: true,
                ..self.clone().map(|a| a.abs())
            },
        }
    }
    fn sign(&self) -> Sign {
        self.c[0].sign().strict()
    }
    fn hull(&self, o: &Self) -> Self {
        let mut r = self.clone().zip(o.clone(), |a, b| a.hull(&b));
        r.bad = true;
        r
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Interval;

    /// Taylor coefficients of a composite function at t = 0 against closed forms
    /// computed by hand: f(t) = exp(sin(t)) has 1, 1, 1/2, 0, -1/8, -1/15.
    #[test]
    fn exp_sin_coefficients() {
        let mut t = Series::<f64, 6>::var(0.0);
        t.c[1] = 1.0;
        t.n = 6;
        let f = t.sin().exp();
        let want = [1.0, 1.0, 0.5, 0.0, -0.125, -1.0 / 15.0];
        for i in 0..6 {
            assert!((f.c[i] - want[i]).abs() < 1e-14, "{i}: {}", f.c[i]);
        }
    }

    /// atan, sqrt, tanh and division against finite-difference-free closed forms:
    /// atan(t) = t - t^3/3 + t^5/5, sqrt(1+t) = 1 + t/2 - t^2/8 + t^3/16,
    /// tanh(t) = t - t^3/3 + 2t^5/15, 1/(1-t) = sum t^i.
    #[test]
    fn elementary_series() {
        let mut t = Series::<f64, 6>::var(0.0);
        t.c[1] = 1.0;
        t.n = 6;
        let a = t.atan();
        let s = (t + 1.0).sqrt();
        let h = t.tanh();
        let d = Series::cst(1.0) / (-t + 1.0);
        let close = |x: f64, y: f64| (x - y).abs() < 1e-14;
        assert!(close(a.c[1], 1.0) && close(a.c[3], -1.0 / 3.0) && close(a.c[5], 0.2));
        assert!(close(s.c[1], 0.5) && close(s.c[2], -0.125) && close(s.c[3], 1.0 / 16.0));
        assert!(close(h.c[3], -1.0 / 3.0) && close(h.c[5], 2.0 / 15.0));
        assert!((0..6).all(|i| close(d.c[i], 1.0)));
        // ln(1 + t) = t - t^2/2 + t^3/3 - t^4/4 + t^5/5; tan(t) = t + t^3/3 + 2t^5/15.
        let l = (t + 1.0).ln();
        let want = [0.0, 1.0, -0.5, 1.0 / 3.0, -0.25, 0.2];
        assert!((0..6).all(|i| close(l.c[i], want[i])), "{:?}", l.c);
        let g = t.tan();
        assert!(close(g.c[1], 1.0) && close(g.c[3], 1.0 / 3.0) && close(g.c[5], 2.0 / 15.0));
    }

    #[test]
    fn undecided_branches_poison() {
        let x = Series::<Interval, 4>::var(Interval::new(-1.0, 1.0));
        assert!(x.abs().bad);
        let y = Series::<Interval, 4>::var(Interval::new(0.5, 1.0));
        assert!(!y.abs().bad);
        assert!(x.relu().bad);
    }
}

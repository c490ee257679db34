//! Intervals with outward rounding: the first set-valued [`Scalar`].
//!
//! `+ - * /` are computed in round-to-nearest and widened by one ulp outward
//! (`next_down`/`next_up`), which contains the exact result because IEEE 754 arithmetic
//! is correctly rounded. `sqrt` is correctly rounded too (one ulp). `exp`, `tanh`,
//! `atan`, `sin`, `cos` come from the platform's libm, whose documented error is below
//! 1 ulp for these functions on glibc; they are widened by 4 ulps. Monotone functions take
//! the images of the end points; `sin`/`cos` add +-1 when an extremum lies inside the
//! interval, with a 1e-9 margin around the extremum positions so that the rounding of
//! pi never misplaces one. Division by an interval containing 0 gives the whole line.

use crate::scalar::{Scalar, Sign};
use std::f64::consts::{FRAC_PI_2, PI};
use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

/// A closed interval `[lo, hi]` (possibly unbounded).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Interval {
    /// Lower end.
    pub lo: f64,
    /// Upper end.
    pub hi: f64,
}

use crate::round::{down as dn, down_finite as dn_finite, up, up_finite};

fn dn4(x: f64) -> f64 {
    dn(dn(dn(dn(x))))
}

fn up4(x: f64) -> f64 {
    up(up(up(up(x))))
}

/// `[dn(lo), up(hi)]`: the branch-free rounding when both ends are finite (the common
/// case), [`dn`] / [`up`] otherwise; the same floats either way.
#[inline(always)]
fn outward(lo: f64, hi: f64) -> Interval {
    if lo.is_finite() & hi.is_finite() {
        Interval {
            lo: dn_finite(lo),
            hi: up_finite(hi),
        }
    } else {
        Interval {
            lo: dn(lo),
            hi: up(hi),
        }
    }
}

/// The smaller of two floats that are not NaN (one `minsd`).
#[inline(always)]
fn min2(a: f64, b: f64) -> f64 {
    if a < b {
        a
    } else {
        b
    }
}

/// The larger of two floats that are not NaN (one `maxsd`).
#[inline(always)]
fn max2(a: f64, b: f64) -> f64 {
    if a > b {
        a
    } else {
        b
    }
}

impl Interval {
    /// `[lo, hi]`; the ends are swapped if given in the wrong order.
    pub fn new(lo: f64, hi: f64) -> Self {
        if lo <= hi {
            Interval { lo, hi }
        } else {
            Interval { lo: hi, hi: lo }
        }
    }

    /// The degenerate interval `[v, v]`.
    pub fn point(v: f64) -> Self {
        Interval { lo: v, hi: v }
    }

    /// The whole real line.
    pub fn entire() -> Self {
        Interval {
            lo: f64::NEG_INFINITY,
            hi: f64::INFINITY,
        }
    }

    /// Width `hi - lo` (rounded up).
    pub fn width(&self) -> f64 {
        up(self.hi - self.lo)
    }

    /// Whether `x` lies in the interval.
    pub fn contains(&self, x: f64) -> bool {
        self.lo <= x && x <= self.hi
    }

    fn mono(&self, f: impl Fn(f64) -> f64) -> Self {
        Interval {
            lo: dn4(f(self.lo)),
            hi: up4(f(self.hi)),
        }
    }

    /// `f` (sine or cosine) over the interval, whose maximum 1 is at `peak` and minimum
    /// -1 at `trough` (modulo 2 pi): the ends' values rounded outward, widened to the
    /// extrema the interval contains, within [-1, 1].
    fn trig(&self, f: fn(f64) -> f64, peak: f64, trough: f64) -> Self {
        if self.width() >= 2.0 * PI || !self.lo.is_finite() || !self.hi.is_finite() {
            return Interval { lo: -1.0, hi: 1.0 };
        }
        let (a, b) = (f(self.lo), f(self.hi));
        let mut lo = dn4(a.min(b));
        let mut hi = up4(a.max(b));
        if self.hits(peak) {
            hi = 1.0;
        }
        if self.hits(trough) {
            lo = -1.0;
        }
        Interval {
            lo: lo.max(-1.0),
            hi: hi.min(1.0),
        }
    }

    /// Whether `[lo, hi]` contains a point `c + 2 k pi` (with a 1e-9 margin).
    fn hits(&self, c: f64) -> bool {
        let k = ((self.lo - c) / (2.0 * PI)).ceil();
        let p = c + k * 2.0 * PI;
        p <= self.hi + 1e-9 || (p - 2.0 * PI) >= self.lo - 1e-9 && (p - 2.0 * PI) <= self.hi + 1e-9
    }
}

impl Add for Interval {
    type Output = Self;
    #[inline]
    fn add(self, o: Self) -> Self {
        outward(self.lo + o.lo, self.hi + o.hi)
    }
}
impl Sub for Interval {
    type Output = Self;
    #[inline]
    fn sub(self, o: Self) -> Self {
        outward(self.lo - o.hi, self.hi - o.lo)
    }
}
impl Mul for Interval {
    type Output = Self;
    /// The four end products, their least and greatest each rounded outward by one ulp;
    /// unbounded or NaN ends take the general path.
    ///
    /// For finite ends the four products are not NaN, and the exact product set of two
    /// intervals has its extremes among the four exact end products (the product is
    /// bilinear). Rounding to nearest is monotone, so the least (greatest) rounded
    /// product is the rounding of the least (greatest) exact one: the floats the
    /// sign-case selection (Moore's nine cases) picks, without its branches, which
    /// mispredict on mixed signs. Each is within half an ulp of its exact value, so
    /// one ulp outward (`outward`) encloses it. A zero's sign may differ from the
    /// sign-case choice, which rounding then erases (`next_down(+-0)` is the same float).
    #[inline]
    fn mul(self, o: Self) -> Self {
        let (a, b) = (self, o);
        if !(a.is_finite() & b.is_finite()) {
            return mul_general(a, b);
        }
        mul_finite(a, b)
    }
}

impl Interval {
    /// Whether both ends are finite.
    #[inline(always)]
    pub(crate) fn is_finite(&self) -> bool {
        self.lo.is_finite() & self.hi.is_finite()
    }
}

/// The product of two intervals with finite ends (the caller checks, e.g. once for all
/// the components of an interval dual): the four end products, the least and greatest
/// rounded outward ([`Mul`] for the argument).
#[inline(always)]
pub(crate) fn mul_finite(a: Interval, b: Interval) -> Interval {
    let (p1, p2, p3, p4) = (a.lo * b.lo, a.lo * b.hi, a.hi * b.lo, a.hi * b.hi);
    outward(
        min2(min2(p1, p2), min2(p3, p4)),
        max2(max2(p1, p2), max2(p3, p4)),
    )
}

/// The four-product multiplication, for unbounded or NaN ends.
fn mul_general(a: Interval, o: Interval) -> Interval {
    let p = [a.lo * o.lo, a.lo * o.hi, a.hi * o.lo, a.hi * o.hi];
    // 0 * inf is NaN: the product of a zero and an unbounded end contributes 0.
    outward_hull(p.map(|v| if v.is_nan() { 0.0 } else { v }))
}

/// The smallest interval holding the four candidate ends, each end rounded outward.
#[inline]
fn outward_hull(p: [f64; 4]) -> Interval {
    let lo = p.iter().cloned().fold(f64::INFINITY, f64::min);
    let hi = p.iter().cloned().fold(f64::NEG_INFINITY, f64::max);
    Interval {
        lo: dn(lo),
        hi: up(hi),
    }
}

impl Div for Interval {
    type Output = Self;
    #[inline]
    fn div(self, o: Self) -> Self {
        if o.lo <= 0.0 && o.hi >= 0.0 {
            return Interval::entire();
        }
        outward_hull([
            self.lo / o.lo,
            self.lo / o.hi,
            self.hi / o.lo,
            self.hi / o.hi,
        ])
    }
}
impl Neg for Interval {
    type Output = Self;
    #[inline]
    fn neg(self) -> Self {
        Interval {
            lo: -self.hi,
            hi: -self.lo,
        }
    }
}
impl Add<f64> for Interval {
    type Output = Self;
    fn add(self, o: f64) -> Self {
        self + Interval::point(o)
    }
}
impl Sub<f64> for Interval {
    type Output = Self;
    fn sub(self, o: f64) -> Self {
        self - Interval::point(o)
    }
}
impl Mul<f64> for Interval {
    type Output = Self;
    #[inline]
    fn mul(self, o: f64) -> Self {
        if !(self.lo.is_finite() && self.hi.is_finite() && o.is_finite()) {
            return mul_general(self, Interval::point(o));
        }
        let (lo, hi) = if o >= 0.0 {
            (self.lo * o, self.hi * o)
        } else {
            (self.hi * o, self.lo * o)
        };
        outward(lo, hi)
    }
}
impl Div<f64> for Interval {
    type Output = Self;
    /// `self / [o, o]`: for finite ends and a finite nonzero `o` the two quotients of
    /// the ends (division by a point is monotone, decreasing for `o < 0`), rounded
    /// outward; the same floats as the four-quotient hull, which the other cases take.
    #[inline]
    fn div(self, o: f64) -> Self {
        if !(self.lo.is_finite() & self.hi.is_finite() & o.is_finite()) || o == 0.0 {
            return self / Interval::point(o);
        }
        let (lo, hi) = if o > 0.0 {
            (self.lo / o, self.hi / o)
        } else {
            (self.hi / o, self.lo / o)
        };
        outward(lo, hi)
    }
}
impl AddAssign for Interval {
    #[inline]
    fn add_assign(&mut self, o: Self) {
        *self = *self + o;
    }
}
impl SubAssign for Interval {
    #[inline]
    fn sub_assign(&mut self, o: Self) {
        *self = *self - o;
    }
}
impl MulAssign for Interval {
    #[inline]
    fn mul_assign(&mut self, o: Self) {
        *self = *self * o;
    }
}

impl Scalar for Interval {
    fn cst(c: f64) -> Self {
        Interval::point(c)
    }
    fn value(&self) -> f64 {
        0.5 * (self.lo + self.hi)
    }
    fn sin(&self) -> Self {
        self.trig(f64::sin, FRAC_PI_2, -FRAC_PI_2)
    }
    fn cos(&self) -> Self {
        self.trig(f64::cos, 0.0, PI)
    }
    fn tanh(&self) -> Self {
        let r = self.mono(f64::tanh);
        Interval {
            lo: r.lo.max(-1.0),
            hi: r.hi.min(1.0),
        }
    }
    fn atan(&self) -> Self {
        let r = self.mono(f64::atan);
        Interval {
            lo: r.lo.max(-FRAC_PI_2.next_up()),
            hi: r.hi.min(FRAC_PI_2.next_up()),
        }
    }
    fn sqrt(&self) -> Self {
        if self.hi < 0.0 {
            return Interval {
                lo: f64::NAN,
                hi: f64::NAN,
            };
        }
        Interval {
            lo: dn(self.lo.max(0.0).sqrt()).max(0.0),
            hi: up(self.hi.sqrt()),
        }
    }
    fn exp(&self) -> Self {
        let r = self.mono(f64::exp);
        Interval {
            lo: r.lo.max(0.0),
            hi: r.hi,
        }
    }
    fn ln(&self) -> Self {
        // glibc's log is correctly rounded to < 1 ulp; widened by 4 ulps like exp.
        if self.hi.is_nan() || self.hi <= 0.0 {
            return Interval {
                lo: f64::NAN,
                hi: f64::NAN,
            };
        }
        let lo = if self.lo > 0.0 {
            dn4(self.lo.ln())
        } else {
            f64::NEG_INFINITY
        };
        Interval {
            lo,
            hi: up4(self.hi.ln()),
        }
    }
    fn tan(&self) -> Self {
        // Increasing between the poles pi/2 + k pi. Beyond |x| = 1e6 the rounding of
        // k pi could misplace a pole by more than the 1e-9 margin: the whole line.
        let far = |v: f64| v.is_nan() || v.abs() > 1e6;
        if far(self.lo) || far(self.hi) || self.width() >= PI {
            return Interval::entire();
        }
        let k = ((self.lo - FRAC_PI_2) / PI).ceil();
        let pole = FRAC_PI_2 + k * PI; // the first pole at or above lo (up to rounding)
        if pole <= self.hi + 1e-9 || pole - PI >= self.lo - 1e-9 {
            return Interval::entire();
        }
        self.mono(f64::tan)
    }
    fn abs(&self) -> Self {
        if self.lo >= 0.0 {
            *self
        } else if self.hi <= 0.0 {
            -*self
        } else {
            Interval {
                lo: 0.0,
                hi: self.hi.max(-self.lo),
            }
        }
    }
    fn sqr(&self) -> Self {
        let a = self.abs();
        Interval {
            lo: dn(a.lo * a.lo).max(0.0),
            hi: up(a.hi * a.hi),
        }
    }
    fn sign(&self) -> Sign {
        if self.lo > 0.0 {
            Sign::Positive
        } else if self.hi < 0.0 {
            Sign::Negative
        } else if self.lo == 0.0 && self.hi == 0.0 {
            Sign::Zero
        } else if self.lo >= 0.0 {
            Sign::NonNegative
        } else if self.hi <= 0.0 {
            Sign::NonPositive
        } else {
            Sign::Mixed
        }
    }
    fn hull(&self, o: &Self) -> Self {
        Interval {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
        }
    }
    fn relu(&self) -> Self {
        Interval {
            lo: self.lo.max(0.0),
            hi: self.hi.max(0.0),
        }
    }
    fn clamp_to(&self, lo: f64, hi: f64) -> Self {
        Interval {
            lo: self.lo.max(lo).min(hi),
            hi: self.hi.max(lo).min(hi),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn sample(i: &Interval, t: f64) -> f64 {
        i.lo + (i.hi - i.lo) * t
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]
        #[test]
        fn every_operation_contains_its_point_results(
            a in -50.0f64..50.0, wa in 0.0f64..3.0, b in -50.0f64..50.0, wb in 0.0f64..3.0,
            s in 0.0f64..=1.0, t in 0.0f64..=1.0,
        ) {
            let (x, y) = (Interval::new(a, a + wa), Interval::new(b, b + wb));
            let (u, v) = (sample(&x, s), sample(&y, t));
            prop_assert!((x + y).contains(u + v));
            prop_assert!((x - y).contains(u - v));
            prop_assert!((x * y).contains(u * v));
            if !(y.lo <= 0.0 && y.hi >= 0.0) {
                prop_assert!((x / y).contains(u / v));
            }
            prop_assert!(x.sin().contains(u.sin()), "sin {x:?} at {u}");
            prop_assert!(x.cos().contains(u.cos()), "cos {x:?} at {u}");
            prop_assert!(x.tanh().contains(u.tanh()));
            prop_assert!(x.atan().contains(u.atan()));
            prop_assert!((x * 0.1).exp().contains((u * 0.1).exp()));
            prop_assert!(x.abs().contains(u.abs()));
            prop_assert!(x.sqr().contains(u * u));
            let p = Interval::new(a.abs(), a.abs() + wa);
            prop_assert!(p.sqrt().contains(sample(&p, s).sqrt()));
            if p.lo > 0.0 {
                prop_assert!(p.ln().contains(sample(&p, s).ln()));
            }
            let (w, z) = (x * 0.05, y * 0.05);
            prop_assert!(w.tan().contains((u * 0.05).tan()), "tan {w:?} at {}", u * 0.05);
            prop_assert!(x.tan().contains(u.tan()) || x.tan() == Interval::entire());
            prop_assert!(x.smin(&y).contains(u.min(v)));
            prop_assert!(x.smax(&y).contains(u.max(v)));
            let sg = x.sgn();
            let su = if u > 0.0 { 1.0 } else if u < 0.0 { -1.0 } else { 0.0 };
            prop_assert!(sg.contains(su));
            prop_assert!(z.tan().contains((v * 0.05).tan()));
        }
    }

    /// ln and tan against f64 on a grid: every point value lies in the enclosure of a
    /// small interval around it, and the enclosure is tight (a few ulps).
    #[test]
    fn ln_tan_grid_against_f64() {
        for i in 0..4000 {
            let x = -6.0 + 12.0 * i as f64 / 3999.0;
            let xi = Interval::new(x, x.next_up().next_up());
            let t = xi.tan();
            if t != Interval::entire() {
                assert!(t.contains(x.tan()), "tan at {x}: {t:?}");
                assert!(t.hi - t.lo <= 1e-12 * (1.0 + x.tan().abs() * (1.0 + x.tan().abs())));
            }
            // Near a pole the enclosure is the whole line.
            let p = Interval::new(FRAC_PI_2 - 1e-12, FRAC_PI_2 + 1e-12);
            assert_eq!(p.tan(), Interval::entire());
            let y = 1e-3 + 50.0 * i as f64 / 3999.0;
            let yi = Interval::point(y);
            let l = yi.ln();
            assert!(l.contains(y.ln()) && l.hi - l.lo <= 1e-14 * (1.0 + y.ln().abs()));
        }
        assert_eq!(Interval::new(0.0, 1.0).ln().lo, f64::NEG_INFINITY);
        assert!(Interval::new(-2.0, -1.0).ln().lo.is_nan());
        assert_eq!(Interval::new(-1.0, 2.0).sgn(), Interval::new(-1.0, 1.0));
        assert_eq!(Interval::new(0.0, 2.0).sgn(), Interval::new(0.0, 1.0));
        assert_eq!(Interval::new(3.0, 4.0).sgn(), Interval::point(1.0));
    }

    /// The branch-free rounding is `f64::next_up` / `next_down` on every finite float:
    /// random bit patterns (every binade, subnormals) and the edge cases.
    #[test]
    fn trigonometric_extrema_and_signs() {
        let i = Interval::new(1.0, 2.0); // contains pi/2
        assert_eq!(i.sin().hi, 1.0);
        let j = Interval::new(3.0, 3.5); // contains pi
        assert_eq!(j.cos().lo, -1.0);
        assert_eq!(Interval::new(-1.0, 1.0).sign(), Sign::Mixed);
        assert_eq!(Interval::new(0.0, 1.0).sign(), Sign::NonNegative);
        assert_eq!(Interval::new(-1.0, 1.0).relu(), Interval::new(0.0, 1.0));
        assert_eq!(
            Interval::new(0.1, 0.3).clamp_to(0.181, 0.193),
            Interval::new(0.181, 0.193)
        );
        // Outward rounding: 0.1 + 0.2 is not representable; the interval brackets it.
        let s = Interval::point(0.1) + Interval::point(0.2);
        assert!(s.lo < 0.30000000000000004 && s.hi > 0.3);
    }
}

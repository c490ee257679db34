use std::fmt::Debug;
use std::ops::{Add, AddAssign, Div, Mul, MulAssign, Neg, Sub, SubAssign};

/// Three-way outcome of comparing a number (or a set of numbers) with zero.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sign {
    /// Every value is `< 0`.
    Negative,
    /// Every value is `== 0`.
    Zero,
    /// Every value is `> 0`.
    Positive,
    /// Every value is `<= 0` and some may be zero (sets only).
    NonPositive,
    /// Every value is `>= 0` and some may be zero (sets only).
    NonNegative,
    /// The set straddles zero: the comparison is undecided.
    Mixed,
}

impl Sign {
    /// Decided only when every value is strictly positive or strictly negative, else
    /// [`Sign::Mixed`]: the test on which truncated series (and the incremental Taylor
    /// expansion that must agree with them) take a branch, since a branch at a zero
    /// of its condition need not be analytic there.
    pub fn strict(self) -> Sign {
        match self {
            Sign::Positive | Sign::Negative => self,
            _ => Sign::Mixed,
        }
    }
}

/// A number type the plant and network equations can run on.
///
/// Required: field arithmetic (by value, with `f64` on the right), the elementary
/// functions the glider model needs, a constant constructor, a sign test and a hull.
/// Not required: ordering. A point type (f64, [`crate::Dual`]) never answers
/// [`Sign::Mixed`], so [`Scalar::hull`] is only reached by set-valued types.
pub trait Scalar:
    Clone
    + Debug
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + Add<f64, Output = Self>
    + Sub<f64, Output = Self>
    + Mul<f64, Output = Self>
    + Div<f64, Output = Self>
    + AddAssign
    + SubAssign
    + MulAssign
{
    /// The constant `c` in this number type (zero derivative, degenerate set).
    fn cst(c: f64) -> Self;
    /// A representative point value (the value of a dual, the midpoint of a set).
    fn value(&self) -> f64;
    /// Sine.
    fn sin(&self) -> Self;
    /// Cosine.
    fn cos(&self) -> Self;
    /// Sine and cosine together (one argument reduction for f64).
    fn sin_cos(&self) -> (Self, Self) {
        (self.sin(), self.cos())
    }
    /// Hyperbolic tangent.
    fn tanh(&self) -> Self;
    /// Arc tangent (principal branch, values in (-pi/2, pi/2)).
    fn atan(&self) -> Self;
    /// Square root; the argument must be non-negative.
    fn sqrt(&self) -> Self;
    /// Exponential.
    fn exp(&self) -> Self;
    /// Absolute value.
    fn abs(&self) -> Self;
    /// Natural logarithm; the argument must be positive (sets: the part `<= 0` gives
    /// an unbounded lower end).
    fn ln(&self) -> Self;
    /// Tangent. The default `sin / cos` is sound for every type (a set containing a
    /// pole divides by a set containing 0, which is the whole line); types may do better.
    fn tan(&self) -> Self {
        self.sin() / self.cos()
    }
    /// Three-way sign as a number: -1, 0 or 1 exactly for points; for a set straddling
    /// a jump, the hull of the values it can take (e.g. `[-1, 1]`).
    fn sgn(&self) -> Self {
        match self.sign() {
            Sign::Positive => Self::cst(1.0),
            Sign::Negative => Self::cst(-1.0),
            Sign::Zero => Self::cst(0.0),
            Sign::NonNegative => Self::cst(0.0).hull(&Self::cst(1.0)),
            Sign::NonPositive => Self::cst(-1.0).hull(&Self::cst(0.0)),
            Sign::Mixed => Self::cst(-1.0).hull(&Self::cst(1.0)),
        }
    }
    /// `min(self, other)`: exact for points (`self` on ties), the hull of both
    /// operands when the order of two sets is undecided (which encloses the minimum).
    fn smin(&self, other: &Self) -> Self {
        match (self.clone() - other.clone()).sign() {
            Sign::Negative | Sign::Zero | Sign::NonPositive => self.clone(),
            Sign::Positive | Sign::NonNegative => other.clone(),
            Sign::Mixed => self.hull(other),
        }
    }
    /// `max(self, other)`: exact for points (`self` on ties), the hull of both
    /// operands when the order of two sets is undecided (which encloses the maximum).
    fn smax(&self, other: &Self) -> Self {
        match (self.clone() - other.clone()).sign() {
            Sign::Positive | Sign::Zero | Sign::NonNegative => self.clone(),
            Sign::Negative | Sign::NonPositive => other.clone(),
            Sign::Mixed => self.hull(other),
        }
    }
    /// The product `self * o` of two borrowed values: the same number as the product
    /// by value, without copying the operands first (types whose values own their
    /// storage, such as Taylor models, multiply by reference).
    fn mul_by_ref(&self, o: &Self) -> Self {
        self.clone() * o.clone()
    }
    /// The sum `self + o` of two borrowed values: the same number as the sum by value,
    /// without copying the second operand (Taylor models add it into a copy of the
    /// first by reference).
    fn add_by_ref(&self, o: &Self) -> Self {
        self.clone() + o.clone()
    }
    /// The difference `self - o` of two borrowed values, as [`Scalar::add_by_ref`].
    fn sub_by_ref(&self, o: &Self) -> Self {
        self.clone() - o.clone()
    }
    /// The quotient `self / o` with the divisor borrowed: the same number as the
    /// quotient by value (Taylor models keep the divisor's reciprocal for the next
    /// quotient by the same divisor, which a series' recurrence takes at every order).
    fn div_by_ref(self, o: &Self) -> Self {
        self / o.clone()
    }
    /// The order past which this value's products are truncated (Taylor models:
    /// their order; `u32::MAX` for types that keep everything).
    fn trunc_order(&self) -> u32 {
        u32::MAX
    }
    /// `self * o` truncated at order `cap` at the latest (an enclosure of the product,
    /// as [`Scalar::mul_by_ref`]): a sum of products that ends at order `cap` (the
    /// smallest of its terms' [`Scalar::trunc_order`]) need not compute its terms
    /// past it. Types without orders multiply as [`Scalar::mul_by_ref`].
    fn mul_capped(&self, o: &Self, cap: u32) -> Self {
        let _ = cap;
        self.mul_by_ref(o)
    }
    /// `sum_{j in lo..=i} a_j b_{i-j}`, each product truncated at order `cap` (the sums
    /// of products of the series recurrences, `series::conv`): by default the products
    /// one by one ([`Scalar::mul_capped`]), each added to the sum of the earlier ones.
    /// Types may sum them otherwise (Taylor models: into one vector).
    fn conv_capped(a: &[Self], b: &[Self], lo: usize, i: usize, cap: u32) -> Self {
        let mut acc = a[lo].mul_capped(&b[i - lo], cap);
        for j in lo + 1..=i {
            acc += a[j].mul_capped(&b[i - j], cap);
        }
        acc
    }
    /// Square, `x * x` (types may do better, e.g. intervals).
    fn sqr(&self) -> Self {
        self.clone() * self.clone()
    }
    /// Integer power by repeated squaring.
    fn powi(&self, n: u32) -> Self {
        let mut acc = Self::cst(1.0);
        let mut base = self.clone();
        let mut k = n;
        while k > 0 {
            if k & 1 == 1 {
                acc *= base.clone();
            }
            k >>= 1;
            if k > 0 {
                base = base.sqr();
            }
        }
        acc
    }
    /// Logistic sigmoid `1 / (1 + exp(-x))`, written through tanh for stability.
    fn sigmoid(&self) -> Self {
        (self.clone() * 0.5).tanh() * 0.5 + 0.5
    }
    /// Three-way sign of the number (or set).
    fn sign(&self) -> Sign;
    /// The smallest number of this type containing both `self` and `other`.
    /// Point types return `self` (they never need a hull; see [`Sign`]).
    fn hull(&self, other: &Self) -> Self;
    /// Sign of `self - c`.
    fn sign_minus(&self, c: f64) -> Sign {
        (self.clone() - c).sign()
    }
    /// `max(self, 0)`: the ReLU, exact for points, an enclosure for sets.
    fn relu(&self) -> Self {
        match self.sign() {
            Sign::Positive | Sign::NonNegative | Sign::Zero => self.clone(),
            Sign::Negative | Sign::NonPositive => Self::cst(0.0),
            Sign::Mixed => self.hull(&Self::cst(0.0)),
        }
    }
    /// Clamp into `[lo, hi]`, exact for points, an enclosure for sets.
    fn clamp_to(&self, lo: f64, hi: f64) -> Self {
        let low = match self.sign_minus(lo) {
            Sign::Negative | Sign::Zero => return Self::cst(lo),
            Sign::NonPositive => Self::cst(lo),
            Sign::Positive | Sign::NonNegative => self.clone(),
            Sign::Mixed => self.hull(&Self::cst(lo)),
        };
        match low.sign_minus(hi) {
            Sign::Positive | Sign::Zero => Self::cst(hi),
            Sign::NonNegative => Self::cst(hi),
            Sign::Negative | Sign::NonPositive => low,
            Sign::Mixed => low.hull(&Self::cst(hi)),
        }
    }
}

impl Scalar for f64 {
    #[inline(always)]
    fn cst(c: f64) -> Self {
        c
    }
    #[inline(always)]
    fn value(&self) -> f64 {
        *self
    }
    #[inline(always)]
    fn sin(&self) -> Self {
        f64::sin(*self)
    }
    #[inline(always)]
    fn cos(&self) -> Self {
        f64::cos(*self)
    }
    #[inline(always)]
    fn sin_cos(&self) -> (Self, Self) {
        f64::sin_cos(*self)
    }
    #[inline(always)]
    fn tanh(&self) -> Self {
        f64::tanh(*self)
    }
    #[inline(always)]
    fn atan(&self) -> Self {
        f64::atan(*self)
    }
    #[inline(always)]
    fn sqrt(&self) -> Self {
        f64::sqrt(*self)
    }
    #[inline(always)]
    fn exp(&self) -> Self {
        f64::exp(*self)
    }
    #[inline(always)]
    fn abs(&self) -> Self {
        f64::abs(*self)
    }
    #[inline(always)]
    fn ln(&self) -> Self {
        f64::ln(*self)
    }
    #[inline(always)]
    fn tan(&self) -> Self {
        f64::tan(*self)
    }
    #[inline(always)]
    fn sqr(&self) -> Self {
        *self * *self
    }
    #[inline(always)]
    fn sigmoid(&self) -> Self {
        1.0 / (1.0 + f64::exp(-*self))
    }
    #[inline(always)]
    fn sign(&self) -> Sign {
        if *self < 0.0 {
            Sign::Negative
        } else if *self > 0.0 {
            Sign::Positive
        } else if *self == 0.0 {
            Sign::Zero
        } else {
            // NaN: undecided. Point types never hull, so callers get NaN through.
            Sign::Mixed
        }
    }
    #[inline(always)]
    fn hull(&self, _other: &Self) -> Self {
        *self
    }
    #[inline(always)]
    fn sign_minus(&self, c: f64) -> Sign {
        (*self - c).sign()
    }
    /// NaN stays NaN (`f64::max(NaN, 0)` would be 0: a NaN input would come out as a
    /// number).
    #[inline(always)]
    fn relu(&self) -> Self {
        if *self <= 0.0 {
            0.0
        } else {
            *self
        }
    }
    /// NaN stays NaN (see [`Scalar::relu`]).
    #[inline(always)]
    fn clamp_to(&self, lo: f64, hi: f64) -> Self {
        if self.is_nan() {
            *self
        } else {
            self.max(lo).min(hi)
        }
    }
    /// NaN in either operand gives NaN.
    #[inline(always)]
    fn smin(&self, other: &Self) -> Self {
        if self.is_nan() || other.is_nan() {
            f64::NAN
        } else if *self <= *other {
            *self
        } else {
            *other
        }
    }
    /// NaN in either operand gives NaN.
    #[inline(always)]
    fn smax(&self, other: &Self) -> Self {
        if self.is_nan() || other.is_nan() {
            f64::NAN
        } else if *self >= *other {
            *self
        } else {
            *other
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn powi_matches_std() {
        for n in 0..9u32 {
            let x = 1.37_f64;
            let a = Scalar::powi(&x, n);
            let b = x.powi(n as i32);
            assert!((a - b).abs() <= 1e-15 * b.abs(), "n={n}: {a} vs {b}");
        }
    }

    #[test]
    fn clamp_and_relu_points() {
        assert_eq!(Scalar::clamp_to(&0.2, 0.181, 0.193), 0.193);
        assert_eq!(Scalar::clamp_to(&0.1, 0.181, 0.193), 0.181);
        assert_eq!(Scalar::clamp_to(&0.185, 0.181, 0.193), 0.185);
        assert_eq!(Scalar::relu(&-2.0), 0.0);
        assert_eq!(Scalar::relu(&2.0), 2.0);
        assert_eq!(Scalar::sign(&f64::NAN), Sign::Mixed);
        // NaN propagates (issue 35: f64::max(0, NaN) is 0).
        assert!(Scalar::relu(&f64::NAN).is_nan());
        assert!(Scalar::clamp_to(&f64::NAN, 0.181, 0.193).is_nan());
        assert!(Scalar::smax(&1.0, &f64::NAN).is_nan());
        assert!(Scalar::smax(&f64::NAN, &1.0).is_nan());
        assert!(Scalar::smin(&1.0, &f64::NAN).is_nan());
        assert_eq!(Scalar::relu(&f64::INFINITY), f64::INFINITY);
        assert_eq!(Scalar::relu(&-0.0), 0.0);
    }

    #[test]
    fn sgn_min_max_points() {
        assert_eq!(Scalar::sgn(&-3.0), -1.0);
        assert_eq!(Scalar::sgn(&0.0), 0.0);
        assert_eq!(Scalar::sgn(&2.5), 1.0);
        assert_eq!(Scalar::smin(&1.0, &2.0), 1.0);
        assert_eq!(Scalar::smin(&3.0, &2.0), 2.0);
        assert_eq!(Scalar::smax(&1.0, &2.0), 2.0);
        assert_eq!(Scalar::smax(&3.0, &-2.0), 3.0);
        assert_eq!(Scalar::ln(&1.0), 0.0);
        assert_eq!(Scalar::tan(&0.5), 0.5f64.tan());
    }

    #[test]
    fn sigmoid_default_matches_f64() {
        for &x in &[-30.0, -2.0, 0.0, 0.7, 12.0] {
            let via_tanh = (x * 0.5_f64).tanh() * 0.5 + 0.5;
            assert!((Scalar::sigmoid(&x) - via_tanh).abs() < 1e-15);
        }
    }
}

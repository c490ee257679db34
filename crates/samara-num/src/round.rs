//! Outward rounding: the one place where samara's sound bounds widen a float computed in
//! round-to-nearest (IEEE 754 binary64, the platform default, which Rust never changes).
//!
//! Every bound routine (intervals, Taylor models, the CROWN and interval passes of
//! `samara-bounds`, zonotopes in `samara-reach`, the LP certificates of `samara-verify`)
//! takes its directed rounding and its summation error factor from here, so there is one
//! definition to review. The conventions:
//!
//! * [`up`] / [`down`] move a float one ulp outward. A NaN becomes `+inf` / `-inf` (the
//!   widest sound answer), and infinities move like any float (`next_up(-inf) = -MAX`):
//!   a sum that overflowed to `-inf` in round-to-nearest may stand for a finite exact
//!   value, so an upper bound must not stay at `-inf`. [`up_finite`] / [`down_finite`]
//!   are the same floats without branches, for callers that know the float is finite.
//! * [`gamma`] is the relative error factor of a sum or dot product of `k` terms,
//!   `(k + 2) u'` with `u' = 2^-52`: at least twice Higham's `gamma_k = k u / (1 - k u)`
//!   (`u = 2^-53`; Higham, *Accuracy and Stability of Numerical Algorithms*, 2nd ed.,
//!   2002, sec. 3.1) for every `k` below `2^50`.
//! * [`sum_up`] / [`sum_dn`] bound `a + b` by Knuth's TwoSum (exact in round-to-nearest),
//!   stepping one ulp only when the float sum is inexact in the wrong direction.

/// Unit roundoff of binary64 in round-to-nearest, `2^-53`.
pub const UNIT_ROUNDOFF: f64 = f64::EPSILON * 0.5;

/// The next float above `x` (an upper bound of any real that rounds to `x`); NaN gives
/// `+inf`.
#[inline(always)]
pub fn up(x: f64) -> f64 {
    if x.is_nan() {
        f64::INFINITY
    } else {
        x.next_up()
    }
}

/// The next float below `x` (a lower bound of any real that rounds to `x`); NaN gives
/// `-inf`.
#[inline(always)]
pub fn down(x: f64) -> f64 {
    if x.is_nan() {
        f64::NEG_INFINITY
    } else {
        x.next_down()
    }
}

/// `x.next_up()` for a finite `x`, without branches: the same float as
/// [`f64::next_up`] (and so as [`up`]) on every finite input.
///
/// `x + 0.0` maps `-0` to `+0` and leaves every other finite float unchanged (IEEE 754:
/// a sum is exact when it is representable, and `-0 + +0 = +0` in round-to-nearest).
/// For the bit pattern `b` of a finite float of sign bit `s`, the next float above is
/// `b + 1` when `s = 0` (a larger magnitude, `+0` giving the smallest subnormal and `MAX`
/// giving `+inf`) and `b - 1` when `s = 1` (a smaller magnitude, the smallest negative
/// subnormal giving `-0`), i.e. `b + 1 - 2 s`, which is what [`f64::next_up`] computes on
/// the same inputs. Callers test finiteness first (NaN and `+inf` would not map right).
#[inline(always)]
pub fn up_finite(x: f64) -> f64 {
    let b = (x + 0.0).to_bits();
    f64::from_bits(b.wrapping_add(1).wrapping_sub((b >> 63) << 1))
}

/// `x.next_down()` for a finite `x`, without branches: `-(-x).next_up()`, which is how
/// [`f64::next_down`] is defined ([`up_finite`]).
#[inline(always)]
pub fn down_finite(x: f64) -> f64 {
    -up_finite(-x)
}

/// Relative error factor of a recursive sum or dot product of `k` rounded terms,
/// `(k + 2) * 2^-52`: at least twice Higham's `gamma_k` (module documentation).
#[inline]
pub fn gamma(k: usize) -> f64 {
    (k as f64 + 2.0) * f64::EPSILON
}

/// A non-negative error term raised by a relative `1e-9` and rounded up, so that the
/// float evaluation of the term itself cannot make it too small.
#[inline]
pub fn inflate(e: f64) -> f64 {
    up(e * (1.0 + 1e-9))
}

/// Upper bound of the exact `a + b`: the float sum, raised by one ulp only when TwoSum
/// shows it is below the exact sum. A NaN sum gives `+inf`.
#[inline(always)]
pub fn sum_up(a: f64, b: f64) -> f64 {
    let s = a + b;
    if !s.is_finite() {
        return if s.is_nan() {
            f64::INFINITY
        } else {
            s.max(f64::MIN)
        };
    }
    let bb = s - a;
    let e = (a - (s - bb)) + (b - bb);
    if e > 0.0 {
        s.next_up()
    } else {
        s
    }
}

/// Lower bound of the exact `a + b` (see [`sum_up`]). A NaN sum gives `-inf`.
#[inline(always)]
pub fn sum_dn(a: f64, b: f64) -> f64 {
    let s = a + b;
    if !s.is_finite() {
        return if s.is_nan() {
            f64::NEG_INFINITY
        } else {
            s.min(f64::MAX)
        };
    }
    let bb = s - a;
    let e = (a - (s - bb)) + (b - bb);
    if e < 0.0 {
        s.next_down()
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn branch_free_rounding_is_next_up_and_next_down() {
        let mut s = 0x2545_f491_4f6c_dd1du64;
        let mut edge = vec![0.0, -0.0, f64::MAX, f64::MIN, f64::MIN_POSITIVE, 1.0, -1.0];
        edge.extend([
            f64::from_bits(1),
            -f64::from_bits(1),
            f64::from_bits(0xf_ffff),
        ]);
        for i in 0..200_000 {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            let x = match edge.get(i) {
                Some(&e) => e,
                None if i % 3 == 0 => f64::from_bits(s >> 12) * if s & 1 == 0 { 1.0 } else { -1.0 },
                None => f64::from_bits(s),
            };
            if !x.is_finite() {
                continue;
            }
            assert_eq!(up_finite(x).to_bits(), x.next_up().to_bits(), "up {x:e}");
            assert_eq!(
                down_finite(x).to_bits(),
                x.next_down().to_bits(),
                "down {x:e}"
            );
        }
    }

    /// Exact comparisons through `i128` arithmetic on integers scaled by a power of two:
    /// the bounds hold for random sums whose exact value is known independently.
    #[test]
    fn sums_are_bounded_against_exact_integer_arithmetic() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for _ in 0..100_000 {
            // a, b: integers times 2^-60, so that their exact sum is an integer times 2^-60.
            let ia = (next() >> 8) as i64 - (1i64 << 55);
            let ib = (next() >> 30) as i64 - (1i64 << 33);
            let (a, b) = (ia as f64 * 2f64.powi(-60), ib as f64 * 2f64.powi(-60));
            // Recover the integers the floats hold exactly (they may have been rounded).
            let (ea, eb) = ((a * 2f64.powi(60)) as i128, (b * 2f64.powi(60)) as i128);
            let exact = ea + eb;
            let hi = sum_up(a, b);
            let lo = sum_dn(a, b);
            // hi * 2^60 and lo * 2^60 are exact in f64 (power-of-two scaling).
            // Truncation toward zero keeps both comparisons conservative.
            assert!((hi * 2f64.powi(60)) as i128 >= exact);
            assert!((lo * 2f64.powi(60)) as i128 <= exact);
            assert!(up(a) > a && down(a) < a);
        }
    }

    #[test]
    fn nan_and_overflow_round_outward() {
        assert_eq!(up(f64::NAN), f64::INFINITY);
        assert_eq!(down(f64::NAN), f64::NEG_INFINITY);
        // -inf from an overflow may stand for a finite value: its upper bound is finite.
        assert_eq!(up(f64::NEG_INFINITY), f64::MIN);
        assert_eq!(down(f64::INFINITY), f64::MAX);
        assert_eq!(sum_up(f64::MIN, f64::MIN), f64::MIN);
        assert_eq!(sum_dn(f64::MAX, f64::MAX), f64::MAX);
        assert_eq!(sum_up(f64::INFINITY, f64::NEG_INFINITY), f64::INFINITY);
        assert!(gamma(10) >= 2.0 * 10.0 * UNIT_ROUNDOFF / (1.0 - 10.0 * UNIT_ROUNDOFF));
    }
}

//! The interval product, sum, difference and division by a point against exact rational
//! arithmetic (`num-rational`), at 100,000 random pairs of intervals whose ends mix
//! random bit patterns (normal and subnormal), zeros of both signs, small integers,
//! powers of two near the overflow and underflow thresholds, and infinities.
//!
//! For every pair the exact products (quotients, sums) of the ends and of random
//! points inside lie in the computed interval, and each finite end is within two ulps of
//! the exact extreme (one rounding to nearest, one ulp outward). The product and the
//! division by a point are also compared float for float with the previous
//! implementation (Moore's nine sign cases, the four-quotient hull), which the
//! branch-free forms must reproduce.

use num_rational::BigRational;
use samara_num::Interval;

use crate::support::Rng;

/// The rounding cases on top of the shared generator.
impl Rng {
    /// A float from a mix of the cases that matter to rounding.
    fn float(&mut self) -> f64 {
        let sign = if self.next_u64() & 1 == 0 { 1.0 } else { -1.0 };
        match self.next_u64() % 10 {
            // Any finite bit pattern (mostly huge or tiny magnitudes).
            0 => loop {
                let x = f64::from_bits(self.next_u64());
                if x.is_finite() {
                    break x;
                }
            },
            // Subnormals.
            1 => sign * f64::from_bits(self.next_u64() >> 12),
            2 => sign * 0.0,
            3 => sign * (self.next_u64() % 7) as f64,
            // Near the overflow threshold (products overflow) and the underflow one.
            4 => sign * 2f64.powi(500 + (self.next_u64() % 524) as i32) * (1.0 + self.unit()),
            5 => sign * 2f64.powi(-540 - (self.next_u64() % 480) as i32) * (1.0 + self.unit()),
            6 => sign * f64::INFINITY,
            // Moderate values, the common case.
            _ => sign * 10f64.powi((self.next_u64() % 9) as i32 - 4) * self.unit(),
        }
    }
    fn interval(&mut self) -> Interval {
        Interval::new(self.float(), self.float())
    }
    /// A finite point of `x`: an end, or a random point between them.
    fn point_in(&mut self, x: Interval) -> Option<f64> {
        let lo = if x.lo.is_finite() { x.lo } else { f64::MIN };
        let hi = if x.hi.is_finite() { x.hi } else { f64::MAX };
        let p = match self.next_u64() % 3 {
            0 => lo,
            1 => hi,
            _ => lo + (hi - lo) * self.unit(),
        };
        (p.is_finite() && x.contains(p)).then_some(p)
    }
}

fn q(x: f64) -> BigRational {
    BigRational::from_float(x).expect("finite")
}

/// `lo <= v <= hi` for the exact value `v` (infinite ends bound everything).
fn encloses(r: Interval, v: &BigRational) -> bool {
    let lo_ok = r.lo == f64::NEG_INFINITY || (r.lo.is_finite() && q(r.lo) <= *v);
    let hi_ok = r.hi == f64::INFINITY || (r.hi.is_finite() && q(r.hi) >= *v);
    lo_ok && hi_ok
}

/// Each finite end within two ulps of the exact extreme `lo_x` / `hi_x`: moving the end
/// two floats inward crosses it.
fn tight(r: Interval, lo_x: &BigRational, hi_x: &BigRational) -> bool {
    let lo_ok = !r.lo.is_finite() || {
        let inner = r.lo.next_up().next_up();
        !inner.is_finite() || q(inner) > *lo_x
    };
    let hi_ok = !r.hi.is_finite() || {
        let inner = r.hi.next_down().next_down();
        !inner.is_finite() || q(inner) < *hi_x
    };
    lo_ok && hi_ok
}

/// The product as it was computed before (Moore's nine sign cases, one ulp outward).
fn mul_sign_cases(a: Interval, b: Interval) -> Interval {
    let (lo, hi) = if a.lo >= 0.0 {
        if b.lo >= 0.0 {
            (a.lo * b.lo, a.hi * b.hi)
        } else if b.hi <= 0.0 {
            (a.hi * b.lo, a.lo * b.hi)
        } else {
            (a.hi * b.lo, a.hi * b.hi)
        }
    } else if a.hi <= 0.0 {
        if b.lo >= 0.0 {
            (a.lo * b.hi, a.hi * b.lo)
        } else if b.hi <= 0.0 {
            (a.hi * b.hi, a.lo * b.lo)
        } else {
            (a.lo * b.hi, a.lo * b.lo)
        }
    } else if b.lo >= 0.0 {
        (a.lo * b.hi, a.hi * b.hi)
    } else if b.hi <= 0.0 {
        (a.hi * b.lo, a.lo * b.lo)
    } else {
        (
            (a.lo * b.hi).min(a.hi * b.lo),
            (a.lo * b.lo).max(a.hi * b.hi),
        )
    };
    let up = |x: f64| {
        if x.is_nan() {
            f64::INFINITY
        } else {
            x.next_up()
        }
    };
    let dn = |x: f64| {
        if x.is_nan() {
            f64::NEG_INFINITY
        } else {
            x.next_down()
        }
    };
    Interval {
        lo: dn(lo),
        hi: up(hi),
    }
}

fn finite(x: Interval) -> bool {
    x.lo.is_finite() && x.hi.is_finite()
}

#[test]
fn products_sums_and_quotients_enclose_the_exact_values() {
    let mut rng = Rng(0x49_5eed);
    let (mut checked, mut compared) = (0usize, 0usize);
    for _ in 0..100_000 {
        let (x, y) = (rng.interval(), rng.interval());
        let p = x * y;
        if finite(x) && finite(y) {
            // The same floats as the sign cases, and tight around the exact extremes.
            assert_eq!(p, mul_sign_cases(x, y), "{x:?} * {y:?}");
            compared += 1;
            let ends = [x.lo, x.hi].map(q);
            let ys = [y.lo, y.hi].map(q);
            let prods: Vec<BigRational> = ends
                .iter()
                .flat_map(|a| ys.iter().map(move |b| a * b))
                .collect();
            let lo = prods.iter().min().expect("four").clone();
            let hi = prods.iter().max().expect("four").clone();
            assert!(
                encloses(p, &lo) && encloses(p, &hi),
                "{x:?} * {y:?} = {p:?}"
            );
            assert!(tight(p, &lo, &hi), "{x:?} * {y:?} = {p:?} not tight");
            let (s, d) = (x + y, x - y);
            assert!(encloses(s, &(q(x.lo) + q(y.lo))) && encloses(s, &(q(x.hi) + q(y.hi))));
            assert!(tight(s, &(q(x.lo) + q(y.lo)), &(q(x.hi) + q(y.hi))));
            assert!(encloses(d, &(q(x.lo) - q(y.hi))) && encloses(d, &(q(x.hi) - q(y.lo))));
            assert!(tight(d, &(q(x.lo) - q(y.hi)), &(q(x.hi) - q(y.lo))));
        }
        // Random points, also of intervals with infinite ends.
        for _ in 0..2 {
            if let (Some(u), Some(v)) = (rng.point_in(x), rng.point_in(y)) {
                let (qu, qv) = (q(u), q(v));
                assert!(encloses(p, &(&qu * &qv)), "{u} * {v} not in {p:?}");
                assert!(encloses(x + y, &(&qu + &qv)), "{u} + {v}");
                assert!(encloses(x - y, &(&qu - &qv)), "{u} - {v}");
                if v != 0.0 {
                    let r = x / v;
                    assert!(encloses(r, &(&qu / &qv)), "{u} / {v} not in {r:?}");
                    // The point divisor's fast path gives the four-quotient hull's floats.
                    let hull = x / Interval::point(v);
                    assert!(
                        r == hull || r.lo.is_nan() && hull.lo.is_nan(),
                        "{x:?} / {v}"
                    );
                    assert!(encloses(x * v, &(&qu * &qv)), "{u} * {v} (point)");
                }
                checked += 1;
            }
        }
    }
    // The mixes must exercise both paths.
    assert!(
        compared > 40_000 && checked > 80_000,
        "{compared} {checked}"
    );
}

#[test]
fn special_ends_round_as_before() {
    let z = Interval::point(0.0);
    let nz = Interval::point(-0.0);
    let tiny = f64::from_bits(1);
    // An exact zero product is still widened by one ulp (the previous behaviour).
    assert_eq!(z * Interval::new(-3.0, 2.0), Interval::new(-tiny, tiny));
    assert_eq!(nz * nz, Interval::new(-tiny, tiny));
    // Overflow: +-inf ends stay, and a finite bound of an overflowed end is kept.
    let big = Interval::new(f64::MAX, f64::MAX);
    let p = big * Interval::point(2.0);
    assert_eq!((p.lo, p.hi), (f64::MAX, f64::INFINITY));
    let m = big * Interval::point(-2.0);
    assert_eq!((m.lo, m.hi), (f64::NEG_INFINITY, f64::MIN));
    // Infinite ends: 0 * inf contributes 0.
    let e = Interval::entire() * z;
    assert!(e.contains(0.0) && e.lo >= -tiny && e.hi <= tiny);
    assert_eq!(Interval::new(1.0, 2.0) / 0.0, Interval::entire());
    assert_eq!(Interval::new(1.0, 2.0) / -0.0, Interval::entire());
    // Sums of opposite infinities are the whole line.
    let s = Interval::point(f64::INFINITY) + Interval::point(f64::NEG_INFINITY);
    assert_eq!(s, Interval::entire());
}

//! Tanh and sigmoid: convex on `z <= 0`, concave on `z >= 0`. On a piece where
//! `h(z) = +-(f(z) - a z)` is convex, its maximum is at the piece's ends; where it is
//! concave, it lies below its tangent at (a floating-point approximation of) its
//! maximiser, which is rigorous at any point. Slopes: CROWN's chord over a range of fixed
//! curvature on the chord side and the tangent at the midpoint on the other; on a range
//! containing the inflection point (CROWN's mixed case) the best slope for the area
//! criterion is searched among the chord, the end and midpoint derivatives and a ternary
//! search over the slope range (the optimum is CROWN's tangent through an end point,
//! reached up to the search's resolution; every candidate is sound). The functions are
//! evaluated in `samara_num::Interval` (outward rounding, libm widened by 4 ulps).

use super::{pick, Relax};
use samara_nn::Activation;
use samara_num::{Interval, Scalar};

/// CROWN-style lines for tanh or sigmoid over `[l, u]` (module doc); `act` is one of
/// the two.
pub fn relax(act: Activation, l: f64, u: f64) -> Relax {
    let upper = |a: f64| max_of(act, 1.0, a, l, u);
    let lower = |a: f64| -max_of(act, -1.0, a, l, u);
    let mid = 0.5 * l + 0.5 * u;
    let d = |z: f64| df(act, z).value();
    let (fl, fu) = (f(act, l).value(), f(act, u).value());
    let mut cands = vec![0.0, d(l), d(u), d(mid)];
    let chord = (fu - fl) / (u - l);
    if chord.is_finite() {
        cands.push(chord);
    }
    let mut r = pick(&cands, mid, upper, lower);
    if l < 0.0 && u > 0.0 {
        // Mixed curvature: ternary search of the slope for each line, over
        // [0, max f'] (f' is largest at 0).
        let amax = d(0.0);
        let search = |val: &dyn Fn(f64) -> f64| -> f64 {
            let (mut a, mut b) = (0.0, amax);
            for _ in 0..48 {
                let m1 = a + (b - a) / 3.0;
                let m2 = b - (b - a) / 3.0;
                if val(m1) <= val(m2) {
                    b = m2;
                } else {
                    a = m1;
                }
            }
            0.5 * (a + b)
        };
        let au = search(&|a| upper(a) + a * mid);
        let al = search(&|a| -(lower(a) + a * mid));
        let (bu, bl) = (upper(au), lower(al));
        if bu + au * mid < r.bu + r.au * mid {
            r.au = au;
            r.bu = bu;
        }
        if bl + al * mid > r.bl + r.al * mid {
            r.al = al;
            r.bl = bl;
        }
    }
    r
}

/// Enclosure of `tanh(z)` or `sigmoid(z)`.
pub fn f(act: Activation, z: f64) -> Interval {
    let x = Interval::point(z);
    if act == Activation::Tanh {
        x.tanh()
    } else {
        x.sigmoid()
    }
}

/// Enclosure of the derivative of `tanh` or `sigmoid` at `z`.
pub fn df(act: Activation, z: f64) -> Interval {
    let f = f(act, z);
    let one = Interval::point(1.0);
    if act == Activation::Tanh {
        one - f.sqr()
    } else {
        f * (one - f)
    }
}

/// An approximate non-negative solution of `f'(z) = a` (`+inf` when `a <= 0`, 0 when
/// `a` is at least the maximum of `f'`); only used to place a tangent, never for soundness.
fn dinv(act: Activation, a: f64) -> f64 {
    if a <= 0.0 {
        return f64::INFINITY;
    }
    if act == Activation::Tanh {
        if a >= 1.0 {
            0.0
        } else {
            (1.0 - a).sqrt().atanh()
        }
    } else if a >= 0.25 {
        0.0
    } else {
        let s = 0.5 * (1.0 + (1.0 - 4.0 * a).sqrt());
        (s / (1.0 - s)).ln()
    }
}

/// A rigorous upper bound of `h(z) = s (f(z) - a z)` over `[l, u]` for `f` = tanh or
/// sigmoid, `s = +-1`: split at the inflection point 0; on a convex piece the maximum is
/// at an end; on a concave piece `h` lies below its tangent at any point, taken near the
/// maximiser.
fn max_of(act: Activation, s: f64, a: f64, l: f64, u: f64) -> f64 {
    let h = |z: f64| (f(act, z) - Interval::point(a) * Interval::point(z)) * s;
    let piece = |p: f64, q: f64| -> f64 {
        // f is convex on z <= 0; s = -1 flips the curvature.
        let convex = (q <= 0.0) == (s > 0.0);
        if convex {
            return h(p).hi.max(h(q).hi);
        }
        let zs = dinv(act, a);
        let mut z1 = if q <= 0.0 { -zs } else { zs };
        if z1.is_nan() {
            z1 = 0.5 * p + 0.5 * q;
        }
        let z1 = z1.clamp(p, q);
        let dh = (df(act, z1) - Interval::point(a)) * s;
        let t1 = dh * (Interval::point(p) - Interval::point(z1));
        let t2 = dh * (Interval::point(q) - Interval::point(z1));
        (h(z1) + t1).hi.max((h(z1) + t2).hi)
    };
    let r = if l < 0.0 && u > 0.0 {
        piece(l, 0.0).max(piece(0.0, u))
    } else {
        piece(l, u)
    };
    if r.is_nan() {
        f64::INFINITY
    } else {
        r
    }
}

//! ONNX `Sign`, a step: `-1` for `z < 0`, `0` at `z = 0`, `1` for `z > 0` (the binarised
//! activations of BNNs, e.g. VNN-COMP 2023's traffic-sign networks).
//!
//! - Interval rule: `[sign(l), sign(u)]` (the function is non-decreasing).
//! - A range inside one piece (`u < 0`, `l > 0`, or `l = u = 0`) is passed exactly as a
//!   constant.
//! - Otherwise the function is constant on up to three pieces: `-1` on `[l, 0)`, `0` at
//!   `0`, `1` on `(0, u]`. For a slope `a`, `f(z) - a z` is linear on each piece, so
//!   its extremes over the range lie at the pieces' ends (the closure of each piece:
//!   a superset, still sound); the intercepts are those extremes, rounded outward.
//!   Candidate slopes: 0 (the constant bounds `-1` and `1`, or `0` where a side is
//!   absent), the lines through the jump's corners, `2 / u` below and `2 / (-l)` above
//!   across 0 (`-1 + 2 z / u <= sign(z) <= 1 + 2 z / (-l)`), and `1 / u`, `1 / (-l)`
//!   when an end is 0 (`z / u <= sign(z)` on `[0, u]`: `Sign(0) = 0`, not 1). CROWN's
//!   area criterion (the line's value at the midpoint) picks among them.
//!
//! Every line is sound whatever its slope, so rounding of `2 / u` etc. only affects
//! tightness.

use super::{pick, sub_prod, Relax};

/// `sign(z)` in f64 (NaN stays NaN): the IR's own evaluation.
#[inline]
pub fn f(z: f64) -> f64 {
    samara_nn::Activation::Sign.apply_f64(z)
}

/// The interval rule: `sign([l, u])`, exact.
#[inline]
pub fn interval(l: f64, u: f64) -> (f64, f64) {
    // `f(-0.0)` is `-0.0`; the bounds are plain 0 then.
    (f(l) + 0.0, f(u) + 0.0)
}

/// The constant pieces met by `[l, u]`: (value, closure of the piece).
fn pieces(l: f64, u: f64) -> Vec<(f64, f64, f64)> {
    let mut v = Vec::with_capacity(3);
    if l < 0.0 {
        v.push((-1.0, l, u.min(0.0)));
    }
    if l <= 0.0 && u >= 0.0 {
        v.push((0.0, 0.0, 0.0));
    }
    if u > 0.0 {
        v.push((1.0, l.max(0.0), u));
    }
    v
}

/// The linear relaxation over `[l, u]` (module doc).
pub fn relax(l: f64, u: f64) -> Relax {
    let (fl, fu) = interval(l, u);
    if fl == fu || l.is_nan() || u.is_nan() {
        // One piece (or no information): constant bounds.
        return Relax {
            al: 0.0,
            bl: fl,
            au: 0.0,
            bu: fu,
        };
    }
    let ps = pieces(l, u);
    // Rigorous range of `c - a z` over a piece's closure [p, q].
    let ends = |a: f64, c: f64, p: f64, q: f64| {
        if a == 0.0 {
            (c, c)
        } else {
            let (x, y) = (sub_prod(c, a, p), sub_prod(c, a, q));
            (x.lo.min(y.lo), x.hi.max(y.hi))
        }
    };
    let upper = |a: f64| {
        ps.iter()
            .map(|&(c, p, q)| ends(a, c, p, q).1)
            .fold(f64::NEG_INFINITY, f64::max)
    };
    let lower = |a: f64| {
        ps.iter()
            .map(|&(c, p, q)| ends(a, c, p, q).0)
            .fold(f64::INFINITY, f64::min)
    };
    let mut cands = vec![0.0];
    for s in [2.0 / u, 2.0 / -l, 1.0 / u, 1.0 / -l] {
        if s.is_finite() && s > 0.0 {
            cands.push(s);
        }
    }
    // The midpoint of an infinite range is not finite: constant bounds then.
    let mid = 0.5 * l + 0.5 * u;
    if !mid.is_finite() {
        return Relax {
            al: 0.0,
            bl: fl,
            au: 0.0,
            bu: fu,
        };
    }
    pick(&cands, mid, upper, lower)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// The relaxation encloses `sign` at the ends, at 0, next to 0 on both sides and on
    /// a grid, for random ranges including ones with an end at 0 (where `Sign(0) = 0`).
    #[test]
    fn lines_enclose_sign_at_the_jump_and_everywhere() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for k in 0..20_000 {
            let scale: f64 = [1e-3, 1.0, 37.0, 1e6][rng.gen_range(0..4)];
            let (a, b): (f64, f64) = (rng.gen_range(-scale..scale), rng.gen_range(-scale..scale));
            let (l, u) = match k % 5 {
                0 => (0.0, a.abs()),
                1 => (-a.abs(), 0.0),
                2 => (a, a),
                _ => (a.min(b), a.max(b)),
            };
            let r = relax(l, u);
            let (il, iu) = interval(l, u);
            let mut zs = vec![
                l,
                u,
                0.0,
                f64::MIN_POSITIVE,
                -f64::MIN_POSITIVE,
                1e-300,
                -1e-300,
            ];
            zs.extend((0..=100).map(|t| l + (u - l) * t as f64 / 100.0));
            for z in zs.into_iter().filter(|&z| z >= l && z <= u) {
                let v = f(z);
                // Exact comparison: the lines' values in f64 with a margin of the
                // rounding of `a z + b` (two operations).
                let tol = 4.0 * f64::EPSILON * (r.al * z).abs().max((r.au * z).abs());
                assert!(
                    r.al * z + r.bl <= v + tol && v <= r.au * z + r.bu + tol,
                    "[{l}, {u}] at {z}: {r:?}"
                );
                assert!(il <= v && v <= iu, "interval [{il}, {iu}] at {z}");
            }
        }
    }

    #[test]
    fn stable_ranges_are_constants_and_zero_ends_use_the_jump_lines() {
        assert_eq!(
            relax(0.5, 3.0),
            Relax {
                al: 0.0,
                bl: 1.0,
                au: 0.0,
                bu: 1.0
            }
        );
        assert_eq!(
            relax(-3.0, -0.5),
            Relax {
                al: 0.0,
                bl: -1.0,
                au: 0.0,
                bu: -1.0
            }
        );
        assert_eq!(
            relax(0.0, 0.0),
            Relax {
                al: 0.0,
                bl: 0.0,
                au: 0.0,
                bu: 0.0
            }
        );
        // On [0, 4]: z / 4 <= sign(z) <= 1 (Sign(0) = 0 rules out the constant 1 below).
        let r = relax(0.0, 4.0);
        assert_eq!((r.al, r.au, r.bu), (0.25, 0.0, 1.0));
        assert!(r.bl <= 0.0 && r.bl > -1e-15, "{r:?}");
        // On [-1, 3] (midpoint 1): -1 + 2 z / 3 below (the line through the jump's
        // lower corner and (3, 1)), the constant 1 above.
        let r = relax(-1.0, 3.0);
        assert_eq!((r.al, r.au, r.bu), (2.0 / 3.0, 0.0, 1.0), "{r:?}");
        assert!(r.bl <= -1.0 && r.bl > -1.0 - 1e-15, "{r:?}");
        assert_eq!(interval(-2.0, 0.0), (-1.0, 0.0));
    }
}

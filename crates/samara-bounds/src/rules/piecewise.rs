//! ReLU and clamp as piecewise-linear functions with slopes 0 and 1 and kinks: a range
//! inside one linear piece is passed exactly; otherwise `f(z) - a z` is piecewise linear,
//! its extremes lie at the range ends and the kinks, and the slope is chosen among 0, 1
//! and the chords between those points by the area between the line and the function
//! (CROWN's criterion; for ReLU this gives the chord above and DeepPoly/CROWN's adaptive
//! 0-or-1 slope below, the rules of [`super::relu`]).

use super::{pick, sub_prod, Relax};

/// Piecewise-linear `f` with slopes 0 or 1 and kinks `bps` (sorted).
pub fn relax(f: impl Fn(f64) -> f64, bps: &[f64], l: f64, u: f64) -> Relax {
    let inside: Vec<f64> = bps.iter().copied().filter(|&b| b > l && b < u).collect();
    if inside.is_empty() {
        // One linear piece, passed exactly: the identity (the only slope-1 piece of ReLU
        // and Clamp) or a constant.
        let (fl, fu) = (f(l), f(u));
        if fl == l && fu == u {
            return Relax::IDENTITY;
        }
        debug_assert!(fl == fu);
        return Relax {
            al: 0.0,
            bl: fl.min(fu),
            au: 0.0,
            bu: fl.max(fu),
        };
    }
    let mut pts = vec![l];
    pts.extend_from_slice(&inside);
    pts.push(u);
    let g = |a: f64, z: f64| sub_prod(f(z), a, z);
    let upper = |a: f64| {
        pts.iter()
            .map(|&z| g(a, z).hi)
            .fold(f64::NEG_INFINITY, f64::max)
    };
    let lower = |a: f64| {
        pts.iter()
            .map(|&z| g(a, z).lo)
            .fold(f64::INFINITY, f64::min)
    };
    let mut cands = vec![0.0, 1.0];
    for (i, &x) in pts.iter().enumerate() {
        for &y in &pts[i + 1..] {
            let s = (f(y) - f(x)) / (y - x);
            if s.is_finite() {
                cands.push(s);
            }
        }
    }
    let mid = 0.5 * l + 0.5 * u;
    pick(&cands, mid, upper, lower)
}

//! One home per operator's bound rules (the layout of auto_LiRPA, Xu et al., NeurIPS
//! 2020: a file per operator with its interval rule, its linear relaxation and the range
//! of its optimisable slopes). Every bound routine of samara takes an activation's rules
//! from here: the forward symbolic pass and CROWN/alpha-CROWN of [`crate::symbolic`], the
//! back-substitution of [`crate::pwl`] (and so reachability's network step in
//! `samara-reach`), the branching scores of the searches, CROWN over linear sets
//! ([`crate::linset`]) and the input-split search of [`crate::smooth`].
//!
//! - [`relu`]: `max(z, 0)`: the interval rule, the upper chord `u (z - l) / (u - l)` (in
//!   f64 to steer a search, rounded up where a bound rests on it), the lower slopes
//!   `alpha in [0, 1]` with CROWN's default, and the chord's largest gap
//!   `u (-l) / (u - l)` (BaBSR's intercept score).
//! - [`piecewise`]: ReLU and clamp as piecewise-linear functions with slopes 0 and 1 for
//!   [`crate::linset`]: the slope among 0, 1 and the chords between the ends and the
//!   kinks by CROWN's area criterion, intercepts rigorous.
//! - [`sigmoid_tanh`]: the chord and tangent lines of the S-shaped activations, with
//!   rigorous intercepts (convex/concave pieces split at the inflection point 0).
//! - [`sign`]: the step `Sign` (-1, 0, 1): constant on a range inside one piece; across
//!   the jump, the constant bounds or the lines through the jump's corners, intercepts
//!   rigorous (`Sign(0) = 0` is a piece of its own).
//!
//! Relaxations here are sound for *any* slope: the intercept is a rigorous bound of
//! `f(z) - a z` over the range, so the slope choice only affects tightness. Directed
//! rounding comes from `samara_num::round` (the one rounding module).

pub mod piecewise;
pub mod relu;
pub mod sigmoid_tanh;
pub mod sign;

use samara_nn::Activation;
use samara_num::Interval;

/// Lower and upper lines of one activation over its pre-activation range:
/// `al z + bl <= f(z) <= au z + bu` for every real `z` in the range, exactly.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Relax {
    /// Slope of the lower line.
    pub al: f64,
    /// Intercept of the lower line.
    pub bl: f64,
    /// Slope of the upper line.
    pub au: f64,
    /// Intercept of the upper line.
    pub bu: f64,
}

impl Relax {
    /// The lines of a neuron passed on exactly (`f(z) = z`): both are `z` itself.
    pub const IDENTITY: Relax = Relax {
        al: 1.0,
        bl: 0.0,
        au: 1.0,
        bu: 0.0,
    };
}

/// The interval rule: a sound range of `f(z)` for `z in [l, u]` (every activation here
/// is monotone, so the ends' images bound it; tanh and sigmoid in outward-rounded
/// [`Interval`] arithmetic, clipped to their ranges; sign exactly).
pub fn interval(act: Activation, l: f64, u: f64) -> (f64, f64) {
    match act {
        Activation::Relu => (l.max(0.0), u.max(0.0)),
        Activation::Clamp { lo, hi } => (l.max(lo).min(hi), u.max(lo).min(hi)),
        Activation::Tanh | Activation::Sigmoid => {
            let (a, b) = (sigmoid_tanh::f(act, l), sigmoid_tanh::f(act, u));
            let (lo, hi) = if act == Activation::Tanh {
                (-1.0, 1.0)
            } else {
                (0.0, 1.0)
            };
            (a.lo.max(lo), b.hi.min(hi))
        }
        Activation::Sign => sign::interval(l, u),
    }
}

/// The linear relaxation: sound lines for one activation over `[l, u]` (module doc).
pub fn relax(act: Activation, l: f64, u: f64) -> Relax {
    match act {
        Activation::Relu => piecewise::relax(|z| z.max(0.0), &[0.0], l, u),
        Activation::Clamp { lo, hi } => {
            let bps: Vec<f64> = [lo, hi].into_iter().filter(|b| b.is_finite()).collect();
            piecewise::relax(|z| z.max(lo).min(hi), &bps, l, u)
        }
        Activation::Tanh | Activation::Sigmoid => sigmoid_tanh::relax(act, l, u),
        Activation::Sign => sign::relax(l, u),
    }
}

/// Enclosure of `f - a z`: the exact value when the f64 operations are exact (checked
/// with an FMA residual and a two-sum error term), else outward interval arithmetic.
pub(crate) fn sub_prod(f: f64, a: f64, z: f64) -> Interval {
    let p = a * z;
    let tiny = p.abs() < 1e-290 && !(a == 0.0 || z == 0.0);
    if !tiny && p.is_finite() && f.is_finite() {
        let e = a.mul_add(z, -p); // a z = p + e exactly (no underflow)
        let s = f - p;
        let bp = s - f;
        let t = (f - (s - bp)) + (-p - bp); // f - p = s + t exactly
        if e == 0.0 && t == 0.0 {
            return Interval::point(s);
        }
    }
    Interval::point(f) - Interval::point(a) * Interval::point(z)
}

/// Among slopes `cands`, the upper line with the least value at `mid` and the lower line
/// with the greatest (CROWN's area criterion); the intercepts are `upper(a)`, `lower(a)`.
pub(crate) fn pick(
    cands: &[f64],
    mid: f64,
    upper: impl Fn(f64) -> f64,
    lower: impl Fn(f64) -> f64,
) -> Relax {
    let mut best_u = (f64::INFINITY, 0.0, f64::INFINITY);
    let mut best_l = (f64::NEG_INFINITY, 0.0, f64::NEG_INFINITY);
    for &a in cands {
        let bu = upper(a);
        let vu = bu + a * mid;
        if vu < best_u.0 {
            best_u = (vu, a, bu);
        }
        let bl = lower(a);
        let vl = bl + a * mid;
        if vl > best_l.0 {
            best_l = (vl, a, bl);
        }
    }
    Relax {
        al: best_l.1,
        bl: best_l.2,
        au: best_u.1,
        bu: best_u.2,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// Every relaxation is checked on a dense grid and at random points, in f64 with a
    /// tolerance far below the margins involved (1e-12 absolute on values in [-1e2, 1e2]).
    #[test]
    fn relaxations_are_sound_on_grids() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let acts = [
            Activation::Relu,
            Activation::Tanh,
            Activation::Sigmoid,
            Activation::Clamp { lo: -0.5, hi: 1.5 },
            Activation::Clamp {
                lo: f64::NEG_INFINITY,
                hi: 0.25,
            },
            Activation::Clamp {
                lo: 0.0,
                hi: f64::INFINITY,
            },
            Activation::Sign,
        ];
        for _ in 0..3000 {
            let act = acts[rng.gen_range(0..acts.len())];
            let scale: f64 = [0.01, 1.0, 5.0, 40.0][rng.gen_range(0..4)];
            let (a, b): (f64, f64) = (rng.gen_range(-scale..scale), rng.gen_range(-scale..scale));
            let (l, u) = if rng.gen_bool(0.05) {
                (a, a)
            } else {
                (a.min(b), a.max(b))
            };
            let r = relax(act, l, u);
            for t in 0..=200 {
                let z = if t < 200 {
                    l + (u - l) * t as f64 / 200.0
                } else {
                    u
                };
                let z = z.clamp(l, u);
                let f = act.apply_f64(z);
                let lo = r.al * z + r.bl;
                let hi = r.au * z + r.bu;
                assert!(
                    lo <= f + 1e-12 && f <= hi + 1e-12,
                    "{act:?} on [{l}, {u}] at {z}: {lo} <= {f} <= {hi} ({r:?})"
                );
            }
        }
    }

    #[test]
    fn relu_relaxation_is_crowns() {
        // Intercepts are rounded outward by an ulp even when exact.
        let r = relax(Activation::Relu, -1.0, 3.0);
        assert!(r.al == 1.0 && r.bl.abs() < 1e-300, "{r:?}");
        assert!((r.au - 0.75).abs() < 1e-15 && (r.bu - 0.75).abs() < 1e-15);
        let r = relax(Activation::Relu, -3.0, 1.0);
        assert!(r.al == 0.0 && r.bl.abs() < 1e-300, "{r:?}");
        let r = relax(Activation::Relu, 0.5, 3.0);
        assert_eq!(
            r,
            Relax {
                al: 1.0,
                bl: 0.0,
                au: 1.0,
                bu: 0.0
            }
        );
    }

    #[test]
    fn tanh_chord_in_convex_region() {
        let (l, u) = (-3.0f64, -1.0f64);
        let r = relax(Activation::Tanh, l, u);
        let chord = (u.tanh() - l.tanh()) / (u - l);
        assert!((r.au - chord).abs() < 1e-12, "{r:?} vs {chord}");
        assert!((r.au * l + r.bu - l.tanh()).abs() < 1e-12);
    }
}

//! Constraints decided by bounds alone, with no rounding where there is none.
//!
//! A degenerate query (an output that is exactly 0 on the whole box because its ReLU is
//! never active, or two outputs computed by the same row of the last layer, so that
//! `Y_0 - Y_1` is exactly 0) has a constraint whose sound f64 bound sits exactly at 0.
//! The search's bounds ([`crate::symbolic`]) always widen by the rounding they might have
//! made, so such a bound comes out as `-1e-323` (or `-1e-16`), a strict `g < 0` is never
//! closed, and the search splits the box until the time limit. This module computes
//! interval bounds that widen only where an operation was inexact: every product and sum
//! is checked with an error-free transformation (Dekker's TwoProduct via `fma`, Knuth's
//! TwoSum) and rounded outward only when its error is not zero. Exactly computed values
//! stay exact, so an exactly zero output gives the interval `[0, 0]` and a constraint
//! over it is decided: never (`g >= 0` against a strict `g < 0`, `g > 0` against
//! `g <= 0`) or always (`g < 0`, or `g <= 0` for a non-strict one).
//!
//! A constraint over the outputs, `c . y + d`, is bounded twice: through the output
//! intervals, and (when the last map has no ReLU) through the combined row
//! `r = c^T W_last` of the last layer applied to the last hidden layer's intervals, which
//! is exactly 0 when the compared outputs are the same expression. Both bounds are sound;
//! their intersection is used.

use crate::query::OutputConstraint;
use samara_nn::Affine;
use std::time::Instant;

/// Products or sums this small may have lost bits to underflow, which the error-free
/// transformations do not see: such results are widened by this much instead.
const TINY: f64 = 1e-280;

/// A closed interval `[lo, hi]` of reals (ends may be infinite).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Iv {
    /// Lower end.
    pub lo: f64,
    /// Upper end.
    pub hi: f64,
}

/// `a + b` with its exact error (`a + b = s + e` exactly; Knuth's TwoSum).
fn two_sum(a: f64, b: f64) -> (f64, f64) {
    let s = a + b;
    let bb = s - a;
    let e = (a - (s - bb)) + (b - bb);
    (s, e)
}

/// A lower (`up = false`) or upper bound of the exact `a + b`: the f64 sum, moved one
/// step outward only when it was inexact.
fn add_dir(a: f64, b: f64, up: bool) -> f64 {
    let (s, e) = two_sum(a, b);
    if !s.is_finite() {
        return if s.is_nan() {
            if up {
                f64::INFINITY
            } else {
                f64::NEG_INFINITY
            }
        } else {
            s
        };
    }
    if up && e > 0.0 {
        s.next_up()
    } else if !up && e < 0.0 {
        s.next_down()
    } else {
        s
    }
}

/// A lower or upper bound of the exact product `a * b` (exact when the f64 product was).
fn mul_dir(a: f64, b: f64, up: bool) -> f64 {
    if a == 0.0 || b == 0.0 {
        return 0.0;
    }
    let p = a * b;
    if !p.is_finite() {
        return p;
    }
    if p.abs() < TINY {
        // Underflow may have happened: the error term is not exact there.
        return if up { p + TINY } else { p - TINY };
    }
    let e = a.mul_add(b, -p);
    if up && e > 0.0 {
        p.next_up()
    } else if !up && e < 0.0 {
        p.next_down()
    } else {
        p
    }
}

impl Iv {
    /// The point interval `[v, v]`.
    pub fn point(v: f64) -> Self {
        Iv { lo: v, hi: v }
    }

    /// `self + o`, rounded outward only where inexact.
    pub fn plus(self, o: Iv) -> Iv {
        Iv {
            lo: add_dir(self.lo, o.lo, false),
            hi: add_dir(self.hi, o.hi, true),
        }
    }

    /// `k * self` for a number `k`, rounded outward only where inexact.
    pub fn scale(self, k: f64) -> Iv {
        if k == 0.0 {
            return Iv::point(0.0);
        }
        let (a, b) = if k > 0.0 {
            (self.lo, self.hi)
        } else {
            (self.hi, self.lo)
        };
        Iv {
            lo: mul_dir(k, a, false),
            hi: mul_dir(k, b, true),
        }
    }

    /// `self * o` for two intervals.
    pub fn times(self, o: Iv) -> Iv {
        if (self.lo == 0.0 && self.hi == 0.0) || (o.lo == 0.0 && o.hi == 0.0) {
            return Iv::point(0.0);
        }
        let ps = [
            (self.lo, o.lo),
            (self.lo, o.hi),
            (self.hi, o.lo),
            (self.hi, o.hi),
        ];
        let lo = ps
            .iter()
            .map(|(a, b)| mul_dir(*a, *b, false))
            .fold(f64::INFINITY, f64::min);
        let hi = ps
            .iter()
            .map(|(a, b)| mul_dir(*a, *b, true))
            .fold(f64::NEG_INFINITY, f64::max);
        if lo.is_nan() || hi.is_nan() {
            return Iv {
                lo: f64::NEG_INFINITY,
                hi: f64::INFINITY,
            };
        }
        Iv { lo, hi }
    }

    /// `max(self, 0)` (exact).
    pub fn relu(self) -> Iv {
        Iv {
            lo: self.lo.max(0.0),
            hi: self.hi.max(0.0),
        }
    }
}

/// `W x + b` over intervals, each rounded outward only where the operation was inexact.
pub fn affine(m: &Affine, x: &[Iv]) -> Vec<Iv> {
    affine_until(m, x, None).expect("no deadline")
}

/// Rows of a map larger than this many weights are bounded in parallel.
const PARALLEL_WEIGHTS: usize = 1 << 16;

/// [`affine`] that gives up (`None`) past `deadline`, checked between rows: on a
/// CIFAR-size dense layer one pass takes a large part of a second.
fn affine_until(m: &Affine, x: &[Iv], deadline: Option<Instant>) -> Option<Vec<Iv>> {
    let late = || deadline.is_some_and(|d| Instant::now() >= d);
    let row = |i: usize| {
        if late() {
            return None;
        }
        // Zero weights skipped: their terms are the exact point 0.
        let mut acc = Iv::point(m.b[i]);
        m.row(i)
            .for_each_nonzero(|j, w| acc = acc.plus(x[j].scale(w)));
        Some(acc)
    };
    if m.stored() > PARALLEL_WEIGHTS {
        use rayon::prelude::*;
        (0..m.out).into_par_iter().map(row).collect()
    } else {
        (0..m.out).map(row).collect()
    }
}

/// Intervals of the last hidden layer's activations (the last map's input; the box
/// itself for a single map) and of the outputs, over the box `[lo, hi]`.
pub fn layer_intervals(maps: &[(Affine, bool)], lo: &[f64], hi: &[f64]) -> (Vec<Iv>, Vec<Iv>) {
    layer_intervals_until(maps, lo, hi, None).expect("no deadline")
}

/// [`layer_intervals`] that gives up (`None`) past `deadline`.
pub fn layer_intervals_until(
    maps: &[(Affine, bool)],
    lo: &[f64],
    hi: &[f64],
    deadline: Option<Instant>,
) -> Option<(Vec<Iv>, Vec<Iv>)> {
    let mut a: Vec<Iv> = lo
        .iter()
        .zip(hi)
        .map(|(l, h)| Iv { lo: *l, hi: *h })
        .collect();
    let mut last_in = a.clone();
    for (k, (m, r)) in maps.iter().enumerate() {
        if k + 1 == maps.len() {
            last_in = a.clone();
        }
        let mut z = affine_until(m, &a, deadline)?;
        if *r {
            z.iter_mut().for_each(|v| *v = v.relu());
        }
        a = z;
    }
    Some((last_in, a))
}

/// A sound interval of `c . y + d` over the box, given [`layer_intervals`]: the
/// intersection of the bound through the outputs and (when the last map has no ReLU)
/// the bound through the last layer's combined row.
pub fn constraint_interval(
    maps: &[(Affine, bool)],
    k: &OutputConstraint,
    last_in: &[Iv],
    out: &[Iv],
) -> Iv {
    let d = Iv::point(k.obj.d);
    let via_out = k
        .obj
        .c
        .iter()
        .zip(out)
        .fold(d, |acc, (c, y)| acc.plus(y.scale(*c)));
    let Some((last, false)) = maps.last() else {
        return via_out;
    };
    // c . (W a + b) + d = sum_j (sum_o c_o W_oj) a_j + (sum_o c_o b_o + d).
    let mut cst = d;
    let mut row = vec![Iv::point(0.0); last.inp];
    for (o, c) in k.obj.c.iter().enumerate() {
        if *c == 0.0 {
            continue;
        }
        cst = cst.plus(Iv::point(last.b[o]).scale(*c));
        last.row(o)
            .for_each_nonzero(|j, w| row[j] = row[j].plus(Iv::point(w).scale(*c)));
    }
    let via_row = row
        .iter()
        .zip(last_in)
        .fold(cst, |acc, (r, a)| acc.plus(r.times(*a)));
    Iv {
        lo: via_out.lo.max(via_row.lo),
        hi: via_out.hi.min(via_row.hi),
    }
}

/// What the bounds say of one constraint `g < 0` (strict) or `g <= 0` over a box.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Fate {
    /// It holds at no point of the box.
    Never,
    /// It holds at every point of the box.
    Always,
    /// Not decided by the bounds.
    Open,
}

/// Decide each constraint of a conjunction over the box `[lo, hi]` by [`Iv`] bounds
/// (sound: `Never` only when the constraint fails everywhere, `Always` only when it
/// holds everywhere).
pub fn fates(
    maps: &[(Affine, bool)],
    cs: &[OutputConstraint],
    lo: &[f64],
    hi: &[f64],
) -> Vec<Fate> {
    fates_given(maps, cs, &layer_intervals(maps, lo, hi))
}

/// [`fates`] given the box's [`layer_intervals`], so that the cases of one query that
/// share a box (a VNN-LIB disjunction over the outputs on one input region, e.g. the nine
/// "another class wins" cases of an image property) propagate the box through the
/// network once, not once per case: on a CIFAR network lowered to dense layers that pass
/// is the costliest step before the search.
pub fn fates_given(
    maps: &[(Affine, bool)],
    cs: &[OutputConstraint],
    intervals: &(Vec<Iv>, Vec<Iv>),
) -> Vec<Fate> {
    if maps.is_empty() {
        return vec![Fate::Open; cs.len()];
    }
    let (last_in, out) = intervals;
    cs.iter()
        .map(|k| {
            let g = constraint_interval(maps, k, last_in, out);
            if g.lo.is_nan() || g.hi.is_nan() {
                Fate::Open
            } else if (k.strict && g.lo >= 0.0) || g.lo > 0.0 {
                Fate::Never
            } else if g.hi < 0.0 || (!k.strict && g.hi <= 0.0) {
                Fate::Always
            } else {
                Fate::Open
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn exact_operations_stay_exact_and_inexact_ones_widen() {
        assert_eq!(add_dir(0.5, 0.5, false), 1.0);
        assert_eq!(
            Iv::point(0.5).plus(Iv::point(0.5)).plus(Iv::point(-1.0)),
            Iv::point(0.0)
        );
        // 0.1 + 0.2 is inexact in f64: the interval must contain the exact sum.
        let s = Iv::point(0.1).plus(Iv::point(0.2));
        assert!(s.lo < s.hi && s.lo <= 0.1 + 0.2 && 0.1 + 0.2 <= s.hi);
        assert_eq!(Iv::point(0.7).scale(-1.0), Iv::point(-0.7));
        let p = Iv::point(0.1).scale(3.0);
        assert!(p.lo < p.hi, "{p:?}");
        assert_eq!(
            Iv::point(0.0).times(Iv {
                lo: -1e300,
                hi: 1e300
            }),
            Iv::point(0.0)
        );
    }

    /// Random products and sums of dyadic numbers checked against exact integer
    /// arithmetic (the operands are k / 2^20 with |k| < 2^30, so every exact result is
    /// an i128 multiple of 2^-40).
    #[test]
    fn bounds_contain_the_exact_results() {
        let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(35);
        for _ in 0..20000 {
            let ka: i64 = r.gen_range(-(1 << 30)..(1 << 30));
            let kb: i64 = r.gen_range(-(1 << 30)..(1 << 30));
            let kc: i64 = r.gen_range(-(1 << 50)..(1 << 50));
            let (a, b) = (ka as f64 / 1048576.0, kb as f64 / 1048576.0);
            let c = kc as f64 / (1u64 << 40) as f64;
            // a * b + c exactly, in units of 2^-40.
            let exact = ka as i128 * kb as i128 + kc as i128;
            let iv = Iv::point(a).scale(b).plus(Iv::point(c));
            let unit = 2f64.powi(-40);
            // Compare in units: the i128 is exact; the interval ends scaled by 2^40 are
            // exact in f64 (a power-of-two scaling).
            let (lo, hi) = (
                (iv.lo / unit).floor() as i128,
                (iv.hi / unit).ceil() as i128,
            );
            assert!(
                lo <= exact && exact <= hi,
                "{a} * {b} + {c}: [{lo}, {hi}] vs {exact}"
            );
            // Small operands multiply and add exactly in f64: a point interval.
            if ka.abs() < 1 << 20 && kb.abs() < 1 << 20 && kc.abs() < 1 << 40 {
                assert_eq!(iv.lo, iv.hi);
            }
        }
    }
}

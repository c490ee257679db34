//! The validated Taylor step both engines take: the a-priori enclosure of every
//! solution over a step, the solution's Taylor coefficients in time on any number type,
//! and the Lagrange remainder. The zonotope engine ([`crate::zonotope::flow`]) runs them
//! on intervals and interval duals around a Lohner step; the Taylor-model engine
//! ([`crate::taylor::flow`]) on Taylor models in the initial-set parameters.
//!
//! One step of length `h` from the box `bz` (Nedialkov, Jackson & Corliss, "Validated
//! solutions of initial value problems for ordinary differential equations", Appl. Math.
//! Comput. 105, 1999):
//! 1. `apriori_by`: a box `B` with `bz + [0, h] f(B) ⊆ B` (Picard-Lindeloef), which
//!    contains every solution from `bz` over `[0, h]`;
//! 2. `series`: the time coefficients `x_0 .. x_p` of the solution, by Taylor-mode
//!    automatic differentiation of the right-hand side recorded as a
//!    [`samara_system::Graph`] (`x_{k+1} = f(x)_k / (k + 1)`);
//! 3. `lagrange_remainder`: `x_{p+1}(B) h^{p+1}` from the same coefficients on `B`,
//!    which encloses `x(h) - sum_k x_k h^k` for every solution in `B`.

use samara_num::{Interval, Scalar, Series};
use samara_system::taylor::SeriesScratch;
use samara_system::Graph;

/// Whether every interval of `a` lies inside the matching interval of `b`.
pub(crate) fn subset(a: &[Interval], b: &[Interval]) -> bool {
    a.iter().zip(b).all(|(x, y)| y.lo <= x.lo && x.hi <= y.hi)
}

/// The intersection of two enclosures of the same set; where rounding makes it look
/// empty or one side is not finite, the finite one (`b` if both are). Both enclose the
/// same values, so they meet; an empty intersection can only be rounding or NaN noise.
pub(crate) fn meet(a: Interval, b: Interval) -> Interval {
    let fin = |x: Interval| x.lo.is_finite() && x.hi.is_finite();
    if !fin(a) {
        return b;
    }
    if !fin(b) {
        return a;
    }
    let (lo, hi) = (a.lo.max(b.lo), a.hi.min(b.hi));
    if lo <= hi {
        Interval { lo, hi }
    } else {
        b
    }
}

/// Whether every end of every interval of `v` is finite.
pub(crate) fn finite(v: &[Interval]) -> bool {
    v.iter().all(|x| x.lo.is_finite() && x.hi.is_finite())
}

/// A-priori enclosure over `[0, h]` of every solution of `x' = f(x)` from the box `bz`
/// (`f` an interval enclosure of the right-hand side): the Picard-Lindeloef test
/// `bz + [0, h] f(B) ⊆ B` on an inflated iterate; `None` if it does not close in 12 tries.
pub(crate) fn apriori_by(
    f: impl Fn(&[Interval]) -> Vec<Interval>,
    bz: &[Interval],
    h: f64,
) -> Option<Vec<Interval>> {
    let th = Interval::new(0.0, h);
    let f0 = f(bz);
    if !finite(&f0) {
        return None;
    }
    let mut b: Vec<Interval> = bz.iter().zip(&f0).map(|(z, f)| *z + th * *f).collect();
    for _ in 0..12 {
        // Inflate, then test.
        let inf: Vec<Interval> = b
            .iter()
            .map(|x| {
                let w = 0.2 * (x.hi - x.lo) + 1e-12 * (1.0 + x.lo.abs().max(x.hi.abs()));
                Interval::new(x.lo - w, x.hi + w)
            })
            .collect();
        let fb = f(&inf);
        if !finite(&fb) {
            return None;
        }
        let nb: Vec<Interval> = bz.iter().zip(&fb).map(|(z, f)| *z + th * *f).collect();
        if subset(&nb, &inf) {
            return Some(nb);
        }
        b = nb;
    }
    None
}

/// `h^k`, rounded outward.
pub(crate) fn pow_up(h: f64, k: usize) -> Interval {
    let mut p = Interval::point(1.0);
    for _ in 0..k {
        p = p * h;
    }
    p
}

/// The Lagrange remainder of a step of length `h` and time order `p`:
/// `x_{p+1}(B) h^{p+1}` for each state, from the time coefficients `tb` computed on the
/// a-priori box `B` (every solution stays in `B`, and `x_{p+1}(y) = x^{(p+1)}(tau) /
/// (p+1)!` for the solution through `y`). The first `n` states only.
pub(crate) fn lagrange_remainder<const K: usize>(
    tb: &[Series<Interval, K>],
    n: usize,
    p: usize,
    h: f64,
) -> Vec<Interval> {
    let hp = pow_up(h, p + 1);
    tb[..n].iter().map(|c| c.c[p + 1] * hp).collect()
}

/// Taylor coefficients `0..=upto` in time of the solution of `x' = g(x, u)` from `x0`
/// under the constant inputs `u`, on series with coefficients in `S` (intervals,
/// interval duals, Taylor models), each state's coefficient `k >= 1` passed through
/// `trim` (as [`samara_system::taylor::solution_series_trimmed`] says; `trim` must
/// return an enclosure of its argument); `None` if a branch of `g` was undecided (a
/// `bad` series). The incremental recurrences over the graph first (O(K^2)); where the
/// graph has an instruction without one, the graph run on series per order (O(K^3), the
/// same recurrences, which ignores `trim`: an economy, never needed for soundness).
pub(crate) fn series<S: Scalar, const K: usize>(
    g: &Graph,
    x0: &[S],
    u: &[S],
    upto: usize,
    trim: &dyn Fn(usize, S) -> S,
) -> Option<Vec<Series<S, K>>> {
    series_in::<S, K>(g, x0, u, upto, trim, &mut SeriesScratch::default())
}

/// [`series`] with the incremental expansion's tables in `scratch` (reused across the
/// expansions of a step; the same numbers).
pub(crate) fn series_in<S: Scalar, const K: usize>(
    g: &Graph,
    x0: &[S],
    u: &[S],
    upto: usize,
    trim: &dyn Fn(usize, S) -> S,
    scratch: &mut SeriesScratch<S>,
) -> Option<Vec<Series<S, K>>> {
    if let Some(s) =
        samara_system::taylor::solution_series_trimmed_in::<S, K>(g, x0, u, upto, trim, scratch)
    {
        return (!s.iter().any(|v| v.bad)).then_some(s);
    }
    let d = x0.len();
    let mut x: Vec<Series<S, K>> = x0.iter().map(|v| Series::var(v.clone())).collect();
    let us: Vec<Series<S, K>> = u.iter().map(|v| Series::constant(v.clone())).collect();
    let mut out = vec![Series::<S, K>::cst(0.0); d];
    let mut scratch = Vec::new();
    for i in 0..upto {
        for xj in x.iter_mut() {
            xj.n = i + 1;
        }
        g.eval_with(&mut scratch, &x, &us, &mut out);
        for j in 0..d {
            if out[j].bad || out[j].n <= i {
                return None;
            }
            x[j].c[i + 1] = out[j].c[i].clone() / (i as f64 + 1.0);
        }
    }
    for xj in x.iter_mut() {
        xj.n = upto + 1;
    }
    Some(x)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The a-priori box of `x' = -x^2` from `[1, 2]` over `[0, 0.2]` contains the exact
    /// solutions `x0 / (1 + x0 t)` (sampled over the box and the step), and a
    /// right-hand side that is not finite gives no box.
    #[test]
    fn apriori_box_contains_the_exact_solutions() {
        let f = |x: &[Interval]| vec![-(x[0] * x[0])];
        let (bz, h) = (vec![Interval::new(1.0, 2.0)], 0.2);
        let b = apriori_by(f, &bz, h).expect("the Picard test closes");
        for i in 0..=50 {
            for j in 0..=50 {
                let x0 = 1.0 + i as f64 / 50.0;
                let t = h * j as f64 / 50.0;
                let x = x0 / (1.0 + x0 * t);
                assert!(b[0].lo <= x && x <= b[0].hi, "{x} outside {:?}", b[0]);
            }
        }
        let inf = |x: &[Interval]| vec![x[0] / Interval::new(-1.0, 1.0)];
        assert!(apriori_by(inf, &bz, h).is_none());
    }

    /// Two enclosures of the same set meet in their intersection; a side that is not
    /// finite (a NaN model) leaves the other, and an empty intersection (rounding) the
    /// second.
    #[test]
    fn meet_keeps_the_finite_side() {
        let a = Interval::new(0.0, 2.0);
        let b = Interval::new(1.0, 3.0);
        assert_eq!(meet(a, b), Interval::new(1.0, 2.0));
        let nan = Interval {
            lo: f64::NAN,
            hi: f64::NAN,
        };
        assert_eq!(meet(nan, b), b);
        assert_eq!(meet(a, nan), a);
        assert_eq!(meet(Interval::new(0.0, 0.5), b), b);
    }
}

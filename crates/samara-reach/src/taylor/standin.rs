//! Polynomial stand-ins for terms that a Taylor step cannot expand: an `abs` whose operand
//! crosses 0 over the step, a `sqrt` whose operand comes close to 0 (the glider's damping
//! `omega sqrt(omega^2 + 1e-5)`, analytic but with a radius of convergence of
//! `sqrt(1e-5) = 0.003` in omega; the full model's `omega |omega|`, not analytic at 0).
//!
//! Over one step whose a-priori box is `B`, such a term `f(z)` is written as
//! `p(z) + w(t)`: `p` the Chebyshev interpolant of `f` over the operand's range `Z` on
//! `B`, `w(t) = f(z(t)) - p(z(t))` a disturbance bounded by `W`, the rigorous range of
//! `f - p` over `Z` (mean-value form on 128 pieces). The right-hand side with the
//! polynomial is analytic, so the nominal flow `y' = F(y, 0)` is a Taylor-model step;
//! the true solution `x' = F(x, w(t))` differs from it by `e = x - y`, which solves the
//! linear equation `e' = A(t) e + b(t) w(t)` with `A(t)` and `b(t)` the means of the
//! Jacobians along the segment from `(y, 0)` to `(x, w)`, hence in the interval Jacobians
//! `Jx`, `Jw` over the hull of both a-priori boxes (the mean-value theorem, or Lebourg's
//! for a Lipschitz kink; the step is refused where a branch or kink is undecided over
//! that hull, since a jump escapes every Jacobian). `e(0) = 0`, so `e` stays in any box
//! `E` with `[0, h] (Jx E + Jw W) ⊆ E` (the Picard iterates of the linear equation stay in
//! `E`), and `e(h) ∈ h (Jx E + Jw W)`. This is the "smooth enclosure with a bounded
//! remainder" of a non-smooth right-hand side (cf. the time-varying uncertainties of
//! Chen, Abraham & Sankaranarayanan, "Flow*", CAV 2013, and the mean-value error
//! propagation of Lohner's method).

use crate::taylor_step::meet;
use samara_num::{IDual, Interval, Scalar};
use samara_system::{Graph, Op, StandIn, Un};

/// Degree of the stand-in polynomials.
const DEGREE: usize = 2;
/// Pieces of the operand's range on which `f - p` is bounded.
const PIECES: usize = 128;

/// The stand-ins of one step: the graph with them and the disturbances' ranges (one per
/// stand-in, inputs `n_inputs ..` of the graph).
pub(crate) struct StandIns {
    /// The right-hand side with every stand-in in place.
    pub graph: Graph,
    /// Range of each disturbance `f(z) - p(z)` over the step.
    pub dist: Vec<Interval>,
}

fn fun<S: Scalar>(f: Un, z: &S) -> S {
    match f {
        Un::Abs => z.abs(),
        _ => z.sqrt(),
    }
}

fn poly<S: Scalar>(coef: &[f64], centre: f64, z: &S) -> S {
    let d = z.clone() - centre;
    let mut acc = S::cst(coef[coef.len() - 1]);
    for &c in coef[..coef.len() - 1].iter().rev() {
        acc = acc * d.clone() + c;
    }
    acc
}

/// Whether `f` over the operand range `z` needs a stand-in: `abs` across 0, `sqrt` whose
/// operand spans more than a factor 2 (its Taylor expansion about the centre converges
/// only within the distance to 0).
fn needs(f: Un, z: Interval) -> bool {
    if !(z.lo.is_finite() && z.hi.is_finite()) {
        return false;
    }
    match f {
        Un::Abs => z.lo < 0.0 && z.hi > 0.0,
        Un::Sqrt => z.lo >= 0.0 && z.hi > 2.0 * z.lo,
        _ => false,
    }
}

/// Solve the small dense system `a c = b` by Gaussian elimination with partial pivoting
/// (the interpolant need not be exact: its error is bounded rigorously afterwards).
fn solve(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Vec<f64> {
    let n = b.len();
    for k in 0..n {
        let p = (k..n)
            .max_by(|&i, &j| a[i][k].abs().total_cmp(&a[j][k].abs()))
            .unwrap_or(k);
        a.swap(k, p);
        b.swap(k, p);
        let (top, rest) = a.split_at_mut(k + 1);
        let pivot = &top[k];
        for (i, row) in rest.iter_mut().enumerate() {
            let r = row[k] / pivot[k];
            for (x, y) in row[k..].iter_mut().zip(&pivot[k..]) {
                *x -= r * y;
            }
            b[k + 1 + i] -= r * b[k];
        }
    }
    let mut c = vec![0.0; n];
    for k in (0..n).rev() {
        let s: f64 = (k + 1..n).map(|j| a[k][j] * c[j]).sum();
        c[k] = (b[k] - s) / a[k][k];
    }
    c
}

/// The Chebyshev interpolant of `f` over `z` (coefficients in powers of `z - centre`) and
/// a rigorous enclosure of `f - p` over `z`; `None` if either is not finite.
pub(crate) fn fit(f: Un, z: Interval) -> Option<(f64, Vec<f64>, Interval)> {
    let centre = 0.5 * (z.lo + z.hi);
    let r = 0.5 * (z.hi - z.lo);
    let n = DEGREE + 1;
    let nodes: Vec<f64> = (0..n)
        .map(|k| r * (std::f64::consts::PI * (2 * k + 1) as f64 / (2 * n) as f64).cos())
        .collect();
    let a: Vec<Vec<f64>> = nodes
        .iter()
        .map(|&t| (0..n).map(|j| t.powi(j as i32)).collect())
        .collect();
    let b: Vec<f64> = nodes
        .iter()
        .map(|&t| fun(f, &(centre + t).max(z.lo).min(z.hi)))
        .collect();
    let mut coef = solve(a, b);
    if coef.iter().any(|c| !c.is_finite()) {
        return None;
    }
    // Centre the disturbance: shift the constant by the middle of f - p's range (the
    // interpolant is not the minimax one), then bound f - p again for the shifted p.
    let d = dist_bound(f, &coef, centre, z)?;
    coef[0] += 0.5 * (d.lo + d.hi);
    let d = dist_bound(f, &coef, centre, z)?;
    Some((centre, coef, d))
}

/// The pieces on which `f - p` is bounded: for `abs`, each side of the kink at 0 cut
/// evenly (so `abs` is linear on every piece); for `sqrt`, cuts crowding towards the
/// lower end quadratically (its slope is unbounded at 0, so the first piece must be
/// short: its natural enclosure is as wide as the square root of its width).
fn pieces(f: Un, z: Interval) -> Vec<Interval> {
    let cut = |a: f64, b: f64, n: usize, sq: bool| -> Vec<Interval> {
        (0..n)
            .map(|k| {
                let at = |k: usize| {
                    if k == n {
                        b
                    } else {
                        let r = k as f64 / n as f64;
                        a + (b - a) * if sq { r * r } else { r }
                    }
                };
                Interval::new(at(k), at(k + 1).max(at(k)))
            })
            .collect()
    };
    match f {
        Un::Abs if z.lo < 0.0 && z.hi > 0.0 => {
            let mut v = cut(z.lo, 0.0, PIECES / 2, false);
            v.extend(cut(0.0, z.hi, PIECES / 2, false));
            v
        }
        Un::Sqrt => cut(z.lo, z.hi, PIECES, true),
        _ => cut(z.lo, z.hi, PIECES, false),
    }
}

/// Rigorous enclosure of `f - p` over `z` (mean-value form on the [`pieces`]).
fn dist_bound(f: Un, coef: &[f64], centre: f64, z: Interval) -> Option<Interval> {
    let mut dist: Option<Interval> = None;
    for piece in pieces(f, z) {
        let m = 0.5 * (piece.lo + piece.hi);
        let pm = Interval::point(m);
        let at_m = fun(f, &pm) - poly(coef, centre, &pm);
        let dz = IDual::<1>::var(piece, 0);
        let e = fun(f, &dz) - poly(coef, centre, &dz);
        let mv = at_m + e.d[0] * (piece - pm);
        let v = meet(mv, e.v);
        if !(v.lo.is_finite() && v.hi.is_finite()) || v.lo > v.hi {
            return None;
        }
        dist = Some(match dist {
            None => v,
            Some(d) => d.hull(&v),
        });
    }
    dist
}

/// The stand-ins the right-hand side `g` needs over the box `b` (states) and `bu`
/// (inputs); `None` if it needs none or one cannot be fitted.
pub(crate) fn plan(g: &Graph, b: &[Interval], bu: &[Interval]) -> Option<StandIns> {
    let mut vals: Vec<Interval> = Vec::new();
    let mut out = vec![Interval::point(0.0); g.outputs.len()];
    g.eval_with(&mut vals, b, bu, &mut out);
    let mut subs = Vec::new();
    let mut dist = Vec::new();
    for (i, op) in g.ops.iter().enumerate() {
        if let Op::Un(f, a) = *op {
            if needs(f, vals[a]) {
                let (centre, coef, d) = fit(f, vals[a])?;
                subs.push(StandIn {
                    node: i,
                    centre,
                    coef,
                    input: bu.len() + dist.len(),
                });
                dist.push(d);
            }
        }
    }
    if subs.is_empty() {
        return None;
    }
    Some(StandIns {
        graph: g.with_stand_ins(&subs),
        dist,
    })
}

/// Interval Jacobians of `g` over the box `d` (states), `u` (inputs) and `w` (the
/// disturbances, inputs after `u`): `df/dx` (`n x n`, row-major) and `df/dw`
/// (`n x w.len()`), by forward mode on [`IDual`] (8 directions per pass).
pub(crate) fn jacobians(
    g: &Graph,
    d: &[Interval],
    u: &[Interval],
    w: &[Interval],
) -> (Vec<Interval>, Vec<Interval>) {
    let (n, m) = (d.len(), w.len());
    let zero = Interval::point(0.0);
    let mut jx = vec![zero; n * n];
    let mut jw = vec![zero; n * m];
    let mut scratch = Vec::new();
    let mut out = vec![IDual::<8>::constant(zero); g.outputs.len()];
    let mut start = 0;
    while start < n + m {
        let seed = |k: usize, v: Interval| {
            if k >= start && k < start + 8 {
                IDual::<8>::var(v, k - start)
            } else {
                IDual::<8>::constant(v)
            }
        };
        let xs: Vec<IDual<8>> = d.iter().enumerate().map(|(k, &v)| seed(k, v)).collect();
        let mut us: Vec<IDual<8>> = u.iter().map(|&v| IDual::<8>::constant(v)).collect();
        us.extend(w.iter().enumerate().map(|(k, &v)| seed(n + k, v)));
        g.eval_with(&mut scratch, &xs, &us, &mut out);
        for i in 0..n {
            for k in start..(start + 8).min(n + m) {
                let v = out[i].d[k - start];
                if k < n {
                    jx[i * n + k] = v;
                } else {
                    jw[i * m + (k - n)] = v;
                }
            }
        }
        start += 8;
    }
    (jx, jw)
}

/// Bound of the deviation `e = x - y` of the true flow from the nominal one over a step of
/// length `h` (module docs): a box `E` containing `e(t)` for `t` in `[0, h]` and the
/// enclosure of `e(h)`; `None` if the Picard test does not close.
pub(crate) fn deviation(
    jx: &[Interval],
    jw: &[Interval],
    w: &[Interval],
    h: f64,
) -> Option<(Vec<Interval>, Vec<Interval>)> {
    let m = w.len();
    let n = jw.len().checked_div(m).unwrap_or(0);
    let zero = Interval::point(0.0);
    // The disturbance's direct effect Jw W, row by row.
    let bw: Vec<Interval> = (0..n)
        .map(|i| (0..m).fold(zero, |acc, j| acc + jw[i * m + j] * w[j]))
        .collect();
    let image = |e: &[Interval], t: Interval| -> Vec<Interval> {
        (0..n)
            .map(|i| t * (0..n).fold(bw[i], |acc, k| acc + jx[i * n + k] * e[k]))
            .collect()
    };
    let th = Interval::new(0.0, h);
    let mut e: Vec<Interval> = image(&vec![zero; n], th);
    for _ in 0..12 {
        let inf: Vec<Interval> = e
            .iter()
            .map(|x| {
                let r = 0.2 * (x.hi - x.lo) + 1e-15 + 1e-12 * x.lo.abs().max(x.hi.abs());
                Interval::new(x.lo - r, x.hi + r)
            })
            .collect();
        let next = image(&inf, th);
        if next.iter().any(|x| !(x.lo.is_finite() && x.hi.is_finite())) {
            return None;
        }
        if next
            .iter()
            .zip(&inf)
            .all(|(a, b)| b.lo <= a.lo && a.hi <= b.hi)
        {
            // e(t) stays in `inf`, hence in its image `next`, for every t in [0, h].
            let end: Vec<Interval> = image(&next, Interval::point(h))
                .iter()
                .zip(&next)
                .map(|(a, b)| meet(*a, *b))
                .collect();
            return Some((next, end));
        }
        e = next;
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    /// The disturbance bound against point evaluations (an independent computation: the
    /// function and the polynomial evaluated at a point with outward rounding): for 400
    /// random operand ranges of `abs` across 0 and `sqrt` near 0, `f(z) - p(z)` at 2,000
    /// points of each (the ends, abs's kink, random points) lies in `W`, and `W` is at most 1.5x the sampled spread plus the
    /// width of the sampled points' own rounding (not vacuous).
    #[test]
    fn disturbance_bounds_contain_every_point_and_are_tight() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        for case in 0..400 {
            let (f, z) = if case % 2 == 0 {
                let lo = -rng.gen_range(1e-4..1.0);
                (Un::Abs, Interval::new(lo, rng.gen_range(1e-4..1.0)))
            } else {
                let lo = rng.gen_range(0.0..1e-4);
                (Un::Sqrt, Interval::new(lo, lo + rng.gen_range(1e-5..1.0)))
            };
            assert!(needs(f, z), "{f:?} over {z:?} needs a stand-in");
            let (centre, coef, w) = fit(f, z).expect("fits");
            let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
            for k in 0..2000 {
                let x = if k == 0 {
                    z.lo
                } else if k == 1 {
                    z.hi
                } else if k == 2 && f == Un::Abs {
                    0.0
                } else {
                    rng.gen_range(z.lo..=z.hi)
                };
                let p = Interval::point(x);
                let d = fun(f, &p) - poly(&coef, centre, &p);
                assert!(
                    d.lo <= w.hi && w.lo <= d.hi,
                    "{f:?} over {z:?}: f - p at {x} is {d:?}, outside {w:?}"
                );
                lo = lo.min(d.lo);
                hi = hi.max(d.hi);
            }
            assert!(
                w.hi - w.lo <= 1.5 * (hi - lo) + 1e-12,
                "{f:?} over {z:?}: bound {w:?} against sampled [{lo}, {hi}]"
            );
        }
    }

    /// The graph with a stand-in, fed the true disturbance `f(z) - p(z)` as its input,
    /// computes the original function (to rounding), at 1,000 random points.
    #[test]
    fn stand_in_graph_with_the_true_disturbance_is_the_original() {
        let sys = samara_system::System::parse(
            "state w, v\ninput u\nw' = -w * sqrt(w^2 + 1e-5) + u * abs(v)\nv' = w\nperiod 1\nhorizon 1\nobserve w\nactuate u = net[0]\ninit w in [-1, 1]\ninit v in [-1, 1]\n",
            "t.sys",
        )
        .expect("parses");
        let g = sys.rhs_graph();
        let b = [Interval::new(-0.05, 0.05), Interval::new(-0.3, 0.2)];
        let bu = [Interval::new(0.5, 1.5)];
        let si = plan(g, &b, &bu).expect("needs stand-ins");
        assert_eq!(si.dist.len(), 2, "the sqrt near 0 and the abs across 0");
        let subs: Vec<(usize, Un, usize)> = g
            .ops
            .iter()
            .enumerate()
            .filter_map(|(i, op)| match *op {
                Op::Un(f @ (Un::Sqrt | Un::Abs), a) => Some((i, f, a)),
                _ => None,
            })
            .collect();
        // The stand-ins' polynomials, fitted over the operands' ranges on the box as
        // plan() fits them.
        let mut r = Vec::new();
        let mut o = [Interval::point(0.0); 2];
        g.eval_with(&mut r, &b, &bu, &mut o);
        let fits: Vec<(f64, Vec<f64>)> = subs
            .iter()
            .map(|&(_, f, a)| {
                let (centre, coef, _) = fit(f, r[a]).expect("fits");
                (centre, coef)
            })
            .collect();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for _ in 0..1000 {
            let x = [rng.gen_range(-0.05..0.05), rng.gen_range(-0.3..0.2)];
            let u = [rng.gen_range(0.5..1.5)];
            let mut vals: Vec<f64> = Vec::new();
            let mut want = [0.0; 2];
            g.eval_with(&mut vals, &x, &u, &mut want);
            // The true disturbances, in the order plan() numbered them.
            let mut ue = u.to_vec();
            for (&(_, f, a), (centre, coef)) in subs.iter().zip(&fits) {
                let z = vals[a];
                ue.push(fun(f, &z) - poly(coef, *centre, &z));
            }
            let mut got = [0.0; 2];
            si.graph.eval(&x, &ue, &mut got);
            for i in 0..2 {
                assert!(
                    (got[i] - want[i]).abs() <= 1e-12 * (1.0 + want[i].abs()),
                    "output {i} at {x:?}: {} vs {}",
                    got[i],
                    want[i]
                );
            }
        }
    }
}

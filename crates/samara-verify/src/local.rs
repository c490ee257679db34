//! Relational properties around a fixed point, decided where they are thin.
//!
//! A local Lipschitz property (`for x1 in ball(x0, eps), |f(x1) - f(x0)| <= L
//! norm(x1 - x0)`, the case study's `p5_lipschitz`) lowers to a query with two
//! applications of one network: `f` at the data point `p` (a degenerate box) and `f` at
//! `x1` in the ball `B`. Every inequality of its counterexample region is homogeneous in
//! `d = x1 - p`: it is exactly 0 at `d = 0` (both sides of the Lipschitz bound vanish).
//! The region's closure therefore contains `x1 = p` whether or not the property holds,
//! and no bound over a box around `p` can show it empty: the branch and bound reports
//! `thin_region`. Near `p` the question is one about the network's linear piece:
//!
//! 1. A box `P = [p - delta, p + delta] ∩ B` on which every ReLU is stable (sound
//!    interval bounds, [`samara_bounds::symbolic::hidden_pre`]; `delta` halved from the
//!    ball's radius until they are). There `f(p + d) = f(p) + J d` with `J` the piece's
//!    Jacobian, computed in exact rational arithmetic.
//! 2. On `P` each disjunct is a cone `{d : g_i . d (cmp) 0}` (the rows `g_i` exact). A
//!    cone meets `P - p` outside `0` iff it meets one face of the cube of radius `t`
//!    (`t` the smallest extent of `P - p` on a side where it has one: scaling a cone point
//!    to infinity norm `t` keeps it in `P - p`). Each face is a box: the min-max LP of
//!    [`samara_bounds::lp::minmax`] gives either a point (re-evaluated concretely, then
//!    checked beyond rounding and in exact arithmetic like every counterexample of this
//!    crate) or weights whose combination of the rows is positive on the face, which is
//!    checked in exact rational arithmetic (the certificate of emptiness).
//!    `d = 0` itself is in the disjunct only if none of its inequalities is strict
//!    (then it is a counterexample like any other and this route steps aside).
//! 3. `B \ P` is covered by the boxes `{x1 in B : x1_k >= p_k + delta}` and
//!    `{x1 in B : x1_k <= p_k - delta}`; `p` lies in none of them, so their questions are
//!    not thin there, and the ordinary engine ([`crate::prove`]) decides them.
//!
//! The route applies only to that shape (two applications of the same piecewise-linear
//! network, one at a point inside the other's box, every row homogeneous at the point in
//! exact arithmetic); anything else, and a point on a kink of the network (no stable
//! box), goes to the ordinary engine unchanged.

use crate::exact::{exact_satisfies, q};
use crate::net::PwlNet;
use crate::point::Point;
use crate::{prove, Counterexample, Prepared, Settings, UnknownReason, Verdict, VerifyError};
use num_rational::BigRational;
use num_traits::{Signed, Zero};
use samara_spec::normal::{Cmp, Goal, Query, Var};
use std::time::Instant;

/// Relative tolerance (against the magnitude of the row's constant and of its terms at
/// the point) within which a row's value at the point counts as the rounding of an exact
/// 0 (the lowering folds the point's coordinates into constants in f64: a few ulps).
pub(crate) const HOMOGENEOUS_TOLERANCE: f64 = 1e-12;

/// One homogeneous row `g . d (cmp) 0`, `g` exact.
struct Row {
    g: Vec<BigRational>,
    strict: bool,
}

/// The shape this module decides: the point application, the ball application, the
/// network.
struct Shape<'a> {
    ip: usize,
    ib: usize,
    net: &'a PwlNet,
    p: Vec<f64>,
}

fn shape<'a>(q0: &Query, prep: &'a Prepared) -> Option<Shape<'a>> {
    if q0.goal != Goal::Prove || !q0.free_vars.is_empty() || q0.applications.len() != 2 {
        return None;
    }
    let (a0, a1) = (&q0.applications[0], &q0.applications[1]);
    if a0.network != a1.network || a0.n_inputs != a1.n_inputs {
        return None;
    }
    let is_point = |a: &samara_spec::normal::Application| a.input_box.iter().all(|b| b.0 == b.1);
    let (ip, ib) = match (is_point(a0), is_point(a1)) {
        (true, false) => (0, 1),
        (false, true) => (1, 0),
        _ => return None,
    };
    let p: Vec<f64> = q0.applications[ip].input_box.iter().map(|b| b.0).collect();
    // Inside the ball's box, or outside it only by the rounding of the domain's bounds
    // (a data point on the domain's edge: 1.0 against a normalised bound
    // 0.9999999999999999); the box is then widened to hold it (see `prove_near_point`).
    let inside = q0.applications[ib].input_box.iter().zip(&p).all(|(b, v)| {
        let tol = HOMOGENEOUS_TOLERANCE * v.abs().max(b.0.abs()).max(b.1.abs());
        b.0 - tol <= *v && *v <= b.1 + tol
    });
    if !inside || p.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let net = prep.pwl.get(&a0.network)?.as_ref().ok()?;
    Some(Shape { ip, ib, net, p })
}

/// A box `(lo, hi)` and the phase of every ReLU map's neurons on it (`true` active).
type StableBox = (Vec<f64>, Vec<f64>, Vec<Vec<bool>>);

/// A box around `p` inside `[lo, hi]` on which every ReLU of `net` is stable, with the
/// phase of each ReLU map's neurons there (`true` active).
fn stable_box(net: &PwlNet, p: &[f64], lo: &[f64], hi: &[f64]) -> Option<StableBox> {
    let mut delta = lo
        .iter()
        .zip(hi)
        .zip(p)
        .map(|((a, b), v)| (v - a).max(b - v))
        .fold(0.0, f64::max);
    for _ in 0..60 {
        let plo: Vec<f64> = p.iter().zip(lo).map(|(v, a)| (v - delta).max(*a)).collect();
        let phi: Vec<f64> = p.iter().zip(hi).map(|(v, b)| (v + delta).min(*b)).collect();
        let pre = samara_bounds::symbolic::hidden_pre(&net.maps, &plo, &phi, None);
        let exact_pre = exact_where_possible(net, &plo, &phi);
        let mut phases = Vec::new();
        let mut stable = true;
        for (k, (_, relu)) in net.maps.iter().enumerate() {
            if !*relu {
                continue;
            }
            let Some(b) = pre.get(k) else {
                stable = false;
                break;
            };
            let mut ph = Vec::with_capacity(b.len());
            for (i, &(l, u)) in b.iter().enumerate() {
                // The symbolic bounds are the tighter; the intervals that round only
                // where inexact keep a neuron that is exactly 0 on the box (a dead
                // layer below it) at [0, 0] where the symbolic ones widen it by an ulp.
                let e = exact_pre[k][i];
                let (l, u) = (l.max(e.lo), u.min(e.hi));
                if l >= 0.0 {
                    ph.push(true);
                } else if u <= 0.0 {
                    ph.push(false);
                } else {
                    stable = false;
                    break;
                }
            }
            if !stable {
                break;
            }
            phases.push(ph);
        }
        if stable {
            return Some((plo, phi, phases));
        }
        delta *= 0.5;
    }
    None
}

/// Pre-activation intervals of every map over the box, rounded only where an operation
/// was inexact ([`samara_bounds::constant::Iv`]).
fn exact_where_possible(
    net: &PwlNet,
    lo: &[f64],
    hi: &[f64],
) -> Vec<Vec<samara_bounds::constant::Iv>> {
    use samara_bounds::constant::Iv;
    let mut a: Vec<Iv> = lo
        .iter()
        .zip(hi)
        .map(|(l, h)| Iv { lo: *l, hi: *h })
        .collect();
    let mut out = Vec::with_capacity(net.maps.len());
    for (m, relu) in &net.maps {
        let z = samara_bounds::constant::affine(m, &a);
        a = if *relu {
            z.iter().map(|v| v.relu()).collect()
        } else {
            z.clone()
        };
        out.push(z);
    }
    out
}

/// The exact Jacobian `J` (outputs x inputs) of the network on a box where every ReLU
/// has the given phase.
fn jacobian(net: &PwlNet, phases: &[Vec<bool>]) -> Option<Vec<Vec<BigRational>>> {
    let n = net.maps.first()?.0.inp;
    // Rows of the running product, starting from the identity.
    let mut j: Vec<Vec<BigRational>> = (0..n)
        .map(|i| {
            (0..n)
                .map(|c| {
                    if c == i {
                        BigRational::from_integer(1.into())
                    } else {
                        BigRational::zero()
                    }
                })
                .collect()
        })
        .collect();
    let mut r = 0;
    for (m, relu) in &net.maps {
        let mut next = Vec::with_capacity(m.out);
        for i in 0..m.out {
            let active = !*relu || phases.get(r).and_then(|ph| ph.get(i)).copied()?;
            let mut row = vec![BigRational::zero(); n];
            if active {
                for (k, w) in m.row(i).nonzeros() {
                    let jk = &j[k];
                    let w = q(w)?;
                    for (c, v) in jk.iter().enumerate() {
                        if !v.is_zero() {
                            row[c] += &w * v;
                        }
                    }
                }
            }
            next.push(row);
        }
        if *relu {
            r += 1;
        }
        j = next;
    }
    Some(j)
}

/// The disjunct's rows in `d` on the linear piece (`None`: a row is not homogeneous at
/// `p`, the route does not apply; `Some(None)`: a constant row is false, the disjunct is
/// empty).
fn rows(
    cs: &[samara_spec::normal::Constraint],
    sh: &Shape,
    jac: &[Vec<BigRational>],
) -> Option<Option<Vec<Row>>> {
    let n = sh.p.len();
    let mut out = Vec::new();
    for c in cs {
        let mut g = vec![BigRational::zero(); n];
        let mut at0 = q(c.expr.constant)?;
        let mut mag = c.expr.constant.abs();
        let mut y0 = vec![0.0; jac.len()];
        let mut y1 = vec![0.0; jac.len()];
        for (v, a) in &c.expr.terms {
            match *v {
                Var::Input { app, index } if index < n => {
                    let a = q(*a)?;
                    at0 += &a * q(sh.p[index])?;
                    mag += (num_traits::ToPrimitive::to_f64(&a).unwrap_or(f64::INFINITY)
                        * sh.p[index])
                        .abs();
                    if app == sh.ib {
                        g[index] += a;
                    } else if app != sh.ip {
                        return None;
                    }
                }
                Var::Output { app, index } if index < jac.len() => {
                    if app == sh.ip {
                        y0[index] += a;
                    } else if app == sh.ib {
                        y1[index] += a;
                    } else {
                        return None;
                    }
                }
                _ => return None,
            }
        }
        // c0 f(p) + c1 f(p + d) = (c0 + c1) f(p) + c1 J d: homogeneous only if c0 = -c1.
        for k in 0..jac.len() {
            if y0[k] + y1[k] != 0.0 || (y0[k] != 0.0 && y0[k] != -y1[k]) {
                return None;
            }
            if y1[k] != 0.0 {
                let a = q(y1[k])?;
                for (gi, jv) in g.iter_mut().zip(&jac[k]) {
                    *gi += &a * jv;
                }
            }
        }
        // Homogeneous up to the lowering's rounding: the point's coordinates are folded
        // into the constants in f64 (`d_j - d_k` arrives as `x1_j - x1_k + (p_k - p_j)`
        // rounded), so the value at `d = 0` is 0 only within a few ulps of the terms.
        // Within HOMOGENEOUS_TOLERANCE the row is read as the exactly homogeneous one it
        // was lowered from; beyond it the route does not apply.
        let at0 = num_traits::ToPrimitive::to_f64(&at0).unwrap_or(f64::INFINITY);
        if at0.abs() > HOMOGENEOUS_TOLERANCE * mag {
            return None;
        }
        if g.iter().all(|v| v.is_zero()) {
            // The row is `0 (cmp) 0`.
            if c.cmp == Cmp::Lt {
                return Some(None);
            }
            continue;
        }
        match c.cmp {
            Cmp::Le => out.push(Row { g, strict: false }),
            Cmp::Lt => out.push(Row { g, strict: true }),
            Cmp::Eq => {
                out.push(Row {
                    g: g.iter().map(|v| -v).collect(),
                    strict: false,
                });
                out.push(Row { g, strict: false });
            }
        }
    }
    Some(Some(out))
}

/// What one face of the cube came to.
enum Face {
    Empty,
    Point(Vec<f64>),
    Undecided,
}

fn face(rows: &[Row], lo: &[f64], hi: &[f64]) -> Face {
    let coef: Vec<Vec<f64>> = rows
        .iter()
        .map(|r| {
            r.g.iter()
                .map(|v| num_traits::ToPrimitive::to_f64(v).unwrap_or(f64::NAN))
                .collect()
        })
        .collect();
    let refs: Vec<&[f64]> = coef.iter().map(|v| v.as_slice()).collect();
    let Some(mm) = samara_bounds::lp::minmax(&refs, &vec![0.0; rows.len()], lo, hi) else {
        return Face::Undecided;
    };
    if mm.value < 0.0 {
        return Face::Point(mm.x);
    }
    // Certificate: min over the face of sum lambda_i g_i . d > 0, exactly.
    let n = lo.len();
    let mut h = vec![BigRational::zero(); n];
    for (r, l) in rows.iter().zip(&mm.lambda) {
        if *l <= 0.0 {
            continue;
        }
        let Some(l) = q(*l) else {
            return Face::Undecided;
        };
        for (hi_, g) in h.iter_mut().zip(&r.g) {
            *hi_ += &l * g;
        }
    }
    let mut min = BigRational::zero();
    for (k, c) in h.iter().enumerate() {
        let (Some(a), Some(b)) = (q(lo[k]), q(hi[k])) else {
            return Face::Undecided;
        };
        let (u, v) = (c * a, c * b);
        min += if u < v { u } else { v };
    }
    if min.is_positive() {
        Face::Empty
    } else {
        Face::Undecided
    }
}

/// Decide a query of the shape of the module doc, or `None` when it has another shape
/// (the caller runs the ordinary engine).
pub(crate) fn prove_near_point(
    q0: &Query,
    prep: &Prepared,
    s: &Settings,
) -> Option<Result<Verdict, VerifyError>> {
    let t0 = Instant::now();
    let sh = shape(q0, prep)?;
    let b1 = &q0.applications[sh.ib].input_box;
    let lo: Vec<f64> = b1.iter().map(|b| b.0).collect();
    let hi: Vec<f64> = b1.iter().map(|b| b.1).collect();
    // The box widened to hold the point (a proof over the wider box holds for the
    // query's; points are clamped into the query's box before they are checked).
    let wlo: Vec<f64> = lo.iter().zip(&sh.p).map(|(a, v)| a.min(*v)).collect();
    let whi: Vec<f64> = hi.iter().zip(&sh.p).map(|(b, v)| b.max(*v)).collect();
    let (plo, phi, phases) = stable_box(sh.net, &sh.p, &wlo, &whi)?;
    let jac = jacobian(sh.net, &phases)?;
    let mut per_disjunct = Vec::with_capacity(q0.region.len());
    for conj in &q0.region {
        match rows(conj, &sh, &jac)? {
            None => per_disjunct.push(None),
            // d = 0 satisfies a disjunct without strict rows: an ordinary counterexample.
            Some(r) if !r.iter().any(|r| r.strict) => return None,
            Some(r) => per_disjunct.push(Some(r)),
        }
    }
    // The faces of the box P - p that do not pass through 0: scaling a point of a cone
    // until it meets the box's boundary lands on one of them.
    let n = sh.p.len();
    let ext_lo: Vec<f64> = (0..n).map(|k| sh.p[k] - plo[k]).collect();
    let ext_hi: Vec<f64> = (0..n).map(|k| phi[k] - sh.p[k]).collect();
    if ext_lo
        .iter()
        .chain(&ext_hi)
        .any(|e| !(*e >= 0.0 && e.is_finite()))
    {
        return None;
    }
    let mut faces = Vec::new();
    for k in 0..n {
        for (reach, sign) in [(ext_hi[k], 1.0), (ext_lo[k], -1.0)] {
            if reach <= 0.0 {
                continue;
            }
            let mut flo: Vec<f64> = ext_lo.iter().map(|e| -e).collect();
            let mut fhi = ext_hi.clone();
            flo[k] = sign * reach;
            fhi[k] = sign * reach;
            faces.push((flo, fhi));
        }
    }
    if faces.is_empty() {
        return None;
    }
    let nets: Vec<&PwlNet> = vec![sh.net; 2];
    let plain = prep.plain.get(&q0.applications[0].network)?;
    let mut unknown: Option<UnknownReason> = None;
    for (di, rs) in per_disjunct.iter().enumerate() {
        let Some(rs) = rs else { continue };
        for (flo, fhi) in &faces {
            match face(rs, flo, fhi) {
                Face::Empty => {}
                Face::Undecided => {
                    unknown.get_or_insert(UnknownReason::ThinRegion { bound: 0.0 });
                }
                Face::Point(d) => {
                    let x1: Vec<f64> =
                        sh.p.iter()
                            .zip(&d)
                            .zip(lo.iter().zip(&hi))
                            .map(|((v, dv), (a, b))| (v + dv).clamp(*a, *b))
                            .collect();
                    let mut inputs = vec![Vec::new(), Vec::new()];
                    inputs[sh.ip] = sh.p.clone();
                    inputs[sh.ib] = x1;
                    let outputs = inputs.iter().map(|x| plain.eval_f64(x)).collect();
                    let pt = Point {
                        inputs,
                        outputs,
                        free: Vec::new(),
                    };
                    let cs = &q0.region[di];
                    if pt.robustly_satisfies(cs).is_ok()
                        && exact_satisfies(&nets, &pt, cs) == Some(true)
                    {
                        let margin = pt.margin(cs);
                        return Some(Ok(Verdict::Violated(Counterexample {
                            point: pt,
                            margin,
                            exact: Some(true),
                            disjunct: di,
                        })));
                    }
                    unknown.get_or_insert(UnknownReason::ThinRegion { bound: 0.0 });
                }
            }
        }
    }
    // B \ P: the boxes beyond P's faces, by the ordinary engine.
    for k in 0..n {
        for upper in [true, false] {
            let mut b = b1.clone();
            if upper {
                if phi[k] >= hi[k] {
                    continue;
                }
                b[k].0 = phi[k].max(lo[k]);
            } else {
                if plo[k] <= lo[k] {
                    continue;
                }
                b[k].1 = plo[k].min(hi[k]);
            }
            let mut sub = q0.clone();
            sub.applications[sh.ib].input_box = b;
            let left = s.timeout.left(t0);
            if left.is_zero() {
                return Some(Ok(Verdict::Unknown(UnknownReason::Timeout { nodes: 0 })));
            }
            match prove(
                &sub,
                prep,
                &Settings {
                    timeout: left,
                    ..*s
                },
            ) {
                Ok(Verdict::Proved) => {}
                Ok(Verdict::Violated(c)) => return Some(Ok(Verdict::Violated(c))),
                Ok(Verdict::Unknown(u)) => {
                    unknown.get_or_insert(u);
                }
                Err(e) => return Some(Err(e)),
            }
        }
    }
    Some(Ok(match unknown {
        Some(u) => Verdict::Unknown(u),
        None => Verdict::Proved,
    }))
}

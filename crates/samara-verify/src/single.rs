//! The exact engine's front: every [`Problem`] (a critical value, the slack form of a
//! `Prove` query, one network application or several) is lowered to one
//! piecewise-linear network and solved by the branch-and-bound optimiser of
//! `samara-bounds` ([`samara_bounds::optimise`]: attacks, input and ReLU splitting,
//! CROWN and alpha-CROWN bounds, LP bounds certified by weak duality), with the
//! constraints on inputs, free variables and outputs as linear rows inside the bounding.
//!
//! Several applications (a relational property such as the case study's
//! `p5_lipschitz`, `f(x1)` against `f(x0)`) become one network: the block-diagonal
//! product of the applications' networks ([`product`]), inputs and outputs
//! concatenated, so the relational rows are ordinary linear rows over the product's
//! inputs and outputs. Free variables without a finite bound get one from the
//! constraints they appear in alone and sound interval bounds of the other terms
//! ([`bound_free`]); one that stays unbounded gives `Unsupported`.
//!
//! Every witness is re-evaluated through the plain networks (`Network::eval_f64`) and
//! checked against the constraints in f64 before it counts, so the contracts of
//! [`BabResult`] hold: `best` satisfies every constraint, `upper` is a sound bound of
//! the objective when the search is `complete`.

use crate::net::{affine_bounds, PwlNet};
use crate::point::{repair_free, tighten, BabResult, Limits, Point, Problem};
use samara_bounds::optimise::{self as opt, Accepted, LinearFn};
use samara_nn::Affine;
use samara_spec::normal::{Cmp, LinExpr, Var};
use std::borrow::Cow;
use std::time::Instant;

/// The maps of one network that computes every application at once: the
/// block-diagonal product of `nets`, inputs and outputs concatenated in order.
///
/// The networks may differ in depth and in where their ReLUs are. Map `k` of the
/// product applies a ReLU when map `k` of any network does; a network whose map `k` has
/// none (or that has no map `k`: an identity) carries its vector `a` through that ReLU
/// as the pair `(a, -a)`, from which the next map takes `a = relu(a) - relu(-a)`. Only
/// negations and zeros are added, so the product computes exactly the networks' values.
pub fn product(nets: &[&PwlNet]) -> Vec<(Affine, bool)> {
    if let [one] = nets {
        return one.maps.clone();
    }
    let depth = nets.iter().map(|n| n.maps.len()).max().unwrap_or(0);
    // Per network: its vector's width, and whether it is carried as `(a, -a)`.
    let mut state: Vec<(usize, bool)> = nets.iter().map(|n| (n.n_inputs(), false)).collect();
    let mut maps = Vec::with_capacity(depth + 1);
    for k in 0..depth {
        let relu = nets.iter().any(|n| n.maps.get(k).is_some_and(|m| m.1));
        let mut blocks: Vec<(Affine, bool)> = Vec::with_capacity(nets.len());
        for (n, st) in nets.iter().zip(state.iter_mut()) {
            let (w, split) = *st;
            let m = match n.maps.get(k) {
                Some((m, _)) => Cow::Borrowed(m),
                None => Cow::Owned(identity(w)),
            };
            let own_relu = n.maps.get(k).is_some_and(|m| m.1);
            // The block's rows over its current vector (`(a, -a)` when split).
            let cols = if split { 2 * m.inp } else { m.inp };
            let mut rows = vec![0.0; m.out * cols];
            for i in 0..m.out {
                m.row(i).for_each_nonzero(|j, c| {
                    rows[i * cols + j] = c;
                    if split {
                        rows[i * cols + m.inp + j] = -c;
                    }
                });
            }
            let carry = relu && !own_relu;
            if carry {
                let mut both = rows.clone();
                both.extend(rows.iter().map(|c| -c));
                let mut b = m.b.clone();
                b.extend(m.b.iter().map(|c| -c));
                blocks.push((Affine::new(cols, 2 * m.out, both, b), true));
            } else {
                blocks.push((Affine::new(cols, m.out, rows, m.b.clone()), own_relu));
            }
            *st = (m.out, carry);
        }
        maps.push((block_diagonal(&blocks), relu));
    }
    if maps.last().is_some_and(|m| m.1) || state.iter().any(|s| s.1) {
        let blocks: Vec<(Affine, bool)> = state
            .iter()
            .map(|&(w, split)| {
                let cols = if split { 2 * w } else { w };
                let mut rows = vec![0.0; w * cols];
                for i in 0..w {
                    rows[i * cols + i] = 1.0;
                    if split {
                        rows[i * cols + w + i] = -1.0;
                    }
                }
                (Affine::new(cols, w, rows, vec![0.0; w]), false)
            })
            .collect();
        maps.push((block_diagonal(&blocks), false));
    }
    maps
}

fn identity(n: usize) -> Affine {
    let mut w = vec![0.0; n * n];
    for i in 0..n {
        w[i * n + i] = 1.0;
    }
    Affine::new(n, n, w, vec![0.0; n])
}

/// The block-diagonal map of `blocks` (their flags are not used).
fn block_diagonal(blocks: &[(Affine, bool)]) -> Affine {
    let inp: usize = blocks.iter().map(|b| b.0.inp).sum();
    let out: usize = blocks.iter().map(|b| b.0.out).sum();
    let mut w = vec![0.0; out * inp];
    let mut b = Vec::with_capacity(out);
    let (mut r0, mut c0) = (0, 0);
    for (m, _) in blocks {
        for i in 0..m.out {
            let wi = &mut w[(r0 + i) * inp + c0..(r0 + i) * inp + c0 + m.inp];
            m.row(i).for_each_nonzero(|j, v| wi[j] = v);
        }
        b.extend_from_slice(&m.b);
        r0 += m.out;
        c0 += m.inp;
    }
    Affine::new(inp, out, w, b)
}

/// Starts of the attack when a search left open by rounding is run again (see
/// [`solve`]).
const RETRY_ATTACK_STARTS: usize = 8;

/// Sound interval bounds of the outputs of `maps` over the input box (outward rounded).
fn output_bounds(maps: &[(Affine, bool)], lo: &[f64], hi: &[f64]) -> Vec<(f64, f64)> {
    let (mut l, mut h) = (lo.to_vec(), hi.to_vec());
    for (m, relu) in maps {
        let (zl, zh) = affine_bounds(m, &l, &h);
        if *relu {
            l = zl.iter().map(|v| v.max(0.0)).collect();
            h = zh.iter().map(|v| v.max(0.0)).collect();
        } else {
            (l, h) = (zl, zh);
        }
    }
    l.into_iter().zip(h).collect()
}

/// Finite bounds for free variables from the inequalities in which a free variable is
/// the only one (`a t + rest <= 0`, `rest` bounded below by the intervals `range` of
/// its other variables, outward rounded): two rounds, as a bound found in one row can
/// serve another's.
pub fn bound_free(
    free: &mut [(f64, f64)],
    constraints: &[samara_spec::normal::Constraint],
    range: &dyn Fn(Var) -> (f64, f64),
) {
    use crate::net::{down, up};
    for _ in 0..2 {
        for c in constraints {
            if c.cmp == Cmp::Eq {
                continue;
            }
            let mut frees = c.expr.terms.iter().filter_map(|(v, a)| match v {
                Var::Free(k) => Some((*k, *a)),
                _ => None,
            });
            let (Some((k, a)), None) = (frees.next(), frees.next()) else {
                continue;
            };
            if a == 0.0 || k >= free.len() {
                continue;
            }
            // rest >= rmin (outward rounded).
            let mut rmin = c.expr.constant;
            for (v, coef) in &c.expr.terms {
                if matches!(v, Var::Free(_)) {
                    continue;
                }
                let (l, h) = range(*v);
                rmin = down(rmin + down((coef * l).min(coef * h)));
            }
            if rmin.is_nan() || rmin == f64::NEG_INFINITY {
                continue;
            }
            // a t <= -rest <= -rmin.
            let fr = &mut free[k];
            if a > 0.0 {
                fr.1 = fr.1.min(up(up(-rmin) / a));
            } else {
                fr.0 = fr.0.max(down(up(-rmin) / a));
            }
        }
    }
}

/// The row `e` as a function over `v = (x, t)` and the outputs `y` of the product.
fn row(e: &LinExpr, lay: &Layout, sign: f64) -> LinearFn {
    let mut f = LinearFn {
        v: vec![0.0; lay.nx + lay.nf],
        y: vec![0.0; lay.ny],
        d: sign * e.constant,
    };
    for (v, a) in &e.terms {
        match *v {
            Var::Input { app, index } => f.v[lay.inp[app] + index] += sign * a,
            Var::Free(k) => f.v[lay.nx + k] += sign * a,
            Var::Output { app, index } => f.y[lay.out[app] + index] += sign * a,
        }
    }
    f
}

/// Where each application's inputs and outputs lie in the product network.
struct Layout {
    inp: Vec<usize>,
    out: Vec<usize>,
    nx: usize,
    ny: usize,
    nf: usize,
}

/// Solve `p`: maximise its objective (with none, find a point) over its region, by the
/// optimiser on the product of its networks (see the module doc).
pub fn solve(p: &Problem<'_>, limits: Limits) -> BabResult {
    let t0 = Instant::now();
    if let Some(what) = p.malformed() {
        // Never index out of bounds: a malformed problem is not searched.
        return BabResult::unexplored(
            f64::INFINITY,
            false,
            Some(crate::UnknownReason::Unsupported { what }),
        );
    }
    // No time or no nodes: no claim (even for a problem settled at the root).
    if limits.timeout.is_zero() || limits.nodes == 0 {
        return BabResult::unexplored(
            f64::INFINITY,
            false,
            Some(if limits.timeout.is_zero() {
                crate::UnknownReason::Timeout { nodes: 0 }
            } else {
                crate::UnknownReason::NodeLimit { nodes: 0 }
            }),
        );
    }
    let boxes = tighten(&p.boxes, &p.constraints);
    let bad = |(l, h): &(f64, f64)| l.is_nan() || h.is_nan() || l > h;
    if boxes.iter().flatten().any(bad) || p.free.iter().any(bad) {
        return BabResult::unexplored(f64::NEG_INFINITY, true, None);
    }
    let mut lay = Layout {
        inp: Vec::new(),
        out: Vec::new(),
        nx: 0,
        ny: 0,
        nf: p.free.len(),
    };
    for n in &p.nets {
        lay.inp.push(lay.nx);
        lay.out.push(lay.ny);
        lay.nx += n.n_inputs();
        lay.ny += n.n_outputs();
    }
    let maps = product(&p.nets);
    let mut lo: Vec<f64> = boxes.iter().flatten().map(|b| b.0).collect();
    let mut hi: Vec<f64> = boxes.iter().flatten().map(|b| b.1).collect();
    let mut free = p.free.clone();
    if free.iter().any(|f| !f.0.is_finite() || !f.1.is_finite()) {
        let ys = output_bounds(&maps, &lo, &hi);
        let range = |v: Var| match v {
            Var::Input { app, index } => boxes[app][index],
            Var::Output { app, index } => ys[lay.out[app] + index],
            Var::Free(k) => p.free[k],
        };
        bound_free(&mut free, &p.constraints, &range);
        if free.iter().any(bad) {
            return BabResult::unexplored(f64::NEG_INFINITY, true, None);
        }
        if let Some(k) = free
            .iter()
            .position(|f| !f.0.is_finite() || !f.1.is_finite())
        {
            return BabResult::unexplored(
                f64::INFINITY,
                false,
                Some(crate::UnknownReason::Unsupported {
                    what: format!(
                        "free variable {k} has an infinite range that no constraint of the property limits; declare a finite range for it"
                    ),
                }),
            );
        }
    }
    lo.extend(free.iter().map(|f| f.0));
    hi.extend(free.iter().map(|f| f.1));
    let mut constraints = Vec::new();
    for c in &p.constraints {
        match c.cmp {
            Cmp::Eq => {
                for sign in [1.0, -1.0] {
                    constraints.push(opt::Constraint {
                        f: row(&c.expr, &lay, sign),
                        strict: false,
                    });
                }
            }
            Cmp::Le | Cmp::Lt => constraints.push(opt::Constraint {
                f: row(&c.expr, &lay, 1.0),
                strict: c.cmp == Cmp::Lt,
            }),
        }
    }
    let zero = LinExpr {
        terms: Vec::new(),
        constant: 0.0,
    };
    let objective = row(p.objective.as_ref().unwrap_or(&zero), &lay, 1.0);
    let problem = opt::Problem {
        maps: &maps,
        lo,
        hi,
        constraints,
        objective,
    };
    let settings = opt::Settings {
        deadline: limits.timeout.deadline_from(t0),
        max_nodes: limits.nodes,
        gap: limits.gap,
        floor: p.floor,
        ..opt::Settings::default()
    };
    let point = |v: &[f64]| {
        let inputs: Vec<Vec<f64>> = boxes
            .iter()
            .zip(&lay.inp)
            .map(|(bx, &o)| {
                bx.iter()
                    .enumerate()
                    .map(|(j, (l, h))| v[o + j].clamp(*l, *h))
                    .collect()
            })
            .collect();
        let outputs = inputs
            .iter()
            .zip(&p.plain)
            .map(|(x, net)| net.eval_f64(x))
            .collect();
        let mut pt = Point {
            inputs,
            outputs,
            free: v[lay.nx..].to_vec(),
        };
        repair_free(&mut pt, &free, &p.constraints, p.objective.as_ref());
        pt
    };
    let value = |pt: &Point| {
        p.objective
            .as_ref()
            .map(|o| o.eval(|v| pt.value(v)))
            .unwrap_or(0.0)
    };
    let accept = |v: &[f64]| -> Option<Accepted> {
        let pt = point(v);
        if !pt.satisfies(&p.constraints) {
            return None;
        }
        let value = value(&pt);
        if !value.is_finite() {
            return None;
        }
        let stop = p
            .stop_when
            .as_ref()
            .is_some_and(|cs| value >= p.floor && pt.satisfies(cs));
        let mut v: Vec<f64> = pt.inputs.concat();
        v.extend(&pt.free);
        Some(Accepted { v, value, stop })
    };
    let mut r = opt::optimise(&problem, &settings, &accept);
    // A completed search that leaves the question open by rounding only (a slack bound
    // in [floor, floor + rounding] with no witness, or leaves where no point was
    // accepted) is run again with a short attack first: its incumbent cuts the boxes of
    // every node from the root on, which changes the leaves the search ends in (on the
    // case study's `p5_lipschitz`, 2 of its 360 points need it; most re-runs are
    // vacuity checks whose premise truly touches the domain, hence the short attack).
    // Each run is sound on its own; the second one's answer is taken.
    let open = r.complete
        && (r.thin > 0
            || (p.floor.is_finite()
                && r.upper >= p.floor
                && r.best.as_ref().is_none_or(|a| a.value < p.floor)));
    let late = settings.deadline.is_some_and(|d| Instant::now() >= d);
    let spent = r.nodes;
    if open && !late && (limits.nodes == 0 || spent < limits.nodes) {
        if std::env::var_os("SAMARA_OPT_TRACE").is_some() {
            eprintln!(
                "single: left open by rounding after {spent} nodes; again with the attack first"
            );
        }
        r = opt::optimise(
            &problem,
            &opt::Settings {
                attack_after: 0,
                attack_starts: RETRY_ATTACK_STARTS.min(settings.attack_starts),
                max_nodes: if limits.nodes == 0 {
                    0
                } else {
                    limits.nodes - spent
                },
                ..settings
            },
            &accept,
        );
        r.nodes += spent;
    }
    let best = r.best.map(|a| {
        let pt = point(&a.v);
        (pt, a.value)
    });
    let nodes = r.nodes;
    BabResult {
        best,
        upper: r.upper,
        complete: r.complete || r.stopped_early,
        nodes,
        thin_leaves: r.thin,
        stop: r.stop.map(|s| match s {
            opt::Stop::Timeout => crate::UnknownReason::Timeout { nodes },
            opt::Stop::NodeLimit => crate::UnknownReason::NodeLimit { nodes },
        }),
    }
}

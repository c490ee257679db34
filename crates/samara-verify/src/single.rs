//! The one-network front of the exact engine: a problem of [`crate::engine`] with a
//! single piecewise-linear network application and finite bounds on its free variables
//! goes to the branch-and-bound optimiser of `samara-bounds`
//! ([`samara_bounds::optimise`]: input and ReLU splitting, CROWN bounds, LP bounds
//! certified by weak duality), with the constraints on inputs, free variables and outputs
//! as linear rows inside the bounding. Every witness is re-evaluated through the plain
//! network (`Network::eval_f64`) and checked against the constraints in f64, as the old
//! engine's are, so the contracts of [`crate::engine::BabResult`] hold unchanged.
//!
//! Order: [`solve`] (critical values) gives the ReLU-phase engine
//! ([`crate::engine::Problem::solve`]) a first try of 40 nodes, which settles the
//! queries of networks whose ReLUs the domain mostly fixes, then the optimiser has the
//! time left; [`solve_prove`] (the slack form of `Prove`) runs the optimiser first and
//! the phase engine after it when the optimiser is not decisive. Problems the optimiser
//! does not take (several applications, relational queries, infinite free bounds) stay
//! with the phase engine.

use crate::engine::{repair_free, tighten, BabResult, Limits, Point, Problem};
use samara_bounds::optimise::{self as opt, Accepted, LinearFn};
use samara_num::Timeout;
use samara_spec::normal::{Cmp, LinExpr, Var};
use std::time::Instant;

/// Solve `p` by the optimiser when it fits (see the module doc), else by the old engine.
pub fn solve(p: Problem<'_>, limits: Limits) -> BabResult {
    let t0 = Instant::now();
    if solve_single(
        &p,
        Limits {
            timeout: Timeout::from_secs(0),
            ..limits
        },
    )
    .is_none()
    {
        return p.solve(limits);
    }
    // The phase engine first, within a small node budget: on networks whose ReLUs the
    // domain mostly fixes (the case study's 6-6-4-1 and samara-trained 6-64-32-1 ones)
    // its full LP relaxation settles a query in a few nodes where the optimiser's input
    // splitting takes thousands (the wide dl2 network's empty P1: 0.09 s against 11 s).
    let first = Problem {
        nets: p.nets.clone(),
        plain: p.plain.clone(),
        boxes: p.boxes.clone(),
        free: p.free.clone(),
        constraints: p.constraints.clone(),
        objective: p.objective.clone(),
        floor: p.floor,
        stop_when: p.stop_when.clone(),
    }
    .solve(Limits {
        nodes: limits.nodes.min(PHASE_FIRST_NODES),
        ..limits
    });
    let left = limits.timeout.left(t0);
    if first.complete || limits.nodes <= PHASE_FIRST_NODES || left.is_zero() {
        return first;
    }
    solve_single(
        &p,
        Limits {
            timeout: left,
            nodes: limits.nodes - first.nodes.min(limits.nodes),
            ..limits
        },
    )
    .unwrap_or(first)
}

/// The node budget of the phase engine's first try in [`solve`].
const PHASE_FIRST_NODES: usize = 40;

/// [`solve`] for the slack form of a `Prove` question (`p.floor` = 0, `p.stop_when`
/// the region): the optimiser's answer when it is decisive (a witness of the region, or
/// a completed search whose sound bound is below the floor); otherwise the ReLU-phase
/// engine decides with the time left (its LP bound closes regions whose slack bound
/// the optimiser leaves within rounding of 0).
pub fn solve_prove(p: Problem<'_>, limits: Limits) -> BabResult {
    let t0 = Instant::now();
    let Some(r) = solve_single(&p, limits) else {
        return p.solve(limits);
    };
    let found = r.best.as_ref().is_some_and(|(pt, v)| {
        *v >= p.floor && p.stop_when.as_ref().is_some_and(|cs| pt.satisfies(cs))
    });
    let empty = r.complete && r.upper < p.floor;
    let left = limits.timeout.left(t0);
    if found || empty || left.is_zero() {
        return r;
    }
    p.solve(Limits {
        timeout: left,
        ..limits
    })
}

/// The row `e` as a function over `v = (x, t)` and the outputs.
fn row(e: &LinExpr, nx: usize, nf: usize, ny: usize, sign: f64) -> LinearFn {
    let mut f = LinearFn {
        v: vec![0.0; nx + nf],
        y: vec![0.0; ny],
        d: sign * e.constant,
    };
    for (v, a) in &e.terms {
        match *v {
            Var::Input { index, .. } => f.v[index] += sign * a,
            Var::Free(k) => f.v[nx + k] += sign * a,
            Var::Output { index, .. } => f.y[index] += sign * a,
        }
    }
    f
}

/// The optimiser's answer to `p`, or `None` when `p` is not a one-network problem with
/// finite free bounds and variables in range.
pub fn solve_single(p: &Problem<'_>, limits: Limits) -> Option<BabResult> {
    let t0 = Instant::now();
    let ([net], [plain], [bx]) = (p.nets.as_slice(), p.plain.as_slice(), p.boxes.as_slice()) else {
        return None;
    };
    let nx = net.n_inputs();
    let ny = net.n_outputs();
    let nf = p.free.len();
    if bx.len() != nx || p.free.iter().any(|f| !f.0.is_finite() || !f.1.is_finite()) {
        return None;
    }
    let in_range = |e: &LinExpr| {
        e.terms.iter().all(|(v, _)| match *v {
            Var::Input { app, index } => app == 0 && index < nx,
            Var::Output { app, index } => app == 0 && index < ny,
            Var::Free(k) => k < nf,
        })
    };
    if !p
        .constraints
        .iter()
        .map(|c| &c.expr)
        .chain(&p.objective)
        .all(in_range)
    {
        return None;
    }
    // No time or no nodes: no claim, as the phase engine (even for a problem settled at
    // the root).
    if limits.timeout.is_zero() || limits.nodes == 0 {
        return Some(BabResult {
            best: None,
            upper: f64::INFINITY,
            complete: false,
            nodes: 0,
            thin_leaves: 0,
            stop: Some(if limits.timeout.is_zero() {
                crate::UnknownReason::Timeout { nodes: 0 }
            } else {
                crate::UnknownReason::NodeLimit { nodes: 0 }
            }),
        });
    }
    let bx = tighten(std::slice::from_ref(bx), &p.constraints).remove(0);
    let empty = BabResult {
        best: None,
        upper: f64::NEG_INFINITY,
        complete: true,
        nodes: 0,
        thin_leaves: 0,
        stop: None,
    };
    let bad = |(l, h): &(f64, f64)| l.is_nan() || h.is_nan() || l > h;
    if bx.iter().any(bad) || p.free.iter().any(bad) {
        return Some(empty);
    }
    let mut constraints = Vec::new();
    for c in &p.constraints {
        match c.cmp {
            Cmp::Eq => {
                for sign in [1.0, -1.0] {
                    constraints.push(opt::Constraint {
                        f: row(&c.expr, nx, nf, ny, sign),
                        strict: false,
                    });
                }
            }
            Cmp::Le | Cmp::Lt => constraints.push(opt::Constraint {
                f: row(&c.expr, nx, nf, ny, 1.0),
                strict: c.cmp == Cmp::Lt,
            }),
        }
    }
    let zero = LinExpr {
        terms: Vec::new(),
        constant: 0.0,
    };
    let objective = row(p.objective.as_ref().unwrap_or(&zero), nx, nf, ny, 1.0);
    let mut lo: Vec<f64> = bx.iter().map(|b| b.0).collect();
    let mut hi: Vec<f64> = bx.iter().map(|b| b.1).collect();
    lo.extend(p.free.iter().map(|f| f.0));
    hi.extend(p.free.iter().map(|f| f.1));
    let problem = opt::Problem {
        maps: &net.maps,
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
        let inputs: Vec<f64> = v[..nx]
            .iter()
            .zip(&bx)
            .map(|(x, (l, h))| x.clamp(*l, *h))
            .collect();
        let outputs = plain.eval_f64(&inputs);
        let mut pt = Point {
            inputs: vec![inputs],
            outputs: vec![outputs],
            free: v[nx..].to_vec(),
        };
        repair_free(&mut pt, &p.free, &p.constraints, p.objective.as_ref());
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
        let mut v = pt.inputs[0].clone();
        v.extend(&pt.free);
        Some(Accepted { v, value, stop })
    };
    let r = opt::optimise(&problem, &settings, &accept);
    let best = r.best.map(|a| {
        let pt = point(&a.v);
        (pt, a.value)
    });
    let nodes = r.nodes;
    Some(BabResult {
        best,
        upper: r.upper,
        complete: r.complete || r.stopped_early,
        nodes,
        thin_leaves: r.thin,
        stop: r.stop.map(|s| match s {
            opt::Stop::Timeout => crate::UnknownReason::Timeout { nodes },
            opt::Stop::NodeLimit => crate::UnknownReason::NodeLimit { nodes },
        }),
    })
}

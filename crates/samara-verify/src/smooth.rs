//! Queries on networks that are not piecewise linear (sigmoid, tanh, the step `Sign`):
//! a front over the one input-split engine for them, [`samara_bounds::smooth`] (CROWN
//! bounds intersected with interval bounds, the interval rule alone after a layer of
//! steps, the inputs fixed in every disjunct folded into the first layer's bias, an
//! attack with the straight-through gradient through `Sign` first). A query of several
//! applications is one network of them side by side ([`samara_bounds::smooth::Apps`]),
//! and a constraint over inputs as well as outputs is one over that network's outputs
//! with those inputs carried through, so every query without free variables is one the
//! engine states as [`Case`]s ([`to_cases`]).
//!
//! Contract, as for every verdict of this crate: `Proved` only from the engine's sound
//! bounds having closed every piece; a point only when its f64 outputs satisfy the
//! disjunct beyond rounding ([`Point::robustly_satisfies`]); anything cut short is
//! `Unknown` with its reason.

use crate::boxq::BoxUnknown;
use crate::point::Point;
use crate::route::box_reason;
use crate::{Counterexample, UnknownReason, Verdict};
use samara_bounds::search::{Case, CasePoint, Outcome, OutputConstraint, Settings};
use samara_bounds::smooth::Apps;
use samara_bounds::symbolic::Objective;
use samara_nn::{Activation, Layer, Network};
use samara_num::Timeout;
use samara_spec::normal::{Cmp, Query, Var};

/// The inputs carried to the outputs and the cases with their disjuncts' indices
/// ([`to_cases`]).
pub type Cases = (Vec<usize>, Vec<(usize, Case)>);

/// The query as the engine's cases over `nets` side by side: the inputs to carry to the
/// outputs (indices into the concatenated inputs, [`Apps::through`]) and, per disjunct
/// that is not empty, its index and its case: the applications' boxes concatenated and
/// tightened by the constraints on a single input, the other constraints over the
/// networks' outputs and the carried inputs (an equality as two inequalities).
/// `None` with free variables, a variable out of range, or a box that is not finite.
/// One application and no input carried is the VNN-COMP shape ([`crate::boxq`]).
pub fn to_cases(q: &Query) -> Option<Cases> {
    if !q.free_vars.is_empty() {
        return None;
    }
    let apps = &q.applications;
    let in_at: Vec<usize> = apps
        .iter()
        .scan(0, |s, a| {
            *s += a.n_inputs;
            Some(*s - a.n_inputs)
        })
        .collect();
    let out_at: Vec<usize> = apps
        .iter()
        .scan(0, |s, a| {
            *s += a.n_outputs;
            Some(*s - a.n_outputs)
        })
        .collect();
    let n_out: usize = apps.iter().map(|a| a.n_outputs).sum();
    let input = |v: &Var| match *v {
        Var::Input { app, index } if app < apps.len() && index < apps[app].n_inputs => {
            Some(in_at[app] + index)
        }
        _ => None,
    };
    // Inputs in constraints of several terms are carried through.
    let mut through: Vec<usize> = Vec::new();
    for c in q.region.iter().flatten() {
        let e = c.expr.clone().normalised();
        if e.terms.len() > 1 {
            for (v, _) in &e.terms {
                if let Var::Input { .. } = v {
                    let i = input(v)?;
                    if !through.contains(&i) {
                        through.push(i);
                    }
                }
            }
        }
    }
    let width = n_out + through.len();
    let mut cases = Vec::new();
    for (di, conj) in q.region.iter().enumerate() {
        let mut lo: Vec<f64> = apps
            .iter()
            .flat_map(|a| a.input_box.iter().map(|b| b.0))
            .collect();
        let mut hi: Vec<f64> = apps
            .iter()
            .flat_map(|a| a.input_box.iter().map(|b| b.1))
            .collect();
        let mut cons = Vec::new();
        for c in conj {
            let e = c.expr.clone().normalised();
            if let [(v @ Var::Input { .. }, k)] = e.terms.as_slice() {
                // k x_i + d (cmp) 0: a bound on x_i (strict bounds widened to closed
                // ones; a point on the edge is caught by the final re-check).
                let i = input(v)?;
                let t = -e.constant / k;
                if !t.is_finite() {
                    return None;
                }
                if *k > 0.0 || c.cmp == Cmp::Eq {
                    hi[i] = hi[i].min(t);
                }
                if *k < 0.0 || c.cmp == Cmp::Eq {
                    lo[i] = lo[i].max(t);
                }
                continue;
            }
            let mut coef = vec![0.0; width];
            for (v, k) in &e.terms {
                let at = match *v {
                    Var::Output { app, index }
                        if app < apps.len() && index < apps[app].n_outputs =>
                    {
                        out_at[app] + index
                    }
                    Var::Input { .. } => {
                        let i = input(v)?;
                        n_out + through.iter().position(|t| *t == i)?
                    }
                    _ => return None,
                };
                coef[at] += k;
            }
            if c.cmp == Cmp::Eq {
                cons.push(OutputConstraint {
                    obj: Objective {
                        c: coef.iter().map(|v| -v).collect(),
                        d: -e.constant,
                    },
                    strict: false,
                });
            }
            cons.push(OutputConstraint {
                obj: Objective {
                    c: coef,
                    d: e.constant,
                },
                strict: c.cmp == Cmp::Lt,
            });
        }
        if lo.iter().chain(&hi).any(|v| !v.is_finite()) {
            return None;
        }
        if lo.iter().zip(&hi).any(|(a, b)| a > b) {
            continue; // an empty disjunct
        }
        cases.push((
            di,
            Case {
                lo,
                hi,
                constraints: cons,
            },
        ));
    }
    Some((through, cases))
}

/// Whether a network has a step (`Sign`) layer.
pub fn has_steps(net: &Network) -> bool {
    net.layers
        .iter()
        .any(|l| matches!(l, Layer::Act(Activation::Sign)))
}

/// Decide `q` over `nets` (the applications' networks, in order) with
/// [`samara_bounds::smooth::solve_apps`] within `timeout`; `None` when the query is not
/// one the engine states ([`to_cases`]). Networks with a step give the first attack
/// half the time (their gradient is the straight-through estimator's, a direction
/// only, and an image-sized binarised network is rarely proved by bounds).
pub fn prove(q: &Query, nets: &[&Network], timeout: Timeout) -> Option<Verdict> {
    let (through, cases) = to_cases(q)?;
    if cases.is_empty() {
        return Some(Verdict::Proved);
    }
    let apps = Apps {
        nets: nets.to_vec(),
        through,
    };
    let mut settings = Settings {
        timeout,
        ..Default::default()
    };
    let half = 0.5 * timeout.secs();
    if nets.iter().any(|n| has_steps(n)) && half.is_finite() {
        settings.attack_seconds = settings.attack_seconds.max(half);
    }
    // The point of the concatenated inputs `x`, evaluated by every network.
    let point = |x: &[f64]| {
        let mut inputs = Vec::new();
        let mut at = 0;
        for n in nets {
            inputs.push(x[at..at + n.n_inputs()].to_vec());
            at += n.n_inputs();
        }
        Point {
            outputs: nets
                .iter()
                .zip(&inputs)
                .map(|(n, x)| n.eval_f64(x))
                .collect(),
            inputs,
            free: vec![],
        }
    };
    let plain: Vec<Case> = cases.iter().map(|c| c.1.clone()).collect();
    let (outcome, stats) = samara_bounds::smooth::solve_apps(&apps, &plain, &settings);
    let nodes = stats.pieces as usize;
    Some(match outcome {
        Outcome::Proved => Verdict::Proved,
        Outcome::Violated(CasePoint { case, x, .. }) => {
            let d = cases[case].0;
            let pt = point(&x);
            match pt.robustly_satisfies(&q.region[d]) {
                Ok(()) => Verdict::Violated(Counterexample {
                    margin: pt.margin(&q.region[d]),
                    point: pt,
                    exact: None,
                    disjunct: d,
                }),
                Err((margin, tolerance)) => {
                    Verdict::Unknown(UnknownReason::Rounding { margin, tolerance })
                }
            }
        }
        Outcome::Unknown(r) => Verdict::Unknown(match box_reason(BoxUnknown::Stopped(r)) {
            UnknownReason::Timeout { .. } => UnknownReason::Timeout { nodes },
            UnknownReason::NodeLimit { .. } => UnknownReason::NodeLimit { nodes },
            other => other,
        }),
    })
}

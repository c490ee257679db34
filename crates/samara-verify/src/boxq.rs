//! The input-split route for box-shaped queries (the VNN-COMP shape): one network, no
//! free variables, `Prove`, and every disjunct of the counterexample region made of
//! bounds on single inputs plus linear constraints over the outputs only. Such queries
//! go to [`samara_bounds::search`] (symbolic and CROWN bounds, input splitting, an attack
//! first), which suits low-dimensional inputs; anything else stays with the ReLU-phase
//! branch and bound of [`crate::single`].
//!
//! Contract, as for every verdict of this crate: a point is reported only after every
//! constraint of its disjunct (input bounds included, strict ones strictly) is shown to
//! hold there rigorously: on an interval enclosure of its outputs that rounds only where
//! inexact, or failing that with its outputs recomputed in exact rational arithmetic
//! ([`crate::exact::rigorous_satisfies`]);
//! `Proved` only from the search's sound bounds having closed every piece; anything cut
//! short is `Unknown` with its reason.

use crate::exact::rigorous_satisfies;
use crate::net::PwlNet;
use crate::point::Point;
use crate::Counterexample;
use samara_bounds::search::{self, Case, CasePoint, Outcome, OutputConstraint, StopReason};
use samara_bounds::symbolic::Objective;
use samara_num::Timeout;
use samara_spec::normal::{Cmp, Goal, Query, Var};

/// The answer of the input-split route.
#[derive(Clone, Debug, PartialEq)]
pub enum BoxAnswer {
    /// Every disjunct is empty.
    Proved,
    /// A point re-checked in exact arithmetic.
    Violated(Counterexample),
    /// Cut short, or a found point that exact arithmetic did not confirm.
    Unknown(BoxUnknown),
}

/// Why the input-split route gave no verdict.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BoxUnknown {
    /// The search stopped (time, piece budget, or a piece too thin to split).
    Stopped(StopReason),
    /// The point found satisfied the constraints in f64 but not in exact arithmetic.
    NotConfirmed,
}

/// The query as input-split cases (one per non-empty disjunct, with the disjunct's
/// index), or `None` when it is not box-shaped (see the module doc).
pub fn to_cases(q: &Query) -> Option<Vec<(usize, Case)>> {
    if q.applications.len() != 1 || q.goal != Goal::Prove {
        return None;
    }
    match cases_side_by_side(q)? {
        (through, cases) if through.is_empty() => Some(cases),
        _ => None,
    }
}

/// Constraints decided by bounds that round only where an operation was inexact
/// ([`samara_bounds::constant`]): a case with a constraint that holds nowhere on its box
/// is dropped, a constraint that holds everywhere is removed (a case left with none holds
/// at every point of its box: the search's first candidate is one, re-checked exactly).
/// Degenerate queries (an output exactly 0 on the box compared with 0, two outputs of the
/// same expression compared) are so decided at once instead of splitting the box until
/// the time limit: the search's own bounds always widen by a possible rounding, so a
/// strict constraint whose bound is exactly 0 is never closed by them.
fn settle_constant_constraints(
    maps: &[(samara_nn::Affine, bool)],
    cases: Vec<(usize, Case)>,
    deadline: Option<std::time::Instant>,
) -> Vec<(usize, Case)> {
    use samara_bounds::constant::{fates_given, layer_intervals_until, Fate, Iv};
    // One interval pass per distinct box: the cases of a disjunction usually share it.
    type Intervals = (Vec<Iv>, Vec<Iv>);
    let mut seen: Vec<(Vec<f64>, Vec<f64>, Intervals)> = Vec::new();
    cases
        .into_iter()
        .filter_map(|(di, mut c)| {
            let at = match seen.iter().position(|(l, h, _)| *l == c.lo && *h == c.hi) {
                Some(i) => i,
                None => {
                    // Settling is only a shortcut: past the deadline the case stays as it is.
                    let Some(iv) = layer_intervals_until(maps, &c.lo, &c.hi, deadline) else {
                        return Some((di, c));
                    };
                    seen.push((c.lo.clone(), c.hi.clone(), iv));
                    seen.len() - 1
                }
            };
            let f = fates_given(maps, &c.constraints, &seen[at].2);
            if f.contains(&Fate::Never) {
                return None;
            }
            let mut k = 0;
            c.constraints.retain(|_| {
                k += 1;
                f[k - 1] != Fate::Always
            });
            Some((di, c))
        })
        .collect()
}

/// Decide a box-shaped query on `net` (`None` when the query is not box-shaped).
/// `timeout` covers the whole call: the bound pass that settles constant constraints
/// counts against it.
pub fn prove_boxes(q: &Query, net: &PwlNet, timeout: Timeout) -> Option<BoxAnswer> {
    let t0 = std::time::Instant::now();
    let deadline = timeout.deadline_from(t0);
    let cases = settle_constant_constraints(&net.maps, to_cases(q)?, deadline);
    if cases.is_empty() {
        return Some(BoxAnswer::Proved);
    }
    let plain: Vec<Case> = cases.iter().map(|c| c.1.clone()).collect();
    let settings = search::Settings {
        timeout: timeout.left(t0),
        ..Default::default()
    };
    let (outcome, _) = search::solve(&net.maps, &plain, &settings);
    Some(match outcome {
        Outcome::Proved => BoxAnswer::Proved,
        Outcome::Unknown(r) => BoxAnswer::Unknown(BoxUnknown::Stopped(r)),
        Outcome::Violated(CasePoint { case, x, .. }) => {
            let disjunct = cases[case].0;
            let point = Point {
                outputs: vec![net.eval(&x)],
                inputs: vec![x],
                free: vec![],
            };
            let cs = &q.region[disjunct];
            let exact = rigorous_satisfies(&[net], &point, cs);
            if exact != Some(true) {
                return Some(BoxAnswer::Unknown(BoxUnknown::NotConfirmed));
            }
            BoxAnswer::Violated(Counterexample {
                margin: point.margin(cs),
                point,
                exact,
                disjunct,
            })
        }
    })
}

/// The inputs carried to the outputs and the cases with their disjuncts' indices
/// ([`cases_side_by_side`]).
pub type Cases = (Vec<usize>, Vec<(usize, Case)>);

/// The query as the engine's cases over `nets` side by side: the inputs to carry to the
/// outputs (indices into the concatenated inputs, [`samara_bounds::smooth::Apps::through`]) and, per disjunct
/// that is not empty, its index and its case: the applications' boxes concatenated and
/// tightened by the constraints on a single input, the other constraints over the
/// networks' outputs and the carried inputs (an equality as two inequalities).
/// `None` with free variables, a variable out of range, or a box that is not finite.
/// One application and no input carried is the VNN-COMP shape ([`to_cases`]); several
/// are the relational queries of [`crate::smooth`].
pub fn cases_side_by_side(q: &Query) -> Option<Cases> {
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

//! Exact verification of network properties for samara.
//!
//! Queries come in the linear normal form of `samara-spec`: a disjunction of
//! conjunctions of linear constraints over the inputs and outputs of one or more
//! network applications (the counterexample region), with a goal: `Prove` (is the
//! region empty?) or `Optimise` (its supremum/infimum of an objective: the critical
//! value of a parameter).
//!
//! The engine ([`engine`]) is branch and bound over ReLU phases with LP relaxations
//! solved by Clarabel; bounds are made sound from the dual ([`lp`]).
//!
//! Tolerance policy (stated and tested):
//! - A `Violated` verdict always carries a point that violates the property when its
//!   outputs are recomputed by the plain f64 evaluator (`Network::eval_f64`), strict
//!   inequalities strictly. Its margin is reported. When the margin is within 1e-6 of
//!   the boundary (and the networks are piecewise linear) the point is re-checked in
//!   exact rational arithmetic ([`exact`]); if exact arithmetic disagrees with f64 the
//!   verdict is `Unknown`, not `Violated`.
//! - `Proved` means, for every disjunct, a sound upper bound below 0 of the largest
//!   slack `s` with which all its inequalities hold (`e_i + s <= 0`): the closure of the
//!   region is empty. A region that touches its boundary only (the closure is not
//!   empty but no f64 point lies strictly inside) gives `Unknown`, never `Proved`.
//! - Critical values: `value` is the objective at a concrete witness (a lower bound of
//!   the supremum, exact in f64); `upper` is a sound upper bound; `attained` when they
//!   agree to 1e-9; `vacuous` when the witness value reaches the domain extreme to 1e-6
//!   relative. Networks are taken with their weights as stored (float32 weights
//!   are exact in f64).

// Numeric kernels index several arrays (columns, bounds, weights) by one index.
#![allow(clippy::needless_range_loop)]

pub mod case_study;
pub mod engine;
pub mod exact;
pub mod lp;
#[cfg(feature = "highs")]
pub mod milp;
pub mod net;
pub mod robustness;
pub mod smooth;
pub mod tighten;

use engine::{Limits, Point, Problem};
use net::PwlNet;
use rayon::prelude::*;
use samara_nn::Network;
use samara_spec::normal::{Goal, Query, Sense, Var};
use std::collections::HashMap;
use std::time::Instant;
pub use tighten::LpTighten;

/// Verification settings.
#[derive(Clone, Copy, Debug)]
pub struct Settings {
    /// Time limit per query (seconds).
    pub timeout: f64,
    /// Node limit per disjunct.
    pub max_nodes: usize,
    /// Absolute optimality gap at which a critical value counts as exact.
    pub gap: f64,
    /// LP-based tightening of each unstable neuron's pre-activation bounds
    /// ([`tighten`]). Default `Off`: measured on the case study's networks, the LPs
    /// save about as much branch-and-bound work as they cost (`Root` halves one
    /// published network's table and slows the 6-64-32-1 one's by up to 20 %).
    pub lp_tighten: LpTighten,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            timeout: 60.0,
            max_nodes: 200_000,
            gap: 1e-9,
            lp_tighten: LpTighten::Off,
        }
    }
}

/// Bad input (not a verdict).
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum VerifyError {
    /// A query names a network that was not given.
    #[error("query `{query}` uses network `{network}`, which was not given; pass --network {network}=FILE")]
    MissingNetwork {
        /// Query.
        query: String,
        /// Network name.
        network: String,
    },
    /// Dimensions disagree.
    #[error(
        "query `{query}`: network `{network}` has {found} {what} but the property uses {expected}"
    )]
    Dimension {
        /// Query.
        query: String,
        /// Network.
        network: String,
        /// inputs or outputs.
        what: &'static str,
        /// Expected by the query.
        expected: usize,
        /// Found in the network.
        found: usize,
    },
    /// The goal does not fit the call.
    #[error("query `{0}`: {1}")]
    Goal(String, String),
}

/// A counterexample with its margin (how far inside the counterexample region it is;
/// negative numbers are safe margins).
#[derive(Clone, Debug, PartialEq)]
pub struct Counterexample {
    /// The point.
    pub point: Point,
    /// Worst constraint value at the point (< 0 strictly inside).
    pub margin: f64,
    /// Re-checked in exact rational arithmetic (done when the margin is within 1e-6 of
    /// the boundary and the networks are piecewise linear).
    pub exact: Option<bool>,
    /// Which disjunct it satisfies.
    pub disjunct: usize,
}

/// The answer to a `prove` query.
#[derive(Clone, Debug, PartialEq)]
pub enum Verdict {
    /// The counterexample region is empty.
    Proved,
    /// A concrete, re-evaluated counterexample.
    Violated(Counterexample),
    /// Not settled, with the reason.
    Unknown(String),
}

/// The answer to an `optimise` (critical value) query.
#[derive(Clone, Debug, PartialEq)]
pub struct Critical {
    /// Objective at the best concrete witness (`None`: the region is empty).
    pub value: Option<f64>,
    /// Sound bound on the other side (upper bound for `Max`, lower for `Min`).
    pub bound: f64,
    /// The witness.
    pub witness: Option<Point>,
    /// Value and bound agree to the gap.
    pub attained: bool,
    /// The extreme of the objective over the input domain alone (no network
    /// constraint); when the critical value reaches it, the property only holds where
    /// its precondition is empty.
    pub domain_extreme: Option<f64>,
    /// The critical value lies at the edge of what the domain reaches.
    pub vacuous: bool,
    /// The search finished within its limits.
    pub complete: bool,
    /// Branch-and-bound nodes.
    pub nodes: usize,
    /// Wall time.
    pub seconds: f64,
}

/// Networks prepared for the exact engine.
pub struct Prepared<'a> {
    plain: HashMap<String, &'a Network>,
    pwl: HashMap<String, Result<PwlNet, net::EncodeError>>,
}

impl<'a> Prepared<'a> {
    /// Prepare named networks.
    pub fn new(nets: &'a HashMap<String, Network>) -> Self {
        Prepared {
            plain: nets.iter().map(|(k, v)| (k.clone(), v)).collect(),
            pwl: nets
                .iter()
                .map(|(k, v)| (k.clone(), PwlNet::from_network(v)))
                .collect(),
        }
    }

    fn check(&self, q: &Query) -> Result<(), VerifyError> {
        for a in &q.applications {
            let Some(n) = self.plain.get(&a.network) else {
                return Err(VerifyError::MissingNetwork {
                    query: q.name.clone(),
                    network: a.network.clone(),
                });
            };
            for (what, expected, found) in [
                ("inputs", a.n_inputs, n.n_inputs()),
                ("outputs", a.n_outputs, n.n_outputs()),
            ] {
                if expected != found {
                    return Err(VerifyError::Dimension {
                        query: q.name.clone(),
                        network: a.network.clone(),
                        what,
                        expected,
                        found,
                    });
                }
            }
        }
        Ok(())
    }

    fn problem(
        &self,
        q: &Query,
        disjunct: usize,
        objective: Option<samara_spec::normal::LinExpr>,
    ) -> Result<Problem<'_>, String> {
        let mut nets = Vec::new();
        let mut plain = Vec::new();
        for a in &q.applications {
            match &self.pwl[&a.network] {
                Ok(p) => nets.push(p),
                Err(e) => return Err(e.to_string()),
            }
            plain.push(self.plain[&a.network]);
        }
        Ok(Problem {
            nets,
            plain,
            boxes: q.applications.iter().map(|a| a.input_box.clone()).collect(),
            free: q.free_vars.iter().map(|f| (f.1, f.2)).collect(),
            constraints: q.region[disjunct].clone(),
            objective,
            floor: f64::NEG_INFINITY,
            stop_when: None,
        })
    }
}

fn limits(s: &Settings, t0: Instant) -> Limits {
    Limits {
        seconds: (s.timeout - t0.elapsed().as_secs_f64()).max(0.0),
        nodes: s.max_nodes,
        gap: s.gap,
        tighten: s.lp_tighten,
    }
}

/// Is the counterexample region of `q` empty?
pub fn prove(q: &Query, prep: &Prepared, s: &Settings) -> Result<Verdict, VerifyError> {
    prep.check(q)?;
    let t0 = Instant::now();
    let mut unknown = None;
    for d in 0..q.region.len() {
        // Slack formulation: maximise s subject to e_i + s <= 0 for every inequality.
        // The region is empty iff the sound bound of max s is negative; a concrete point
        // with s > 0 satisfies every constraint strictly.
        let mut p = match prep.problem(q, d, None) {
            Ok(p) => p,
            Err(e) => {
                // Smooth activations: the interval prover with input splitting.
                if !q.free_vars.is_empty() {
                    return Ok(Verdict::Unknown(e));
                }
                let nets: Vec<&Network> = q
                    .applications
                    .iter()
                    .map(|a| prep.plain[&a.network])
                    .collect();
                let boxes: Vec<Vec<(f64, f64)>> =
                    q.applications.iter().map(|a| a.input_box.clone()).collect();
                let boxes = engine::tighten(&boxes, &q.region[d]);
                let left = (s.timeout - t0.elapsed().as_secs_f64()).max(0.0);
                match smooth::search(&nets, &boxes, &q.region[d], left, 2_000_000) {
                    smooth::SmoothResult::Empty => continue,
                    smooth::SmoothResult::Witness(pt) => {
                        let margin = pt.margin(&q.region[d]);
                        return Ok(Verdict::Violated(Counterexample {
                            point: pt,
                            margin,
                            exact: None,
                            disjunct: d,
                        }));
                    }
                    smooth::SmoothResult::Unknown(r) => {
                        unknown = Some(r);
                        continue;
                    }
                }
            }
        };
        let original = q.region[d].clone();
        // Only s >= 0 matters, where every inequality holds: tighten the boxes with them.
        p.boxes = engine::tighten(&p.boxes, &original);
        let k = p.free.len();
        p.free.push((-1e3, 1e3));
        for c in p.constraints.iter_mut() {
            if c.cmp != samara_spec::normal::Cmp::Eq {
                c.expr.terms.push((Var::Free(k), 1.0));
                c.cmp = samara_spec::normal::Cmp::Le;
            }
        }
        p.objective = Some(samara_spec::normal::LinExpr {
            terms: vec![(Var::Free(k), 1.0)],
            constant: 0.0,
        });
        p.floor = 0.0;
        p.stop_when = Some(original.clone());
        let r = p.solve(limits(s, t0));
        if let Some((mut pt, _)) = r.best.clone() {
            pt.free.truncate(k);
            if pt.satisfies(&original) {
                let margin = pt.margin(&original);
                let mut exact = None;
                if margin > -1e-6 {
                    let nets: Vec<&PwlNet> = q
                        .applications
                        .iter()
                        .filter_map(|a| prep.pwl[&a.network].as_ref().ok())
                        .collect();
                    if nets.len() == q.applications.len() {
                        exact = exact::exact_satisfies(&nets, &pt, &original);
                    }
                }
                if exact == Some(false) {
                    unknown = Some(format!(
                        "a point violates the property in f64 (margin {margin:.3e}) but not in exact arithmetic: the property sits at the rounding level there"
                    ));
                    continue;
                }
                return Ok(Verdict::Violated(Counterexample {
                    point: pt,
                    margin,
                    exact,
                    disjunct: d,
                }));
            }
        }
        if !r.complete {
            unknown = Some(format!(
                "time or node limit reached after {} nodes",
                r.nodes
            ));
        } else if r.upper >= 0.0 {
            unknown = Some(format!(
                "the counterexample region's closure is not empty (sound bound {:.3e} >= 0) but no f64 point strictly inside it was found: it is thinner than the tolerance",
                r.upper
            ));
        }
    }
    Ok(match unknown {
        Some(u) => Verdict::Unknown(u),
        None => Verdict::Proved,
    })
}

/// The supremum (or infimum) of the query's objective over its counterexample region.
pub fn optimise(q: &Query, prep: &Prepared, s: &Settings) -> Result<Critical, VerifyError> {
    prep.check(q)?;
    let Goal::Optimise {
        objective, sense, ..
    } = &q.goal
    else {
        return Err(VerifyError::Goal(
            q.name.clone(),
            "not a critical-value query".into(),
        ));
    };
    let t0 = Instant::now();
    let sign = if *sense == Sense::Max { 1.0 } else { -1.0 };
    let mut obj = objective.clone();
    obj.terms.iter_mut().for_each(|t| t.1 *= sign);
    obj.constant *= sign;
    let mut best: Option<(Point, f64)> = None;
    let mut upper = f64::NEG_INFINITY;
    let mut complete = true;
    let mut nodes = 0;
    let mut dom = f64::NEG_INFINITY;
    for d in 0..q.region.len() {
        let p = match prep.problem(q, d, Some(obj.clone())) {
            Ok(p) => p,
            Err(e) => return Err(VerifyError::Goal(q.name.clone(), e)),
        };
        let r = p.solve(limits(s, t0));
        nodes += r.nodes;
        complete &= r.complete && r.thin_leaves == 0;
        upper = upper.max(r.upper);
        if let Some((pt, v)) = r.best {
            if best.as_ref().is_none_or(|b| v > b.1) {
                best = Some((pt, v));
            }
        }
        // The same objective over the domain alone: drop constraints on outputs.
        let mut pd = prep
            .problem(q, d, Some(obj.clone()))
            .map_err(|e| VerifyError::Goal(q.name.clone(), e))?;
        pd.constraints.retain(|c| {
            !c.expr
                .terms
                .iter()
                .any(|(v, _)| matches!(v, Var::Output { .. }))
        });
        let rd = pd.solve(limits(s, t0));
        dom = dom.max(rd.upper);
    }
    let value = best.as_ref().map(|b| b.1);
    let attained = value.is_some_and(|v| upper - v <= s.gap.max(1e-9 * v.abs()));
    let vacuous = value.is_some_and(|v| v >= dom - 1e-6 * (1.0 + dom.abs()));
    Ok(Critical {
        value: value.map(|v| sign * v),
        bound: sign * upper,
        witness: best.map(|b| b.0),
        attained,
        domain_extreme: dom.is_finite().then_some(sign * dom),
        vacuous,
        complete,
        nodes,
        seconds: t0.elapsed().as_secs_f64(),
    })
}

/// Run many prove queries in parallel (rayon), in order.
pub fn prove_all(qs: &[Query], prep: &Prepared, s: &Settings) -> Vec<Result<Verdict, VerifyError>> {
    qs.par_iter().map(|q| prove(q, prep, s)).collect()
}

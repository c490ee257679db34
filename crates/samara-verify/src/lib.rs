//! Exact verification of network properties for samara.
//!
//! Queries come in the linear normal form of `samara-spec`: a disjunction of
//! conjunctions of linear constraints over the inputs and outputs of one or more
//! network applications (the counterexample region), with a goal: `Prove` (is the
//! region empty?) or `Optimise` (its supremum/infimum of an objective: the critical
//! value of a parameter).
//!
//! Every exact question (a critical value, the slack form of a `Prove` query, one
//! network application or several) is solved by one engine, the branch-and-bound
//! optimiser of `samara-bounds` (attacks, input and ReLU splitting, CROWN and
//! alpha-CROWN bounds, small LPs certified by weak duality), through [`single`]: a query
//! with several applications is lowered to one network, the block-diagonal product of
//! its applications' networks ([`single::product`]). A counterexample point is a
//! [`point::Point`].
//!
//! Tolerance policy (stated and tested):
//! - A result is reported only from a completed argument: a search cut short by the time
//!   or node limit, a value the encoding cannot take (not finite, or above
//!   [`MAX_MAGNITUDE`]) or numerical trouble gives `Unknown` (and an incomplete
//!   [`Critical`]) with a typed [`UnknownReason`], never `Proved` or a critical value.
//! - A `Violated` verdict always carries a point that violates the property when its
//!   outputs are recomputed by the plain f64 evaluator (`Network::eval_f64`), strict
//!   inequalities strictly, and beyond rounding: every inequality that involves a
//!   variable holds with a margin larger than `1e-9 (|constant| + sum |a_i v_i|)`
//!   ([`point::Point::robustly_satisfies`]; the lowering folds constants in f64, so a
//!   `0 < 0` can arrive as `-6e-19 < 0`). A point inside only within that tolerance
//!   gives `Unknown` (`rounding`). Its margin (the worst inequality with a variable;
//!   equalities and constant rows left out) is reported. When the margin is within 1e-6
//!   of the boundary (and the networks are piecewise linear) the point is re-checked in
//!   exact rational arithmetic ([`exact`]); if exact arithmetic disagrees with f64 the
//!   verdict is `Unknown`, not `Violated`.
//! - An input box empty by rounding only is widened to contain the exact one (a proof
//!   carries over; a counterexample becomes `Unknown`); an input box empty beyond
//!   rounding makes `Proved` vacuous ([`empty_input_box`] says so).
//! - `Proved` means, for every disjunct, a sound upper bound below 0 of the largest
//!   slack `s` with which all its inequalities hold (`e_i + s <= 0`): the closure of the
//!   region is empty. A region that touches its boundary only (the closure is not
//!   empty but no f64 point lies strictly inside) gives `Unknown`, never `Proved`.
//! - Critical values: `value` is the objective at a concrete witness (a lower bound of
//!   the supremum, exact in f64); `upper` is a sound upper bound; `attained` when they
//!   agree to 1e-9; `vacuous` when the witness value reaches the domain extreme to 1e-6
//!   relative. Networks are taken with their weights as stored (float32 weights
//!   are exact in f64).
#![warn(missing_docs)]
// Numeric kernels index several arrays (columns, bounds, weights) by one index.
#![allow(clippy::needless_range_loop)]

pub mod boxq;
pub mod exact;
mod local;
pub mod lp;
#[cfg(feature = "highs")]
pub mod milp;
/// The piecewise-linear encoding and its interval/DeepPoly bounds, shared with reachability
/// (they live in `samara-bounds`).
pub use samara_bounds::pwl as net;
pub mod point;
pub mod robustness;
pub mod route;
pub mod single;
pub mod smooth;

use net::PwlNet;
use point::{Limits, Point, Problem};
use rayon::prelude::*;
use samara_nn::Network;
pub use samara_num::Timeout;
use samara_spec::normal::{Goal, Query, Sense, Var};
use std::collections::HashMap;
use std::time::Instant;

/// Verification settings.
#[derive(Clone, Copy, Debug)]
pub struct Settings {
    /// Time limit per query (none: no limit). A search cut short by it is `unknown`
    /// (timeout), never proved or violated.
    pub timeout: Timeout,
    /// Node limit per disjunct.
    pub max_nodes: usize,
    /// Absolute optimality gap at which a critical value counts as exact.
    pub gap: f64,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            timeout: Timeout::from_secs(60),
            max_nodes: 200_000,
            gap: 1e-9,
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
    /// A constraint or objective names a variable the query does not have (an input or
    /// output index beyond the network's, an application or free variable that does not
    /// exist), or an input box of the wrong length.
    #[error("query `{query}`: {detail}")]
    Variable {
        /// Query.
        query: String,
        /// What is wrong, naming the variable.
        detail: String,
    },
}

/// Why a search was cut short: the typed reason behind every `Unknown` and every
/// incomplete critical value. A result is only ever reported from a search that ran to
/// completion; anything else carries one of these.
#[derive(Clone, Debug, PartialEq)]
pub enum UnknownReason {
    /// The time limit ran out.
    Timeout {
        /// Branch-and-bound nodes (or input boxes) explored.
        nodes: usize,
    },
    /// The node limit was reached.
    NodeLimit {
        /// Nodes explored.
        nodes: usize,
    },
    /// The region's closure is not empty (sound bound `>= 0`) but no f64 point lies
    /// strictly inside it, or leaves of the search could not be made concrete: the
    /// region is thinner than the tolerance.
    ThinRegion {
        /// The sound bound of the slack (or of the objective).
        bound: f64,
    },
    /// A candidate counterexample satisfies the region only within the rounding error of
    /// its constraints (or only in f64, not in exact arithmetic): it need not violate the
    /// property.
    Rounding {
        /// Its margin (worst constraint value).
        margin: f64,
        /// The rounding tolerance it did not clear.
        tolerance: f64,
    },
    /// A coefficient, constant or bound is not finite or larger than the encoding handles
    /// (magnitudes above [`MAX_MAGNITUDE`]).
    OutOfRange {
        /// The offending value.
        value: f64,
    },
    /// Numerical trouble: a bound or objective value came out not a number.
    Numerical {
        /// What.
        what: String,
    },
    /// Something the engine cannot decide (e.g. smooth activations with a free
    /// parameter).
    Unsupported {
        /// What.
        what: String,
    },
}

/// Largest magnitude of a coefficient, constant or input bound the engine takes: beyond
/// it the LP encoding's rounding-error bounds swamp the quantities compared.
pub const MAX_MAGNITUDE: f64 = 1e12;

impl UnknownReason {
    /// A short machine-readable tag: `timeout`, `node_limit`, `thin_region`,
    /// `rounding`, `out_of_range`, `numerical` or `unsupported`.
    pub fn kind(&self) -> &'static str {
        match self {
            UnknownReason::Timeout { .. } => "timeout",
            UnknownReason::NodeLimit { .. } => "node_limit",
            UnknownReason::ThinRegion { .. } => "thin_region",
            UnknownReason::Rounding { .. } => "rounding",
            UnknownReason::OutOfRange { .. } => "out_of_range",
            UnknownReason::Numerical { .. } => "numerical",
            UnknownReason::Unsupported { .. } => "unsupported",
        }
    }
}

impl std::fmt::Display for UnknownReason {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            // The input-split route does not count nodes (0 here).
            UnknownReason::Timeout { nodes: 0 } => {
                write!(f, "time limit reached (raise --timeout)")
            }
            UnknownReason::Timeout { nodes } => write!(
                f,
                "time limit reached after {nodes} nodes (raise --timeout)"
            ),
            UnknownReason::NodeLimit { nodes } => write!(f, "node limit reached after {nodes} nodes"),
            UnknownReason::ThinRegion { bound } => write!(
                f,
                "the counterexample region's closure is not empty (sound bound {bound:.3e}) but no f64 point strictly inside it was found: it is thinner than the tolerance"
            ),
            UnknownReason::Rounding { margin, tolerance } => write!(
                f,
                "a point violates the property only at the rounding level (margin {margin:.3e}, rounding tolerance {tolerance:.3e}): the property sits at the rounding level there"
            ),
            UnknownReason::OutOfRange { value } => write!(
                f,
                "a coefficient, constant or bound ({value:e}) is outside what the encoding handles (finite, magnitude at most {MAX_MAGNITUDE:e}); rescale the property"
            ),
            UnknownReason::Numerical { what } => write!(f, "numerical trouble: {what}"),
            UnknownReason::Unsupported { what } => write!(f, "{what}"),
        }
    }
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

/// The answer to a `prove` query, in samara's one answer vocabulary
/// ([`samara_num::Outcome`]): `Proved` (the counterexample region is empty),
/// `Violated` with a concrete, re-evaluated counterexample, or `Unknown` with the reason.
pub type Verdict = samara_num::Outcome<Counterexample, UnknownReason>;

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
    /// The search finished within its limits (and every leaf was settled): only then are
    /// `value`, `bound` and `vacuous` results. Equivalent to `unknown.is_none()`.
    pub complete: bool,
    /// Why the search is not complete.
    pub unknown: Option<UnknownReason>,
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

/// Weights above which a network's layers are freed on a thread of their own (about
/// 128 MB): freeing a lowered convolutional network's gigabytes takes seconds under
/// memory pressure, which would count against the caller's time limit.
pub const FREE_APART_WEIGHTS: usize = 1 << 24;

impl Drop for Prepared<'_> {
    fn drop(&mut self) {
        let weights: usize = self
            .pwl
            .values()
            .flatten()
            .flat_map(|p| p.maps.iter().map(|(a, _)| a.stored()))
            .sum();
        if weights > FREE_APART_WEIGHTS {
            let pwl = std::mem::take(&mut self.pwl);
            std::thread::spawn(move || drop(pwl));
        }
    }
}

impl<'a> Prepared<'a> {
    /// Prepare named networks.
    pub fn new(nets: &'a HashMap<String, Network>) -> Self {
        Self::new_until(nets, None).expect("no deadline")
    }

    /// [`Prepared::new`] that gives up (`None`) once `deadline` has passed (checked
    /// before each layer's copy: a lowered convolutional network takes gigabytes).
    pub fn new_until(
        nets: &'a HashMap<String, Network>,
        deadline: Option<std::time::Instant>,
    ) -> Option<Self> {
        Self::borrowing_until(nets.iter().map(|(k, v)| (k.clone(), v)).collect(), deadline)
    }

    /// [`Prepared::new_until`] over networks the caller holds elsewhere (shared by
    /// several instances, as `samara vnncomp` does), so no copy of an image-sized
    /// network is made to prepare it.
    pub fn borrowing_until(
        plain: HashMap<String, &'a Network>,
        deadline: Option<std::time::Instant>,
    ) -> Option<Self> {
        let mut pwl = HashMap::new();
        for (k, v) in &plain {
            let p = match PwlNet::from_network_until(v, deadline) {
                Ok(Some(p)) => Ok(p),
                Ok(None) => return None,
                Err(e) => Err(e),
            };
            pwl.insert(k.clone(), p);
        }
        Some(Prepared { plain, pwl })
    }

    fn check(&self, q: &Query) -> Result<(), VerifyError> {
        check_variables(q)?;
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

/// Check that every variable a query uses exists: each application's input box has its
/// `n_inputs` entries, and every input, output and free variable in the region and the
/// objective is within its application's counts (the engine indexes by them).
pub fn check_variables(q: &Query) -> Result<(), VerifyError> {
    let err = |detail: String| VerifyError::Variable {
        query: q.name.clone(),
        detail,
    };
    for (i, a) in q.applications.iter().enumerate() {
        if a.input_box.len() != a.n_inputs {
            return Err(err(format!(
                "application {i} of network `{}` has an input box of {} entries for {} inputs",
                a.network,
                a.input_box.len(),
                a.n_inputs
            )));
        }
    }
    let objective = match &q.goal {
        Goal::Optimise { objective, .. } => Some(objective),
        Goal::Prove => None,
    };
    let exprs = q.region.iter().flatten().map(|c| &c.expr).chain(objective);
    for e in exprs {
        for (v, _) in &e.terms {
            let (app, index, what) = match *v {
                Var::Input { app, index } => (app, index, "input"),
                Var::Output { app, index } => (app, index, "output"),
                Var::Free(k) => {
                    if k >= q.free_vars.len() {
                        return Err(err(format!(
                            "free variable {k} is used but the query declares {}",
                            q.free_vars.len()
                        )));
                    }
                    continue;
                }
            };
            let Some(a) = q.applications.get(app) else {
                return Err(err(format!(
                    "{what} {index} of application {app} is used but the query has {} application(s)",
                    q.applications.len()
                )));
            };
            let n = if what == "input" {
                a.n_inputs
            } else {
                a.n_outputs
            };
            if index >= n {
                return Err(err(format!(
                    "{what} {index} of network `{}` is used but it has {n} {what}s (indices 0 to {})",
                    a.network,
                    n as isize - 1
                )));
            }
        }
    }
    Ok(())
}

/// The first coefficient, constant or bound of `q` the encoding cannot take (not finite
/// or of magnitude above [`MAX_MAGNITUDE`]); free-variable bounds may be infinite.
pub fn out_of_range(q: &Query) -> Option<f64> {
    let bad = |v: f64| !v.is_finite() || v.abs() > MAX_MAGNITUDE;
    let objective = match &q.goal {
        Goal::Optimise { objective, .. } => Some(objective),
        Goal::Prove => None,
    };
    for e in q.region.iter().flatten().map(|c| &c.expr).chain(objective) {
        if bad(e.constant) {
            return Some(e.constant);
        }
        if let Some(t) = e.terms.iter().find(|t| bad(t.1)) {
            return Some(t.1);
        }
    }
    for a in &q.applications {
        for (l, h) in &a.input_box {
            for v in [*l, *h] {
                if bad(v) {
                    return Some(v);
                }
            }
        }
    }
    for (_, l, h) in &q.free_vars {
        for v in [*l, *h] {
            if v.is_nan() || (v.is_finite() && v.abs() > MAX_MAGNITUDE) {
                return Some(v);
            }
        }
    }
    None
}

/// The first application whose input box is empty (a bound above its other bound, by
/// more than rounding: `prove` widens boxes empty only by rounding): the query's input
/// domain is empty, so `Proved` holds vacuously (e.g. a data point outside
/// the declared domain, whose ball is clipped to it). `(application, input)`.
pub fn empty_input_box(q: &Query) -> Option<(usize, usize)> {
    q.applications.iter().enumerate().find_map(|(a, app)| {
        app.input_box
            .iter()
            .position(|(l, h)| l.is_nan() || h.is_nan() || l - h > 1e-9 * (1.0 + l.abs() + h.abs()))
            .map(|k| (a, k))
    })
}

/// Is the property's premise empty over the input domain? The premise of a disjunct is
/// its constraints on inputs (and free variables) alone, the ones that name no network
/// output. When every disjunct's premise is empty, `Proved` holds without looking at
/// the networks: it is vacuous. Decided with the engine's own sound slack bound (the
/// premise region's closure is empty), so never `true` when a point of the premise
/// exists; `false` when not decided within `s.timeout` (an undecided premise is not
/// called vacuous).
pub fn premise_empty(q: &Query, prep: &Prepared, s: &Settings) -> Result<bool, VerifyError> {
    prep.check(q)?;
    if out_of_range(q).is_some() {
        return Ok(false);
    }
    let mut p = q.clone();
    p.goal = Goal::Prove;
    for d in &mut p.region {
        d.retain(|c| {
            !c.expr
                .terms
                .iter()
                .any(|(v, _)| matches!(v, Var::Output { .. }))
        });
    }
    let (w, _) = widen_rounding_boxes(&p);
    Ok(prove_checked(&w, prep, s)? == Verdict::Proved)
}

/// Why a `Proved` verdict of `q` is vacuous, if it is: an input box empty beyond
/// rounding ([`empty_input_box`]) or a premise empty over the domain
/// ([`premise_empty`], given at most `s.timeout` seconds). Shared by the CLI and the
/// Python package, whose reports say `vacuous: true` with this text.
pub fn vacuity(q: &Query, prep: &Prepared, s: &Settings) -> Result<Option<String>, VerifyError> {
    if let Some((app, k)) = empty_input_box(q) {
        return Ok(Some(format!(
            "the input domain of network call {app} is empty (input {k}): a data point outside the declared domain, whose ball the domain clips away"
        )));
    }
    if premise_empty(q, prep, s)? {
        return Ok(Some(
            "no point of the input domain meets the property's premise (its constraints on the inputs are infeasible over the domain), so the network was never checked".into(),
        ));
    }
    Ok(None)
}

/// `s` with only the time its limit leaves after `t0` (never negative): one time
/// limit as a deadline over several searches (a command's `--timeout` covers all its
/// queries, not each).
pub fn left_after(s: &Settings, t0: Instant) -> Settings {
    Settings {
        timeout: s.timeout.left(t0),
        ..*s
    }
}

fn limits(s: &Settings, t0: Instant) -> Limits {
    Limits {
        timeout: s.timeout.left(t0),
        nodes: s.max_nodes,
        gap: s.gap,
    }
}

/// Boxes empty only by rounding (`lo > hi` by at most `1e-9 (1 + |lo| + |hi|)`, e.g. a
/// data point on the domain's edge whose ball is clipped to the domain after both went
/// through a unit conversion) are widened to `[hi, lo]`, which contains the exact box.
/// Returns the widened query and by how much it was widened (0 if not).
fn widen_rounding_boxes(q: &Query) -> (std::borrow::Cow<'_, Query>, f64) {
    let thin = |l: f64, h: f64| l > h && l - h <= 1e-9 * (1.0 + l.abs() + h.abs());
    let mut by = 0.0f64;
    for a in &q.applications {
        for (l, h) in &a.input_box {
            if thin(*l, *h) {
                by = by.max(l - h);
            }
        }
    }
    if by == 0.0 {
        return (std::borrow::Cow::Borrowed(q), 0.0);
    }
    let mut w = q.clone();
    for a in &mut w.applications {
        for b in &mut a.input_box {
            if thin(b.0, b.1) {
                *b = (b.1, b.0);
            }
        }
    }
    (std::borrow::Cow::Owned(w), by)
}

/// Is the counterexample region of `q` empty?
pub fn prove(q: &Query, prep: &Prepared, s: &Settings) -> Result<Verdict, VerifyError> {
    prep.check(q)?;
    if let Some(value) = out_of_range(q) {
        return Ok(Verdict::Unknown(UnknownReason::OutOfRange { value }));
    }
    // A relational property around a fixed point, thin there (local Lipschitz bounds).
    if let Some(v) = local::prove_near_point(q, prep, s) {
        return v;
    }
    let (w, widened) = widen_rounding_boxes(q);
    let v = prove_checked(&w, prep, s)?;
    Ok(match v {
        // The widened box contains the exact one: a proof carries over; a counterexample
        // may lie in the sliver outside it.
        Verdict::Violated(c) if widened > 0.0 => Verdict::Unknown(UnknownReason::Rounding {
            margin: c.margin,
            tolerance: widened,
        }),
        v => v,
    })
}

/// Queries with a network that is not piecewise linear (sigmoid, tanh, `Sign`): the
/// input-split engine of [`samara_bounds::smooth`] through [`smooth::prove`]. `None`
/// when every network is piecewise linear, or the query is not one that engine states
/// (free variables, a box that is not finite).
fn smooth_query(q: &Query, prep: &Prepared, s: &Settings, t0: Instant) -> Option<Verdict> {
    if q.applications
        .iter()
        .all(|a| prep.pwl.get(&a.network).is_some_and(|p| p.is_ok()))
    {
        return None;
    }
    let nets: Vec<&Network> = q
        .applications
        .iter()
        .map(|a| prep.plain.get(&a.network).copied())
        .collect::<Option<_>>()?;
    smooth::prove(q, &nets, s.timeout.left(t0))
}

fn prove_checked(q: &Query, prep: &Prepared, s: &Settings) -> Result<Verdict, VerifyError> {
    let t0 = Instant::now();
    let mut unknown = None;
    if let Some(v) = smooth_query(q, prep, s, t0) {
        return Ok(v);
    }
    for d in 0..q.region.len() {
        // Slack formulation: maximise s subject to e_i + s <= 0 for every inequality.
        // The region is empty iff the sound bound of max s is negative; a concrete point
        // with s > 0 satisfies every constraint strictly.
        let mut p = match prep.problem(q, d, None) {
            Ok(p) => p,
            Err(e) => {
                // A network the optimiser cannot encode, in a query the smooth engine
                // does not state either (free variables).
                return Ok(Verdict::Unknown(UnknownReason::Unsupported { what: e }));
            }
        };
        let original = q.region[d].clone();
        // Only s >= 0 matters, where every inequality holds: tighten the boxes with them.
        p.boxes = point::tighten(&p.boxes, &original);
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
        let r = single::solve(&p, limits(s, t0));
        if let Some((mut pt, _)) = r.best.clone() {
            pt.free.truncate(k);
            if pt.satisfies(&original) {
                let margin = pt.margin(&original);
                // Re-checked concretely beyond rounding: a point that is in the region
                // only within the rounding error of the lowered constraints (e.g.
                // `0 < 0` computed as `-6e-19 < 0`) need not violate the property.
                if let Err((margin, tolerance)) = pt.robustly_satisfies(&original) {
                    unknown = Some(UnknownReason::Rounding { margin, tolerance });
                    continue;
                }
                let mut exact = None;
                if margin > -1e-6 {
                    let nets: Vec<&PwlNet> = q
                        .applications
                        .iter()
                        .filter_map(|a| prep.pwl[&a.network].as_ref().ok())
                        .collect();
                    if nets.len() == q.applications.len() {
                        exact = exact::rigorous_satisfies(&nets, &pt, &original);
                    }
                }
                if exact == Some(false) {
                    unknown = Some(UnknownReason::Rounding {
                        margin,
                        tolerance: 0.0,
                    });
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
            unknown = Some(
                r.stop
                    .clone()
                    .unwrap_or(UnknownReason::Timeout { nodes: r.nodes }),
            );
        } else if r.upper.is_nan() {
            unknown = Some(UnknownReason::Numerical {
                what: "the sound bound of the slack is not a number".into(),
            });
        } else if r.upper >= 0.0 {
            unknown = Some(UnknownReason::ThinRegion { bound: r.upper });
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
    if let Some(value) = out_of_range(q) {
        return Ok(Critical {
            value: None,
            bound: if *sense == Sense::Max {
                f64::INFINITY
            } else {
                f64::NEG_INFINITY
            },
            witness: None,
            attained: false,
            domain_extreme: None,
            vacuous: false,
            complete: false,
            unknown: Some(UnknownReason::OutOfRange { value }),
            nodes: 0,
            seconds: t0.elapsed().as_secs_f64(),
        });
    }
    let sign = if *sense == Sense::Max { 1.0 } else { -1.0 };
    let mut obj = objective.clone();
    obj.terms.iter_mut().for_each(|t| t.1 *= sign);
    obj.constant *= sign;
    let mut best: Option<(Point, f64)> = None;
    let mut upper = f64::NEG_INFINITY;
    let mut unknown: Option<UnknownReason> = None;
    let mut nodes = 0;
    let mut dom = f64::NEG_INFINITY;
    for d in 0..q.region.len() {
        let p = match prep.problem(q, d, Some(obj.clone())) {
            Ok(p) => p,
            Err(e) => return Err(VerifyError::Goal(q.name.clone(), e)),
        };
        let r = single::solve(&p, limits(s, t0));
        nodes += r.nodes;
        if !r.complete {
            unknown.get_or_insert(r.stop.clone().unwrap_or(UnknownReason::Timeout { nodes }));
        } else if r.thin_leaves > 0 {
            unknown.get_or_insert(UnknownReason::ThinRegion { bound: r.upper });
        }
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
        let rd = single::solve(&pd, limits(s, t0));
        if !rd.complete {
            // Without the domain's extreme, vacuity is not decided.
            unknown.get_or_insert(rd.stop.clone().unwrap_or(UnknownReason::Timeout { nodes }));
        }
        dom = dom.max(rd.upper);
    }
    if upper.is_nan() || dom.is_nan() || best.as_ref().is_some_and(|b| !b.1.is_finite()) {
        unknown.get_or_insert(UnknownReason::Numerical {
            what: format!(
                "bound {upper:e}, domain extreme {dom:e}, witness value {:?}",
                best.as_ref().map(|b| b.1)
            ),
        });
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
        complete: unknown.is_none(),
        unknown,
        nodes,
        seconds: t0.elapsed().as_secs_f64(),
    })
}

/// Run many prove queries in parallel (rayon), in order.
pub fn prove_all(qs: &[Query], prep: &Prepared, s: &Settings) -> Vec<Result<Verdict, VerifyError>> {
    qs.par_iter().map(|q| prove(q, prep, s)).collect()
}

//! The data of an exact question and its answer: the problem (applications of
//! networks, input boxes, free variables, one conjunction of linear constraints, an
//! objective), concrete points and their checks, the search's result and limits.
//! [`crate::single`] solves a [`Problem`].

use crate::net::PwlNet;
use samara_nn::Network;
use samara_num::Timeout;
use samara_spec::normal::{Cmp, Constraint, LinExpr, Var};

/// The problem: applications of networks, input boxes, one conjunction of constraints,
/// an objective (maximised).
pub struct Problem<'a> {
    /// Networks by application.
    pub nets: Vec<&'a PwlNet>,
    /// The plain networks (for concrete re-evaluation).
    pub plain: Vec<&'a Network>,
    /// Input box per application.
    pub boxes: Vec<Vec<(f64, f64)>>,
    /// Free variables' bounds.
    pub free: Vec<(f64, f64)>,
    /// The conjunction.
    pub constraints: Vec<Constraint>,
    /// Objective to maximise.
    pub objective: Option<LinExpr>,
    /// Nodes whose sound bound is below this are pruned (default `-inf`).
    pub floor: f64,
    /// Stop as soon as a witness satisfies these constraints with objective value
    /// `>= floor` (used by `prove`: the original, unslacked region).
    pub stop_when: Option<Vec<Constraint>>,
}

impl Problem<'_> {
    /// What makes the problem unsearchable (a variable beyond its network's inputs or
    /// outputs, a box of the wrong length, a network without layers), if anything.
    pub(crate) fn malformed(&self) -> Option<String> {
        if self.nets.len() != self.boxes.len() || self.nets.len() != self.plain.len() {
            return Some("applications, networks and input boxes disagree in number".into());
        }
        for (ai, net) in self.nets.iter().enumerate() {
            if net.maps.is_empty() {
                return Some(format!("application {ai}: a network without layers"));
            }
            if self.boxes[ai].len() != net.n_inputs() {
                return Some(format!(
                    "application {ai}: an input box of {} entries for {} inputs",
                    self.boxes[ai].len(),
                    net.n_inputs()
                ));
            }
        }
        let n_out = |ai: usize| self.nets[ai].maps.last().map(|m| m.0.out).unwrap_or(0);
        let exprs = self
            .constraints
            .iter()
            .map(|c| &c.expr)
            .chain(&self.objective);
        for e in exprs {
            for (v, _) in &e.terms {
                let ok = match *v {
                    Var::Input { app, index } => {
                        app < self.nets.len() && index < self.nets[app].n_inputs()
                    }
                    Var::Output { app, index } => app < self.nets.len() && index < n_out(app),
                    Var::Free(k) => k < self.free.len(),
                };
                if !ok {
                    return Some(format!("variable {v:?} does not exist in the problem"));
                }
            }
        }
        None
    }
}

/// A concrete point: inputs per application, outputs per application, free values.
#[derive(Clone, Debug, PartialEq)]
pub struct Point {
    /// Inputs per application (raw units of the network).
    pub inputs: Vec<Vec<f64>>,
    /// Outputs per application, evaluated by the plain f64 evaluator.
    pub outputs: Vec<Vec<f64>>,
    /// Values of the free variables.
    pub free: Vec<f64>,
}

impl Point {
    /// Value of a variable.
    pub fn value(&self, v: Var) -> f64 {
        match v {
            Var::Input { app, index } => self.inputs[app][index],
            Var::Output { app, index } => self.outputs[app][index],
            Var::Free(k) => self.free[k],
        }
    }

    /// Worst value of the inequality constraints that involve a variable (<= 0 means
    /// they all hold, strict ones strictly; the more negative, the deeper inside the
    /// region the point lies). Equalities and constant constraints (`0 <= 0`, which the
    /// case splits of `norm` and `|e|` produce) say nothing about depth and are left out
    /// (check them with [`Point::satisfies`]); with no such inequality the margin is 0.
    pub fn margin(&self, cs: &[Constraint]) -> f64 {
        let m = cs
            .iter()
            .filter(|c| c.cmp != Cmp::Eq && !c.expr.terms.is_empty())
            .map(|c| {
                let e = c.expr.eval(|v| self.value(v));
                match c.cmp {
                    Cmp::Le => e,
                    Cmp::Lt => {
                        if e < 0.0 {
                            e
                        } else {
                            e.max(f64::MIN_POSITIVE)
                        }
                    }
                    Cmp::Eq => e.abs(),
                }
            })
            .fold(f64::NEG_INFINITY, f64::max);
        if m == f64::NEG_INFINITY {
            0.0
        } else {
            m
        }
    }

    /// The rounding tolerance of a constraint at this point: a bound on the error with
    /// which the constraint's value was computed, both here (f64 evaluation) and when the
    /// property was lowered (constants folded in f64, e.g. a data point's raw value
    /// subtracted from a normalised one): `1e-9 (|constant| + sum |a_i v_i|)`.
    pub fn tolerance(&self, c: &Constraint) -> f64 {
        let mag = c.expr.constant.abs()
            + c.expr
                .terms
                .iter()
                .map(|(v, a)| (a * self.value(*v)).abs())
                .sum::<f64>();
        1e-9 * mag
    }

    /// Whether the point lies in the region beyond rounding: every constraint that
    /// involves a variable holds with a margin larger than its [`Point::tolerance`]
    /// (equalities hold exactly, constant constraints hold exactly). `Err((margin,
    /// tolerance))` of the first constraint that does not clear its tolerance.
    pub fn robustly_satisfies(&self, cs: &[Constraint]) -> Result<(), (f64, f64)> {
        for c in cs {
            let e = c.expr.eval(|v| self.value(v));
            let ok = match c.cmp {
                Cmp::Eq => e == 0.0,
                _ if c.expr.terms.is_empty() => c.holds(|_| 0.0, 0.0),
                Cmp::Le => e <= 0.0 && (e == 0.0 && self.exact_zero(c) || e < -self.tolerance(c)),
                Cmp::Lt => e < -self.tolerance(c),
            };
            if !ok {
                return Err((e, self.tolerance(c)));
            }
        }
        Ok(())
    }

    /// A constraint whose terms all vanish at the point (every variable it uses is 0, or
    /// pairs of equal values cancel with opposite coefficients) and whose constant is 0:
    /// its value is exactly 0 whatever the rounding of its coefficients.
    fn exact_zero(&self, c: &Constraint) -> bool {
        if c.expr.constant != 0.0 {
            return false;
        }
        if c.expr.terms.iter().all(|(v, _)| self.value(*v) == 0.0) {
            return true;
        }
        // a x + b y with x == y and a == -b (e.g. d_j - d_k between identical points).
        let mut ts: Vec<(f64, f64)> = c
            .expr
            .terms
            .iter()
            .map(|(v, a)| (self.value(*v), *a))
            .filter(|(x, _)| *x != 0.0)
            .collect();
        ts.sort_by(|p, q| p.0.total_cmp(&q.0).then(p.1.total_cmp(&q.1)));
        let mut i = 0;
        while i < ts.len() {
            let mut j = i;
            let mut sum = 0.0;
            while j < ts.len() && ts[j].0 == ts[i].0 {
                sum += ts[j].1;
                j += 1;
            }
            if sum != 0.0 {
                return false;
            }
            i = j;
        }
        true
    }

    /// Whether every constraint holds exactly in f64.
    pub fn satisfies(&self, cs: &[Constraint]) -> bool {
        cs.iter().all(|c| c.holds(|v| self.value(v), 0.0))
    }
}

/// Outcome of a branch and bound.
#[derive(Clone, Debug)]
pub struct BabResult {
    /// Best concrete witness (satisfies every constraint) and its objective value.
    pub best: Option<(Point, f64)>,
    /// Sound upper bound of the objective over the region (`-inf` if empty).
    pub upper: f64,
    /// Whether the search finished (else a time or node limit stopped it).
    pub complete: bool,
    /// Nodes explored.
    pub nodes: usize,
    /// Leaves whose LP was feasible but whose point could not be made concrete
    /// (regions thinner than the tolerance).
    pub thin_leaves: usize,
    /// Which limit stopped an incomplete search (`None` when `complete`).
    pub stop: Option<crate::UnknownReason>,
}

impl BabResult {
    /// A search that explored no node.
    pub(crate) fn unexplored(
        upper: f64,
        complete: bool,
        stop: Option<crate::UnknownReason>,
    ) -> Self {
        BabResult {
            best: None,
            upper,
            complete,
            nodes: 0,
            thin_leaves: 0,
            stop,
        }
    }
}

/// Limits of a search.
#[derive(Clone, Copy, Debug)]
pub struct Limits {
    /// Wall-clock limit of the search.
    pub timeout: Timeout,
    /// Node limit.
    pub nodes: usize,
    /// Stop once the gap `upper - best` is below this (absolute).
    pub gap: f64,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            timeout: Timeout::from_secs(60),
            nodes: 200_000,
            gap: 1e-9,
        }
    }
}

/// Input boxes tightened by the constraints on a single input (`a x_k + c cmp 0`).
pub fn tighten(boxes: &[Vec<(f64, f64)>], constraints: &[Constraint]) -> Vec<Vec<(f64, f64)>> {
    let mut b = boxes.to_vec();
    for c in constraints {
        if let [(Var::Input { app, index }, coef)] = c.expr.terms.as_slice() {
            let t = -c.expr.constant / coef;
            let r = &mut b[*app][*index];
            match (c.cmp, *coef > 0.0) {
                (Cmp::Eq, _) => {
                    r.0 = r.0.max(t);
                    r.1 = r.1.min(t);
                }
                (_, true) => r.1 = r.1.min(crate::net::up(t)),
                (_, false) => r.0 = r.0.max(crate::net::down(t)),
            }
        }
    }
    b
}

/// Repair the free variables of a concrete point: each goes to the end of its range
/// that the objective prefers (kept where it is without a preference), limited by the
/// constraints it appears in given the point's other values.
pub(crate) fn repair_free(
    p: &mut Point,
    free: &[(f64, f64)],
    constraints: &[Constraint],
    objective: Option<&LinExpr>,
) {
    for k in 0..free.len() {
        let dir = objective
            .and_then(|o| {
                o.terms
                    .iter()
                    .find(|(v, _)| *v == Var::Free(k))
                    .map(|t| t.1.signum())
            })
            .unwrap_or(0.0);
        let (mut l, mut h) = free[k];
        for c in constraints {
            let Some(a) = c
                .expr
                .terms
                .iter()
                .find(|(v, _)| *v == Var::Free(k))
                .map(|t| t.1)
            else {
                continue;
            };
            let mut q = p.clone();
            q.free[k] = 0.0;
            let rest = c.expr.eval(|v| q.value(v));
            // a t + rest <= 0
            if a > 0.0 {
                h = h.min(-rest / a);
            } else {
                l = l.max(-rest / a);
            }
        }
        p.free[k] = if dir > 0.0 {
            h
        } else if dir < 0.0 {
            l
        } else {
            p.free[k].clamp(l, h)
        };
    }
}

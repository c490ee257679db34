//! Branch and bound over ReLU phases with sound LP bounds (the exact engine).
//!
//! A node fixes some ReLUs active or inactive; the others get the triangle relaxation
//! (Ehlers 2017, "Formal verification of piece-wise linear feed-forward neural
//! networks") over sound interval bounds. Each node's LP gives a sound upper bound
//! (see [`crate::lp`]) and a primal point that is re-evaluated through the network: if
//! it satisfies the region it is a concrete witness. Nodes whose bound cannot beat the
//! best witness are pruned; a node with every ReLU fixed is a linear region, where the
//! LP is exact. The result is therefore exact up to the LP tolerance, and every number
//! reported as attained comes from a concrete, re-evaluated point.

use crate::lp::{Lp, LpResult, Row};
use crate::net::{affine_bounds, PwlNet};
use crate::tighten::{lp_tighten, InputConstraint, LpTighten};
use samara_nn::Network;
use samara_num::Timeout;
use samara_spec::normal::{Cmp, Constraint, LinExpr, Var};
use std::collections::BinaryHeap;
use std::sync::Arc;
use std::time::Instant;

/// Where each application's variables live in the LP.
struct AppVars {
    x: usize,
    /// Per map: offset of z, and offset of a if a ReLU follows.
    maps: Vec<(usize, Option<usize>)>,
    out: usize,
}

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

/// A node's phase decisions: per application, per ReLU map, per neuron: 0 free,
/// 1 active, -1 inactive.
#[derive(Clone, Debug)]
struct Node {
    phases: Vec<Vec<Vec<i8>>>,
    upper: f64,
    /// LP-tightened bounds of an ancestor (flat `lo`, `hi` over the LP's variables),
    /// valid in this node's subtree.
    seed: Option<Arc<(Vec<f64>, Vec<f64>)>>,
}

impl PartialEq for Node {
    fn eq(&self, o: &Self) -> bool {
        self.upper == o.upper
    }
}
impl Eq for Node {}
impl PartialOrd for Node {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Node {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        self.upper.total_cmp(&o.upper)
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
    fn unexplored(upper: f64, complete: bool, stop: Option<crate::UnknownReason>) -> Self {
        BabResult {
            best: None,
            upper,
            complete,
            nodes: 0,
            thin_leaves: 0,
            stop,
        }
    }

    /// A search that stopped at its first witness (the stop criterion was reached).
    fn stopped_at_witness(best: Option<(Point, f64)>, nodes: usize, thin_leaves: usize) -> Self {
        BabResult {
            best,
            upper: f64::INFINITY,
            complete: true,
            nodes,
            thin_leaves,
            stop: None,
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
    /// LP-based tightening of the pre-activation bounds ([`crate::tighten`]).
    pub tighten: LpTighten,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            timeout: Timeout::from_secs(60),
            nodes: 200_000,
            gap: 1e-9,
            tighten: LpTighten::Off,
        }
    }
}

impl<'a> Problem<'a> {
    fn layout(&self) -> (Vec<AppVars>, usize) {
        let mut n = 0usize;
        let mut apps = Vec::new();
        for net in &self.nets {
            let x = n;
            n += net.n_inputs();
            let mut maps = Vec::new();
            for (m, relu) in &net.maps {
                let z = n;
                n += m.out;
                let a = if *relu {
                    let a = n;
                    n += m.out;
                    Some(a)
                } else {
                    None
                };
                maps.push((z, a));
            }
            let last = maps.last().expect("at least one map");
            let out = last.1.unwrap_or(last.0);
            apps.push(AppVars { x, maps, out });
        }
        (apps, n)
    }

    fn var_index(&self, apps: &[AppVars], n_net: usize, v: Var) -> usize {
        match v {
            Var::Input { app, index } => apps[app].x + index,
            Var::Output { app, index } => apps[app].out + index,
            Var::Free(k) => n_net + k,
        }
    }

    /// Input boxes tightened by single-variable constraints.
    fn tightened_boxes(&self) -> Vec<Vec<(f64, f64)>> {
        tighten(&self.boxes, &self.constraints)
    }
}

/// The intersection of two sets of bounds (either may be absent).
fn meet(
    a: Option<&(Vec<f64>, Vec<f64>)>,
    b: Option<&(Vec<f64>, Vec<f64>)>,
) -> Option<(Vec<f64>, Vec<f64>)> {
    match (a, b) {
        (None, None) => None,
        (Some(x), None) | (None, Some(x)) => Some(x.clone()),
        (Some(x), Some(y)) => Some((
            x.0.iter().zip(&y.0).map(|(p, q)| p.max(*q)).collect(),
            x.1.iter().zip(&y.1).map(|(p, q)| p.min(*q)).collect(),
        )),
    }
}

/// Input boxes tightened by the constraints on a single input (`a x_k + c cmp 0`).
pub fn tighten(boxes: &[Vec<(f64, f64)>], constraints: &[Constraint]) -> Vec<Vec<(f64, f64)>> {
    {
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
}

impl Problem<'_> {
    /// Interval bounds of every variable under a node's phases; `None` if contradictory.
    fn bounds(
        &self,
        apps: &[AppVars],
        n: usize,
        boxes: &[Vec<(f64, f64)>],
        phases: &[Vec<Vec<i8>>],
        seed: Option<&(Vec<f64>, Vec<f64>)>,
    ) -> Option<(Vec<f64>, Vec<f64>)> {
        let n_net = n;
        let mut lo = vec![0.0; n_net + self.free.len()];
        let mut hi = vec![0.0; n_net + self.free.len()];
        for (ai, (net, av)) in self.nets.iter().zip(apps).enumerate() {
            let xl: Vec<f64> = boxes[ai].iter().map(|b| b.0).collect();
            let xh: Vec<f64> = boxes[ai].iter().map(|b| b.1).collect();
            if xl.iter().zip(&xh).any(|(l, h)| l > h) {
                return None;
            }
            lo[av.x..av.x + xl.len()].copy_from_slice(&xl);
            hi[av.x..av.x + xh.len()].copy_from_slice(&xh);
            // Interval pass (with the node's phases), then symbolic back-substitution.
            let mut zlo: Vec<Vec<f64>> = Vec::new();
            let mut zhi: Vec<Vec<f64>> = Vec::new();
            let (mut alo, mut ahi) = (xl.clone(), xh.clone());
            let mut relu_k = 0;
            for (k, (m, relu)) in net.maps.iter().enumerate() {
                let (mut zl, mut zh) = affine_bounds(m, &alo, &ahi);
                if let Some((sl, sh)) = seed {
                    let zo = av.maps[k].0;
                    for i in 0..m.out {
                        zl[i] = zl[i].max(sl[zo + i]);
                        zh[i] = zh[i].min(sh[zo + i]);
                    }
                }
                if *relu {
                    crate::net::clamp_to_phases(&phases[ai][relu_k], &mut zl, &mut zh);
                    relu_k += 1;
                    if zl.iter().zip(zh.iter()).any(|(l, h)| l > h) {
                        return None;
                    }
                    alo = zl.iter().map(|v| v.max(0.0)).collect();
                    ahi = zh.iter().map(|v| v.max(0.0)).collect();
                } else {
                    alo = zl.clone();
                    ahi = zh.clone();
                }
                zlo.push(zl);
                zhi.push(zh);
            }
            if net.maps.len() > 1 {
                crate::net::deeppoly(net, &xl, &xh, &phases[ai], &mut zlo, &mut zhi);
            }
            let mut relu_k = 0;
            for (k, (m, relu)) in net.maps.iter().enumerate() {
                let (zo, ao) = av.maps[k];
                let (zl, zh) = (&mut zlo[k], &mut zhi[k]);
                if *relu {
                    crate::net::clamp_to_phases(&phases[ai][relu_k], zl, zh);
                    relu_k += 1;
                    if zl.iter().zip(zh.iter()).any(|(l, h)| l > h) {
                        return None;
                    }
                    let a = ao.expect("relu var");
                    for i in 0..m.out {
                        lo[a + i] = zl[i].max(0.0);
                        hi[a + i] = zh[i].max(0.0);
                    }
                } else if zl.iter().zip(zh.iter()).any(|(l, h)| l > h) {
                    return None;
                }
                lo[zo..zo + m.out].copy_from_slice(zl);
                hi[zo..zo + m.out].copy_from_slice(zh);
            }
        }
        for (k, f) in self.free.iter().enumerate() {
            lo[n_net + k] = f.0;
            hi[n_net + k] = f.1;
        }
        Some((lo, hi))
    }

    /// Finite bounds for free variables from constraints with exactly one free variable.
    fn bound_free(&mut self, apps: &[AppVars], n_net: usize, lo: &[f64], hi: &[f64]) {
        for _ in 0..2 {
            for c in &self.constraints {
                let frees: Vec<(usize, f64)> = c
                    .expr
                    .terms
                    .iter()
                    .filter_map(|(v, a)| {
                        if let Var::Free(k) = v {
                            Some((*k, *a))
                        } else {
                            None
                        }
                    })
                    .collect();
                if frees.len() != 1 || c.cmp == Cmp::Eq {
                    continue;
                }
                let (k, a) = frees[0];
                // a t + rest <= 0; rest in [rmin, rmax].
                let (mut rmin, mut rmax) = (c.expr.constant, c.expr.constant);
                for (v, coef) in &c.expr.terms {
                    if matches!(v, Var::Free(_)) {
                        continue;
                    }
                    let j = self.var_index(apps, n_net, *v);
                    let (p, q) = (coef * lo[j], coef * hi[j]);
                    rmin += p.min(q);
                    rmax += p.max(q);
                }
                let fr = &mut self.free[k];
                if a > 0.0 {
                    fr.1 = fr.1.min(crate::net::up(crate::net::up(-rmin) / a));
                } else {
                    fr.0 = fr.0.max(crate::net::down(crate::net::down(-rmin) / a));
                }
                let _ = rmax;
            }
        }
    }

    /// LP-tightened bounds of every application's pre-activations under `phases`
    /// (flat, over the LP's variables; only the `z` entries are meaningful), from the
    /// node's bounds `lo`/`hi` and the query's constraints on one application's inputs.
    /// `None` if an LP proves the node empty.
    fn lp_tighten(
        &self,
        apps: &[AppVars],
        lo: &[f64],
        hi: &[f64],
        phases: &[Vec<Vec<i8>>],
    ) -> Option<(Vec<f64>, Vec<f64>)> {
        let (mut tlo, mut thi) = (lo.to_vec(), hi.to_vec());
        for (ai, (net, av)) in self.nets.iter().zip(apps).enumerate() {
            let nx = net.n_inputs();
            let inputs: Vec<InputConstraint> = self
                .constraints
                .iter()
                .filter_map(|c| {
                    let row: Option<Row> = c
                        .expr
                        .terms
                        .iter()
                        .map(|(v, a)| match v {
                            Var::Input { app, index } if *app == ai => Some((*index, *a)),
                            _ => None,
                        })
                        .collect();
                    // Strict inequalities relaxed to their closure (sound for bounds).
                    row.filter(|r| !r.is_empty()).map(|row| InputConstraint {
                        row,
                        rhs: -c.expr.constant,
                        eq: c.cmp == Cmp::Eq,
                    })
                })
                .collect();
            let (xl, xh) = (&lo[av.x..av.x + nx], &hi[av.x..av.x + nx]);
            let mut zlo: Vec<Vec<f64>> = Vec::new();
            let mut zhi: Vec<Vec<f64>> = Vec::new();
            for (k, (m, _)) in net.maps.iter().enumerate() {
                let zo = av.maps[k].0;
                zlo.push(lo[zo..zo + m.out].to_vec());
                zhi.push(hi[zo..zo + m.out].to_vec());
            }
            lp_tighten(net, xl, xh, &inputs, &phases[ai], &mut zlo, &mut zhi, true)?;
            for (k, (m, _)) in net.maps.iter().enumerate() {
                let zo = av.maps[k].0;
                tlo[zo..zo + m.out].copy_from_slice(&zlo[k]);
                thi[zo..zo + m.out].copy_from_slice(&zhi[k]);
            }
        }
        Some((tlo, thi))
    }

    /// Build the node LP.
    fn lp(
        &self,
        apps: &[AppVars],
        n_net: usize,
        phases: &[Vec<Vec<i8>>],
        lo: &[f64],
        hi: &[f64],
        shrink: f64,
    ) -> Lp {
        let n = n_net + self.free.len();
        let mut lp = Lp {
            n,
            lo: lo.to_vec(),
            hi: hi.to_vec(),
            c: vec![0.0; n],
            ..Default::default()
        };
        for (ai, (net, av)) in self.nets.iter().zip(apps).enumerate() {
            let mut prev = av.x;
            let mut relu_k = 0;
            for (k, (m, relu)) in net.maps.iter().enumerate() {
                let (zo, ao) = av.maps[k];
                lp.push_affine(m, zo, prev);
                if *relu {
                    let a = ao.expect("relu var");
                    let ph = &phases[ai][relu_k];
                    relu_k += 1;
                    lp.push_relu(a, zo, &lo[zo..zo + m.out], &hi[zo..zo + m.out], ph);
                    prev = a;
                } else {
                    prev = zo;
                }
            }
        }
        for c in &self.constraints {
            let row: Row = c
                .expr
                .terms
                .iter()
                .map(|(v, a)| (self.var_index(apps, n_net, *v), *a))
                .collect();
            match c.cmp {
                Cmp::Eq => lp.eq.push((row, -c.expr.constant)),
                Cmp::Le | Cmp::Lt => lp.le.push((row, -c.expr.constant - shrink)),
            }
        }
        if let Some(obj) = &self.objective {
            for (v, a) in &obj.terms {
                lp.c[self.var_index(apps, n_net, *v)] += a;
            }
        }
        lp
    }

    /// The concrete point behind an LP primal: inputs clamped into their boxes, outputs
    /// evaluated by the plain network, free variables repaired to their best value.
    fn concretise(
        &self,
        apps: &[AppVars],
        n_net: usize,
        boxes: &[Vec<(f64, f64)>],
        x: &[f64],
    ) -> Point {
        let inputs: Vec<Vec<f64>> = apps
            .iter()
            .zip(boxes)
            .map(|(av, b)| {
                b.iter()
                    .enumerate()
                    .map(|(j, (l, h))| x[av.x + j].clamp(*l, *h))
                    .collect()
            })
            .collect();
        let outputs = inputs
            .iter()
            .zip(&self.plain)
            .map(|(i, net)| net.eval_f64(i))
            .collect();
        let mut p = Point {
            inputs,
            outputs,
            free: x[n_net..].to_vec(),
        };
        repair_free(
            &mut p,
            &self.free,
            &self.constraints,
            self.objective.as_ref(),
        );
        p
    }

    /// What makes the problem unsearchable (a variable beyond its network's inputs or
    /// outputs, a box of the wrong length, a network without layers), if anything.
    fn malformed(&self) -> Option<String> {
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

    fn stop_reached(&self, best: &Option<(Point, f64)>) -> bool {
        match (&self.stop_when, best) {
            (Some(cs), Some((p, v))) => *v >= self.floor && p.satisfies(cs),
            _ => false,
        }
    }

    fn objective_value(&self, p: &Point) -> f64 {
        self.objective
            .as_ref()
            .map(|o| o.eval(|v| p.value(v)))
            .unwrap_or(0.0)
    }

    /// Run the branch and bound. With no objective, stops at the first witness.
    pub fn solve(mut self, limits: Limits) -> BabResult {
        let t0 = Instant::now();
        if let Some(what) = self.malformed() {
            // Never index out of bounds: a malformed problem is not searched.
            return BabResult::unexplored(
                f64::INFINITY,
                false,
                Some(crate::UnknownReason::Unsupported { what }),
            );
        }
        let (apps, n_net) = self.layout();
        let boxes = self.tightened_boxes();
        let phases0: Vec<Vec<Vec<i8>>> = self
            .nets
            .iter()
            .map(|net| {
                net.maps
                    .iter()
                    .filter(|m| m.1)
                    .map(|m| vec![0i8; m.0.out])
                    .collect()
            })
            .collect();
        let Some((lo0, hi0)) = self.bounds(&apps, n_net, &boxes, &phases0, None) else {
            return BabResult::unexplored(f64::NEG_INFINITY, true, None);
        };
        self.bound_free(&apps, n_net, &lo0, &hi0);
        if self
            .free
            .iter()
            .any(|f| !f.0.is_finite() || !f.1.is_finite() || f.0 > f.1)
        {
            if self.free.iter().any(|f| f.0 > f.1) {
                return BabResult::unexplored(f64::NEG_INFINITY, true, None);
            }
            return BabResult::unexplored(f64::INFINITY, false, None);
        }
        let mut best: Option<(Point, f64)> = None;
        let mut closed_upper = f64::NEG_INFINITY;
        // Delayed root tightening (`LpTighten::Root`): once the search has solved as
        // many node LPs as the tightening will (two per unstable neuron), the root's
        // bounds are tightened and then hold at every node: a search that settles
        // quickly never pays for it, a long one pays at most double.
        let root_lps: usize = if limits.tighten == LpTighten::Root {
            let mut u = 0;
            for (net, av) in self.nets.iter().zip(&apps) {
                for (k, (m, relu)) in net.maps.iter().enumerate() {
                    let zo = av.maps[k].0;
                    if *relu {
                        u += (0..m.out)
                            .filter(|&i| lo0[zo + i] < 0.0 && hi0[zo + i] > 0.0)
                            .count();
                    }
                }
            }
            2 * u
        } else {
            usize::MAX
        };
        let mut root_seed: Option<(Vec<f64>, Vec<f64>)> = None;
        let phases_root = phases0.clone();
        let mut heap = BinaryHeap::new();
        heap.push(Node {
            phases: phases0,
            upper: f64::INFINITY,
            seed: None,
        });
        let mut nodes = 0usize;
        let mut thin = 0usize;
        let mut complete = true;
        let mut stop = None;
        'nodes: while let Some(node) = heap.pop() {
            let incumbent = best.as_ref().map(|b| b.1).unwrap_or(f64::NEG_INFINITY);
            if node.upper < self.floor {
                continue;
            }
            if node.upper <= incumbent + limits.gap {
                closed_upper = closed_upper.max(node.upper);
                continue;
            }
            let timed_out = limits.timeout.expired(t0, Instant::now());
            if nodes >= limits.nodes || timed_out {
                complete = false;
                stop = Some(if timed_out {
                    crate::UnknownReason::Timeout { nodes }
                } else {
                    crate::UnknownReason::NodeLimit { nodes }
                });
                closed_upper = closed_upper.max(node.upper);
                for n in heap.drain() {
                    closed_upper = closed_upper.max(n.upper);
                }
                break;
            }
            nodes += 1;
            if nodes == root_lps.saturating_add(1) {
                // (None: the root tightening failed to help; the search goes on without.)
                root_seed = self
                    .lp_tighten(&apps, &lo0, &hi0, &phases_root)
                    .and_then(|s| self.bounds(&apps, n_net, &boxes, &phases_root, Some(&s)));
            }
            let node_seed = meet(node.seed.as_deref(), root_seed.as_ref());
            let Some((mut lo, mut hi)) =
                self.bounds(&apps, n_net, &boxes, &node.phases, node_seed.as_ref())
            else {
                continue;
            };
            let mut seed = node.seed.clone();
            let depth: usize = node
                .phases
                .iter()
                .flatten()
                .flatten()
                .map(|p| (*p != 0) as usize)
                .sum();
            // LP tightening is lazy: only for a node that its LP neither prunes nor
            // settles, i.e. one about to be branched on; then its LP is solved again.
            let mut tighten = limits.tighten.at(depth);
            let mut found = false;
            // Both LPs' bounds are sound for the node: keep the smaller.
            let mut cap = f64::INFINITY;
            let (upper, pick) = loop {
                let lp = self.lp(&apps, n_net, &node.phases, &lo, &hi, 0.0);
                // The LP maximises the objective's linear part; add its constant soundly.
                let k0 = self.objective.as_ref().map(|o| o.constant).unwrap_or(0.0);
                let (upper, x) = match lp.solve() {
                    LpResult::Infeasible => continue 'nodes,
                    LpResult::Bound { upper, x } => (crate::net::up(upper + k0), Some(x)),
                    LpResult::Failed { upper } => (crate::net::up(upper + k0), None),
                };
                let upper = upper.min(cap);
                let incumbent = best.as_ref().map(|b| b.1).unwrap_or(f64::NEG_INFINITY);
                if upper < self.floor {
                    continue 'nodes;
                }
                if upper <= incumbent + limits.gap {
                    closed_upper = closed_upper.max(upper);
                    continue 'nodes;
                }
                // Concrete witness from the primal.
                if let Some(x) = &x {
                    let p = self.concretise(&apps, n_net, &boxes, x);
                    if p.satisfies(&self.constraints) {
                        let v = self.objective_value(&p);
                        if best.as_ref().is_none_or(|b| v > b.1) {
                            best = Some((p, v));
                        }
                        found = true;
                    }
                }
                if found && self.stop_reached(&best) {
                    return BabResult::stopped_at_witness(best, nodes, thin);
                }
                // Branch on the unstable neuron whose relaxation is most violated at x.
                let mut pick: Option<(usize, usize, usize, f64)> = None;
                for (ai, av) in apps.iter().enumerate() {
                    let mut rk = 0;
                    for (k, (m, relu)) in self.nets[ai].maps.iter().enumerate() {
                        if !*relu {
                            continue;
                        }
                        let (zo, ao) = av.maps[k];
                        let a = ao.expect("relu var");
                        for i in 0..m.out {
                            if node.phases[ai][rk][i] != 0 || lo[zo + i] >= 0.0 || hi[zo + i] <= 0.0
                            {
                                continue;
                            }
                            let score = match &x {
                                Some(x) => {
                                    (x[a + i] - x[zo + i].max(0.0)).abs()
                                        + 1e-12 * (hi[zo + i] - lo[zo + i])
                                }
                                None => hi[zo + i] - lo[zo + i],
                            };
                            if pick.is_none_or(|p| score > p.3) {
                                pick = Some((ai, rk, i, score));
                            }
                        }
                        rk += 1;
                    }
                }
                // (Not when the witness just found settles the node.)
                let settled = best.as_ref().is_some_and(|b| upper <= b.1 + limits.gap);
                if pick.is_some() && tighten && !settled {
                    tighten = false;
                    let s = self.lp_tighten(&apps, &lo, &hi, &node.phases);
                    let Some(s) = s else {
                        continue 'nodes;
                    };
                    let Some(b) = self.bounds(&apps, n_net, &boxes, &node.phases, Some(&s)) else {
                        continue 'nodes;
                    };
                    (lo, hi) = b;
                    seed = Some(Arc::new(s));
                    cap = upper;
                    continue;
                }
                break (upper, pick);
            };
            match pick {
                Some((ai, rk, i, _)) => {
                    for s in [1i8, -1] {
                        let mut ph = node.phases.clone();
                        ph[ai][rk][i] = s;
                        heap.push(Node {
                            phases: ph,
                            upper,
                            seed: seed.clone(),
                        });
                    }
                }
                None => {
                    // A linear region: the LP is exact here. Make the point concrete if it
                    // was not (tolerance): shrink the region constraints slightly.
                    if !found {
                        let shrunk = self.lp(&apps, n_net, &node.phases, &lo, &hi, 1e-9);
                        let mut ok = false;
                        if let LpResult::Bound { x, .. } = shrunk.solve() {
                            let p = self.concretise(&apps, n_net, &boxes, &x);
                            if p.satisfies(&self.constraints) {
                                let v = self.objective_value(&p);
                                if best.as_ref().is_none_or(|b| v > b.1) {
                                    best = Some((p, v));
                                }
                                ok = true;
                                if self.stop_reached(&best) {
                                    return BabResult::stopped_at_witness(best, nodes, thin);
                                }
                            }
                        }
                        if !ok {
                            thin += 1;
                        }
                    }
                    closed_upper = closed_upper.max(upper);
                }
            }
        }
        let upper = closed_upper.max(best.as_ref().map(|b| b.1).unwrap_or(f64::NEG_INFINITY));
        BabResult {
            best,
            upper,
            complete,
            nodes,
            thin_leaves: thin,
            stop,
        }
    }
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

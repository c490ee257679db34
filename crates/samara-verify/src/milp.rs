//! A plain big-M MILP encoding solved by HiGHS (feature `highs`): the cross-check and
//! alternative engine. Each ReLU with pre-activation bounds `l < 0 < u` gets a binary
//! `d`: `a >= z, a >= 0, a <= z - l (1 - d), a <= u d` (Tjeng, Xiao & Tedrake, ICLR
//! 2019). Tight big-M constants are what makes such MILPs solvable (Tjeng et al.), so the
//! bounds are tightened twice before a layer is encoded:
//! - the tightest of interval arithmetic, CROWN and 20 alpha-CROWN steps over the input
//!   box (sound, outward-rounded);
//! - then, for each ReLU still unstable, the minimum and maximum of its pre-activation
//!   over the **LP relaxation** built so far (earlier layers with `d` in `[0, 1]`, and
//!   the region's constraints on the inputs alone, such as P1's `x + y >= ystar`): the
//!   "LP-tightened bounds" of Tjeng et al., section 4. An input constraint that cuts
//!   the box to a sliver turns most ReLUs stable this way, which interval and CROWN
//!   bounds over the box cannot see. One HiGHS LP is kept for the whole disjunct and
//!   only its objective changes between these solves, so each one starts from the
//!   previous optimal basis (a few simplex iterations) instead of from scratch;
//! - then ([`MilpOptions::sweep`]) each ReLU still unstable once more over the whole
//!   relaxation with the region's output constraints (the counterexample condition,
//!   such as P1's `ex < 0.187`), in layer order, each new bound tightening the
//!   relaxation for the next: optimisation-based bound tightening (OBBT) under the
//!   property's own constraints. The MILP is then encoded with those bounds.
//!
//! Strict constraints are taken non-strictly (the closure), so the optimum is the
//! supremum. HiGHS works in floating point: each LP bound is widened by
//! [`LP_MARGIN`] (relative) before it is used, and this engine is for cross-checks, not
//! proofs. The whole computation (bounds and every disjunct's MILP) stops at
//! [`MilpOptions::time_limit`] wall-clock seconds: [`MilpError::TimeLimit`] then, never a
//! value.

use crate::net::{affine_bounds, PwlNet};
use crate::point::tighten;
use highs::{Col, HighsModelStatus, Model, RowProblem, Sense as HSense};
use samara_bounds::symbolic;
use samara_spec::normal::{Cmp, Goal, Query, Sense, Var};
use std::collections::HashMap;
use std::time::{Duration, Instant};

/// The default overall time limit of [`optimise_milp`], in seconds.
pub const TIME_LIMIT_S: f64 = 120.0;

/// The relative widening of a bound found by an LP (HiGHS's feasibility tolerance is
/// 1e-7): `v +- LP_MARGIN * (1 + |v|)`.
pub const LP_MARGIN: f64 = 1e-6;

/// HiGHS's relative and absolute MIP gaps (its defaults, 1e-4 and 1e-6, let "optimal"
/// stop 1e-4 of the value short: too loose for a cross-check to 1e-5).
pub const MIP_GAP: f64 = 1e-7;

/// Options of [`optimise_milp_with`].
#[derive(Clone, Debug)]
pub struct MilpOptions {
    /// Wall-clock limit in seconds for the whole query: the bound computations and
    /// every disjunct's MILP together (`f64::INFINITY`: none). HiGHS is given what
    /// remains of it at each solve, and no solve starts after it.
    pub time_limit: f64,
    /// After the layer-by-layer LP bounds, tighten every unstable ReLU again over the
    /// whole relaxation with the region's output constraints (see `sweep`), then
    /// encode the MILP with those bounds.
    pub sweep: bool,
    /// HiGHS's MIP and primal feasibility tolerances (`None`: its defaults, 1e-6 and
    /// 1e-7). An indicator within 1e-6 of 0 or 1 times a big-M of tens leaves a ReLU
    /// 1e-5 of slack, so a point "feasible" by the defaults may miss the property's
    /// output constraint by that much: a cross-check at 1e-5 needs them tighter.
    pub feasibility_tolerance: Option<f64>,
}

impl Default for MilpOptions {
    fn default() -> Self {
        Self {
            time_limit: TIME_LIMIT_S,
            sweep: true,
            feasibility_tolerance: None,
        }
    }
}

/// Why [`optimise_milp_with`] gives no value.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MilpError {
    /// The query applies a network that was not given.
    #[error("network `{0}` missing")]
    MissingNetwork(String),
    /// [`MilpOptions::time_limit`] passed before the answer was known.
    #[error("time limit of {limit} s reached during the {phase} (best value found {incumbent:?}, HiGHS's bound {dual_bound:?})")]
    TimeLimit {
        /// The limit, in seconds.
        limit: f64,
        /// `LP bounds`, `MILP` or `CROWN bounds`.
        phase: &'static str,
        /// In the MILP: the best value of a feasible point found so far (over the
        /// disjuncts done and this one), if any.
        incumbent: Option<f64>,
        /// In the MILP of the last disjunct: HiGHS's dual bound on the optimum (over
        /// every disjunct), so that the optimum lies between `incumbent` and it.
        dual_bound: Option<f64>,
    },
    /// An option is out of range.
    #[error("{0}")]
    Options(String),
    /// HiGHS ended otherwise (numerical trouble, an unbounded MILP, an interrupt).
    #[error("HiGHS: {0}")]
    Solver(String),
}

/// What the MILP computation did, summed over the disjuncts.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MilpStats {
    /// ReLUs unstable after interval, CROWN and alpha-CROWN bounds.
    pub unstable_crown: usize,
    /// ReLUs still unstable after the LP bounds: the MILP's binary variables.
    pub binaries: usize,
    /// LPs solved for bounds (two per ReLU unstable after CROWN).
    pub lp_solves: usize,
    /// Simplex iterations of those LPs.
    pub lp_iterations: u64,
    /// Wall-clock seconds of the bound computations (CROWN and LP).
    pub bound_seconds: f64,
    /// Wall-clock seconds of the MILP solves.
    pub milp_seconds: f64,
}

/// The optimum (or, for a `Prove` query, `Some(0.0)` if the region is non-empty) with
/// what it took.
#[derive(Clone, Debug, PartialEq)]
pub struct MilpOutcome {
    /// The optimum over every disjunct, `None` if the region is empty.
    pub value: Option<f64>,
    /// HiGHS's dual bound on it (the largest over the disjuncts for a maximum, the
    /// least for a minimum): the optimum lies between `value` and `bound`, within
    /// [`MIP_GAP`].
    pub bound: Option<f64>,
    /// Counts and times.
    pub stats: MilpStats,
}

/// The wall-clock deadline of one query.
#[derive(Clone, Copy)]
struct Deadline {
    at: Option<Instant>,
    limit: f64,
}

impl Deadline {
    /// Seconds left before `phase` may start a solve, or the time-limit error.
    fn left(&self, phase: &'static str) -> Result<f64, MilpError> {
        match self.at {
            None => Ok(f64::INFINITY),
            Some(at) => {
                let now = Instant::now();
                if now >= at {
                    Err(self.expired(phase))
                } else {
                    Ok((at - now).as_secs_f64())
                }
            }
        }
    }

    fn expired(&self, phase: &'static str) -> MilpError {
        MilpError::TimeLimit {
            limit: self.limit,
            phase,
            incumbent: None,
            dual_bound: None,
        }
    }
}

/// The LP relaxation, kept in one HiGHS instance: columns and rows are added as layers
/// are encoded, and each bound is an objective change and a hot-started simplex run.
struct Relaxation {
    model: Option<Model>,
    cols: Vec<Col>,
    solves: usize,
    iterations: u64,
}

/// How one LP ended.
enum LpEnd {
    Value(f64),
    Infeasible,
    /// Numerical trouble and the like: the caller keeps the bound it had.
    Unknown,
}

impl Relaxation {
    fn new() -> Self {
        let mut m = Model::new(RowProblem::default());
        m.make_quiet();
        // Each LP hot-starts from the previous basis; presolve would discard it.
        m.set_option("presolve", "off");
        Self {
            model: Some(m),
            cols: Vec::new(),
            solves: 0,
            iterations: 0,
        }
    }

    fn model(&mut self) -> &mut Model {
        self.model
            .as_mut()
            .expect("the relaxation's model is put back after each solve")
    }

    fn add_col(&mut self, lo: f64, hi: f64) {
        let c = self.model().add_col(0.0, lo..=hi, []);
        self.cols.push(c);
    }

    fn add_row(&mut self, lo: f64, hi: f64, row: &[(usize, f64)]) {
        let r: Vec<(Col, f64)> = row.iter().map(|&(c, w)| (self.cols[c], w)).collect();
        self.model().add_row(lo..=hi, r);
    }

    fn set_costs(&mut self, row: &[(usize, f64)], zero: bool) {
        let p = self.model().as_mut_ptr();
        for &(c, w) in row {
            // SAFETY: `p` is the live HiGHS instance owned by `self.model`; `c` is one
            // of its columns.
            unsafe {
                highs_sys::Highs_changeColCost(
                    p,
                    c as highs_sys::HighsInt,
                    if zero { 0.0 } else { w },
                );
            }
        }
    }

    fn set_bounds(&mut self, c: usize, lo: f64, hi: f64) {
        let p = self.model().as_mut_ptr();
        // SAFETY: `p` is the live HiGHS instance owned by `self.model`; `c` is one of
        // its columns.
        unsafe {
            highs_sys::Highs_changeColBounds(p, c as highs_sys::HighsInt, lo, hi);
        }
    }

    /// The optimum of the current objective over the relaxation in `sense`.
    fn optimum(&mut self, sense: HSense, deadline: &Deadline) -> Result<LpEnd, MilpError> {
        let left = deadline.left("LP bounds")?;
        let mut m = self.model.take().expect("the relaxation's model");
        m.set_sense(sense);
        // HiGHS's run clock accumulates over the runs of one instance: the limit is
        // the time run so far plus what is left.
        // SAFETY: `m` is a live HiGHS instance.
        let ran = unsafe { highs_sys::Highs_getRunTime(m.as_mut_ptr()) };
        m.set_option("time_limit", (ran + left).min(1e20));
        let solved = m.try_solve();
        self.solves += 1;
        let mut solved = solved.map_err(|e| MilpError::Solver(format!("LP bound: {e:?}")))?;
        let mut it: highs_sys::HighsInt = 0;
        // SAFETY: a live instance; the name is a NUL-terminated info key.
        unsafe {
            highs_sys::Highs_getIntInfoValue(
                solved.as_mut_ptr(),
                c"simplex_iteration_count".as_ptr(),
                &mut it,
            );
        }
        self.iterations += it.max(0) as u64;
        let end = match solved.status() {
            HighsModelStatus::Optimal => LpEnd::Value(solved.objective_value()),
            HighsModelStatus::Infeasible => LpEnd::Infeasible,
            HighsModelStatus::ReachedTimeLimit => return Err(deadline.expired("LP bounds")),
            _ => LpEnd::Unknown,
        };
        self.model = Some(Model::from(solved));
        Ok(end)
    }

    /// The range of `sum row + constant` over the relaxation, widened by
    /// [`LP_MARGIN`]; `None` if the relaxation is infeasible (then so is the MILP).
    /// A side that ends otherwise (numerical trouble) stays infinite: the caller keeps
    /// the bound it had.
    fn range(
        &mut self,
        row: &[(usize, f64)],
        constant: f64,
        deadline: &Deadline,
    ) -> Result<Option<(f64, f64)>, MilpError> {
        let mut out = [f64::NEG_INFINITY, f64::INFINITY];
        self.set_costs(row, false);
        for (k, sense) in [HSense::Minimise, HSense::Maximise].into_iter().enumerate() {
            match self.optimum(sense, deadline)? {
                LpEnd::Value(v) => {
                    let v = v + constant;
                    let m = LP_MARGIN * (1.0 + v.abs());
                    out[k] = if k == 0 { v - m } else { v + m };
                }
                LpEnd::Infeasible => return Ok(None),
                LpEnd::Unknown => {}
            }
        }
        self.set_costs(row, true);
        Ok(Some((out[0], out[1])))
    }
}

/// The MILP (a row problem, passed to HiGHS once complete) and its LP relaxation (live),
/// built column by column in step: column `i` is the same variable in both; only the
/// MILP's ReLU indicators are integer.
struct Pair {
    milp: RowProblem,
    milp_cols: Vec<Col>,
    lp: Relaxation,
}

impl Pair {
    fn column(&mut self, cost: f64, lo: f64, hi: f64, integer: bool) -> usize {
        let c = self
            .milp
            .add_column_with_integrality(cost, lo..=hi, integer);
        self.milp_cols.push(c);
        self.lp.add_col(lo, hi);
        self.milp_cols.len() - 1
    }

    fn row(&mut self, lo: f64, hi: f64, row: &[(usize, f64)]) {
        let r: Vec<(Col, f64)> = row.iter().map(|&(c, w)| (self.milp_cols[c], w)).collect();
        self.milp.add_row(lo..=hi, r);
        self.lp.add_row(lo, hi, row);
    }
}

/// [`optimise_milp_with`] with the default options ([`TIME_LIMIT_S`]), the value alone.
pub fn optimise_milp(q: &Query, nets: &HashMap<String, PwlNet>) -> Result<Option<f64>, MilpError> {
    optimise_milp_with(q, nets, &MilpOptions::default()).map(|o| o.value)
}

/// Pre-activation bounds: per application, per affine map, per neuron.
type Bounds = Vec<Vec<Vec<(f64, f64)>>>;

/// One affine map of an encoded network: its output columns (pre-activations), their
/// bounds, and each ReLU's indicator column (`None` where the ReLU is stable).
struct Layer {
    z: Vec<usize>,
    bounds: Vec<(f64, f64)>,
    d: Vec<Option<usize>>,
    relu: bool,
}

/// One disjunct encoded: the MILP and its LP relaxation (region rows included), with
/// the layers of each application.
struct Encoding {
    pb: Pair,
    layers: Vec<Vec<Layer>>,
    binaries: usize,
}

/// Encodes the disjunct `conj` over `boxes`. The pre-activation bounds are `given`
/// or else computed (interval, CROWN, alpha-CROWN, then the layer-by-layer LP bounds).
/// `None` if an LP shows the disjunct empty.
#[allow(clippy::too_many_arguments)]
fn encode(
    q: &Query,
    conj: &[samara_spec::normal::Constraint],
    boxes: &[Vec<(f64, f64)>],
    nets: &HashMap<String, PwlNet>,
    coef: &dyn Fn(Var) -> f64,
    given: Option<&Bounds>,
    deadline: &Deadline,
    stats: &mut MilpStats,
) -> Result<Option<Encoding>, MilpError> {
    let mut pb = Pair {
        milp: RowProblem::default(),
        milp_cols: Vec::new(),
        lp: Relaxation::new(),
    };
    // Every input and free variable first, then the region's constraints on them
    // alone: the LP bounds of every layer see those.
    let ins: Vec<Vec<usize>> = boxes
        .iter()
        .enumerate()
        .map(|(ai, b)| {
            b.iter()
                .enumerate()
                .map(|(i, (l, h))| pb.column(coef(Var::Input { app: ai, index: i }), *l, *h, false))
                .collect()
        })
        .collect();
    let frees: Vec<usize> = q
        .free_vars
        .iter()
        .enumerate()
        .map(|(k, f)| pb.column(coef(Var::Free(k)), f.1, f.2, false))
        .collect();
    let on_inputs = |c: &samara_spec::normal::Constraint| {
        c.expr
            .terms
            .iter()
            .all(|(v, _)| !matches!(v, Var::Output { .. }))
    };
    let add_rows = |pb: &mut Pair, outs: &[Vec<usize>], inputs_only: bool| {
        let col = |v: Var| match v {
            Var::Input { app, index } => ins[app][index],
            Var::Output { app, index } => outs[app][index],
            Var::Free(k) => frees[k],
        };
        for c in conj.iter().filter(|c| on_inputs(c) == inputs_only) {
            let row: Vec<_> = c.expr.terms.iter().map(|(v, a)| (col(*v), *a)).collect();
            let k = -c.expr.constant;
            let (lo, hi) = match c.cmp {
                Cmp::Eq => (k, k),
                Cmp::Le | Cmp::Lt => (f64::NEG_INFINITY, k),
            };
            pb.row(lo, hi, &row);
        }
    };
    add_rows(&mut pb, &[], true);
    let mut outs = Vec::new();
    let mut all_layers = Vec::new();
    let mut binaries = 0;
    for (ai, app) in q.applications.iter().enumerate() {
        let net = nets
            .get(&app.network)
            .ok_or_else(|| MilpError::MissingNetwork(app.network.clone()))?;
        let (mut lo, mut hi): (Vec<f64>, Vec<f64>) = boxes[ai].iter().copied().unzip();
        let pre = match given {
            Some(g) => g[ai].clone(),
            None => {
                let mut pre = symbolic::crown_pre(&net.maps, &lo, &hi, None);
                symbolic::alpha_pre_until(&net.maps, &mut pre, &lo, &hi, 20, deadline.at);
                pre
            }
        };
        let mut prev = ins[ai].clone();
        let mut layers = Vec::new();
        let n_maps = net.maps.len();
        for (k, (m, relu)) in net.maps.iter().enumerate() {
            let (mut zl, mut zh) = affine_bounds(m, &lo, &hi);
            if let Some(p) = pre.get(k) {
                for (r, &(l, h)) in p.iter().enumerate() {
                    (zl[r], zh[r]) = (zl[r].max(l), zh[r].min(h));
                }
            }
            let rows: Vec<Vec<(usize, f64)>> = (0..m.out)
                .map(|r| m.row(r).nonzeros().map(|(j, w)| (prev[j], w)).collect())
                .collect();
            if *relu && given.is_none() {
                for r in 0..m.out {
                    if zl[r] < 0.0 && zh[r] > 0.0 {
                        stats.unstable_crown += 1;
                        let Some((l, h)) = pb.lp.range(&rows[r], m.b[r], deadline)? else {
                            stats.lp_solves += pb.lp.solves;
                            stats.lp_iterations += pb.lp.iterations;
                            return Ok(None);
                        };
                        (zl[r], zh[r]) = (zl[r].max(l), zh[r].min(h));
                    }
                }
            }
            let last = k + 1 == n_maps;
            let mut zs = Vec::new();
            for r in 0..m.out {
                let c = if last && !*relu {
                    coef(Var::Output { app: ai, index: r })
                } else {
                    0.0
                };
                let z = pb.column(c, zl[r], zh[r], false);
                let mut row = vec![(z, 1.0)];
                row.extend(rows[r].iter().map(|&(c, w)| (c, -w)));
                pb.row(m.b[r], m.b[r], &row);
                zs.push(z);
            }
            let mut ds = vec![None; m.out];
            if *relu {
                let mut a_s = Vec::new();
                for r in 0..m.out {
                    let (l, u) = (zl[r], zh[r]);
                    let c = if last {
                        coef(Var::Output { app: ai, index: r })
                    } else {
                        0.0
                    };
                    let a = pb.column(c, 0.0, u.max(0.0), false);
                    if l >= 0.0 {
                        pb.row(0.0, 0.0, &[(a, 1.0), (zs[r], -1.0)]);
                    } else if u <= 0.0 {
                        pb.row(0.0, 0.0, &[(a, 1.0)]);
                    } else {
                        binaries += 1;
                        let d = pb.column(0.0, 0.0, 1.0, true);
                        pb.row(0.0, f64::INFINITY, &[(a, 1.0), (zs[r], -1.0)]);
                        pb.row(f64::NEG_INFINITY, -l, &[(a, 1.0), (zs[r], -1.0), (d, -l)]);
                        pb.row(f64::NEG_INFINITY, 0.0, &[(a, 1.0), (d, -u)]);
                        ds[r] = Some(d);
                    }
                    a_s.push(a);
                }
                layers.push(Layer {
                    z: zs,
                    bounds: zl.iter().copied().zip(zh.iter().copied()).collect(),
                    d: ds,
                    relu: true,
                });
                lo = zl.iter().map(|v| v.max(0.0)).collect();
                hi = zh.iter().map(|v| v.max(0.0)).collect();
                prev = a_s;
            } else {
                layers.push(Layer {
                    z: zs.clone(),
                    bounds: zl.iter().copied().zip(zh.iter().copied()).collect(),
                    d: ds,
                    relu: false,
                });
                lo = zl;
                hi = zh;
                prev = zs;
            }
        }
        outs.push(prev);
        all_layers.push(layers);
    }
    // The output rows last: in the MILP, and in the relaxation for the sweep.
    add_rows(&mut pb, &outs, false);
    stats.lp_solves += pb.lp.solves;
    stats.lp_iterations += pb.lp.iterations;
    pb.lp.solves = 0;
    pb.lp.iterations = 0;
    Ok(Some(Encoding {
        pb,
        layers: all_layers,
        binaries,
    }))
}

/// The second tightening: every ReLU still unstable, in layer order, bounded over the
/// whole relaxation, the region's output constraints included (the counterexample
/// condition `ex < 0.187` of P1, say, which the layer-by-layer LPs cannot see); each new
/// bound tightens the relaxation for the next (column bounds, and an indicator fixed
/// where the ReLU turned stable). `None` if the relaxation is empty.
fn sweep(
    enc: &mut Encoding,
    deadline: &Deadline,
    stats: &mut MilpStats,
) -> Result<Option<Bounds>, MilpError> {
    let mut out: Bounds = enc
        .layers
        .iter()
        .map(|ls| ls.iter().map(|l| l.bounds.clone()).collect())
        .collect();
    let lp = &mut enc.pb.lp;
    let mut result = Some(());
    'all: for (ai, layers) in enc.layers.iter().enumerate() {
        for (k, layer) in layers.iter().enumerate() {
            if !layer.relu {
                continue;
            }
            for r in 0..layer.z.len() {
                let (l, u) = out[ai][k][r];
                if !(l < 0.0 && u > 0.0) {
                    continue;
                }
                let Some((nl, nu)) = lp.range(&[(layer.z[r], 1.0)], 0.0, deadline)? else {
                    result = None;
                    break 'all;
                };
                let (l, u) = (l.max(nl), u.min(nu));
                if l > u {
                    result = None;
                    break 'all;
                }
                out[ai][k][r] = (l, u);
                lp.set_bounds(layer.z[r], l, u);
                if let Some(d) = layer.d[r] {
                    if l >= 0.0 {
                        lp.set_bounds(d, 1.0, 1.0);
                    } else if u <= 0.0 {
                        lp.set_bounds(d, 0.0, 0.0);
                    }
                }
            }
        }
    }
    stats.lp_solves += lp.solves;
    stats.lp_iterations += lp.iterations;
    Ok(result.map(|_| out))
}

/// The optimum of an `Optimise` query (over every disjunct), `None` if the region is
/// empty; for a `Prove` query, `Some(0.0)` if the region is non-empty. Returns within
/// about a second of `opts.time_limit` ([`MilpError::TimeLimit`] then).
pub fn optimise_milp_with(
    q: &Query,
    nets: &HashMap<String, PwlNet>,
    opts: &MilpOptions,
) -> Result<MilpOutcome, MilpError> {
    let start = Instant::now();
    if opts.time_limit.is_nan() || opts.time_limit < 0.0 {
        return Err(MilpError::Options(format!(
            "time limit {}: must be >= 0 seconds",
            opts.time_limit
        )));
    }
    let deadline = Deadline {
        at: Duration::try_from_secs_f64(opts.time_limit)
            .ok()
            .and_then(|d| start.checked_add(d)),
        limit: opts.time_limit,
    };
    let mut stats = MilpStats::default();
    let (obj, sense) = match &q.goal {
        Goal::Optimise {
            objective, sense, ..
        } => (Some(objective.clone()), *sense),
        Goal::Prove => (None, Sense::Max),
    };
    let coef = |v: Var| -> f64 {
        obj.as_ref()
            .map(|o| o.terms.iter().filter(|t| t.0 == v).map(|t| t.1).sum())
            .unwrap_or(0.0)
    };
    let mut best: Option<f64> = None;
    let mut bound: Option<f64> = None;
    let pick = |a: Option<f64>, v: f64| {
        Some(match (a, sense) {
            (None, _) => v,
            (Some(b), Sense::Max) => b.max(v),
            (Some(b), Sense::Min) => b.min(v),
        })
    };
    let constant = obj.as_ref().map(|o| o.constant).unwrap_or(0.0);
    for (i_conj, conj) in q.region.iter().enumerate() {
        let t_bounds = Instant::now();
        deadline.left("CROWN bounds")?;
        let boxes = tighten(
            &q.applications
                .iter()
                .map(|a| a.input_box.clone())
                .collect::<Vec<_>>(),
            conj,
        );
        if boxes.iter().flatten().any(|(l, h)| l > h) {
            continue;
        }
        let enc = encode(q, conj, &boxes, nets, &coef, None, &deadline, &mut stats)?;
        let enc = match enc {
            Some(mut e) if opts.sweep => match sweep(&mut e, &deadline, &mut stats)? {
                Some(b) => encode(
                    q,
                    conj,
                    &boxes,
                    nets,
                    &coef,
                    Some(&b),
                    &deadline,
                    &mut stats,
                )?,
                None => None,
            },
            e => e,
        };
        stats.bound_seconds += t_bounds.elapsed().as_secs_f64();
        let Some(enc) = enc else {
            continue;
        };
        stats.binaries += enc.binaries;
        let t_milp = Instant::now();
        let left = deadline.left("MILP")?;
        let mut model = enc.pb.milp.optimise(if sense == Sense::Max {
            HSense::Maximise
        } else {
            HSense::Minimise
        });
        model.make_quiet();
        model.set_option("time_limit", left.min(1e20));
        model.set_option("mip_rel_gap", MIP_GAP);
        model.set_option("mip_abs_gap", MIP_GAP);
        if let Some(t) = opts.feasibility_tolerance {
            model.set_option("mip_feasibility_tolerance", t);
            model.set_option("primal_feasibility_tolerance", t);
        }
        let solved = model.try_solve();
        stats.milp_seconds += t_milp.elapsed().as_secs_f64();
        let mut solved = solved.map_err(|e| MilpError::Solver(format!("MILP: {e:?}")))?;
        let info = |solved: &mut highs::SolvedModel, key: &std::ffi::CStr| {
            let mut v = f64::NAN;
            // SAFETY: a live instance; `key` is a NUL-terminated info name.
            unsafe {
                highs_sys::Highs_getDoubleInfoValue(solved.as_mut_ptr(), key.as_ptr(), &mut v);
            }
            v.is_finite().then_some(v + constant)
        };
        match solved.status() {
            HighsModelStatus::Optimal => {
                let v = solved.objective_value() + constant;
                best = pick(best, v);
                bound = pick(bound, info(&mut solved, c"mip_dual_bound").unwrap_or(v));
            }
            HighsModelStatus::Infeasible => {}
            HighsModelStatus::ReachedTimeLimit => {
                let mut has_point: highs_sys::HighsInt = 0;
                // SAFETY: as above.
                unsafe {
                    highs_sys::Highs_getIntInfoValue(
                        solved.as_mut_ptr(),
                        c"primal_solution_status".as_ptr(),
                        &mut has_point,
                    );
                }
                // 2: a feasible point (HiGHS's kSolutionStatusFeasible).
                let inc = if has_point == 2 {
                    pick(best, solved.objective_value() + constant)
                } else {
                    best
                };
                let dual = info(&mut solved, c"mip_dual_bound")
                    .filter(|_| i_conj + 1 == q.region.len())
                    .and_then(|d| pick(bound, d));
                return Err(MilpError::TimeLimit {
                    limit: deadline.limit,
                    phase: "MILP",
                    incumbent: inc,
                    dual_bound: dual,
                });
            }
            s => return Err(MilpError::Solver(format!("MILP: {s:?}"))),
        }
    }
    Ok(MilpOutcome {
        value: best,
        bound,
        stats,
    })
}

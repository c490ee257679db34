//! Branch and bound for the optimum of a linear objective over one piecewise-linear
//! network's graph: maximise `e . v + c . y + d0` over `v = (x, t)` in a box (the network
//! inputs `x` and extra free variables `t`, such as a parameter of a property), `y =
//! f(x)`, subject to a conjunction of linear constraints `a . v + c . y + d <= 0` (or
//! `< 0`). A critical value is this optimisation, searched as one branch and bound with a
//! global upper bound (the largest bound of the open nodes) and a lower bound (the best
//! concrete point) that meet, not as a sequence of decision queries.
//!
//! A node is an input box together with phases fixed for some ReLUs. Its bound: full
//! CROWN pre-activation bounds over the box (Zhang et al., NeurIPS 2018) with the fixed
//! neurons clamped ([`crate::phases`]), linear lower bounds in `x` of each output
//! function the constraints and the objective use (alpha-CROWN, Xu et al., ICLR 2021),
//! which turn every constraint into a linear row over `v` that every point of the node
//! satisfies; each fixed phase is one more such row. The small LP over `v` in the box
//! with those rows ([`crate::lp::min_linear`]) proposes multipliers `lambda >= 0`; the
//! bound is `max over the box of (objective - lambda . rows)`, formed and maximised with
//! outward rounding ([`crate::symbolic::Linear::combine`]): weak duality, so the float LP
//! value itself is never trusted. With every ReLU of a node fixed or stable the network
//! is affine there and the LP is exact (up to its rounding slack), so the leaves of the
//! search close.
//!
//! Objective cut-off: a point whose value is at most the incumbent's adds nothing, so
//! every node's box is first shrunk to the points that satisfy the rows over `v` alone
//! (the constraints without outputs) and `objective >= incumbent` when the objective has
//! no output term (bound propagation with outward rounding); the same rows, projected
//! onto the inputs, cut the set over which the earliest unstable layer's pre-activation
//! bounds are computed ([`crate::phases`]' LP tightening). For P1 (`x + y >= ystar`,
//! maximise `ystar`) this confines the search to the corner of the box where
//! `x + y` exceeds the incumbent. The search's final bound is `max(bound of the open
//! and closed nodes, incumbent)`, so the points cut off are covered.
//!
//! Incumbents: each node's LP primal point (solved with every row pushed inward by a
//! rounding-size margin, so a point on a strict constraint's boundary is not proposed),
//! handed to the caller's `accept`, which re-evaluates the network concretely and says
//! whether the point satisfies every constraint and with which objective value: a lower
//! bound is only ever a value at an accepted point.
//!
//! Search: best first (largest bound), in batches evaluated in parallel (rayon); the
//! batch is a fixed number of nodes and incumbents are updated between batches in a
//! fixed order, so the result does not depend on the number of threads. A node with at
//! most [`Settings::phase_max_unstable`] unstable ReLUs is split on a ReLU: in the earliest layer with unstable neurons (so that every phase row
//! is exact once all are fixed), the neuron whose relaxation is loosest at the node's LP
//! point (the chord above, CROWN's lower line below; BaBSR-like, Bunel et al., JMLR
//! 2020). Otherwise every input is tried (strong branching: both halves bounded, the
//! chosen halves keep their bounds) and the product rule picks the split (Achterberg,
//! 2007: the split that lowers both halves' bounds); when the best split closes less
//! than 1% of the node's gap to the incumbent, the bound there is the relaxation's, not
//! the box's, and the node is split on a ReLU instead; an input 64 times narrower than
//! the widest (relative to the problem's box) gives way to the widest. Nodes whose bound
//! is within the gap of the incumbent are closed; the search stops when the global bound
//! meets the incumbent, at the deadline or at the node limit. An attack (projected
//! steps from seeded starts) gives incumbents once the search has bounded
//! [`Settings::attack_after`] nodes without closing (a few starts; the rest after four
//! times as many nodes), or before the root when that is 0:
//! most small questions (the slack form of a relational property on a small network,
//! asked thousands of times by a P5 table) close in a few nodes, and for them the
//! attack would be most of the work.
//!
//! With the environment variable `SAMARA_OPT_TRACE` set, the search prints its bounds
//! and node count to stderr every 2,000 nodes and when it finishes (as `SAMARA_SEARCH_PROFILE` does for
//! [`crate::search`]).

// Measured on the Goedel + Lipschitz 6-64-32-1 network's P1 (normalised spec, 2 cores):
// input splitting alone never lowers the global bound (45.91, the box's corner, which
// every piece that keeps it still reaches); ReLU splitting from the root reaches the
// exact value in 11,400 nodes; the rules above without the cut-off in about 12,000
// nodes and 3.3 s of CPU, with it (and 4 alpha-CROWN steps, input splitting allowed
// below ReLU splits, 20 unstable ReLUs for ReLU splitting) in about 3,400 and 0.9 s.
// On the generated Lipschitz networks (bench/verify/gen_lipschitz.sh, seeds 1 and 3)
// input splitting below ReLU splits is what closes P1 (seed 1: 23,700 nodes without
// alpha steps and 5,500 with; ReLU splitting only: no answer in 60 s).

use crate::phases::unstable;
use crate::rules::relu;
use crate::symbolic::{self, Linear, Objective};
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use samara_nn::Affine;
use std::collections::BinaryHeap;
use std::sync::Arc;
use std::time::Instant;

/// A linear function `v_coef . v + y_coef . y + d` of the variables `v = (x, t)` and the
/// network's outputs `y`.
#[derive(Clone, Debug, PartialEq)]
pub struct LinearFn {
    /// Coefficients over `v` (inputs first, then the extra variables).
    pub v: Vec<f64>,
    /// Coefficients over the outputs (empty or all zero: no output).
    pub y: Vec<f64>,
    /// Constant.
    pub d: f64,
}

impl LinearFn {
    fn uses_outputs(&self) -> bool {
        self.y.iter().any(|c| *c != 0.0)
    }
}

/// One constraint `f <= 0` (`f < 0` when `strict`). An equality is given as two.
#[derive(Clone, Debug, PartialEq)]
pub struct Constraint {
    /// The function.
    pub f: LinearFn,
    /// Strict inequality (the bounds treat it as its closure; points are checked by the
    /// caller's `accept`).
    pub strict: bool,
}

/// The problem: maximise `objective` over `v` in `[lo, hi]` with `y = f(x)` and every
/// constraint holding. `x` is the first `maps[0].inp` entries of `v`.
pub struct Problem<'a> {
    /// The network as a chain of affine maps (see [`crate::pwl::PwlNet`]).
    pub maps: &'a [(Affine, bool)],
    /// Lower ends of the box over `v` (finite).
    pub lo: Vec<f64>,
    /// Upper ends of the box over `v` (finite).
    pub hi: Vec<f64>,
    /// The conjunction.
    pub constraints: Vec<Constraint>,
    /// The objective, maximised.
    pub objective: LinearFn,
}

/// Limits and choices of the search.
#[derive(Clone, Debug)]
pub struct Settings {
    /// Stop (incomplete) at this instant.
    pub deadline: Option<Instant>,
    /// Most nodes bounded (0: no limit).
    pub max_nodes: usize,
    /// Absolute gap at which the search stops; the gap used is
    /// `max(gap, 1e-9 |incumbent|)`.
    pub gap: f64,
    /// Nodes whose bound is below this are dropped (for a feasibility question asked as
    /// "is the largest slack non-negative?": 0).
    pub floor: f64,
    /// A node that at most this many ReLUs cross is split on a ReLU, not on an input.
    pub phase_max_unstable: usize,
    /// alpha-CROWN steps for the output bounds of a node (0: CROWN's slopes).
    pub alpha_iters: usize,
    /// Nodes per parallel batch (fixed, so that results do not depend on threads).
    pub batch: usize,
    /// Starts of the initial attack (0: none).
    pub attack_starts: usize,
    /// Steps per start of the initial attack.
    pub attack_steps: usize,
    /// Nodes bounded before the attack runs (0: before the root, whose box its
    /// incumbent then cuts). Most small questions close within a few nodes, and for
    /// them the attack would be most of the work.
    pub attack_after: usize,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            deadline: None,
            max_nodes: 0,
            gap: 1e-9,
            floor: f64::NEG_INFINITY,
            phase_max_unstable: 20,
            alpha_iters: 4,
            batch: 8,
            attack_starts: 64,
            attack_steps: 100,
            attack_after: 100,
        }
    }
}

/// A point the caller accepted.
#[derive(Clone, Debug, PartialEq)]
pub struct Accepted {
    /// The point (the caller may repair it, e.g. set the extra variables to their best
    /// values given the inputs).
    pub v: Vec<f64>,
    /// Its objective value, computed concretely by the caller.
    pub value: f64,
    /// End the search at once (e.g. a counterexample was found).
    pub stop: bool,
}

/// Why a search stopped short.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stop {
    /// The deadline passed.
    Timeout,
    /// The node limit was reached.
    NodeLimit,
}

/// The answer.
#[derive(Clone, Debug, PartialEq)]
pub struct Outcome {
    /// The best accepted point and its value (a lower bound of the optimum).
    pub best: Option<Accepted>,
    /// A sound upper bound of the optimum (`-inf`: no point; meaningless after an early
    /// stop, where it is `+inf`).
    pub upper: f64,
    /// The search ran to completion (no limit cut it short, no early stop).
    pub complete: bool,
    /// Which limit stopped it.
    pub stop: Option<Stop>,
    /// The caller's `accept` asked to stop.
    pub stopped_early: bool,
    /// Nodes bounded.
    pub nodes: usize,
    /// Leaves (the network affine on them) whose bound stays above the incumbent but
    /// where no point was accepted: the region there is thinner than the rounding.
    pub thin: usize,
}

impl Outcome {
    /// Keep an accepted point if it beats the best so far; when the caller asked to
    /// stop at it, mark the early stop (no bound claimed) and say so.
    fn take(&mut self, a: Accepted) -> bool {
        let stop = a.stop;
        if self.best.as_ref().is_none_or(|b| a.value > b.value) {
            self.best = Some(a);
        }
        if stop {
            self.stopped_early = true;
            self.complete = false;
            self.upper = f64::INFINITY;
        }
        stop
    }
}

/// How far (relative to each row's magnitude) the LP pushes its primal point inside the
/// rows: first a rounding-size margin, at a leaf more until a point is accepted (a point
/// on a strict constraint's boundary is no witness; a deeper one loses objective value:
/// the row's multiplier times the push, which on a flat network is large: seed 1 of
/// bench/verify/gen_lipschitz.sh has a multiplier of 1.2e7 on P1's output row, so a
/// first push of 1e-12 lost 1.2e-5 of ystar, 1e-15 loses 1e-8).
const SHRINK: [f64; 7] = [1e-15, 1e-13, 1e-12, 1e-10, 1e-8, 1e-6, 1e-4];

/// Starts of the attack's first round (see [`optimise`]); the rest run only when its
/// points leave the search open.
const ATTACK_FIRST_ROUND: usize = 8;

/// One fixed phase: map, neuron, active.
type Fix = (usize, usize, bool);
type Bounds = Vec<Vec<(f64, f64)>>;

/// A bounded node.
struct Node {
    lo: Vec<f64>,
    hi: Vec<f64>,
    fixes: Vec<Fix>,
    /// Pre-activation bounds valid on the node.
    pre: Arc<Bounds>,
    /// Lower bounds (over `x`) of the fixed phases' functions, each `<= 0` on the node.
    phase_fs: Arc<Vec<Linear>>,
    upper: f64,
    /// Unstable, unfixed ReLUs.
    unstable: usize,
    /// Candidate point (the LP's primal).
    cand: Option<Vec<f64>>,
    /// Creation order (ties of the heap).
    id: u64,
}

impl PartialEq for Node {
    fn eq(&self, o: &Self) -> bool {
        self.cmp(o).is_eq()
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
        self.upper.total_cmp(&o.upper).then(o.id.cmp(&self.id))
    }
}

/// `f` (over `x`) as a function over `v` (zero coefficients for the extra variables).
fn extend(f: &Linear, nv: usize) -> Linear {
    let mut coef = f.coef.clone();
    coef.resize(nv, 0.0);
    Linear {
        coef,
        cst: f.cst,
        slack: f.slack,
    }
}

/// The part of `f` over `v` as an exact linear function (`scale` = 1 or -1, exact).
fn exact_v(f: &LinearFn, scale: f64) -> Linear {
    Linear {
        coef: f.v.iter().map(|c| scale * c).collect(),
        cst: scale * f.d,
        slack: 0.0,
    }
}

/// Shrink the box `[lo, hi]` to the points that can satisfy every row `r(v) <= 0`
/// (each `r` a lower bound, slack subtracted, of a function that is `<= 0` there):
/// bound propagation, each variable of each row bounded by the row's other terms at
/// their best over the box, rounded outward (the other terms' sum by [`Linear::min_over`]'s
/// error bound, the quotient by one step). A few rounds; `false` when the box is empty.
/// Every point of the old box that satisfies the rows lies in the new one.
fn propagate(rows: &[&Linear], lo: &mut [f64], hi: &mut [f64]) -> bool {
    for _ in 0..4 {
        let mut changed = false;
        for r in rows {
            let n = r.coef.len().min(lo.len());
            // The sum of the terms at their minima, and the magnitude of its terms.
            let mut sum = r.cst;
            let mut mag = r.cst.abs();
            let picks: Vec<f64> = (0..n)
                .map(|t| {
                    let (a, b) = (r.coef[t] * lo[t], r.coef[t] * hi[t]);
                    mag += a.abs().max(b.abs());
                    a.min(b)
                })
                .collect();
            for p in &picks {
                sum += p;
            }
            if sum.is_nan() || mag.is_nan() || !mag.is_finite() {
                return true;
            }
            // `sum` (and `sum - picks[t]`) are within `err` of their exact values.
            let err = ((n as f64 + 4.0) * f64::EPSILON * mag + r.slack) * (1.0 + 1e-9);
            if (sum - err).next_down() > 0.0 {
                return false;
            }
            for t in 0..n {
                let c = r.coef[t];
                if c == 0.0 {
                    continue;
                }
                // c v_t <= -(rest), rest >= m.
                let m = ((sum - picks[t]).next_down() - err).next_down();
                let q = -m / c;
                if c > 0.0 {
                    let u = q.next_up();
                    if u < hi[t] {
                        hi[t] = u.max(lo[t]);
                        changed = true;
                    }
                } else {
                    let l = q.next_down();
                    if l > lo[t] {
                        lo[t] = l.min(hi[t]);
                        changed = true;
                    }
                }
                if (c > 0.0 && q.next_up() < lo[t]) || (c < 0.0 && q.next_down() > hi[t]) {
                    return false;
                }
            }
        }
        if !changed {
            break;
        }
    }
    true
}

struct Ctx<'a> {
    p: &'a Problem<'a>,
    s: &'a Settings,
    nx: usize,
    nv: usize,
    /// Whether any constraint or the objective uses the outputs.
    net: bool,
    /// The constraints that do not use the outputs, as exact rows `f(v) <= 0` over `v`.
    vrows: Vec<Linear>,
}

/// The bound of one node, or `None` when the node is shown empty (or below the floor).
struct Eval {
    /// The node's box, shrunk by [`propagate`].
    lo: Vec<f64>,
    hi: Vec<f64>,
    upper: f64,
    /// The largest sound lower bound over the node of a constraint that uses the
    /// outputs (how close the relaxation is to cutting the node; `-inf` without one).
    row_lb: f64,
    pre: Arc<Bounds>,
    phase_fs: Arc<Vec<Linear>>,
    unstable: usize,
    cand: Option<Vec<f64>>,
}

impl Ctx<'_> {
    fn late(&self) -> bool {
        self.s.deadline.is_some_and(|d| Instant::now() >= d)
    }

    /// A sound lower bound (over `v`, on the node) of `sign * f` for a function `f` of
    /// `v` and `y`.
    fn lower_of(&self, f: &LinearFn, sign: f64, pre: &Bounds, lo: &[f64], hi: &[f64]) -> Linear {
        let ex = exact_v(f, sign);
        if !f.uses_outputs() {
            return ex;
        }
        let (xl, xh) = (&lo[..self.nx], &hi[..self.nx]);
        let obj = Objective {
            c: f.y.iter().map(|c| sign * c).collect(),
            d: 0.0,
        };
        let g = if self.s.alpha_iters > 0 {
            symbolic::alpha_lower_until(
                self.p.maps,
                pre,
                &obj,
                xl,
                xh,
                self.s.alpha_iters,
                self.s.deadline,
            )
        } else {
            symbolic::backward_lower(self.p.maps, pre, &obj, xl, xh)
        };
        extend(&g, self.nv).combine(1.0, &ex, 1.0, lo, hi)
    }

    /// The rows every point of a node that can beat `cut` satisfies, exactly over `v`:
    /// the constraints that do not use the outputs and, when the objective does not,
    /// `cut - objective(v) <= 0` (a point whose value is at most the incumbent's adds
    /// nothing to the search).
    fn cut_row(&self, cut: f64) -> Option<Linear> {
        if !cut.is_finite() || self.p.objective.uses_outputs() {
            return None;
        }
        let mut r = exact_v(&self.p.objective, -1.0);
        let d = r.cst;
        r.cst = d + cut;
        // The rounding of the constant's sum, subtracted (a lower bound).
        r.slack = f64::EPSILON * (d.abs() + cut.abs());
        Some(r)
    }

    /// The rows over `v` alone (with the cut row) as rows over the inputs `x`: each
    /// row's terms in the extra variables replaced by their minimum over the box
    /// `[lo, hi]` (sound: a row `<= 0` at a point stays `<= 0` with a smaller term).
    /// Rows without an input term are left out.
    fn xrows(&self, rows: &[&Linear], lo: &[f64], hi: &[f64]) -> Vec<Linear> {
        let nx = self.nx;
        rows.iter()
            .filter(|r| r.coef[..nx].iter().any(|c| *c != 0.0))
            .map(|r| {
                let t = Linear {
                    coef: r.coef[nx..].to_vec(),
                    cst: r.cst,
                    slack: r.slack,
                };
                // Sound lower bound of the row's constant and extra-variable part.
                let m = t.min_over(&lo[nx..], &hi[nx..]);
                Linear {
                    coef: r.coef[..nx].to_vec(),
                    cst: m,
                    slack: 0.0,
                }
            })
            .collect()
    }

    /// Whether the inputs' part of the box `[lo, hi]` is narrower than that of
    /// `[in_lo, in_hi]` by more than a thousandth on some side: then bounds computed on
    /// the new box are worth their cost.
    fn shrank(&self, lo: &[f64], hi: &[f64], in_lo: &[f64], in_hi: &[f64]) -> bool {
        (0..self.nx).any(|t| (hi[t] - lo[t]) < 0.999 * (in_hi[t] - in_lo[t]))
    }

    /// Bound a node: its box `lo, hi`, its phases `fixes` (the last one new when
    /// `new_fix`), from its parent's bounds and phase rows; the LP's primal point is
    /// pushed inside the rows by `shrink` (relative). The box is first shrunk to the
    /// points that satisfy the rows over `v` alone and can beat the incumbent `cut`
    /// ([`propagate`]; the node's points outside it have values at most `cut`, which the
    /// search's final bound covers); the shrunk box is the [`Eval`]'s.
    #[allow(clippy::too_many_arguments)]
    fn eval(
        &self,
        lo: &[f64],
        hi: &[f64],
        fixes: &[Fix],
        parent_pre: Option<&Arc<Bounds>>,
        parent_fs: &Arc<Vec<Linear>>,
        new_fix: bool,
        shrink: f64,
        cut: f64,
    ) -> Option<Eval> {
        let (in_lo, in_hi) = (lo, hi);
        let (mut lo, mut hi) = (lo.to_vec(), hi.to_vec());
        let cr = self.cut_row(cut);
        let rows: Vec<&Linear> = self.vrows.iter().chain(cr.as_ref()).collect();
        if !propagate(&rows, &mut lo, &mut hi) {
            return None;
        }
        let (lo, hi) = (&lo[..], &hi[..]);
        let (xl, xh) = (&lo[..self.nx], &hi[..self.nx]);
        let maps = self.p.maps;
        let mut phase_fs = parent_fs.clone();
        let pre: Arc<Bounds> = if !self.net {
            Arc::new(Vec::new())
        } else if new_fix {
            let parent = parent_pre.expect("a phase split has its parent's bounds");
            let mut clamped = (**parent).clone();
            let &(j, i, on) = fixes.last().expect("a new phase");
            {
                let b = &mut clamped[j][i];
                if on {
                    b.0 = b.0.max(0.0);
                } else {
                    b.1 = b.1.min(0.0);
                }
            }
            let mut nb = if self.shrank(lo, hi, in_lo, in_hi) {
                crate::search::piece_bounds(maps, xl, xh, Some(&clamped), self.s.deadline)
            } else {
                symbolic::crown_pre_from(maps, xl, xh, Some(&clamped), j + 1)
            };
            if nb.iter().flatten().any(|&(l, u)| l > u) {
                return None;
            }
            let mut c = vec![0.0; maps[j].0.out];
            c[i] = if on { -1.0 } else { 1.0 };
            let f =
                symbolic::backward_lower(&maps[..=j], &nb[..j], &Objective { c, d: 0.0 }, xl, xh);
            if f.min_over(xl, xh) > 0.0 {
                return None;
            }
            let mut fs = (**parent_fs).clone();
            fs.push(f);
            // The earliest unstable layer's bounds over the set the phase rows and
            // the input rows cut from the box.
            let mut all = self.xrows(&rows, lo, hi);
            all.extend(fs.iter().cloned());
            crate::phases::tighten(maps, &mut nb, &all, xl, xh)?;
            phase_fs = Arc::new(fs);
            Arc::new(nb)
        } else {
            let mut b = crate::search::piece_bounds(
                maps,
                xl,
                xh,
                parent_pre.map(|p| &**p),
                self.s.deadline,
            );
            let mut all = self.xrows(&rows, lo, hi);
            if !all.is_empty() {
                all.extend(parent_fs.iter().cloned());
                crate::phases::tighten(maps, &mut b, &all, xl, xh)?;
            }
            Arc::new(b)
        };
        if pre
            .iter()
            .flatten()
            .any(|&(l, u)| l > u || l.is_nan() || u.is_nan())
        {
            return None;
        }
        self.eval_with(lo, hi, &pre, &phase_fs, shrink)
    }

    /// The rows, LP bound and candidate of a node with bounds `pre` and phase rows
    /// `phase_fs` valid on it (see [`Ctx::eval`]).
    fn eval_with(
        &self,
        lo: &[f64],
        hi: &[f64],
        pre: &Arc<Bounds>,
        phase_fs: &Arc<Vec<Linear>>,
        shrink: f64,
    ) -> Option<Eval> {
        let maps = self.p.maps;
        let nv = self.nv;
        let mut rows: Vec<Linear> = phase_fs.iter().map(|f| extend(f, nv)).collect();
        for c in &self.p.constraints {
            rows.push(self.lower_of(&c.f, 1.0, pre, lo, hi));
        }
        let mut row_lb = f64::NEG_INFINITY;
        let nfix = phase_fs.len();
        for (k, r) in rows.iter().enumerate() {
            let m = r.min_over(lo, hi);
            if m > 0.0 {
                return None;
            }
            if k >= nfix && self.p.constraints[k - nfix].f.uses_outputs() {
                row_lb = row_lb.max(m);
            }
        }
        let g = self.lower_of(&self.p.objective, -1.0, pre, lo, hi);
        let mut lb = g.min_over(lo, hi);
        let mut cand = None;
        if !rows.is_empty() {
            let a: Vec<&[f64]> = rows.iter().map(|r| &r.coef[..]).collect();
            let xmax: Vec<f64> = lo
                .iter()
                .zip(hi)
                .map(|(a, b)| a.abs().max(b.abs()))
                .collect();
            // Pushed inward by a rounding-size margin, so the primal is not on a strict
            // constraint's boundary; the multipliers are certified against the true rows.
            let d: Vec<f64> = rows
                .iter()
                .map(|r| {
                    let mag = r.cst.abs()
                        + r.coef
                            .iter()
                            .zip(&xmax)
                            .map(|(c, m)| (c * m).abs())
                            .sum::<f64>();
                    r.cst + shrink * (1.0 + mag)
                })
                .collect();
            if let Some(sol) = crate::lp::min_linear(&g.coef, &a, &d, lo, hi) {
                let mut h = g.clone();
                for (r, &l) in rows.iter().zip(&sol.duals) {
                    if l > 0.0 && l.is_finite() {
                        h = h.combine(1.0, r, l, lo, hi);
                    }
                }
                let v = h.min_over(lo, hi);
                if !v.is_nan() {
                    lb = lb.max(v);
                }
                if sol.feasible {
                    cand = Some(sol.x);
                }
            }
        } else {
            cand = Some(g.argmin_corner(lo, hi));
        }
        let upper = -lb;
        if upper.is_nan() || upper < self.s.floor {
            return None;
        }
        // A bound below the objective's least value on the box: the bound holds at every
        // point of the node that satisfies the rows (weak duality), and every point of
        // the box has at least that value, so no point satisfies them: the node is
        // empty. (For P1 with `ystar` in `[0, 100]` where P1 holds for every `ystar`,
        // the search used to keep splitting such nodes for want of an incumbent: half
        // of the nodes of generated seed 4.)
        if !self.p.objective.uses_outputs()
            && upper < exact_v(&self.p.objective, 1.0).min_over(lo, hi)
        {
            return None;
        }
        let unstable = if self.net {
            unstable(maps, pre).len()
        } else {
            0
        };
        Some(Eval {
            lo: lo.to_vec(),
            hi: hi.to_vec(),
            upper,
            row_lb,
            pre: pre.clone(),
            phase_fs: phase_fs.clone(),
            unstable,
            cand,
        })
    }
}

/// The value of `f` at `v` with outputs `y`.
fn value_at(f: &LinearFn, v: &[f64], y: &[f64]) -> f64 {
    f.d + f.v.iter().zip(v).map(|(a, b)| a * b).sum::<f64>()
        + f.y.iter().zip(y).map(|(a, b)| a * b).sum::<f64>()
}

/// The gradient of `f` over `v` at `v` (through the network's active linear piece).
fn grad_at(ctx: &Ctx, f: &LinearFn, v: &[f64]) -> Vec<f64> {
    let mut g = f.v.clone();
    if f.uses_outputs() {
        let gx = crate::attack::gradient(ctx.p.maps, &v[..ctx.nx], &f.y);
        for (a, b) in g.iter_mut().zip(gx) {
            *a += b;
        }
    }
    g
}

/// Starting incumbents: from the box's centre and seeded random starts, projected steps
/// that climb the objective while every constraint holds and descend the summed
/// violation while one does not, with a shrinking step; the best feasible point of each
/// start (checked in f64 here, then by the caller's `accept`).
fn attack(ctx: &Ctx, starts: std::ops::Range<usize>, steps: usize) -> Vec<Vec<f64>> {
    let p = ctx.p;
    let (lo, hi) = (&p.lo, &p.hi);
    let nv = ctx.nv;
    let res: Vec<Option<Vec<f64>>> = starts
        .into_par_iter()
        .map(|r| {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0x5eed ^ r as u64);
            let mut v: Vec<f64> = (0..nv)
                .map(|t| {
                    if r == 0 || hi[t] <= lo[t] {
                        0.5 * (lo[t] + hi[t])
                    } else {
                        rng.gen_range(lo[t]..=hi[t])
                    }
                })
                .collect();
            let mut best: Option<(f64, Vec<f64>)> = None;
            for step in 0..=steps {
                if ctx.late() {
                    break;
                }
                let y = crate::query::forward(p.maps, &v[..ctx.nx], None);
                let vals: Vec<f64> = p
                    .constraints
                    .iter()
                    .map(|c| value_at(&c.f, &v, &y))
                    .collect();
                let feasible = p.constraints.iter().zip(&vals).all(|(c, e)| {
                    if c.strict {
                        *e < 0.0
                    } else {
                        *e <= 0.0
                    }
                });
                if feasible {
                    let o = value_at(&p.objective, &v, &y);
                    if best.as_ref().is_none_or(|b| o > b.0) {
                        best = Some((o, v.clone()));
                    }
                }
                if step == steps {
                    break;
                }
                let g = if feasible {
                    grad_at(ctx, &p.objective, &v)
                } else {
                    let mut g = vec![0.0; nv];
                    for (c, e) in p.constraints.iter().zip(&vals) {
                        if *e >= 0.0 {
                            for (a, b) in g.iter_mut().zip(grad_at(ctx, &c.f, &v)) {
                                *a -= b;
                            }
                        }
                    }
                    g
                };
                let gmax = g
                    .iter()
                    .enumerate()
                    .map(|(t, gt)| (gt * (hi[t] - lo[t])).abs())
                    .fold(0.0, f64::max);
                if gmax.is_nan() || gmax <= 0.0 {
                    break;
                }
                let eta = 0.2 * (1.0 - step as f64 / steps as f64).powi(2) + 1e-6;
                for t in 0..nv {
                    let w = hi[t] - lo[t];
                    v[t] = (v[t] + eta * w * (g[t] * w / gmax)).clamp(lo[t], hi[t]);
                }
            }
            best.map(|b| b.1)
        })
        .collect();
    res.into_iter().flatten().collect()
}

/// The attack's `rounds` of starts (each skipped once the incumbent is within the gap
/// of `upper`, the search's bound), each point handed to `accept` in a fixed order.
/// `true` when `accept` asked to stop.
fn attack_rounds(
    ctx: &Ctx,
    out: &mut Outcome,
    upper: f64,
    rounds: &[std::ops::Range<usize>],
    accept: &(dyn Fn(&[f64]) -> Option<Accepted> + Sync),
) -> bool {
    let s = ctx.s;
    for starts in rounds.iter().cloned() {
        let inc = out
            .best
            .as_ref()
            .map(|b| b.value)
            .unwrap_or(f64::NEG_INFINITY);
        if starts.is_empty() || upper <= inc + s.gap.max(1e-9 * inc.abs()) {
            continue;
        }
        for c in attack(ctx, starts, s.attack_steps) {
            if let Some(a) = accept(&c) {
                if out.take(a) {
                    return true;
                }
            }
        }
    }
    false
}

/// What processing one node gave.
enum Processed {
    /// Children (bounded).
    Split(Vec<Node>, Vec<Vec<f64>>),
    /// A leaf (no unstable ReLU): its bound, and the point accepted there (none: thin).
    Leaf(f64, Option<Accepted>),
    /// Past the deadline.
    Late(f64),
}

/// Maximise the problem's objective (see the module doc). `accept` re-evaluates a
/// candidate `v` concretely and returns it (possibly repaired) with its objective value
/// when it satisfies every constraint; only accepted points count.
pub fn optimise(
    p: &Problem,
    s: &Settings,
    accept: &(dyn Fn(&[f64]) -> Option<Accepted> + Sync),
) -> Outcome {
    let nx = p.maps.first().map(|m| m.0.inp).unwrap_or(0);
    let nv = p.lo.len();
    let net = p.constraints.iter().any(|c| c.f.uses_outputs()) || p.objective.uses_outputs();
    let vrows = p
        .constraints
        .iter()
        .filter(|c| !c.f.uses_outputs())
        .map(|c| exact_v(&c.f, 1.0))
        .collect();
    let ctx = Ctx {
        p,
        s,
        nx,
        nv,
        net,
        vrows,
    };
    let mut out = Outcome {
        best: None,
        upper: f64::NEG_INFINITY,
        complete: true,
        stop: None,
        stopped_early: false,
        nodes: 0,
        thin: 0,
    };
    if p.lo
        .iter()
        .zip(&p.hi)
        .any(|(l, h)| l.is_nan() || h.is_nan() || l > h)
    {
        return out;
    }
    let incumbent = |out: &Outcome| {
        out.best
            .as_ref()
            .map(|b| b.value)
            .unwrap_or(f64::NEG_INFINITY)
    };
    let tol = |inc: f64| s.gap.max(1e-9 * inc.abs());
    let none: Arc<Vec<Linear>> = Arc::new(Vec::new());
    // The attack before the root when asked (its incumbent then cuts the root's box),
    // else once the search has bounded `attack_after` nodes (below).
    let mut attacked = 0;
    if s.attack_after == 0 {
        attacked = 2;
        let first = ATTACK_FIRST_ROUND.min(s.attack_starts);
        let rounds = [0..first, first..s.attack_starts];
        if attack_rounds(&ctx, &mut out, f64::INFINITY, &rounds, accept) {
            return out;
        }
    }
    out.nodes += 1;
    let inc0 = incumbent(&out);
    let Some(root) = ctx.eval(&p.lo, &p.hi, &[], None, &none, false, SHRINK[0], inc0) else {
        // No point of the problem beats the incumbent (if any).
        out.upper = inc0;
        return out;
    };
    let mut closed = f64::NEG_INFINITY;
    // Leaves not settled by an accepted point: their bounds (thin unless the incumbent
    // catches up).
    let mut thin: Vec<f64> = Vec::new();
    let trace = std::env::var_os("SAMARA_OPT_TRACE").is_some();
    let mut next_trace = 0;
    let mut heap = BinaryHeap::new();
    let mut cands: Vec<Vec<f64>> = Vec::new();
    let root = Node {
        lo: root.lo,
        hi: root.hi,
        fixes: Vec::new(),
        pre: root.pre,
        phase_fs: root.phase_fs,
        upper: root.upper,
        unstable: root.unstable,
        cand: root.cand,
        id: 0,
    };
    let mut next_id = 0u64;
    cands.extend(root.cand.clone());
    heap.push(root);
    loop {
        // Candidates in a fixed order.
        for c in cands.drain(..) {
            if let Some(a) = accept(&c) {
                if out.take(a) {
                    return out;
                }
            }
        }
        let inc = incumbent(&out);
        let Some(top) = heap.peek() else { break };
        if top.upper <= inc + tol(inc) {
            for n in heap.drain() {
                closed = closed.max(n.upper);
            }
            break;
        }
        // The attack's rounds, once the search has bounded `attack_after` nodes (the
        // first, a few starts) and four times as many (the rest) without closing. Its
        // incumbent cuts the boxes of the nodes bounded after it (see [`Ctx::eval`]).
        if attacked < 2 && out.nodes >= s.attack_after * [1, 4][attacked] {
            let first = ATTACK_FIRST_ROUND.min(s.attack_starts);
            let starts = [0..first, first..s.attack_starts][attacked].clone();
            attacked += 1;
            if attack_rounds(&ctx, &mut out, top.upper, &[starts], accept) {
                return out;
            }
            continue;
        }
        if trace && out.nodes >= next_trace {
            next_trace = out.nodes + 2000;
            eprintln!(
                "opt: {} nodes, {} open, upper {:.9}, incumbent {inc:.9}, top unstable {} fixes {} widths {:?}",
                out.nodes,
                heap.len(),
                top.upper.max(closed),
                top.unstable,
                top.fixes.len(),
                top.lo.iter().zip(&top.hi).map(|(a, b)| b - a).collect::<Vec<_>>()
            );
        }
        let timed_out = ctx.late();
        if timed_out || (s.max_nodes > 0 && out.nodes >= s.max_nodes) {
            out.complete = false;
            out.stop = Some(if timed_out {
                Stop::Timeout
            } else {
                Stop::NodeLimit
            });
            for n in heap.drain() {
                closed = closed.max(n.upper);
            }
            break;
        }
        let mut batch = Vec::new();
        while batch.len() < s.batch.max(1) {
            let Some(n) = heap.pop() else { break };
            if n.upper <= inc + tol(inc) {
                closed = closed.max(n.upper);
                for n in heap.drain() {
                    closed = closed.max(n.upper);
                }
                break;
            }
            batch.push(n);
        }
        let results: Vec<(Processed, usize)> = batch
            .into_par_iter()
            .map(|n| process(&ctx, n, accept, inc))
            .collect();
        let mut late = false;
        for (r, evals) in results {
            out.nodes += evals;
            match r {
                Processed::Split(children, cs) => {
                    cands.extend(cs);
                    for mut c in children {
                        next_id += 1;
                        c.id = next_id;
                        heap.push(c);
                    }
                }
                Processed::Leaf(u, got) => {
                    closed = closed.max(u);
                    match got {
                        Some(a) => {
                            if out.take(a) {
                                return out;
                            }
                        }
                        None => thin.push(u),
                    }
                }
                Processed::Late(u) => {
                    closed = closed.max(u);
                    late = true;
                }
            }
        }
        if late {
            out.complete = false;
            out.stop = Some(Stop::Timeout);
            for n in heap.drain() {
                closed = closed.max(n.upper);
            }
            break;
        }
    }
    let inc = out
        .best
        .as_ref()
        .map(|b| b.value)
        .unwrap_or(f64::NEG_INFINITY);
    out.thin = thin.iter().filter(|u| **u > inc + tol(inc)).count();
    out.upper = closed.max(inc);
    if trace {
        eprintln!(
            "opt: finished after {} nodes, {attacked} attack rounds, complete {}, upper {:.9}, incumbent {inc:.9}, {} thin",
            out.nodes, out.complete, out.upper, out.thin
        );
    }
    out
}

/// Process one node: a leaf when no ReLU is unstable (its candidate was proposed when it
/// was bounded), else split (a ReLU when few are unstable, else the input chosen by
/// strong branching). Returns also how many nodes were bounded.
fn process(
    ctx: &Ctx,
    n: Node,
    accept: &(dyn Fn(&[f64]) -> Option<Accepted> + Sync),
    incumbent: f64,
) -> (Processed, usize) {
    if n.unstable == 0 {
        // The LP is exact here: its primal, pushed further inside until accepted.
        let mut got = n.cand.as_deref().and_then(accept);
        for &sh in &SHRINK[1..] {
            if got.is_some() || ctx.late() {
                break;
            }
            let e = if n.fixes.is_empty() {
                ctx.eval(
                    &n.lo,
                    &n.hi,
                    &[],
                    Some(&n.pre),
                    &n.phase_fs,
                    false,
                    sh,
                    incumbent,
                )
            } else {
                // The bounds and phase rows of the node, re-used as they are.
                ctx.eval_with(&n.lo, &n.hi, &n.pre, &n.phase_fs, sh)
            };
            got = e.and_then(|e| e.cand).as_deref().and_then(accept);
        }
        return (Processed::Leaf(n.upper, got), 0);
    }
    if ctx.late() {
        return (Processed::Late(n.upper), 0);
    }
    let (xl, xh) = (&n.lo[..ctx.nx], &n.hi[..ctx.nx]);
    let splittable: Vec<usize> = (0..ctx.nx)
        .filter(|&t| {
            let mid = 0.5 * (xl[t] + xh[t]);
            mid > xl[t] && mid < xh[t]
        })
        .collect();
    let relu_only = n.unstable <= ctx.s.phase_max_unstable || splittable.is_empty();
    let mut children = Vec::new();
    let mut cands = Vec::new();
    let mut evals = 0;
    // The ReLU split: earliest layer with unstable neurons, the most balanced one.
    let relu_split = || {
        let mut cands = Vec::new();
        let mut evals = 0;
        let un = unstable(ctx.p.maps, &n.pre);
        let j0 = un[0].0;
        // At the LP's point, the neuron whose relaxation there is loosest (the chord
        // above, CROWN's lower line below); without a point, the most balanced one.
        let z = n.cand.as_ref().map(|x| {
            let a = crate::query::forward(&ctx.p.maps[..j0], &x[..ctx.nx], None);
            let m = &ctx.p.maps[j0].0;
            let mut z = vec![0.0; m.out];
            m.apply_f64(&a, &mut z);
            z
        });
        let score = |u: &(usize, usize)| {
            let (l, h) = n.pre[u.0][u.1];
            let balance = (-l).min(h);
            match &z {
                Some(z) => {
                    let zc = z[u.1].clamp(l, h);
                    let relu = zc.max(0.0);
                    let chord = relu::chord_at(l, h, zc);
                    let lower = relu::default_lower_slope(l, h) * zc;
                    (chord - relu) + (relu - lower) + 1e-9 * balance
                }
                None => balance,
            }
        };
        let &(j, i) = un
            .iter()
            .take_while(|u| u.0 == j0)
            .max_by(|a, b| score(a).total_cmp(&score(b)))
            .expect("an unstable neuron");
        let mut rkids = Vec::new();
        for on in [false, true] {
            let mut fixes = n.fixes.clone();
            fixes.push((j, i, on));
            evals += 1;
            if let Some(e) = ctx.eval(
                &n.lo,
                &n.hi,
                &fixes,
                Some(&n.pre),
                &n.phase_fs,
                true,
                SHRINK[0],
                incumbent,
            ) {
                cands.extend(e.cand.clone());
                rkids.push(Node {
                    lo: e.lo,
                    hi: e.hi,
                    fixes,
                    pre: e.pre,
                    phase_fs: e.phase_fs,
                    upper: e.upper.min(n.upper),
                    unstable: e.unstable,
                    cand: e.cand,
                    id: 0,
                });
            }
        }
        (rkids, cands, evals)
    };
    if relu_only {
        let (kids, cands, evals) = relu_split();
        return (Processed::Split(kids, cands), evals);
    }
    // Strong branching over the inputs; when no input split lowers the larger bound of
    // the halves below the node's (a corner of the box that no constraint cuts bounds
    // both halves: only the network's relaxation is loose there), a ReLU split, once a
    // point is known (before, input splits localise points: candidates of small boxes
    // are feasible far more often).
    // Strong branching over the inputs.
    type Try = ((f64, f64, f64), Vec<Node>, Vec<Vec<f64>>, usize);
    let mut tries: Vec<Try> = Vec::new();
    for &t in &splittable {
        if ctx.late() {
            return (Processed::Late(n.upper), evals);
        }
        let mid = 0.5 * (xl[t] + xh[t]);
        let mut kids = Vec::new();
        let mut kc = Vec::new();
        let mut score = f64::NEG_INFINITY;
        // How much each half's bound lies below the node's (a half shown empty: the
        // whole gap).
        let full = if incumbent.is_finite() {
            (n.upper - incumbent).max(0.0)
        } else {
            1.0 + n.upper.abs()
        };
        let mut gains = Vec::with_capacity(2);
        let mut rows = 0.0;
        for half in 0..2 {
            let (mut lo, mut hi) = (n.lo.clone(), n.hi.clone());
            if half == 0 {
                hi[t] = mid;
            } else {
                lo[t] = mid;
            }
            evals += 1;
            if let Some(e) = ctx.eval(
                &lo,
                &hi,
                &[],
                Some(&n.pre),
                &n.phase_fs,
                false,
                SHRINK[0],
                incumbent,
            ) {
                // (The parent's bound holds on the half too.)
                score = score.max(e.upper.min(n.upper));
                gains.push((n.upper - e.upper).clamp(0.0, full));
                rows += e.row_lb.max(-1e300);
                kc.extend(e.cand.clone());
                kids.push(Node {
                    lo: e.lo,
                    hi: e.hi,
                    fixes: Vec::new(),
                    pre: e.pre,
                    phase_fs: e.phase_fs,
                    upper: e.upper.min(n.upper),
                    unstable: e.unstable,
                    cand: e.cand,
                    id: 0,
                });
            }
        }
        gains.resize(2, full);
        // The product rule of strong branching (Achterberg, 2007): the split that lowers
        // both halves' bounds, not one half's only (halving an input that the objective
        // weighs directly lowers one half a lot and the relaxation's slack not at all);
        // on a tie (a corner of the box that no constraint cuts yet bounds both halves),
        // the split whose halves' constraint bounds rose the most (closest to cutting).
        let eps = 1e-9 * (1.0 + n.upper.abs());
        let prod = gains[0].max(eps) * gains[1].max(eps);
        let key = (-prod, -rows, score);
        tries.push((key, kids, kc, t));
    }
    let order = |a: &Try, b: &Try| {
        a.0 .0
            .total_cmp(&b.0 .0)
            .then(a.0 .1.total_cmp(&b.0 .1))
            .then(a.0 .2.total_cmp(&b.0 .2))
            .then(a.3.cmp(&b.3))
    };
    let mut pick = (0..tries.len())
        .min_by(|&i, &j| order(&tries[i], &tries[j]))
        .expect("a splittable input");
    // Progress: how much the chosen split lowers the larger bound of the halves below
    // the node's. With a point known, a split that closes less than 1% of the node's gap to
    // it is stalled (the bound there is the relaxation's, not the box's): a ReLU split.
    // With none, a split that lowers nothing gives way to the widest input (relative to
    // the problem's box), so that every side keeps shrinking.
    let progress = n.upper - tries[pick].0 .2;
    if incumbent.is_finite() && progress < 0.01 * (n.upper - incumbent) {
        for t in tries {
            cands.extend(t.2);
        }
        let (rk, rc, re) = relu_split();
        cands.extend(rc);
        return (Processed::Split(rk, cands), evals + re);
    }
    // The widest input (relative to the problem's box) instead when no split lowers
    // anything without a point known, or when the chosen input is already 64 times
    // narrower than it: bounds tighten with every side of a box, and a search that
    // keeps halving the same inputs never tightens the others.
    let rel = |t: usize| (xh[t] - xl[t]) / (ctx.p.hi[t] - ctx.p.lo[t]);
    let widest = (0..tries.len())
        .max_by(|&i, &j| rel(tries[i].3).total_cmp(&rel(tries[j].3)).then(j.cmp(&i)))
        .expect("a splittable input");
    if (!incumbent.is_finite() && progress <= 1e-12 * (1.0 + n.upper.abs()))
        || rel(tries[pick].3) * 64.0 < rel(tries[widest].3)
    {
        pick = widest;
    }
    for (k, t) in tries.into_iter().enumerate() {
        if k == pick {
            children.extend(t.1);
        }
        cands.extend(t.2);
    }
    (Processed::Split(children, cands), evals)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bound propagation keeps every point of the box that satisfies the rows, and
    /// reports a box empty only when no sampled point satisfies them: checked on 300
    /// random problems (3 variables, 1-3 rows with slack) against 2,000 sampled points
    /// each, the rows evaluated at the points directly.
    #[test]
    fn propagation_keeps_every_feasible_point() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(42);
        let mut emptied = 0;
        let mut shrunk = 0;
        for _ in 0..300 {
            let n = 3;
            let lo: Vec<f64> = (0..n).map(|_| rng.gen_range(-50.0..0.0)).collect();
            let hi: Vec<f64> = lo.iter().map(|l| l + rng.gen_range(0.1..60.0)).collect();
            let rows: Vec<Linear> = (0..rng.gen_range(1..=3))
                .map(|_| Linear {
                    coef: (0..n)
                        .map(|_| {
                            if rng.gen_bool(0.2) {
                                0.0
                            } else {
                                rng.gen_range(-3.0..3.0)
                            }
                        })
                        .collect(),
                    cst: rng.gen_range(-40.0..40.0),
                    slack: if rng.gen_bool(0.5) { 0.0 } else { 0.01 },
                })
                .collect();
            let refs: Vec<&Linear> = rows.iter().collect();
            let (mut nl, mut nh) = (lo.clone(), hi.clone());
            let ok = propagate(&refs, &mut nl, &mut nh);
            if !ok {
                emptied += 1;
            } else if nl
                .iter()
                .zip(&nh)
                .zip(lo.iter().zip(&hi))
                .any(|((a, b), (c, d))| b - a < d - c)
            {
                shrunk += 1;
            }
            for _ in 0..2000 {
                let v: Vec<f64> = (0..n).map(|t| rng.gen_range(lo[t]..=hi[t])).collect();
                // A point where every row's function (the row plus its slack, which the
                // row bounds from below) is <= 0.
                let feasible = rows.iter().all(|r| {
                    r.cst + r.coef.iter().zip(&v).map(|(c, x)| c * x).sum::<f64>() - r.slack <= 0.0
                });
                if feasible {
                    assert!(ok, "a feasible point {v:?} in a box called empty");
                    for t in 0..n {
                        assert!(
                            nl[t] <= v[t] && v[t] <= nh[t],
                            "{v:?} cut from [{nl:?}, {nh:?}]"
                        );
                    }
                }
            }
        }
        // The check is not vacuous: boxes were shrunk and shown empty.
        assert!(
            emptied > 10 && shrunk > 50,
            "emptied {emptied}, shrunk {shrunk}"
        );
    }
}

//! Validated Taylor-model flowpipe of a system file's plant over one control period.
//!
//! The state is a vector of Taylor models [`Tm`] in the initial-set parameters
//! `xi in [-1, 1]^n`; the plant input `u` (the controller's output for this period) is
//! held constant, also as Taylor models. One step of length `h` (Berz & Makino,
//! "Verified integration of ODEs and flows using differential algebraic methods on
//! high-order Taylor models", Reliable Computing 4, 1998; the Lagrange-remainder form of
//! Nedialkov, Jackson & Corliss, 1999):
//! 1. an a-priori box `B` containing every solution from the set over `[0, h]`:
//!    the Picard test `X0 + [0, h] f(B, U) ⊆ B` on intervals (inflated iteration);
//! 2. the solution's Taylor coefficients `x_0 .. x_p` in time, as Taylor models in
//!    `xi`: the plant's own right-hand side run on `Series<Tm, K>` (Taylor-mode AD,
//!    `x_{k+1} = f(x)_k / (k + 1)`), so the dependence on the initial set is kept in
//!    every coefficient;
//! 3. the Lagrange remainder `h^{p+1} x_{p+1}(B, U)`: the same recurrence on
//!    `Series<Interval, K>` seeded with the box `B` (every solution stays in `B`, and
//!    `x_{p+1}(y) = x^{(p+1)}(tau) / (p+1)!` for the solution through `y`);
//! 4. `x(h) = sum_k x_k h^k` by Horner with the exact `h` (products of a Taylor model
//!    by an `f64` are sound), plus the remainder.
//!
//! Steps are `period / 2^j`, so they add up to the period exactly. A step whose
//! a-priori box fails or whose remainder is wider than the tolerance is halved (down to
//! `period / 2^max_halvings`). Where the right-hand side is not analytic over the set
//! (an `abs`, `sign`, `min`/`max` or a mask undecided over it: the series is `bad`),
//! the step falls back to the first-order enclosure `x(h) in x0 + h f(B, U)` (sound,
//! loses the dependence of that step's increment). Every step's box `B` is returned so
//! that goals over time windows can be checked between control instants.

use super::standin;
use crate::taylor_step::{apriori_by, finite, lagrange_remainder, meet, pow_up, series};
use samara_num::{Interval, Scalar, Series, Tm};
use samara_system::{Graph, System};

/// Time-Taylor series length: orders up to `K - 2` in time plus the remainder term.
const K: usize = 10;

/// How many times a step's remainder tolerance (`rem_tol`, `rem_rel`; the narrowest
/// state's) one time coefficient's joint-degree truncation may add to the step (scaled by
/// `h^k`). Measured on the glider's six-state set at a tenth (order 3, `symbolic:60`,
/// `--lifted-weight 2`): 1 gives 8.1 s, 10 gives 7.1 s and no limit 6.8 s, all at the
/// same x + y ratio (1.170); the limit keeps long steps over few parameters (the
/// logistic test, one parameter, steps of up to 1 s) at their full order.
const TRIM_SHARE: f64 = 10.0;

/// Settings of the flowpipe.
#[derive(Clone, Debug)]
pub struct TmFlowSettings {
    /// Order of the Taylor models in the parameters (set by the driver).
    pub order: u32,
    /// Order of the Taylor expansion in time (1 to `K - 2` = 8; default 6).
    pub time_order: usize,
    /// Absolute tolerance on the width of a step's Lagrange remainder.
    pub rem_tol: f64,
    /// Relative tolerance on the remainder's width, against the set's own width.
    pub rem_rel: f64,
    /// Largest number of halvings of the period for one step (default 12).
    pub max_halvings: u32,
    /// Symbolic remainders inside the period: when positive, after every step whose
    /// interval remainders pass `lift_at` of a state's width, the states are
    /// order-reduced to at most this many parameters and their remainders become fresh
    /// parameters ([`samara_num::tm_reduce::reduce_with`]), so that the next steps map them
    /// through the flow instead of adding them up as intervals (0: off).
    pub max_params: usize,
    /// The share of a state's width its interval remainder may reach inside the period
    /// before the remainders are lifted to parameters (with `max_params`; default 5 %).
    /// Lifting early keeps the interval remainders from wrapping (`r += h |J| r` per
    /// step, whatever the flow's true contraction), at the cost of more reductions. On
    /// the glider's six-state set at a twentieth of its size, 0.1 % ends 1.32x the
    /// flights' x + y spread where 5 % ends 3.07x; on ARCH-COMP, 5 % is as tight and
    /// faster (TORA 0.42 s against 1.03 s; `docs/reach.md`).
    pub lift_at: f64,
    /// How much each lifted parameter (above) weighs toward `order` (default 1: as
    /// much as an initial parameter). With `order`, lifted parameters enter linearly
    /// only (mixed-degree Taylor models, [`samara_num::Tm::with_lifted_weight`]): the
    /// nonlinear dependence stays on the initial set, and each lifted parameter costs
    /// one coefficient per model instead of its share of every monomial of the order.
    pub lifted_weight: u32,
    /// Polynomial stand-ins with a bounded disturbance for terms that a step cannot
    /// expand (an `abs` across 0, a `sqrt` near 0; `crate::standin`), tried before the
    /// plain Taylor step wherever the a-priori box needs them (default on).
    pub stand_ins: bool,
    /// Truncate the solution's time coefficient `k >= 1` at parameter order
    /// `max(2, order + 1 - k)` (a joint degree in parameters and time, as Flow* does;
    /// models of order 2 or less are left whole), bounding the rest into its
    /// remainder: the higher time coefficients, which the step scales by `h^k`, then
    /// cost products on smaller tables (default on).
    pub joint_degree: bool,
    /// Wall-clock deadline: the flowpipe reads the clock before every step it tries
    /// (halvings included) and stops with [`TmFlowError::Timeout`] past it (set by the
    /// reach driver from `--timeout`; default none).
    pub deadline: Option<std::time::Instant>,
}

impl TmFlowSettings {
    /// The remainder tolerance of a coordinate whose a-priori box is `bx`: `rem_tol`,
    /// or `rem_rel` of the box's width where that is larger.
    fn tol(&self, bx: &Interval) -> f64 {
        self.rem_tol.max(self.rem_rel * (bx.hi - bx.lo))
    }
}

impl Default for TmFlowSettings {
    fn default() -> Self {
        TmFlowSettings {
            order: 4,
            time_order: 6,
            rem_tol: 1e-9,
            rem_rel: 1e-7,
            max_halvings: 12,
            max_params: 0,
            lift_at: 0.05,
            lifted_weight: 1,
            stand_ins: true,
            joint_degree: true,
            deadline: None,
        }
    }
}

/// Why a period could not be enclosed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TmFlowError {
    /// No step, down to the smallest, had a valid a-priori enclosure.
    #[error("no validated enclosure at t = {t:.6} into the period (the set is too wide or the right-hand side is singular there)")]
    NoEnclosure {
        /// Time into the period where it failed.
        t: f64,
    },
    /// The deadline of [`TmFlowSettings::deadline`] passed.
    #[error("time budget spent at t = {t:.6} into the period")]
    Timeout {
        /// Time into the period.
        t: f64,
    },
    /// The enclosure stopped being finite.
    #[error("the enclosure became unbounded at t = {t:.6} into the period")]
    Unbounded {
        /// Time into the period.
        t: f64,
    },
}

fn rhs_box(g: &Graph, x: &[Interval], u: &[Interval]) -> Vec<Interval> {
    let mut out = vec![Interval::point(0.0); g.outputs.len()];
    let mut scratch = Vec::new();
    g.eval_with(&mut scratch, x, u, &mut out);
    out
}

/// Taylor coefficients `0..=upto` in time of the solution from `x0` under the constant
/// inputs `u` (the shared step's [`series`], on this flowpipe's series length);
/// `None` if a branch was undecided.
fn taylor<S: Scalar>(g: &Graph, x0: &[S], u: &[S], upto: usize) -> Option<Vec<Series<S, K>>> {
    series::<S, K>(g, x0, u, upto, &|_, v| v)
}

/// One part of a period's flowpipe: a box enclosing every state over its time span and,
/// where a Taylor step validated, Taylor models in the set's parameters that enclose
/// them too (the part's polynomial at its start plus interval terms for the time
/// inside it), which keep the states' dependence for goals that are not boxes.
#[derive(Clone, Debug)]
pub struct Part {
    /// The box.
    pub bounds: Vec<Interval>,
    /// The Taylor models (`None`: the a-priori box only).
    pub models: Option<Vec<Tm>>,
}

/// One step of length `h`; `None` if it cannot be validated at this `h` (then the caller
/// halves it). Returns the state at `h` and parts enclosing the states over `[0, h]`.
fn step(
    sys: &System,
    x: &[Tm],
    u: &[Tm],
    bu: &[Interval],
    h: f64,
    s: &TmFlowSettings,
    last_chance: bool,
) -> Option<(Vec<Tm>, Vec<Part>)> {
    let g = sys.rhs_graph();
    let bz: Vec<Interval> = x.iter().map(|v| v.bound()).collect();
    let b = apriori_by(|x| rhs_box(g, x, bu), &bz, h)?;
    if s.stand_ins {
        if let Some(si) = standin::plan(g, &b, bu) {
            if let Some(r) = stand_in_step(&si, x, u, bu, &bz, &b, h, s, last_chance) {
                return Some(r);
            }
        }
    }
    if let Some(r) = taylor_try(g, x, u, bu, &b, &bz, h, s, last_chance) {
        return Some(r);
    }
    if !last_chance {
        // A shorter step may validate the remainder or decide the undecided branch.
        return None;
    }
    // At the smallest step, where no Taylor step validates (the right-hand side not
    // analytic over the set, or every remainder overflowing): x(h) in x0 + h f(B, U),
    // since the integral of f(x(s)) over [0, h] lies in h * f(B, U).
    let fb = rhs_box(g, &b, bu);
    if !finite(&fb) {
        return None;
    }
    let next: Vec<Tm> = x
        .iter()
        .zip(&fb)
        .map(|(xi, f)| xi.clone().with_rem(Interval::point(h) * *f))
        .collect();
    Some((
        next,
        vec![Part {
            bounds: b,
            models: None,
        }],
    ))
}

/// A step with polynomial stand-ins for the terms that cannot be expanded over `b`
/// ([`crate::standin`]): the nominal flow of the right-hand side with the stand-ins and
/// zero disturbance, as a Taylor step, plus the deviation bound of the true flow from it.
#[allow(clippy::too_many_arguments)]
fn stand_in_step(
    si: &standin::StandIns,
    x: &[Tm],
    u: &[Tm],
    bu: &[Interval],
    bz: &[Interval],
    b: &[Interval],
    h: f64,
    s: &TmFlowSettings,
    last_chance: bool,
) -> Option<(Vec<Tm>, Vec<Part>)> {
    let zero = Interval::point(0.0);
    let nv = x.first().map_or(0, |v| v.n_vars());
    let mut ue = u.to_vec();
    // Zero disturbances on the states' table kind (a classic table in all of a
    // mixed-degree state's lifted parameters would cost seconds to build).
    let zero_dist = |_| match x.first() {
        Some(v) => v.constant_like(0.0, nv, s.order),
        None => Tm::constant(0.0, nv, s.order),
    };
    ue.extend(si.dist.iter().map(zero_dist));
    let mut bue = bu.to_vec();
    bue.extend(si.dist.iter().map(|_| zero));
    let gy = &si.graph;
    let by = apriori_by(|x| rhs_box(gy, x, &bue), bz, h)?;
    // Every check on intervals first (the remainder, the branches over the hull, the
    // deviation), the Taylor models' series last: a step that fails a check then costs
    // no Taylor-model arithmetic (the same results in the same order otherwise).
    let plan = taylor_plan(gy, &bue, &by, bz, h, s, last_chance)?;
    let dbox: Vec<Interval> = b.iter().zip(&by).map(|(p, q)| p.hull(q)).collect();
    let wh: Vec<Interval> = si.dist.iter().map(|w| w.hull(&zero)).collect();
    // The mean-value bound needs the right-hand side with the stand-ins to be Lipschitz
    // over the hull: a branch (`if`, `sign`) undecided there could jump, which no
    // Jacobian sees. The interval series over the hull flags undecided branches (and
    // kinks: an `abs` that crosses 0 over the hull but not over B); then no stand-in
    // step.
    let mut bw = bu.to_vec();
    bw.extend(wh.iter().copied());
    taylor::<Interval>(gy, &dbox, &bw, 1)?;
    let (jx, jw) = standin::jacobians(gy, &dbox, bu, &wh);
    let (e, eh) = standin::deviation(&jx, &jw, &si.dist, h)?;
    let (ynext, yparts) = taylor_models(gy, x, &ue, plan, bz, h, s, &by)?;
    let next: Vec<Tm> = ynext
        .into_iter()
        .zip(&eh)
        .map(|(v, r)| v.with_rem(*r))
        .collect();
    let parts = yparts
        .into_iter()
        .map(|p| Part {
            bounds: p
                .bounds
                .iter()
                .zip(&e)
                .zip(b)
                .map(|((v, ei), bj)| meet(*v + *ei, *bj))
                .collect(),
            models: p.models.map(|ms| {
                ms.into_iter()
                    .zip(&e)
                    .map(|(m, ei)| m.with_rem(*ei))
                    .collect()
            }),
        })
        .collect();
    Some((next, parts))
}

/// The Taylor step proper over the a-priori box `b` of the right-hand side `g`: the time
/// coefficients as Taylor models, the Lagrange remainder over `b`, the highest time order
/// whose remainder is narrow enough; `None` if none is.
#[allow(clippy::too_many_arguments)]
fn taylor_try(
    g: &Graph,
    x: &[Tm],
    u: &[Tm],
    bu: &[Interval],
    b: &[Interval],
    bz: &[Interval],
    h: f64,
    s: &TmFlowSettings,
    last_chance: bool,
) -> Option<(Vec<Tm>, Vec<Part>)> {
    let plan = taylor_plan(g, bu, b, bz, h, s, last_chance)?;
    taylor_models(g, x, u, plan, bz, h, s, b)
}

/// What [`taylor_plan`] settles on intervals before a Taylor step's models are computed:
/// the interval series over the a-priori box, the time order and its Lagrange remainder.
struct StepPlan {
    tb: Vec<Series<Interval, K>>,
    p: usize,
    rem: Vec<Interval>,
}

/// The interval half of [`taylor_try`]: the time order whose remainder over the
/// a-priori box `b` is narrow enough (at the smallest step, the narrowest); `None` if
/// none is.
fn taylor_plan(
    g: &Graph,
    bu: &[Interval],
    b: &[Interval],
    bz: &[Interval],
    h: f64,
    s: &TmFlowSettings,
    last_chance: bool,
) -> Option<StepPlan> {
    let pmax = s.time_order.clamp(1, K - 2);
    // The remainder over the a-priori box decides whether the step validates and at
    // which time order; it needs only the cheap interval series, so it is settled before
    // the Taylor models' series are computed (a step that is then halved costs no
    // Taylor-model arithmetic: every step first tries twice its predecessor's length).
    let tb = taylor::<Interval>(g, b, bu, pmax + 1)?;
    // Widest remainder allowed for a state whose box is `bx`.
    // The highest time order first; where its remainder over B overflows or is too
    // wide (the interval recurrences grow fast on stiff terms: the k-th time
    // coefficient of sqrt(omega^2 + eps) near omega = 0 scales like eps^(-k/2)),
    // lower orders, whose coefficients are the same, with their own remainder
    // h^{p+1} x_{p+1}(B). At the smallest step, the order with the narrowest
    // remainder (relative to the set's widths) is taken.
    let mut best: Option<(f64, usize, Vec<Interval>)> = None;
    for p in (1..=pmax).rev() {
        let rem = lagrange_remainder(&tb, tb.len(), p, h);
        if !finite(&rem) {
            continue;
        }
        let too_wide = rem.iter().zip(bz).any(|(r, bx)| r.hi - r.lo > s.tol(bx));
        if !too_wide {
            best = Some((0.0, p, rem));
            break;
        }
        if last_chance {
            let size: f64 = rem
                .iter()
                .zip(bz)
                .map(|(r, bx)| (r.hi - r.lo) / s.tol(bx))
                .fold(0.0, f64::max);
            if best.as_ref().is_none_or(|b| size < b.0) {
                best = Some((size, p, rem));
            }
        }
    }
    let (_, p, rem) = best?;
    Some(StepPlan { tb, p, rem })
}

/// The Taylor-model half of [`taylor_try`]: the time coefficients as Taylor models up to
/// the planned order, the state at `h` and the step's parts.
#[allow(clippy::too_many_arguments)]
fn taylor_models(
    g: &Graph,
    x: &[Tm],
    u: &[Tm],
    plan: StepPlan,
    bz: &[Interval],
    h: f64,
    s: &TmFlowSettings,
    b: &[Interval],
) -> Option<(Vec<Tm>, Vec<Part>)> {
    let StepPlan { tb, p, rem } = plan;
    // Joint degree in (parameters, time), as Flow* truncates (Chen, Abraham &
    // Sankaranarayanan, "Flow*", CAV 2013): the time coefficient `k >= 1` keeps
    // parameter order `max(2, order + 1 - k)`, and so do the products that read it;
    // what lies past it is bounded into remainders, which the step multiplies by
    // `h^k`. The first coefficient keeps the full order (on the glider's six-state set,
    // dropping its top degree too cost 3 % of tightness), and no coefficient goes below
    // order 2 (linear higher coefficients cost the published setting at order 2 a
    // 15-45 % wider x + y), so models of order 2 or less are flown as before. A
    // truncation is taken only where the coefficient's own dropped terms cost less than
    // `TRIM_SHARE` times the step's remainder tolerance (the narrowest state's), so long
    // steps over few parameters keep their full order.
    let base = x.iter().map(|v| v.order()).max().unwrap_or(0);
    // Coefficients up to the chosen order `p` only.
    let tx = if s.joint_degree && base > 2 {
        let budget = TRIM_SHARE * bz.iter().map(|bx| s.tol(bx)).fold(f64::INFINITY, f64::min);
        let trim = |k: usize, v: Tm| {
            let order = (base + 1).saturating_sub(k as u32).max(2);
            if order >= v.order() {
                // Nothing to truncate (the first coefficient, or one already lower).
                return v;
            }
            let low = v.clone().with_order(order);
            let added = low.rem().width() - v.rem().width();
            if added.is_finite() && added * pow_up(h, k).hi <= budget {
                low
            } else {
                v
            }
        };
        series::<Tm, K>(g, x, u, p, &trim)
    } else {
        taylor::<Tm>(g, x, u, p)
    }?;
    let next: Vec<Tm> = tx
        .iter()
        .zip(&rem)
        .map(|(c, r)| {
            let mut acc = c.c[p].clone();
            for i in (0..p).rev() {
                // Raised to the lower time order's table first, so that the sum keeps
                // that coefficient's order (joint degree).
                acc = acc.raised_to(&c.c[i]) * h + &c.c[i];
            }
            acc.with_rem(*r)
        })
        .collect();
    let boxes = sub_boxes(&tx, &tb, p, h, b);
    Some((next, boxes))
}

/// Parts of a step that [`sub_boxes`] encloses separately.
const SUB_STEPS: usize = 4;

/// Enclosures of the solution over [`SUB_STEPS`] equal parts `[ta, tb]` of a validated
/// step `[0, h]` of time order `p`: for `tau` in the part,
/// `x(tau) = P(ta) + (P(tau) - P(ta)) + x_{p+1}(xi) tau^{p+1}` with `P` the time
/// polynomial (Taylor models in the parameters), so the part's box is the bound of the
/// Taylor model `P(ta)`, plus `[0, tb - ta] * P'([ta, tb])` (the mean value theorem, `P'`
/// on the coefficients' bounds), plus `x_{p+1}(B) * [0, tb^{p+1}]` (the Lagrange
/// remainder over the a-priori box `B`), each intersected with `B`. Much tighter than `B`
/// itself, which is what lets a goal that must hold at all times (an obstacle to avoid, a
/// band) be decided over a period.
fn sub_boxes(
    tx: &[Series<Tm, K>],
    tb: &[Series<Interval, K>],
    p: usize,
    h: f64,
    b: &[Interval],
) -> Vec<Part> {
    let ends: Vec<f64> = (0..=SUB_STEPS)
        .map(|k| {
            if k == SUB_STEPS {
                h
            } else {
                h * k as f64 / SUB_STEPS as f64
            }
        })
        .collect();
    ends.windows(2)
        .map(|w| {
            let (ta, tbe) = (w[0], w[1]);
            let t = Interval { lo: ta, hi: tbe };
            let dt = (Interval::point(tbe) - Interval::point(ta)).hi.max(0.0);
            let tail = Interval {
                lo: 0.0,
                hi: pow_up(tbe, p + 1).hi,
            };
            let (bounds, models): (Vec<Interval>, Vec<Tm>) = tx
                .iter()
                .zip(tb)
                .zip(b)
                .map(|((c, cb), bj)| {
                    let mut at = c.c[p].clone();
                    for i in (0..p).rev() {
                        at = at.raised_to(&c.c[i]) * ta + &c.c[i];
                    }
                    let mut d = c.c[p].bound() * p as f64;
                    for i in (1..p).rev() {
                        d = d * t + c.c[i].bound() * i as f64;
                    }
                    let m = at.with_rem(Interval { lo: 0.0, hi: dt } * d + cb.c[p + 1] * tail);
                    (meet(m.bound(), *bj), m)
                })
                .unzip();
            Part {
                bounds,
                models: Some(models),
            }
        })
        .collect()
}

/// Fly the Taylor-model state `x` under the held inputs `u` for `period`: the state at
/// the period's end and boxes that together enclose every state over `[0, period]`
/// (per step the boxes of `sub_boxes`, or its a-priori box where no Taylor step
/// validated), in time order.
pub fn tm_period(
    sys: &System,
    x: &[Tm],
    u: &[Tm],
    period: f64,
    s: &TmFlowSettings,
) -> Result<(Vec<Tm>, Vec<Vec<Interval>>), TmFlowError> {
    let (next, parts) = tm_period_parts(sys, x, u, period, s)?;
    Ok((next, parts.into_iter().map(|p| p.bounds).collect()))
}

/// [`tm_period`] with the parts' Taylor models ([`Part`]).
pub fn tm_period_parts(
    sys: &System,
    x: &[Tm],
    u: &[Tm],
    period: f64,
    s: &TmFlowSettings,
) -> Result<(Vec<Tm>, Vec<Part>), TmFlowError> {
    let bu: Vec<Interval> = u.iter().map(|v| v.bound()).collect();
    // States and inputs on one table, so that the steps' operations need no conversion.
    let mut all: Vec<Tm> = x.iter().chain(u).cloned().collect();
    Tm::share_table(&mut all);
    let mut u = all.split_off(x.len());
    let jmax = s.max_halvings.min(30);
    let units: u64 = 1 << jmax; // the period in units of period / 2^jmax
    let mut pos: u64 = 0;
    let mut level: u32 = 0; // current step = period / 2^level
    let mut cur = all;
    let mut boxes = Vec::new();
    while pos < units {
        // The largest step allowed at this position, no longer than the current level.
        let mut j = level;
        while j < jmax && pos & ((units >> j) - 1) != 0 {
            j += 1;
        }
        loop {
            if s.deadline.is_some_and(|d| std::time::Instant::now() > d) {
                return Err(TmFlowError::Timeout {
                    t: pos as f64 / units as f64 * period,
                });
            }
            let h = period / (1u64 << j) as f64;
            let last = j >= jmax;
            match step(sys, &cur, &u, &bu, h, s, last) {
                Some((next, b)) => {
                    let t = pos as f64 / units as f64 * period;
                    if next.iter().any(|v| {
                        let r = v.bound();
                        !(r.lo.is_finite() && r.hi.is_finite())
                    }) {
                        return Err(TmFlowError::Unbounded { t });
                    }
                    cur = next;
                    if s.max_params > 0 {
                        let hull: Vec<Interval> = cur.iter().map(|v| v.bound()).collect();
                        if samara_num::tm_reduce::remainders_past(&cur, &hull, s.lift_at) {
                            (cur, u) =
                                samara_num::tm_reduce::reduce_with(&cur, &u, s.max_params, s.order);
                        }
                    }
                    boxes.extend(b);
                    pos += units >> j;
                    // Let the step grow again next time.
                    level = j.saturating_sub(1);
                    break;
                }
                None if !last => j += 1,
                None => {
                    return Err(TmFlowError::NoEnclosure {
                        t: pos as f64 / units as f64 * period,
                    });
                }
            }
        }
    }
    Ok((cur, boxes))
}

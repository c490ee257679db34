//! Sound reachable sets of any closed loop written as a system file (`samara-system`):
//! Taylor-model sets in the initial-set parameters, the plant integrated by the
//! validated Taylor-model flowpipe ([`crate::tmflow`]), the network bounded over each
//! set by CROWN with the set's linear part kept symbolic ([`samara_bounds::linset`]).
//!
//! Data flow of one sub-box `B` of the initial set (states with a non-zero width are
//! the parameters `xi in [-1, 1]^n`, `x_i = mid_i + rad_i xi_i`):
//! 1. at each control instant but the horizon: the resets (when they fire and what the
//!    set at an instant is come from `samara_system::System::begin_period`); the
//!    network's inputs `observe(x)` as Taylor models; their linear part `c + G xi`
//!    goes to CROWN, the rest (higher-order terms and remainders) as a noise box; the
//!    network's outputs come back as `coef . xi + cst +- dev` (Taylor models of
//!    order 1 with an interval remainder) —
//!    or, for networks without ReLU, the network evaluated on the Taylor models
//!    themselves (Taylor expansion of tanh / sigmoid), whichever is narrower;
//! 2. the inputs `actuate(outputs)` then the clips, on Taylor models (a clip that is
//!    inactive over the set stays exact);
//! 3. one control period of the plant by the flowpipe, which also returns the boxes of
//!    every step inside the period (for goals over time windows);
//! 4. the goals decided on the sets: a band with an affine `g(x)` on the Taylor models
//!    themselves (the dependence kept), boxes on the interval hull.
//!
//! Sub-boxes whose enclosure is lost or whose goal is undecided are cut in two along the
//! widest parameter (relative to the initial set) and flown again from `t = 0`, within a
//! budget; the frontier is flown in parallel (`rayon`). Before any of it, simulated
//! flights (the initial box's corners, its centre and random starts) look for a
//! counterexample.
//!
//! Verdicts: `proved` only when every sub-box's sets decide every goal true; `violated`
//! only with a simulated flight that misses a goal; `unknown` with the reason otherwise.

use crate::tmflow::{tm_period_parts, TmFlowSettings};
use rand::{Rng, SeedableRng};
use rayon::prelude::*;
use samara_nn::Network;
use samara_num::{Interval, Scalar, Tm};
use samara_system::sim::{fly, fly_until, goals_hold, SimError, SystemFlight};
use samara_system::{band_decision, GoalKind, System, When};
use serde::{Deserialize, Serialize};
use std::time::Instant;

/// Settings of a system reachability run.
#[derive(Clone, Debug)]
pub struct SystemReachSettings {
    /// Order of the Taylor models (default 4).
    pub order: usize,
    /// Largest number of sub-boxes of the initial set (default 256).
    pub max_boxes: usize,
    /// Simulated flights for falsification before the sets (default 200).
    pub samples: usize,
    /// Seed of the random starts.
    pub seed: u64,
    /// The flowpipe's settings.
    pub flow: TmFlowSettings,
    /// Wall-clock budget in seconds; the run stops splitting and reports `unknown`
    /// when it is spent (default: none).
    pub timeout: Option<f64>,
    /// Re-parameterise the set at a control instant when its remainders have grown
    /// ([`precondition`]; default on).
    pub precondition: bool,
    /// How the network step's error enters the set (`None`: chosen per run, see
    /// [`NetworkError`]; default).
    pub network_error: Option<NetworkError>,
    /// Affine functions of the state whose range at the horizon the run reports, on
    /// the sets and on the flights (default none).
    pub measures: Vec<Measure>,
}

/// An affine function of the state, `offset + coef . x`, whose range at the horizon a
/// run reports twice: enclosed by the sets and spread by the simulated flights. Their
/// ratio is the overestimation that the width criteria of a benchmark measure (the
/// glider's `x + y`: issue 14's "x + y width at t = 20 at most 2x the spread").
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Measure {
    /// What it is called in reports (`x + y`, a goal's text).
    pub name: String,
    /// Coefficients, one per state.
    pub coef: Vec<f64>,
    /// Constant term.
    pub offset: f64,
}

impl Measure {
    /// Its value at one state (f64, for flights).
    pub fn at(&self, x: &[f64]) -> f64 {
        self.offset + self.coef.iter().zip(x).map(|(a, v)| a * v).sum::<f64>()
    }

    /// A sound enclosure over a set: on the Taylor models (the states' dependence
    /// kept), met with the interval sum over the hull (both enclose it).
    fn over(&self, x: &[Tm], hull: &[Interval]) -> Interval {
        let mut by_hull = Interval::point(self.offset);
        for (a, h) in self.coef.iter().zip(hull) {
            if *a != 0.0 {
                by_hull += Interval::point(*a) * *h;
            }
        }
        if x.is_empty() {
            return by_hull;
        }
        // Both hold every value; `meet` keeps the hull's where the other is not finite
        // (a model with a NaN is the whole line) or, by rounding, misses it.
        crate::flow::meet(affine_on(&self.coef, self.offset, x).bound(), by_hull)
    }
}

/// `b + a . x` on Taylor models (the terms with `a_i = 0` skipped): an affine function
/// of the states with their dependence kept, for affine bands and measures.
fn affine_on(a: &[f64], b: f64, x: &[Tm]) -> Tm {
    let mut v = Tm::cst(b);
    for (ai, xi) in a.iter().zip(x) {
        if *ai != 0.0 {
            v += xi.clone() * *ai;
        }
    }
    v
}

/// The measures a system file's goals give: the expression of every affine band
/// checked at the end (named by the goal's text).
pub fn end_band_measures(sys: &System) -> Vec<Measure> {
    sys.goals
        .iter()
        .filter_map(|g| match (&g.kind, &g.when) {
            (
                GoalKind::Band {
                    linear: Some((a, b)),
                    ..
                },
                When::End,
            ) => Some(Measure {
                name: g.text.clone(),
                coef: a.clone(),
                offset: *b,
            }),
            _ => None,
        })
        .collect()
}

/// A measure's range at the horizon: the sets' enclosure (hull over the sub-boxes;
/// `None` unless every sub-box has sets there) and the flights' spread.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct MeasureRange {
    /// The measure's name.
    pub name: String,
    /// Enclosure by the sets.
    pub enclosure: Option<[f64; 2]>,
    /// Range over the simulated flights.
    pub sampled: Option<[f64; 2]>,
    /// Enclosure width over sampled width (where both exist and the latter is > 0).
    pub ratio: Option<f64>,
}

/// How the error of the network step (CROWN's gap, the remainder of the controller's
/// Taylor model) enters the set that the plant then carries over the period.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NetworkError {
    /// As an interval remainder of each input: cheapest, but the states the input
    /// drives lose their correlation through it.
    Interval,
    /// As a fresh parameter per input and period (a symbolic remainder, as a
    /// zonotope's new generator or the predicate variable of NNV's star sets), so the
    /// flow keeps the states it drives correlated; at most `extra` parameters beyond
    /// the state count are kept before the set is re-parameterised ([`precondition`]),
    /// and never more than the term budget of the order allows.
    Symbolic {
        /// Parameters allowed beyond the number of states.
        extra: usize,
    },
}

impl NetworkError {
    /// A mode by name: `interval`, `symbolic` (20 extra parameters), `symbolic:N`
    /// (`N` from 1 to 256) or `auto` (`None`: chosen per run). The error says what to give.
    pub fn parse(v: &str) -> Result<Option<NetworkError>, String> {
        Ok(match v {
            "auto" => None,
            "interval" => Some(NetworkError::Interval),
            "symbolic" => Some(NetworkError::Symbolic { extra: 20 }),
            _ => {
                let n: usize = v
                    .strip_prefix("symbolic:")
                    .and_then(|n| n.parse().ok())
                    .filter(|n| (1..=256).contains(n))
                    .ok_or_else(|| "give `interval`, `symbolic`, `symbolic:N` (N = 1 to 256 extra parameters; past the term budget of the order, N is lowered) or `auto`".to_string())?;
                Some(NetworkError::Symbolic { extra: n })
            }
        })
    }
}

/// The modes tried on the whole initial set when the run chooses (`network_error:
/// None`), cheapest first, each with the largest Taylor-model order it uses (`None`:
/// the run's): the first to decide the goals is kept; when none does, the sub-boxes
/// are flown with the one whose flight got furthest. Symbolic remainders go with
/// order 3: the parameters they add cost less there, and on TORA, the unicycle and
/// NAV order 3 with 20 extra parameters decides where order 4 with 6 or 19 does not
/// (docs/reach.md).
pub const NETWORK_ERROR_LADDER: [(NetworkError, Option<usize>); 2] = [
    (NetworkError::Interval, None),
    (NetworkError::Symbolic { extra: 20 }, Some(3)),
];

/// Most polynomial terms a symbolic remainder may grow the models to (the number of
/// monomials of the order in the parameters kept).
const TERM_BUDGET: usize = 30_000;

impl Default for SystemReachSettings {
    fn default() -> Self {
        SystemReachSettings {
            order: 4,
            max_boxes: 256,
            samples: 200,
            seed: 1,
            flow: TmFlowSettings::default(),
            timeout: None,
            precondition: true,
            network_error: None,
            measures: Vec::new(),
        }
    }
}

/// Why a run could not start.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SystemReachError {
    /// The network does not fit the system.
    #[error("the network has {n_in} inputs and {n_out} outputs; the system observes {obs} values and reads {reads} network outputs: use the controller made for this system")]
    Shape {
        /// Network inputs.
        n_in: usize,
        /// Network outputs.
        n_out: usize,
        /// Values the system observes.
        obs: usize,
        /// Network outputs the system reads.
        reads: usize,
    },
    /// A setting is out of range.
    #[error("{0}")]
    Setting(String),
    /// The simulation of a start failed.
    #[error("simulating a start failed: {0}")]
    Simulation(String),
}

/// The verdict of a system run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "verdict", rename_all = "lowercase")]
pub enum SystemVerdict {
    /// Every flight from the initial set meets every goal (sound enclosure).
    Proved,
    /// A simulated flight misses a goal.
    Violated {
        /// Its initial state.
        initial: Vec<f64>,
        /// The goal it misses (its text in the file).
        goal: String,
    },
    /// Not settled.
    Unknown {
        /// Why.
        reason: String,
    },
    /// The file states no goal.
    #[serde(rename = "none")]
    NoGoal,
}

impl SystemVerdict {
    /// `proved`, `violated`, `unknown` or `none`.
    pub fn name(&self) -> &'static str {
        match self {
            SystemVerdict::Proved => "proved",
            SystemVerdict::Violated { .. } => "violated",
            SystemVerdict::Unknown { .. } => "unknown",
            SystemVerdict::NoGoal => "none",
        }
    }
}

/// The sets of one sub-box.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SystemLeaf {
    /// The sub-box of the initial set.
    pub init: Vec<[f64; 2]>,
    /// Interval hull of the state at each control instant reached (row 0: t = 0).
    pub instants: Vec<Vec<[f64; 2]>>,
    /// Interval hull of the state over each control period (row k: period k).
    pub periods: Vec<Vec<[f64; 2]>>,
    /// Why the enclosure stopped early, if it did (with the time).
    pub failure: Option<String>,
    /// The goals on this sub-box: `Some(true)` proved, `Some(false)` refuted by the
    /// sets (some instant's set misses it entirely), `None` undecided.
    #[serde(skip)]
    pub decided: Vec<Option<bool>>,
    /// Where the flight of the sets stopped because a goal that must hold at every
    /// time (or at the end) was already not proved on them: this sub-box can no longer
    /// prove it, so it is split rather than flown on (its rows end there).
    pub stopped_at: Option<f64>,
    /// The run's measures at the horizon on this sub-box's sets (empty unless they
    /// reach it).
    pub end_measures: Vec<[f64; 2]>,
}

impl SystemLeaf {
    /// Whether this sub-box needs no more work: its sets reach the horizon and prove
    /// every goal (without goals: they reach the horizon). A lost enclosure leaves every
    /// goal undecided; without goals it is what makes a sub-box split.
    fn settled(&self) -> bool {
        self.failure.is_none() && self.decided.iter().all(|d| *d == Some(true))
    }
}

/// Whether a goal that must hold over a window (or at the end) has already failed to
/// be proved on the sets: flying on cannot prove it.
fn undecidable(sys: &System, ok: &[bool]) -> bool {
    sys.goals
        .iter()
        .zip(ok)
        .any(|(g, ok)| !ok && !matches!(g.when, When::Eventually(..)))
}

/// The result of a system run.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct SystemReach {
    /// The system's name.
    pub system: String,
    /// The verdict.
    pub verdict: SystemVerdict,
    /// Hull over the sub-boxes of the state at each control instant.
    pub instants: Vec<Vec<[f64; 2]>>,
    /// Hull over the sub-boxes of the state over each control period.
    pub periods: Vec<Vec<[f64; 2]>>,
    /// Sub-boxes of the final partition.
    pub boxes: usize,
    /// Fraction of the initial set, by volume over its parameters of nonzero width,
    /// whose sub-boxes have sets to the horizon. Below 1 (a lost enclosure, a spent
    /// budget, a goal refuted first) the hulls `instants` and `periods` end where the
    /// shortest sub-box ends, and a count of enclosed sub-boxes says little: they are
    /// the small ones. Exactly 1 when every sub-box reaches the horizon.
    pub covered: f64,
    /// Taylor-model order used.
    pub order: usize,
    /// How the network step's error entered the sets (chosen by the run unless set).
    pub network_error: NetworkError,
    /// Wall time in seconds.
    pub seconds: f64,
    /// The sub-boxes.
    pub leaves: Vec<SystemLeaf>,
    /// The settings' measures at the horizon: sets against flights.
    pub measures: Vec<MeasureRange>,
    /// Simulated flights (falsification; also what containment tests check).
    #[serde(skip)]
    pub flights: Vec<(Vec<f64>, SystemFlight)>,
}

/// The starts of the falsification flights: the initial box's centre, its corners (up
/// to 64 of them) and random points.
pub fn starts(sys: &System, n: usize, seed: u64) -> Vec<Vec<f64>> {
    let init = &sys.init;
    let mut out = vec![init.iter().map(|(l, h)| 0.5 * (l + h)).collect::<Vec<_>>()];
    let free: Vec<usize> = (0..init.len()).filter(|&i| init[i].0 < init[i].1).collect();
    let corners = if free.len() <= 6 {
        1usize << free.len()
    } else {
        64
    };
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    for c in 0..corners {
        let mut x: Vec<f64> = init.iter().map(|(l, _)| *l).collect();
        for (b, &i) in free.iter().enumerate() {
            let hi = if free.len() <= 6 {
                (c >> b) & 1 == 1
            } else {
                rng.gen_bool(0.5)
            };
            x[i] = if hi { init[i].1 } else { init[i].0 };
        }
        out.push(x);
    }
    while out.len() < n {
        out.push(init.iter().map(|(l, h)| rng.gen_range(*l..=*h)).collect());
    }
    out
}

/// The network as the closed loop reads it (f64).
pub(crate) fn controller(net: &Network) -> impl Fn(&[f64]) -> Vec<f64> + Sync + '_ {
    move |x: &[f64]| net.eval_f64(x)
}

/// Sound reachable sets of `sys` under the controller `net`, and the verdict on the
/// file's goals.
pub fn reach_system(
    sys: &System,
    net: &Network,
    s: &SystemReachSettings,
) -> Result<SystemReach, SystemReachError> {
    let t0 = Instant::now();
    let (s, deadline) = checked_settings(sys, net, s, t0)?;
    let s = &s;
    // Falsification first.
    let eval = controller(net);
    let Falsified {
        flights: ok_flights,
        violation,
        unflown,
    } = falsify(sys, net, s, deadline)?;
    let init: Vec<Interval> = sys
        .init
        .iter()
        .map(|&(l, h)| Interval { lo: l, hi: h })
        .collect();
    let mut leaves: Vec<SystemLeaf> = Vec::new();
    let mut mode = s.network_error.unwrap_or(NetworkError::Interval);
    let mut run_s = s.clone();
    let mut verdict = if let Some(v) = violation {
        // The sets are still computed once (for the figure), without refinement.
        let leaf = fly_box(sys, net, &init, s, mode, deadline);
        leaves.push(leaf);
        v
    } else {
        // The whole initial set first, in each mode of the ladder until one decides
        // (without goals: until one keeps its enclosure to the horizon); else the
        // sub-boxes are flown in the mode that got furthest.
        let mut root: Option<SystemLeaf> = None;
        if s.network_error.is_none() {
            let mut best: Option<(usize, NetworkError, SystemReachSettings, SystemLeaf)> = None;
            for (m, cap) in NETWORK_ERROR_LADDER {
                let mut rs = s.clone();
                if let Some(k) = cap {
                    rs.order = rs.order.min(k);
                    rs.flow.order = rs.order as u32;
                }
                let l = fly_box(sys, net, &init, &rs, m, deadline);
                let done = l.decided.contains(&Some(false)) || l.settled();
                let p = progress(&l, sys);
                if done {
                    best = Some((usize::MAX, m, rs, l));
                    break;
                }
                if best.as_ref().is_none_or(|(bp, ..)| p >= *bp) {
                    best = Some((p, m, rs, l));
                }
                if past(deadline) {
                    break;
                }
            }
            if let Some((_, m, rs, l)) = best {
                mode = m;
                run_s = rs;
                root = Some(l);
            }
        }
        // Without a root flight (a fixed network-error mode), the whole set is cut into
        // as many sub-boxes as there are worker threads at once, so that no core idles
        // while one flies the whole set.
        let frontier = match root.take() {
            Some(l) => Frontier::Flown(l),
            None => {
                let k = rayon::current_num_threads().clamp(1, s.max_boxes);
                let mut boxes = vec![init.clone()];
                while boxes.len() < k {
                    let b = boxes.remove(0);
                    let (a, c) = bisect_sensitive(sys, net, &b, &init, sys.steps());
                    boxes.push(a);
                    boxes.push(c);
                }
                Frontier::Boxes(boxes)
            }
        };
        let r = refine(sys, net, &init, &run_s, mode, deadline, frontier);
        leaves = r.leaves;
        let mut reason = None;
        let mut violation_from_sets = None;
        if let Some((g, centre)) = r.refuted {
            // The sets show a sub-box missing the goal entirely at some instant:
            // every flight from it misses it; its centre's flight is the witness.
            match fly(sys, &eval, &centre, 10) {
                Ok(f) if goals_hold(sys, &f).iter().any(|h| !h) => {
                    violation_from_sets = Some(SystemVerdict::Violated {
                        initial: centre,
                        goal: g,
                    });
                }
                _ => {
                    reason = Some(format!(
                        "the enclosure of a sub-box lies outside the goal `{g}`, but no simulated flight from the starts tried missed it"
                    ));
                }
            }
        } else if r.unsettled > 0 {
            let lost = leaves.iter().filter(|l| l.failure.is_some()).count();
            reason = Some(if r.timed_out {
                format!(
                    "timeout after {:.1} s with {} sub-boxes undecided",
                    t0.elapsed().as_secs_f64(),
                    r.unsettled
                )
            } else if lost > 0 {
                format!(
                    "{lost} of {} sub-boxes lost their enclosure ({}) within the budget of {} sub-boxes (--max-boxes)",
                    leaves.len(),
                    leaves.iter().find_map(|l| l.failure.clone()).unwrap_or_default(),
                    s.max_boxes
                )
            } else {
                format!(
                    "{} of {} sub-boxes leave a goal undecided within the budget of {} sub-boxes (--max-boxes)",
                    r.unsettled,
                    leaves.len(),
                    s.max_boxes
                )
            });
        }
        match (violation_from_sets, reason) {
            (Some(v), _) => v,
            // Without goals the sets are the result; a sub-box that stops early says so
            // in its `failure`.
            _ if sys.goals.is_empty() => SystemVerdict::NoGoal,
            (None, Some(r)) => SystemVerdict::Unknown {
                reason: match &unflown {
                    Some(u) => format!("{r}; {u}"),
                    None => r,
                },
            },
            (None, None) => SystemVerdict::Proved,
        }
    };
    if matches!(verdict, SystemVerdict::Proved) && leaves.iter().any(|l| l.failure.is_some()) {
        verdict = SystemVerdict::Unknown {
            reason: "an enclosure was lost".into(),
        };
    }
    let instants = leaf_hull(&leaves, sys.dim(), |l| &l.instants);
    let covered = coverage(&init, &leaves, sys.steps());
    let periods = leaf_hull(&leaves, sys.dim(), |l| &l.periods);
    let measures = measure_ranges(&s.measures, &leaves, &ok_flights, covered);
    Ok(SystemReach {
        system: sys.name.clone(),
        verdict,
        instants,
        periods,
        boxes: leaves.len(),
        covered,
        order: run_s.order,
        network_error: mode,
        seconds: t0.elapsed().as_secs_f64(),
        leaves,
        measures,
        flights: ok_flights,
    })
}

/// The checks every run makes before flying anything (the network fits the system, the
/// order, the budget), the settings with the flow's order set, and the deadline of
/// `s.timeout` counted from `t0`.
pub(crate) fn checked_settings(
    sys: &System,
    net: &Network,
    s: &SystemReachSettings,
    t0: Instant,
) -> Result<(SystemReachSettings, Option<Instant>), SystemReachError> {
    if !sys.fits_controller(net.n_inputs(), net.n_outputs()) {
        return Err(SystemReachError::Shape {
            n_in: net.n_inputs(),
            n_out: net.n_outputs(),
            obs: sys.n_observed(),
            reads: sys.n_net_outputs,
        });
    }
    if !(1..=8).contains(&s.order) {
        return Err(SystemReachError::Setting(format!(
            "the Taylor-model order must be 1 to 8 (got {}); 3-5 is usual",
            s.order
        )));
    }
    if s.max_boxes == 0 {
        return Err(SystemReachError::Setting(
            "the sub-box budget must be at least 1".into(),
        ));
    }
    let mut s = s.clone();
    s.flow.order = s.order as u32;
    // The budget also bounds each sub-box's flight (one wide network can take minutes
    // per box), not only the splitting rounds.
    let deadline = s.timeout.and_then(|t| {
        std::time::Duration::try_from_secs_f64(t)
            .ok()
            .and_then(|d| t0.checked_add(d))
    });
    Ok((s, deadline))
}

/// The falsification flights of a run: the flights that finished, the first that
/// misses a goal (as the verdict), and why a flight could not be finished (the first).
pub(crate) struct Falsified {
    pub(crate) flights: Vec<(Vec<f64>, SystemFlight)>,
    pub(crate) violation: Option<SystemVerdict>,
    pub(crate) unflown: Option<String>,
}

/// Fly the falsification starts ([`starts`]: `s.samples` of them, seeded by `s.seed`)
/// in parallel and look for a goal they miss.
pub(crate) fn falsify(
    sys: &System,
    net: &Network,
    s: &SystemReachSettings,
    deadline: Option<Instant>,
) -> Result<Falsified, SystemReachError> {
    let eval = controller(net);
    let flights: Vec<(Vec<f64>, Result<SystemFlight, SimError>)> = starts(sys, s.samples, s.seed)
        .into_par_iter()
        .map(|x0| {
            let f = fly_until(sys, &eval, &x0, 10, deadline);
            (x0, f)
        })
        .collect();
    let mut ok_flights = Vec::with_capacity(flights.len());
    let mut violation = None;
    // A flight the simulator cannot finish (its step collapsed on a switch, or the
    // budget ran out) witnesses nothing; the sets do not need it.
    let mut unflown: Option<String> = None;
    for (x0, f) in flights {
        let f = match f {
            Ok(f) => f,
            Err(e @ (SimError::StepCollapse { .. } | SimError::Timeout { .. })) => {
                unflown.get_or_insert_with(|| format!("the flight from {x0:?} stopped: {e}"));
                continue;
            }
            Err(e) => return Err(SystemReachError::Simulation(e.to_string())),
        };
        if violation.is_none() {
            if let Some(gi) = goals_hold(sys, &f).iter().position(|h| !h) {
                violation = Some(SystemVerdict::Violated {
                    initial: x0.clone(),
                    goal: sys.goals[gi].text.clone(),
                });
            }
        }
        ok_flights.push((x0, f));
    }
    Ok(Falsified {
        flights: ok_flights,
        violation,
        unflown,
    })
}

/// The hull over `leaves` of one of their rows of boxes (`instants` or `periods`), up to
/// the shortest leaf's rows.
pub(crate) fn leaf_hull(
    leaves: &[SystemLeaf],
    dim: usize,
    rows: impl Fn(&SystemLeaf) -> &Vec<Vec<[f64; 2]>>,
) -> Vec<Vec<[f64; 2]>> {
    let n = leaves.iter().map(|l| rows(l).len()).min().unwrap_or(0);
    (0..n)
        .map(|k| {
            (0..dim)
                .map(|i| {
                    leaves
                        .iter()
                        .fold([f64::INFINITY, f64::NEG_INFINITY], |a, l| {
                            let v = rows(l)[k][i];
                            [a[0].min(v[0]), a[1].max(v[1])]
                        })
                })
                .collect()
        })
        .collect()
}

/// Each measure over the sets at the horizon (hull over the sub-boxes, when every
/// sub-box has sets there) and over the flights' final states.
pub(crate) fn measure_ranges(
    measures: &[Measure],
    leaves: &[SystemLeaf],
    flights: &[(Vec<f64>, SystemFlight)],
    covered: f64,
) -> Vec<MeasureRange> {
    let span = |it: &mut dyn Iterator<Item = [f64; 2]>| {
        it.fold(None, |a: Option<[f64; 2]>, v| {
            Some(a.map_or(v, |a| [a[0].min(v[0]), a[1].max(v[1])]))
        })
    };
    measures
        .iter()
        .enumerate()
        .map(|(j, m)| {
            let all = covered == 1.0 && leaves.iter().all(|l| l.end_measures.len() > j);
            let enclosure = if all {
                span(&mut leaves.iter().map(|l| l.end_measures[j]))
            } else {
                None
            };
            let sampled = span(&mut flights.iter().filter_map(|(_, f)| {
                f.states.last().map(|x| {
                    let v = m.at(x);
                    [v, v]
                })
            }));
            let ratio = match (enclosure, sampled) {
                (Some(e), Some(s)) if s[1] > s[0] => Some((e[1] - e[0]) / (s[1] - s[0])),
                _ => None,
            };
            MeasureRange {
                name: m.name.clone(),
                enclosure,
                sampled,
                ratio,
            }
        })
        .collect()
}

/// The fraction of `init` (by volume over its parameters of nonzero width) whose
/// leaves have sets at all `steps + 1` control instants.
/// Exactly 1 when every leaf does (then `instants` runs to the horizon).
pub(crate) fn coverage(init: &[Interval], leaves: &[SystemLeaf], steps: usize) -> f64 {
    let whole =
        |l: &SystemLeaf| l.failure.is_none() && l.stopped_at.is_none() && l.instants.len() > steps;
    if leaves.iter().all(whole) {
        return 1.0;
    }
    covered_volume(init, leaves, steps).min(1.0)
}

/// The volume share of `init` (over its parameters of nonzero width) of the `leaves`
/// with sets at all `steps + 1` control instants, summed: [`coverage`] for leaves that
/// need not tile the whole set (a shard's).
pub(crate) fn covered_volume(init: &[Interval], leaves: &[SystemLeaf], steps: usize) -> f64 {
    let whole =
        |l: &&SystemLeaf| l.failure.is_none() && l.stopped_at.is_none() && l.instants.len() > steps;
    leaves
        .iter()
        .filter(whole)
        .map(|l| {
            l.init
                .iter()
                .zip(init)
                .filter(|(_, b)| b.hi > b.lo)
                .map(|(v, b)| (v[1] - v[0]) / (b.hi - b.lo))
                .product::<f64>()
        })
        .fold(0.0, |a, v| a + v)
}

/// Where the refinement starts: a flight of the whole set already made (the ladder's
/// best), or boxes still to fly.
enum Frontier {
    Flown(SystemLeaf),
    Boxes(Vec<Vec<Interval>>),
}

/// The state [`refine`] shares between its tasks and ends with: every sub-box flown
/// (sorted by their initial boxes at the end), how many of them are not settled,
/// whether the deadline stopped the splitting, and a goal some sub-box's sets lie
/// entirely outside of (its text and the sub-box's centre).
struct RefineState {
    leaves: Vec<SystemLeaf>,
    unsettled: usize,
    timed_out: bool,
    refuted: Option<(String, Vec<f64>)>,
    /// Sub-boxes made so far (flown or waiting), against the budget.
    boxes: usize,
}

/// Fly the frontier's boxes and split every sub-box that is neither settled (reaches
/// the horizon with every goal proved) nor refuted, as long as the budget and the
/// deadline allow. Asynchronous: a sub-box's halves are flown as soon as it ends, on
/// whichever worker is free, not after the whole round (one slow sub-box no longer holds
/// the others' halves back). A goal refuted by some sub-box's sets stops the splitting;
/// boxes not started by then are not flown.
fn refine(
    sys: &System,
    net: &Network,
    init: &[Interval],
    s: &SystemReachSettings,
    mode: NetworkError,
    deadline: Option<Instant>,
    frontier: Frontier,
) -> RefineState {
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Mutex;
    let stop = AtomicBool::new(false);
    let state = Mutex::new(RefineState {
        leaves: Vec::new(),
        unsettled: 0,
        timed_out: false,
        refuted: None,
        boxes: match &frontier {
            Frontier::Flown(_) => 1,
            Frontier::Boxes(b) => b.len(),
        },
    });
    /// What every task of the scope shares.
    #[derive(Clone, Copy)]
    struct Ctx<'s> {
        sys: &'s System,
        net: &'s Network,
        init: &'s [Interval],
        s: &'s SystemReachSettings,
        mode: NetworkError,
        deadline: Option<Instant>,
        stop: &'s AtomicBool,
        state: &'s Mutex<RefineState>,
    }
    // A flown sub-box: keep it, or split it and fly the halves.
    fn handle<'s>(l: SystemLeaf, scope: &rayon::Scope<'s>, ctx: &'s Ctx<'s>) {
        let Ctx {
            sys,
            init,
            s,
            deadline,
            stop,
            state,
            ..
        } = *ctx;
        let mut st = state.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(gi) = l.decided.iter().position(|d| *d == Some(false)) {
            if st.refuted.is_none() {
                let centre: Vec<f64> = l.init.iter().map(|v| 0.5 * (v[0] + v[1])).collect();
                st.refuted = Some((sys.goals[gi].text.clone(), centre));
            }
            stop.store(true, Ordering::SeqCst);
        }
        if l.settled() {
            st.leaves.push(l);
            return;
        }
        let timed_out = past(deadline);
        if stop.load(Ordering::SeqCst) || timed_out || st.boxes + 1 > s.max_boxes {
            st.timed_out |= timed_out;
            st.unsettled += 1;
            st.leaves.push(l);
            return;
        }
        st.boxes += 1;
        drop(st);
        let b: Vec<Interval> = l
            .init
            .iter()
            .map(|v| Interval { lo: v[0], hi: v[1] })
            .collect();
        let k = l.instants.len().saturating_sub(1);
        let (a, c) = bisect_sensitive(sys, ctx.net, &b, init, k);
        for half in [a, c] {
            scope.spawn(move |sc| fly_and_handle(half, sc, ctx));
        }
    }
    fn fly_and_handle<'s>(b: Vec<Interval>, scope: &rayon::Scope<'s>, ctx: &'s Ctx<'s>) {
        if ctx.stop.load(Ordering::SeqCst) {
            // Kept as a leaf without sets, so that the leaves still tile the initial
            // set and the hulls over them (which end where the shortest leaf ends) claim
            // nothing for the part of the set never flown.
            let mut st = ctx.state.lock().unwrap_or_else(|e| e.into_inner());
            st.unsettled += 1;
            st.leaves.push(empty_leaf(
                ctx.sys,
                &b,
                Some("not flown: a goal was refuted on another sub-box first".into()),
            ));
            return;
        }
        let l = fly_box(ctx.sys, ctx.net, &b, ctx.s, ctx.mode, ctx.deadline);
        handle(l, scope, ctx);
    }
    let ctx = Ctx {
        sys,
        net,
        init,
        s,
        mode,
        deadline,
        stop: &stop,
        state: &state,
    };
    let ctx = &ctx;
    rayon::scope(|sc| match frontier {
        Frontier::Flown(l) => handle(l, sc, ctx),
        Frontier::Boxes(boxes) => {
            for b in boxes {
                sc.spawn(move |sc| fly_and_handle(b, sc, ctx));
            }
        }
    });
    let mut st = state.into_inner().unwrap_or_else(|e| e.into_inner());
    st.leaves.sort_by(|p, q| {
        p.init
            .iter()
            .flatten()
            .zip(q.init.iter().flatten())
            .map(|(a, b)| a.total_cmp(b))
            .find(|o| o.is_ne())
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    st
}

/// How far a sub-box's flight got, in control instants: where its goals became
/// undecidable or its enclosure was lost, else the whole horizon.
fn progress(l: &SystemLeaf, sys: &System) -> usize {
    match (l.stopped_at, &l.failure) {
        (_, Some(_)) => l.instants.len().saturating_sub(1),
        (Some(t), None) => (t / sys.period).round() as usize,
        (None, None) => sys.steps(),
    }
}

/// Cut `b` in two along the parameter whose range moves the state most at control
/// instant `k` (where a sub-box's sets ended; the horizon for the first cut): per
/// parameter of nonzero width, two flights from the box's centre with that parameter at
/// its ends; the effect of a parameter is the sum over the states of its flights'
/// difference, each state scaled by the spread of all these flights in it (so units
/// cancel). A parameter that barely matters (a height interval of 1e-4 beside an
/// angular rate of 0.02) is then not cut only because its relative width ties. Falls
/// back to [`bisect`] where a flight fails or nothing moves.
pub(crate) fn bisect_sensitive(
    sys: &System,
    net: &Network,
    b: &[Interval],
    init: &[Interval],
    k: usize,
) -> (Vec<Interval>, Vec<Interval>) {
    let eval = controller(net);
    let k = k.clamp(1, sys.steps().max(1));
    let centre: Vec<f64> = b.iter().map(|v| 0.5 * (v.lo + v.hi)).collect();
    let row = |x0: &[f64]| -> Option<Vec<f64>> {
        let f = fly(sys, &eval, x0, 1).ok()?;
        f.states.get(k).cloned()
    };
    let mut pairs: Vec<(usize, Vec<f64>, Vec<f64>)> = Vec::new();
    for j in 0..b.len() {
        if b[j].hi <= b[j].lo {
            continue;
        }
        let (mut lo, mut hi) = (centre.clone(), centre.clone());
        lo[j] = b[j].lo;
        hi[j] = b[j].hi;
        match (row(&lo), row(&hi)) {
            (Some(p), Some(q)) => pairs.push((j, p, q)),
            _ => return bisect(b, init),
        }
    }
    let spread: Vec<f64> = (0..sys.dim())
        .map(|i| {
            let (mn, mx) = pairs
                .iter()
                .flat_map(|(_, p, q)| [p[i], q[i]])
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, c), v| {
                    (a.min(v), c.max(v))
                });
            mx - mn
        })
        .collect();
    let mut best: Option<(f64, usize)> = None;
    for (j, p, q) in &pairs {
        let effect: f64 = (0..sys.dim())
            .filter(|&i| spread[i] > 0.0 && spread[i].is_finite())
            .map(|i| (p[i] - q[i]).abs() / spread[i])
            .sum();
        if effect.is_finite() && best.is_none_or(|(e, _)| effect > e) {
            best = Some((effect, *j));
        }
    }
    match best {
        Some((e, j)) if e > 0.0 => cut_at(b, j),
        _ => bisect(b, init),
    }
}

/// Cut `b` in two along the parameter widest relative to the initial set `init`.
fn bisect(b: &[Interval], init: &[Interval]) -> (Vec<Interval>, Vec<Interval>) {
    let rel = |i: usize| {
        let w0 = init[i].hi - init[i].lo;
        if w0 > 0.0 {
            (b[i].hi - b[i].lo) / w0
        } else {
            0.0
        }
    };
    let j = (0..b.len())
        .max_by(|&p, &q| rel(p).total_cmp(&rel(q)))
        .unwrap_or(0);
    cut_at(b, j)
}

/// `b` cut in two at the midpoint of parameter `j`.
pub(crate) fn cut_at(b: &[Interval], j: usize) -> (Vec<Interval>, Vec<Interval>) {
    let m = 0.5 * (b[j].lo + b[j].hi);
    let mut lo = b.to_vec();
    let mut hi = b.to_vec();
    lo[j].hi = m;
    hi[j].lo = m;
    (lo, hi)
}

pub(crate) fn to_pairs(v: &[Interval]) -> Vec<[f64; 2]> {
    v.iter().map(|i| [i.lo, i.hi]).collect()
}

/// A midpoint `m` and radius `r` with `[m - r, m + r]` containing `i` in exact
/// arithmetic (the ends checked with outward-rounded interval sums); `(lo, 0)` for a
/// point.
fn mid_rad(i: Interval) -> (f64, f64) {
    if i.lo == i.hi {
        return (i.lo, 0.0);
    }
    let m = 0.5 * i.lo + 0.5 * i.hi;
    let mut r = (i.hi - m).max(m - i.lo).max(0.0).next_up();
    let (pm, pr) = (Interval::point(m), Interval::point(r));
    let (mut lo, mut hi) = ((pm - pr).hi, (pm + pr).lo);
    // Grow by a step that doubles: one ulp of `r` at a time would take up to 2^52
    // rounds when `r` is tiny against `m` (a point-like interval away from 0).
    let mut step = (r * f64::EPSILON)
        .max(m.abs() * f64::EPSILON)
        .max(f64::MIN_POSITIVE);
    while lo > i.lo || hi < i.hi {
        r = (r + step).next_up();
        step *= 2.0;
        let pr = Interval::point(r);
        (lo, hi) = ((pm - pr).hi, (pm + pr).lo);
    }
    (m, r)
}

/// The constant coefficients of `x` and their degree-1 coefficients over every
/// parameter any of them depends on (rows padded to that count).
fn linear_parts(x: &[Tm]) -> (Vec<f64>, Vec<Vec<f64>>) {
    let n = x.iter().map(|v| v.n_vars()).max().unwrap_or(0);
    x.iter()
        .map(|v| {
            let (c, mut g) = v.linear_part();
            g.resize(n, 0.0);
            (c, g)
        })
        .unzip()
}

/// The Taylor models of a box: `x_i = mid_i + rad_i xi_k` for the `k`-th state of
/// non-zero width, constants otherwise; [`mid_rad`] makes the model's range contain the
/// box.
/// With `lifted_weight > 1` the models are mixed-degree ([`Tm::with_lifted_weight`]):
/// every parameter lifted later weighs that much toward the order.
fn box_models(b: &[Interval], order: u32, lifted_weight: u32) -> Vec<Tm> {
    let free: Vec<usize> = (0..b.len()).filter(|&i| b[i].hi > b[i].lo).collect();
    let n = free.len();
    b.iter()
        .enumerate()
        .map(|(i, v)| match free.iter().position(|&j| j == i) {
            None => Tm::constant(v.lo, n, order),
            Some(k) => {
                let (mid, rad) = mid_rad(*v);
                Tm::var(k, n, order) * rad + mid
            }
        })
        .map(|m| {
            if lifted_weight > 1 {
                m.with_lifted_weight(lifted_weight)
            } else {
                m
            }
        })
        .collect()
}

/// Most higher-order monomials of the inputs' Taylor models the network step keeps as
/// variables of their own (the heaviest; the others go into the noise box).
const MAX_TERM_VARS: usize = 160;

/// The inputs' Taylor models on one monomial table (`None` if they cannot share one).
fn common_basis(obs: &[Tm], order: u32) -> Option<(Tm, Vec<Tm>)> {
    let n = obs.iter().map(|v| v.n_vars()).max().unwrap_or(0);
    let base = Tm::constant(0.0, n, order);
    let obs: Vec<Tm> = obs.iter().map(|v| v.clone() + base.clone()).collect();
    obs.iter()
        .all(|v| v.same_basis(&base))
        .then_some((base, obs))
}

/// The network over a set of inputs given as Taylor models, by CROWN over a linear set
/// whose variables are the parameters *and* the inputs' heaviest higher-order monomials
/// (each monomial `m` a variable of its own over its range, `[-1, 1]`, or `[0, 1]` for
/// even ones): CROWN's affine bounds in those variables are then substituted back into
/// the monomials exactly, so the outputs keep the inputs' polynomial dependence instead
/// of bounding it into a box (the polynomial abstraction of the network's input set, as
/// POLAR and CORA's polynomial zonotopes keep it; Huang et al., ATVA 2022; Kochdumper et
/// al., "Open- and closed-loop neural network verification using polynomial
/// zonotopes", NFM 2023). The other monomials and the remainders form the noise box.
/// For networks without piecewise-linear layers the network evaluated on the Taylor
/// models is also computed, and the narrower result per output kept.
pub fn network_over(net: &Network, obs: &[Tm], order: u32) -> Vec<Tm> {
    let Some((base, obs)) = common_basis(obs, order) else {
        return network_over_linear(net, obs, order);
    };
    let n = base.n_vars();
    // Monomials of degree >= 2 by weight (sum of |coefficient| over the inputs).
    let mut weight: Vec<(usize, f64)> = (n + 1..base.n_terms())
        .filter_map(|m| {
            let w: f64 = obs.iter().map(|v| v.coef(m).abs()).sum();
            // Even monomials are shifted to [-1, 1] by halving: only where that is exact.
            let halves = !base.term_even(m)
                || obs.iter().all(|v| {
                    let h = v.coef(m);
                    (h * 0.5) * 2.0 == h
                });
            (w > 0.0 && halves).then_some((m, w))
        })
        .collect();
    if order < 2 || weight.is_empty() {
        return network_over_linear(net, &obs, order);
    }
    weight.sort_by(|a, b| b.1.total_cmp(&a.1));
    weight.truncate(MAX_TERM_VARS);
    let mons: Vec<usize> = weight.iter().map(|&(m, _)| m).collect();
    let mut kept = vec![false; base.n_terms()];
    for &m in &mons {
        kept[m] = true;
    }
    let mut c = Vec::with_capacity(obs.len());
    let mut noise = Vec::with_capacity(obs.len());
    let mut gens: Vec<Vec<f64>> = vec![Vec::with_capacity(obs.len()); n + mons.len()];
    for o in &obs {
        // The monomials not kept, plus the remainder: the noise box around its midpoint.
        let rest: Vec<(usize, f64)> = (n + 1..o.n_terms())
            .filter(|&m| !kept[m] && o.coef(m) != 0.0)
            .map(|m| (m, o.coef(m)))
            .collect();
        let r = o.from_terms(0.0, &rest).bound() + o.rem();
        let (mr, r0) = mid_rad(r);
        // Centre: constant + the noise box's midpoint + half of each kept even monomial
        // (`h m = h/2 + (h/2) nu` with `nu = 2 m - 1` in [-1, 1]), summed outward.
        let mut centre = Interval::point(o.coef(0)) + Interval::point(mr);
        for (k, g) in gens.iter_mut().enumerate() {
            if k < n {
                g.push(o.coef(k + 1));
            } else {
                let m = mons[k - n];
                let h = o.coef(m);
                if o.term_even(m) {
                    centre += Interval::point(h * 0.5);
                    g.push(h * 0.5);
                } else {
                    g.push(h);
                }
            }
        }
        let (cm, cr) = mid_rad(centre);
        c.push(cm);
        noise.push((r0 + cr).next_up());
    }
    let Ok(e) = samara_bounds::linset::bound_over_linear_set(net, &c, &gens, &noise) else {
        return network_over_linear(net, &obs, order);
    };
    let from_terms: Vec<Tm> = (0..net.n_outputs())
        .map(|j| {
            let a = &e.coef[j];
            let mut terms: Vec<(usize, f64)> = (0..n).map(|k| (k + 1, a[k])).collect();
            // `a nu = 2 a m - a` for an even monomial: the constant moves, outward.
            let mut cst = Interval::point(e.cst[j]);
            for (k, &m) in mons.iter().enumerate() {
                let ak = a[n + k];
                if base.term_even(m) {
                    terms.push((m, 2.0 * ak));
                    cst -= Interval::point(ak);
                } else {
                    terms.push((m, ak));
                }
            }
            let (cm, cr) = mid_rad(cst);
            let dev = (e.dev[j] + cr).next_up();
            base.from_terms(cm, &terms)
                .with_rem(Interval { lo: -dev, hi: dev })
        })
        .collect();
    let direct = smooth_direct(net, &obs);
    from_terms
        .into_iter()
        .enumerate()
        .map(|(j, a)| narrower(a, direct.as_ref().map(|d| d[j].clone())))
        .collect()
}

/// The network evaluated on the Taylor models, for networks without piecewise-linear
/// layers (where the smooth activations' Taylor models can beat CROWN's lines).
fn smooth_direct(net: &Network, obs: &[Tm]) -> Option<Vec<Tm>> {
    let smooth = !net
        .layers
        .iter()
        .any(|l| matches!(l, samara_nn::Layer::Act(a) if a.is_piecewise_linear()));
    smooth.then(|| net.eval::<Tm>(obs))
}

/// The narrower of two enclosures of one output (by the width of their bounds).
fn narrower(a: Tm, b: Option<Tm>) -> Tm {
    match b {
        Some(b) if b.bound().width() < a.bound().width() => b,
        _ => a,
    }
}

/// The network over Taylor-model inputs by CROWN on their linear parts, everything of
/// degree >= 2 and the remainders as a noise box (any network `samara_bounds::linset`
/// supports); for networks without piecewise-linear layers also the network evaluated
/// on the Taylor models, keeping the narrower result per output.
fn network_over_linear(net: &Network, obs: &[Tm], order: u32) -> Vec<Tm> {
    // Linear parts over every parameter any input depends on (after a
    // re-parameterisation there are more than the initial set's).
    let (c0s, g) = linear_parts(obs);
    let n_params = g.first().map_or(0, |r| r.len());
    let mut c = Vec::with_capacity(obs.len());
    let mut noise = Vec::with_capacity(obs.len());
    for (o, c0) in obs.iter().zip(c0s) {
        // Everything that is not linear (higher-order terms, remainder), as a box
        // centred on the linear part's constant shifted by the box's midpoint; the
        // rounding of that shift goes into the box's radius.
        let (mid, r0) = mid_rad(o.nonlinear_bound());
        let centre = c0 + mid;
        let shift_err = (centre - c0 - mid).abs() + f64::EPSILON * centre.abs();
        c.push(centre);
        noise.push((r0 + 2.0 * shift_err).next_up());
    }
    // linset takes the generators: one per parameter, each over the network's inputs.
    let gens: Vec<Vec<f64>> = (0..n_params)
        .map(|k| g.iter().map(|row: &Vec<f64>| row[k]).collect())
        .collect();
    let crown = samara_bounds::linset::bound_over_linear_set(net, &c, &gens, &noise).ok();
    let direct = smooth_direct(net, obs);
    let n_out = net.n_outputs();
    (0..n_out)
        .map(|j| {
            let from_crown = crown.as_ref().map(|e| {
                Tm::affine(e.cst[j], &e.coef[j], order).with_rem(Interval {
                    lo: -e.dev[j],
                    hi: e.dev[j],
                })
            });
            let from_direct = direct.as_ref().map(|d| d[j].clone());
            match (from_crown, from_direct) {
                (Some(a), b) => narrower(a, b),
                (None, Some(b)) => b,
                (None, None) => {
                    // Not supported by CROWN: interval evaluation over the hull.
                    let bb: Vec<Interval> = obs.iter().map(|o| o.bound()).collect();
                    Tm::from_interval(net.eval::<Interval>(&bb)[j])
                }
            }
        })
        .collect()
}

/// The network's outputs with each remainder given a fresh parameter of its own
/// (`u_j = p_j + m_j + r_j xi_{n + j}` with `[m_j - r_j, m_j + r_j]` containing the
/// remainder): the error of the network step becomes a symbol the flow carries, so the
/// states it reaches stay correlated through it (symbolic remainders, as the generators
/// of a zonotope or the new variables of NNV's star sets) instead of independent
/// intervals. `n` is the number of parameters the states already use.
fn lift_remainders(y: Vec<Tm>, n: usize, order: u32) -> Vec<Tm> {
    // Rounding-size remainders stay intervals: a parameter would cost more than it
    // keeps.
    let lift: Vec<bool> = y
        .iter()
        .map(|v| {
            let b = v.bound();
            v.rem().width() > 1e-9 * (1.0 + b.lo.abs().max(b.hi.abs()))
        })
        .collect();
    let total = n + lift.iter().filter(|l| **l).count();
    let mut k = n;
    y.into_iter()
        .zip(lift)
        .map(|(v, l)| {
            let (p, r) = v.split_rem();
            if l {
                let (m, rad) = mid_rad(r);
                let xi = fresh_param(&p, k, total, order);
                let out = p + xi * rad + m;
                k += 1;
                out
            } else {
                p.with_rem(r)
            }
        })
        .collect()
}

/// The parameter `xi_k` of `total` for a symbolic remainder of `p`: on `p`'s own table
/// kind (a mixed-degree `p` gives it its lifted weight), or a classic one of `order`
/// when `p` has no order of its own (a constant).
fn fresh_param(p: &Tm, k: usize, total: usize, order: u32) -> Tm {
    if p.order() == order {
        p.param(k, total)
    } else {
        Tm::var(k, total, order)
    }
}

/// How many times its initial magnitude (`1 + max |x_i|` over the sub-box) a state's
/// enclosure may grow before the sub-box is given up as lost (and split).
const EXPLODED: f64 = 1e3;

/// Number of monomials of total degree at most `order` in `n` variables.
fn monomials(n: usize, order: usize) -> usize {
    // C(n + order, order), computed incrementally (exact: each prefix is a binomial).
    let mut c: usize = 1;
    for k in 1..=order {
        c = c.saturating_mul(n + k) / k;
    }
    c
}

/// Number of monomials of a mixed-degree table ([`Tm::with_lifted_weight`]): `full`
/// parameters of weight 1 and `lifted` of weight `lw`, weighted degree at most `order`
/// (the classic count `monomials(full + lifted, order)` when `lw <= 1`): the lifted
/// monomials of degree `d` times the full ones of degree up to `order - lw d`.
fn mixed_monomials(full: usize, lifted: usize, order: usize, lw: u32) -> usize {
    let lw = (lw as usize).min(order.max(1));
    if lw <= 1 {
        return monomials(full + lifted, order);
    }
    (0..=order / lw)
        .map(|d| {
            // Monomials of degree exactly d in `lifted` variables: C(lifted + d - 1, d).
            let exact = if d == 0 {
                1
            } else if lifted == 0 {
                0
            } else {
                monomials(lifted - 1, d)
            };
            exact.saturating_mul(monomials(full, order - lw * d))
        })
        .fold(0usize, |a, v| a.saturating_add(v))
}

/// Whether the run's time budget (its deadline, if any) is spent.
pub(crate) fn past(deadline: Option<Instant>) -> bool {
    deadline.is_some_and(|d| Instant::now() > d)
}

/// A sub-box `b` without sets (yet): every goal undecided, `failure` saying why, if it
/// stays so.
pub(crate) fn empty_leaf(sys: &System, b: &[Interval], failure: Option<String>) -> SystemLeaf {
    SystemLeaf {
        init: to_pairs(b),
        instants: Vec::new(),
        periods: Vec::new(),
        failure,
        decided: vec![None; sys.goals.len()],
        stopped_at: None,
        end_measures: Vec::new(),
    }
}

/// Fly one sub-box over the horizon and decide the goals on its sets.
pub(crate) fn fly_box(
    sys: &System,
    net: &Network,
    b: &[Interval],
    s: &SystemReachSettings,
    mode: NetworkError,
    deadline: Option<Instant>,
) -> SystemLeaf {
    let mut x = box_models(b, s.order as u32, s.flow.lifted_weight);
    // Most parameters the models may carry before the set is re-parameterised (0: the
    // network's error stays an interval).
    let max_params = match mode {
        NetworkError::Symbolic { extra } if s.precondition => {
            let base = sys.dim();
            let m = net.n_outputs();
            let mut e = extra;
            while e > 0 && mixed_monomials(base, e + m, s.order, s.flow.lifted_weight) > TERM_BUDGET
            {
                e -= 1;
            }
            if e == 0 {
                0
            } else {
                base + e
            }
        }
        _ => 0,
    };
    // A set this much wider than the initial box's magnitude is lost: stop the
    // sub-box (its flow would crawl on) so that it is split.
    let scale: Vec<f64> = b.iter().map(|v| 1.0 + v.lo.abs().max(v.hi.abs())).collect();
    // With symbolic remainders, the flow's own remainders become parameters too.
    let flow = TmFlowSettings {
        max_params,
        deadline,
        ..s.flow.clone()
    };
    let mut leaf = empty_leaf(sys, b, None);
    // Per goal: proved so far over the instants and periods seen (Always, End), or
    // met at some instant (Eventually).
    let mut ok: Vec<bool> = vec![true; sys.goals.len()];
    let mut met: Vec<bool> = vec![false; sys.goals.len()];
    let mut refuted: Vec<bool> = vec![false; sys.goals.len()];
    let steps = sys.steps();
    let mut obs = vec![Tm::cst(0.0); sys.n_observed()];
    let mut u = vec![Tm::cst(0.0); sys.n_inputs()];
    // The plant's semantics from samara-system, as the simulator takes them: the resets
    // act on the initial set, then at the start of every period but at the horizon; the
    // set recorded and checked at an instant k >= 1 is the previous period's flow at its
    // end, before the resets.
    sys.initial_state(&mut x);
    for k in 0..=steps {
        let t = k as f64 * sys.period;
        let hull: Vec<Interval> = x.iter().map(|v| v.bound()).collect();
        leaf.instants.push(to_pairs(&hull));
        check_goals(sys, &x, &hull, t, t, &mut ok, &mut met, &mut refuted);
        if k == steps {
            leaf.end_measures = s
                .measures
                .iter()
                .map(|m| {
                    let r = m.over(&x, &hull);
                    [r.lo, r.hi]
                })
                .collect();
            break;
        }
        if hull
            .iter()
            .zip(&scale)
            .any(|(h, sc)| h.width().is_nan() || h.width() > EXPLODED * sc)
        {
            leaf.failure = Some(format!(
                "the enclosure grew past {EXPLODED} times the initial set's magnitude by t = {t}"
            ));
            break;
        }
        if undecidable(sys, &ok) {
            leaf.stopped_at = Some(t);
            break;
        }
        if past(deadline) {
            leaf.failure = Some(format!(
                "time budget spent before the period starting at t = {t}"
            ));
            break;
        }
        let hull = if sys.resets.is_empty() {
            hull
        } else {
            sys.begin_period(k, &mut x);
            x.iter().map(|v| v.bound()).collect()
        };
        // Room for this period's symbolic remainders (one per input at most).
        let crowded =
            max_params > 0 && x.iter().map(|v| v.n_vars()).max().unwrap_or(0) > max_params;
        if s.precondition && (crowded || needs_precondition(&x, &hull)) {
            if max_params > 0 {
                // Symbolic remainders: order reduction, leaving room for one period's
                // new parameters (one per network output).
                x = reduce(
                    &x,
                    max_params.saturating_sub(net.n_outputs()),
                    s.order as u32,
                );
            } else {
                x = precondition(&x, s.order as u32);
            }
        }
        sys.observe(&x, &mut obs);
        let mut y = network_over(net, &obs, s.order as u32);
        if max_params > 0 {
            let n = x.iter().map(|v| v.n_vars()).max().unwrap_or(0);
            y = lift_remainders(y, n, s.order as u32);
        }
        sys.actuate(&y, &mut u);
        match tm_period_parts(sys, &x, &u, sys.period, &flow) {
            Ok((next, parts)) => {
                let mut ph = parts
                    .first()
                    .map_or_else(|| hull.clone(), |p| p.bounds.clone());
                for part in &parts {
                    for (a, v) in ph.iter_mut().zip(&part.bounds) {
                        *a = Scalar::hull(a, v);
                    }
                }
                leaf.periods.push(to_pairs(&ph));
                // Each part on its own (they cover the period together): an
                // obstacle the flight passes diagonally misses the parts but not
                // their hull; a band is decided on the part's Taylor models too.
                let empty: Vec<Tm> = Vec::new();
                for part in &parts {
                    check_goals(
                        sys,
                        part.models.as_deref().unwrap_or(&empty),
                        &part.bounds,
                        t,
                        t + sys.period,
                        &mut ok,
                        &mut met,
                        &mut refuted,
                    );
                }
                x = next;
                if undecidable(sys, &ok) {
                    leaf.stopped_at = Some(t + sys.period);
                    break;
                }
            }
            Err(e) => {
                leaf.failure = Some(format!("{e} (period starting at t = {t})"));
                break;
            }
        }
    }
    for (gi, g) in sys.goals.iter().enumerate() {
        leaf.decided[gi] = if refuted[gi] {
            Some(false)
        } else if leaf.failure.is_some() {
            None
        } else {
            match g.when {
                When::Eventually(..) => met[gi].then_some(true),
                _ => ok[gi].then_some(true),
            }
        };
    }
    leaf
}

/// Update the per-goal state with the set over `[t1, t2]` (an instant when equal):
/// `x` the Taylor models at an instant (empty over a period: then only the hull).
#[allow(clippy::too_many_arguments)]
fn check_goals(
    sys: &System,
    x: &[Tm],
    hull: &[Interval],
    t1: f64,
    t2: f64,
    ok: &mut [bool],
    met: &mut [bool],
    refuted: &mut [bool],
) {
    let eps = 1e-9 * sys.horizon.max(1.0);
    for (gi, g) in sys.goals.iter().enumerate() {
        // Does [t1, t2] meet the goal's window?
        let (w1, w2) = match g.when {
            When::End => (sys.horizon, sys.horizon),
            When::Always(a, b) | When::Eventually(a, b) => (a, b),
        };
        if t2 < w1 - eps || t1 > w2 + eps {
            continue;
        }
        let instant = t1 == t2;
        // A period that meets the window only at one of its ends: that instant's set
        // is checked on its own (sharper than the period's hull), nothing else to check.
        if !instant && (t2 <= w1 + eps || t1 >= w2 - eps) {
            continue;
        }
        // An instant's set inside the window decides an "eventually" goal; a period's
        // hull only counts for "always" (it covers times inside and outside the window,
        // which is conservative for "always").
        let d = decide_on(g, x, hull);
        match g.when {
            When::End | When::Always(..) => {
                if d != Some(true) {
                    ok[gi] = false;
                }
                if d == Some(false) && instant {
                    refuted[gi] = true;
                }
            }
            When::Eventually(..) => {
                if instant && d == Some(true) {
                    met[gi] = true;
                }
            }
        }
    }
}

/// A goal on a set: by the Taylor models for an affine band (the dependence kept); a
/// band of any other expression by the expression evaluated on the Taylor models and on
/// the interval hull, whichever decides (both enclose it); boxes by the hull.
fn decide_on(g: &samara_system::Goal, x: &[Tm], hull: &[Interval]) -> Option<bool> {
    if let (
        GoalKind::Band {
            graph,
            lo,
            hi,
            linear: None,
            ..
        },
        false,
    ) = (&g.kind, x.is_empty())
    {
        let by_hull = g.decide(hull);
        if by_hull.is_some() {
            return by_hull;
        }
        let mut o = [Tm::cst(0.0)];
        graph.eval(x, &[], &mut o);
        return band_decision(o[0].bound(), *lo, *hi);
    }
    if let (
        GoalKind::Band {
            lo,
            hi,
            linear: Some((a, b)),
            ..
        },
        false,
    ) = (&g.kind, x.is_empty())
    {
        return band_decision(affine_on(a, *b, x).bound(), *lo, *hi);
    }
    g.decide(hull)
}

/// Whether the interval remainders of `x` are large enough, against the sets' own
/// widths (`hull`, the models' bounds), that turning them into parameters pays
/// ([`precondition`], [`reduce`], and inside a period the flow's own lifting).
pub(crate) fn needs_precondition(x: &[Tm], hull: &[Interval]) -> bool {
    remainders_past(x, hull, 0.05)
}

/// Whether some state's interval remainder is wider than `share` of its width.
pub(crate) fn remainders_past(x: &[Tm], hull: &[Interval], share: f64) -> bool {
    x.iter().zip(hull).any(|(v, b)| {
        let r = v.rem();
        let w = b.hi - b.lo;
        w > 0.0 && (r.hi - r.lo) > share * w
    })
}

/// Columns of `l` (`d x n`, taken in order of decreasing norm, then the unit vectors)
/// that are far from the span of the ones chosen before (Gram-Schmidt residual above
/// `1e-3` of the norm, so the chosen set is well conditioned): `(the chosen columns as
/// they are, their orthonormalised versions)`, each up to `d` of them.
fn independent_columns(l: &[Vec<f64>], d: usize) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let n = l.first().map_or(0, |r| r.len());
    let mut cols: Vec<Vec<f64>> = (0..n).map(|k| (0..d).map(|i| l[i][k]).collect()).collect();
    let norm = |v: &[f64]| v.iter().map(|a| a * a).sum::<f64>().sqrt();
    cols.sort_by(|a, b| norm(b).total_cmp(&norm(a)));
    cols.extend((0..d).map(|j| (0..d).map(|i| if i == j { 1.0 } else { 0.0 }).collect()));
    let mut raw: Vec<Vec<f64>> = Vec::with_capacity(d);
    let mut q: Vec<Vec<f64>> = Vec::with_capacity(d);
    for v0 in cols {
        if q.len() == d {
            break;
        }
        let n0 = norm(&v0);
        if !(n0.is_finite() && n0 > 0.0) {
            continue;
        }
        let mut v = v0.clone();
        for _ in 0..2 {
            for u in &q {
                let dot: f64 = u.iter().zip(&v).map(|(a, b)| a * b).sum();
                for (vi, ui) in v.iter_mut().zip(u) {
                    *vi -= dot * ui;
                }
            }
        }
        let n1 = norm(&v);
        if n1 > 1e-3 * n0 {
            q.push(v.iter().map(|a| a / n1).collect());
            raw.push(v0);
        }
    }
    (raw, q)
}

/// Inverse of the `d x d` matrix with columns `a` by Gauss-Jordan elimination with
/// partial pivoting, as rows; `None` when a pivot vanishes or an entry is not finite.
/// Only an approximation: [`reparameterise`] encloses the error `I - A B` it leaves.
fn inverse(a: &[Vec<f64>]) -> Option<Vec<Vec<f64>>> {
    let d = a.len();
    // m = [A | I], rows.
    let mut m: Vec<Vec<f64>> = (0..d)
        .map(|i| {
            let mut r: Vec<f64> = (0..d).map(|k| a[k][i]).collect();
            r.extend((0..d).map(|j| if i == j { 1.0 } else { 0.0 }));
            r
        })
        .collect();
    for col in 0..d {
        let piv = (col..d).max_by(|&x, &y| m[x][col].abs().total_cmp(&m[y][col].abs()))?;
        if m[piv][col] == 0.0 || !m[piv][col].is_finite() {
            return None;
        }
        m.swap(col, piv);
        let p = m[col][col];
        for v in m[col].iter_mut() {
            *v /= p;
        }
        let pivot_row = m[col].clone();
        for (r, row) in m.iter_mut().enumerate() {
            let f = row[col];
            if r != col && f != 0.0 {
                for (x, t) in row.iter_mut().zip(&pivot_row) {
                    *x -= f * t;
                }
            }
        }
    }
    let b: Vec<Vec<f64>> = m.into_iter().map(|r| r[d..].to_vec()).collect();
    b.iter()
        .all(|r| r.iter().all(|v| v.is_finite()))
        .then_some(b)
}

/// Order reduction of a set of Taylor models to at most `max_params` parameters, keeping
/// the higher-order dependence on the parameters that matter: the parameters are ranked
/// by the share of each state's width that depends on them (`Tm::param_weights` over the
/// state's width, summed over states, as Girard's reduction ranks a zonotope's
/// generators; Girard, HSCC 2005), the `max_params - d` heaviest kept and renumbered, every
/// monomial of a dropped one bounded into the remainder (`Tm::reparam`), and each state's
/// remainder then given a fresh parameter of its own (`d` of them): the dropped
/// dependence becomes an axis-aligned box, as a zonotope's reduced generators do. Unlike
/// [`precondition`], the kept parameters keep their nonlinear terms and nothing is
/// inverted.
pub fn reduce(x: &[Tm], max_params: usize, order: u32) -> Vec<Tm> {
    reduce_with(x, &[], max_params, order).0
}

/// [`reduce`] of the states `x` with the models `u` that share their parameters (the
/// held plant inputs inside a period): the parameters are ranked on `x` alone, and `u`
/// is renumbered by the same map (its dropped monomials bounded into its remainder, its
/// remainder left an interval), so the two stay consistent.
pub fn reduce_with(x: &[Tm], u: &[Tm], max_params: usize, order: u32) -> (Vec<Tm>, Vec<Tm>) {
    let d = x.len();
    let n = x.iter().chain(u).map(|v| v.n_vars()).max().unwrap_or(0);
    let keep = max_params.saturating_sub(d).min(n);
    let mut score = vec![0.0; n];
    for v in x {
        let w = v.bound().width();
        if !(w.is_finite() && w > 0.0) {
            continue;
        }
        for (k, pw) in v.param_weights().into_iter().enumerate() {
            score[k] += pw / w;
        }
    }
    // On mixed-degree models the weight-1 parameters (the initial set's) are always
    // kept, in place: they carry the nonlinear dependence, and a lifted parameter moved
    // into their places would be a waste of the weights.
    let full = x
        .iter()
        .chain(u)
        .filter_map(|v| v.full_params())
        .min()
        .unwrap_or(0)
        .min(n);
    let keep = keep.max(full);
    let mut rank: Vec<usize> = (full..n).collect();
    rank.sort_by(|&a, &b| score[b].total_cmp(&score[a]));
    let mut kept: Vec<usize> = (0..full)
        .chain(rank[..keep - full].iter().copied())
        .collect();
    kept.sort_unstable();
    let mut map: Vec<Option<usize>> = vec![None; n];
    for (j, &k) in kept.iter().enumerate() {
        map[k] = Some(j);
    }
    let total = keep + d;
    let xs = x
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let (p, r) = v.reparam(&map, total).split_rem();
            let (m, rad) = mid_rad(r);
            if rad > 0.0 {
                let xi = fresh_param(&p, keep + i, total, order);
                p + xi * rad + m
            } else {
                p + m
            }
        })
        .collect();
    let us = u.iter().map(|v| v.reparam(&map, total)).collect();
    (xs, us)
}

/// Re-parameterise a set of Taylor models as a parallelotope in fresh parameters
/// `zeta in [-1, 1]^d` (Lohner, *Einschliessung der Loesung gewoehnlicher Anfangs- und
/// Randwertaufgaben*, 1988; the preconditioning of Makino & Berz, *Int. J. Diff. Eq.
/// Appl.* 10, 2005, and 2009). Two frames are tried and the one whose new set has the
/// smaller hull (the sum of its widths, each relative to the old set's) is kept:
/// - the **parallelepiped** frame `A` = the linear part's own columns (the largest,
///   well-conditioned ones, completed by unit vectors): the linear part maps to the
///   identity, so a set whose higher-order terms and remainders are small keeps its
///   shape exactly and only those are wrapped;
/// - the **QR** frame `A = Q`, an orthonormal basis aligned with the linear part, which
///   stays well conditioned when the set is thin and the parallelepiped frame would
///   amplify the remainders by its condition number.
///
/// With `c` the constant coefficients and `B` an approximate inverse of `A`,
/// `y = B (x - c)` is bounded in Taylor-model arithmetic by boxes `m_k +- r_k`, and
/// `x = c + A y + (I - A B)(x - c)`; the new models are `c + A (m + r zeta)` with every
/// rounding of their f64 coefficients, and the term `(I - A B)(x - c)` (A B is the
/// identity only to rounding), enclosed by interval arithmetic in the remainders. The
/// remainders and higher-order terms become parameters, so the network and the dynamics
/// see them as directions they can map (and feedback can contract), at the price of the
/// higher-order dependence.
pub fn precondition(x: &[Tm], order: u32) -> Vec<Tm> {
    let d = x.len();
    let (c, l) = linear_parts(x);
    let (raw, q) = independent_columns(&l, d);
    if q.len() != d {
        return x.to_vec();
    }
    let hull: Vec<Interval> = x.iter().map(|v| v.bound()).collect();
    let size = |y: &[Tm]| -> f64 {
        y.iter()
            .zip(&hull)
            .map(|(v, h)| {
                let w = v.bound().width();
                let h = h.width();
                if h > 0.0 {
                    w / h
                } else {
                    w
                }
            })
            .sum()
    };
    let qr = reparameterise(x, &c, &q, &q, order);
    let pp = inverse(&raw).and_then(|b| reparameterise(x, &c, &raw, &b, order));
    match (qr, pp) {
        (Some(a), Some(b)) => {
            if size(&b) <= size(&a) {
                b
            } else {
                a
            }
        }
        (Some(a), None) | (None, Some(a)) => a,
        (None, None) => x.to_vec(),
    }
}

/// The set `x` written as `c + A (m + r zeta)` (see [`precondition`]): `a[k]` the `k`-th
/// column of `A`, `b[k]` the `k`-th row of an approximate inverse `B`. `None` when a
/// bound is not finite.
fn reparameterise(
    x: &[Tm],
    c: &[f64],
    a: &[Vec<f64>],
    b: &[Vec<f64>],
    order: u32,
) -> Option<Vec<Tm>> {
    let d = x.len();
    // Centred models and their boxes.
    let dx: Vec<Tm> = x.iter().zip(c).map(|(v, ci)| v.clone() - *ci).collect();
    let dbox: Vec<Interval> = dx.iter().map(|v| v.bound()).collect();
    if dbox.iter().any(|b| !(b.lo.is_finite() && b.hi.is_finite())) {
        return None;
    }
    // y_k = sum_i b[k][i] dx_i, bounded.
    let ys: Vec<(f64, Interval)> = b
        .iter()
        .map(|bk| {
            let mut acc = Tm::cst(0.0);
            for (bi, dxi) in bk.iter().zip(&dx) {
                if *bi != 0.0 {
                    acc += dxi.clone() * *bi;
                }
            }
            let (m, r) = mid_rad(acc.bound());
            (m, Interval::point(r))
        })
        .collect();
    if ys.iter().any(|(m, r)| !(m.is_finite() && r.hi.is_finite())) {
        return None;
    }
    let out: Vec<Tm> = (0..d)
        .map(|i| {
            // Exact x_i = c_i + sum_k A_ik y_k + e_i with e = (I - A B)(x - c).
            let mut e = Interval::point(0.0);
            for j in 0..d {
                let mut mij = Interval::point(if i == j { 1.0 } else { 0.0 });
                for (ak, bk) in a.iter().zip(b) {
                    mij -= Interval::point(ak[i]) * bk[j];
                }
                e += mij * dbox[j];
            }
            let mut cst = Interval::point(c[i]);
            let mut coef = Vec::with_capacity(d);
            let mut slack = Interval::point(0.0);
            for (k, ak) in a.iter().enumerate() {
                let (m, r) = ys[k];
                cst += Interval::point(ak[i]) * m;
                // (coefficient - mid) zeta_k with |zeta_k| <= 1.
                let (mid, dev) = mid_rad(r * ak[i]);
                coef.push(mid);
                slack += Interval::new(-dev, dev);
            }
            let (cm, cdev) = mid_rad(cst);
            let rem = e + slack + Interval::new(-cdev, cdev);
            Tm::affine(cm, &coef, order)
                .with_rem(Interval::new(rem.lo.next_down(), rem.hi.next_up()))
        })
        .collect();
    out.iter()
        .all(|v| {
            let b = v.bound();
            b.lo.is_finite() && b.hi.is_finite()
        })
        .then_some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A measure keeps the states' dependence (x - x is 0 on the Taylor models, [-2, 2]
    /// on the hull), and a model with a NaN (the whole line) leaves the hull's bound.
    #[test]
    fn measures_keep_dependence_and_survive_nan_models() {
        let m = Measure {
            name: "a - b".into(),
            coef: vec![1.0, -1.0],
            offset: 0.5,
        };
        let x = vec![Tm::var(0, 1, 2), Tm::var(0, 1, 2)];
        let hull = vec![Interval::new(-1.0, 1.0); 2];
        let r = m.over(&x, &hull);
        assert!(r.lo <= 0.5 && 0.5 <= r.hi && r.hi - r.lo < 1e-12, "{r:?}");
        assert_eq!(m.at(&[3.0, 1.0]), 2.5);
        let nan = vec![Tm::cst(f64::NAN), Tm::cst(0.0)];
        let r = m.over(&nan, &hull);
        assert!(r.lo <= -1.5 && r.hi >= 2.5, "{r:?}");
    }

    /// A lifted output (its remainder turned into a fresh parameter) still holds
    /// every value of the original model: at random parameter points, the original's
    /// enclosure `p(xi) + rem` (both ends) is reached by the lifted polynomial at the
    /// new parameter's ends, whose enclosures contain those values; the new parameters
    /// are numbered after the states' and the polynomial part is unchanged.
    #[test]
    fn lifted_remainders_keep_every_value() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut rnd = || rng.gen_range(-1.0..1.0);
        for _ in 0..200 {
            let n = 3;
            let x: Vec<Tm> = (0..n)
                .map(|k| Tm::var(k, n, 3) * (0.5 + rnd().abs()) + rnd())
                .collect();
            let y0 = (x[0].clone() * x[1].clone() + x[2].clone().sqr()) * rnd();
            let r = Interval::new(-rnd().abs() - 1e-3, rnd().abs());
            let y = vec![y0.clone().with_rem(r), Tm::var(0, n, 3)];
            let lifted = lift_remainders(y, n, 3);
            assert_eq!(lifted[0].n_vars(), n + 1);
            assert!(
                lifted[1].rem().width() < 1e-300,
                "rounding-size remainders stay"
            );
            let xi: Vec<f64> = (0..n).map(|_| rnd()).collect();
            let v = y0.eval_at(&xi);
            for (end, target) in [(-1.0, v.lo + r.lo), (1.0, v.hi + r.hi)] {
                let mut p = xi.clone();
                p.push(end);
                let w = lifted[0].eval_at(&p);
                // The ends of the original enclosure are met at the new parameter's
                // ends, up to rounding.
                let tol = 1e-12 * (1.0 + target.abs());
                if end < 0.0 {
                    assert!(w.lo <= target + tol, "{w:?} vs {target}");
                } else {
                    assert!(w.hi >= target - tol, "{w:?} vs {target}");
                }
            }
        }
    }

    /// A band of a non-affine expression is decided on the Taylor models where the
    /// interval hull cannot: on the diagonal set `x = y = xi`, `(x - y)^2 + x^2` ranges
    /// over `[0, 1]` while the hull gives `[0, 5]`; a band `<= 1.5` is proved, a band
    /// `>= 2` refuted, and the hull alone decides neither. Sampling the set agrees.
    #[test]
    fn nonlinear_bands_are_decided_on_the_taylor_models() {
        let src = |band: &str| {
            format!(
                "state x, y\ninput u\nx' = u\ny' = u\nperiod 1\nhorizon 1\n\
                 actuate u = net[0]\ninit x in [-1, 1]\ninit y in [-1, 1]\n\
                 goal band {band} always\n"
            )
        };
        let x = vec![Tm::var(0, 1, 4), Tm::var(0, 1, 4)];
        let hull = vec![Interval::new(-1.0, 1.0); 2];
        for (band, want) in [
            ("(x - y)^2 + x^2 <= 1.5", Some(true)),
            ("(x - y)^2 + x^2 >= 2", Some(false)),
        ] {
            let sys = System::parse(&src(band), "t.sys").unwrap();
            let g = &sys.goals[0];
            assert_eq!(g.decide(&hull), None, "{band}: the hull decides nothing");
            assert_eq!(decide_on(g, &x, &hull), want, "{band}");
            for k in 0..=100 {
                let v = -1.0 + 0.02 * k as f64;
                assert_eq!(g.holds(&[v, v]), want == Some(true), "{band} at {v}");
            }
        }
    }

    #[test]
    fn monomial_counts_are_binomials() {
        assert_eq!(monomials(4, 4), 70);
        assert_eq!(monomials(27, 4), 31_465);
        assert_eq!(monomials(24, 3), 2_925);
        assert_eq!(monomials(0, 5), 1);
        // Mixed degree: the classic count at weight 1; at order 3 with 6 full and 20
        // lifted parameters of weight 3, C(9, 3) + 20 = 104; of weight 2,
        // 84 + 20 * 7 = 224 (each lifted one alone or times one full one).
        assert_eq!(mixed_monomials(6, 20, 3, 1), monomials(26, 3));
        assert_eq!(mixed_monomials(6, 20, 3, 3), 104);
        assert_eq!(mixed_monomials(6, 20, 3, 2), 224);
        // Order 4, weight 2: 210 + 41 * 28 + C(42, 2) = 2,219.
        assert_eq!(mixed_monomials(6, 41, 4, 2), 2_219);
        assert_eq!(mixed_monomials(6, 0, 4, 2), 210);
    }

    /// `mid_rad` ends for intervals whose radius is tiny against their midpoint (it
    /// looped ~2^52 times on `[1, 1 + ulp]`), its range contains the interval under
    /// outward-rounded sums, and its radius stays within a few ulps of the half-width.
    #[test]
    fn mid_rad_contains_and_ends_on_narrow_intervals() {
        let mut cases = vec![
            Interval::new(1.0, 1.0f64.next_up()),
            Interval::new(1e300, 1e300f64.next_up()),
            Interval::new(-1e-300, 1e-300),
            Interval::new(-5e-324, 5e-324),
            Interval::new(-3.0, 7.5),
            Interval::new(0.1, 0.3),
            Interval::new(-1.0f64.next_down(), -1.0),
        ];
        let mut x = 0.7f64;
        for k in 0..2000 {
            x = (x * 3.9 * (1.0 - x)).clamp(1e-9, 1.0 - 1e-9);
            let lo = (x - 0.5) * 10f64.powi(k % 20 - 10);
            let ulps = 1 + (k % 7) as u32;
            let mut hi = lo;
            for _ in 0..ulps {
                hi = hi.next_up();
            }
            cases.push(Interval::new(lo, hi));
        }
        for i in cases {
            let (m, r) = mid_rad(i);
            let (pm, pr) = (Interval::point(m), Interval::point(r));
            assert!(
                (pm - pr).hi <= i.lo && (pm + pr).lo >= i.hi,
                "{i:?}: {m} {r}"
            );
            let half = 0.5 * (i.hi - i.lo);
            let slack = 8.0 * f64::EPSILON * (m.abs() + half) + 1e-320;
            assert!(r <= half * (1.0 + 1e-12) + slack, "{i:?}: radius {r}");
        }
    }
}

//! Sound reachable sets of the network-controlled Alsomitra glider.
//!
//! The closed loop is the same as in simulation (`samara-sim`): at each control instant
//! the network reads the state, its (clipped) output is held for one period while the
//! plant flies. Here both halves run on sets:
//! - [`netstep`]: the controller output over a zonotope, kept affine in the zonotope's
//!   generators (CROWN over the zonotope);
//! - [`flow`]: validated Taylor integration of the plant (Lohner-style, on zonotopes,
//!   with the plant's own equations run on Taylor series of intervals);
//! - this module: the initial set as a box of parameters, split adaptively (mid-flight,
//!   along the parameter the control is most sensitive to) when the network enclosure
//!   is loose or the remainder grows, sub-problems in parallel with `rayon`, goals
//!   checked on the final sets, and falsification by simulation first.
//!
//! Verdicts: `Proved` only when every sub-box's enclosure satisfies the goal; `Violated`
//! only with a concrete simulated trajectory; `Unknown` with the reason otherwise.

pub mod flow;
pub mod netstep;
pub mod zonotope;

use flow::{flow_period, FlowSettings};
use netstep::SetController;
use rayon::prelude::*;
use samara_nn::Network;
use samara_num::{Interval, Scalar};
use samara_plant::{Model, Plant};
use samara_report::{Curve, TrajectoryFigure};
use samara_sim::{fly, Integrator, LoopSettings, NetworkController};
use serde::Serialize;
use std::time::Instant;
pub use zonotope::Zonotope;

/// Errors of bad input (verdicts are values, see [`Verdict`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReachError {
    /// The network does not read the six raw states or does not give one output.
    #[error("the network has {inputs} inputs and {outputs} outputs; the closed loop needs 6 inputs (v_xp, v_yp, omega, theta, x, y in raw units) and 1 output (ex): pass a raw-unit controller such as *_denorm.onnx")]
    NetworkShape {
        /// Inputs found.
        inputs: usize,
        /// Outputs found.
        outputs: usize,
    },
    /// An initial interval is empty, inverted or not finite.
    #[error("initial interval for {name} is [{lo}, {hi}]: give A:B with finite A <= B")]
    BadInterval {
        /// State name.
        name: String,
        /// Lower end.
        lo: f64,
        /// Upper end.
        hi: f64,
    },
    /// The initial box has the wrong number of states.
    #[error("the {model} model has {expected} states; the initial set gives {found}")]
    InitDim {
        /// Model name.
        model: &'static str,
        /// Expected.
        expected: usize,
        /// Found.
        found: usize,
    },
    /// Horizon and period do not fit.
    #[error("horizon {horizon} is not a positive multiple of the period {period}: choose e.g. --horizon 20 --period 0.5")]
    Horizon {
        /// Horizon.
        horizon: f64,
        /// Period.
        period: f64,
    },
    /// A goal bound that is not a positive finite number, or a start time outside the flight.
    #[error("goal: {0}")]
    Goal(String),
}

/// The goal `|x + y| <= ystar` at `t = T`, or for all `t` in `[from, T]`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Goal {
    /// Half-width of the band around the line `y = -x`.
    pub ystar: f64,
    /// Start of the time window (`None`: only at the horizon).
    pub from: Option<f64>,
}

/// Settings of a reachability run. Defaults: the published CORA setting (reduced model,
/// `y0 ∈ [1.4286, 4.2857]`, horizon 20, period 0.5) with the clip of the simulation.
#[derive(Clone, Debug)]
pub struct ReachSettings {
    /// Model variant.
    pub model: Model,
    /// Initial box, one interval per state (`Model::dim` entries).
    pub init: Vec<(f64, f64)>,
    /// Control period (0.5).
    pub period: f64,
    /// Horizon (20).
    pub horizon: f64,
    /// Output clip of the controller (`Some((0.181, 0.193))`; `None` as in CORA).
    pub clip: Option<(f64, f64)>,
    /// Restart the filter state E at 0 every period, as the simulation (true).
    pub reset_filter: bool,
    /// Goal to decide, if any.
    pub goal: Option<Goal>,
    /// Sub-boxes to start from, along the widest parameter; 0 (the default) picks one per
    /// `auto_piece` of its width, rounded up to a power of two and capped by `max_leaves`
    /// (64 on the published interval, whose CORA runs used 8-16 pieces cut by hand).
    pub initial_splits: usize,
    /// Width per initial sub-box when `initial_splits` is 0 (0.05).
    pub auto_piece: f64,
    /// Largest number of sub-boxes (64); sub-boxes that lost their enclosure may use a
    /// quarter more.
    pub max_leaves: usize,
    /// Split a sub-box when the noise part of its `x + y` enclosure exceeds this (0.01).
    pub max_noise: f64,
    /// Sub-boxes narrower than this fraction of the initial width are not split (1e-4).
    pub min_fraction: f64,
    /// Simulated trajectories for falsification and the figure (200).
    pub samples: usize,
    /// Seed of the sampling.
    pub seed: u64,
    /// Keep every sub-box's zonotope at every control instant (tests; memory).
    pub keep_sets: bool,
    /// Validated integrator settings.
    pub flow: FlowSettings,
}

impl ReachSettings {
    /// The published setting for `model`: `y0 ∈ [1.4286, 4.2857]`, start `(1,0,0,0,0,y0)`.
    pub fn published(model: Model) -> Self {
        let mut init = vec![(1.0, 1.0), (0.0, 0.0), (0.0, 0.0), (0.0, 0.0), (0.0, 0.0)];
        init.push((0.1 / 0.07, 0.3 / 0.07));
        if model.has_filter() {
            init.push((0.0, 0.0));
        }
        ReachSettings {
            model,
            init,
            period: 0.5,
            horizon: 20.0,
            clip: Some(samara_plant::EX_RANGE),
            reset_filter: true,
            goal: None,
            initial_splits: 0,
            auto_piece: 0.05,
            max_leaves: 64,
            max_noise: 0.01,
            min_fraction: 1e-4,
            samples: 200,
            seed: 1,
            keep_sets: false,
            flow: FlowSettings::default(),
        }
    }

    fn steps(&self) -> Result<usize, ReachError> {
        let err = ReachError::Horizon {
            horizon: self.horizon,
            period: self.period,
        };
        if !(self.period > 0.0 && self.horizon > 0.0 && self.period.is_finite()) {
            return Err(err);
        }
        let k = self.horizon / self.period;
        if (k - k.round()).abs() > 1e-9 * k.max(1.0) || k.round() < 1.0 {
            return Err(err);
        }
        Ok(k.round() as usize)
    }

    /// Check the settings against the model and network.
    pub fn validate(&self, net: &Network) -> Result<usize, ReachError> {
        if net.n_inputs() != 6 || net.n_outputs() != 1 {
            return Err(ReachError::NetworkShape {
                inputs: net.n_inputs(),
                outputs: net.n_outputs(),
            });
        }
        if self.init.len() != self.model.dim() {
            return Err(ReachError::InitDim {
                model: self.model.name(),
                expected: self.model.dim(),
                found: self.init.len(),
            });
        }
        for (i, &(lo, hi)) in self.init.iter().enumerate() {
            if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
                return Err(ReachError::BadInterval {
                    name: samara_plant::STATE_NAMES[i].into(),
                    lo,
                    hi,
                });
            }
        }
        if let Some(g) = &self.goal {
            if !(g.ystar.is_finite() && g.ystar >= 0.0) {
                return Err(ReachError::Goal(format!(
                    "ystar {} must be a finite number >= 0",
                    g.ystar
                )));
            }
            if let Some(f) = g.from {
                if !(f >= 0.0 && f <= self.horizon) {
                    return Err(ReachError::Goal(format!(
                        "--goal-from {f} must lie in [0, horizon = {}]",
                        self.horizon
                    )));
                }
            }
        }
        self.steps()
    }
}

/// The verdict on the goal.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "verdict", rename_all = "lowercase")]
pub enum Verdict {
    /// Every trajectory from the initial set meets the goal (sound enclosure).
    Proved,
    /// A simulated trajectory misses the goal.
    Violated {
        /// Its initial state.
        initial: Vec<f64>,
        /// Time of the violation.
        t: f64,
        /// Its `x + y` there.
        x_plus_y: f64,
    },
    /// Not settled.
    Unknown {
        /// Why.
        reason: String,
    },
    /// No goal was given.
    #[serde(rename = "none")]
    NoGoal,
}

impl Verdict {
    /// `proved`, `violated`, `unknown` or `none`.
    pub fn name(&self) -> &'static str {
        match self {
            Verdict::Proved => "proved",
            Verdict::Violated { .. } => "violated",
            Verdict::Unknown { .. } => "unknown",
            Verdict::NoGoal => "none",
        }
    }
}

/// The enclosure of one sub-box at one control instant.
#[derive(Clone, Debug, Serialize)]
pub struct StepSet {
    /// Time.
    pub t: f64,
    /// Interval hull of the six physical states (v_xp, v_yp, omega, theta, x, y).
    pub bbox: Vec<[f64; 2]>,
    /// Enclosure of `x + y` at `t`.
    pub x_plus_y: [f64; 2],
    /// Enclosure of `x + y` over the period ending at `t` (at `t = 0`: the start).
    pub x_plus_y_period: [f64; 2],
    /// Control held over the period starting at `t` (absent at the horizon).
    pub ex: Option<[f64; 2]>,
    /// The zonotope (only with `keep_sets`).
    #[serde(skip)]
    pub set: Option<Zonotope>,
}

/// A sub-box of the initial set and its enclosures.
#[derive(Clone, Debug, Serialize)]
pub struct Leaf {
    /// The sub-box, one interval per state.
    pub init: Vec<[f64; 2]>,
    /// Indices of the states that are parameters (the first generators, in order).
    pub params: Vec<usize>,
    /// One record per control instant reached (all of them unless `failure`).
    pub steps: Vec<StepSet>,
    /// Why the enclosure stopped early, if it did.
    pub failure: Option<String>,
    /// Validated steps taken (Taylor, fallback).
    pub flow_steps: (usize, usize),
    /// Largest deviation of the network enclosure over the flight.
    pub max_dev: f64,
    #[serde(skip)]
    z: Zonotope,
    #[serde(skip)]
    h: f64,
}

/// A simulated trajectory: control instants only.
#[derive(Clone, Debug, Serialize)]
pub struct Sample {
    /// Initial state.
    pub initial: Vec<f64>,
    /// States at t = 0, period, 2 period, ...
    pub states: Vec<Vec<f64>>,
    /// Dense (x, y) points for figures.
    pub xy: Vec<(f64, f64)>,
    /// Dense (t, x + y).
    pub txy: Vec<(f64, f64)>,
}

/// The result of a run.
#[derive(Clone, Debug, Serialize)]
pub struct ReachResult {
    /// The verdict on the goal.
    pub verdict: Verdict,
    /// Enclosure of `x + y` at the horizon (hull over sub-boxes).
    pub final_x_plus_y: [f64; 2],
    /// Range of `x + y` at the horizon over the simulated samples.
    pub sampled_x_plus_y: [f64; 2],
    /// Sub-boxes.
    pub leaves: Vec<Leaf>,
    /// Wall time in seconds.
    pub seconds: f64,
    /// Simulated trajectories (falsification and figures).
    #[serde(skip)]
    pub samples: Vec<Sample>,
}

impl ReachResult {
    /// Number of sub-problems (sub-boxes) in the final partition.
    pub fn subproblems(&self) -> usize {
        self.leaves.len()
    }

    /// Width ratio of the enclosure of `x + y` at the horizon to the sampled range.
    pub fn width_ratio(&self) -> f64 {
        (self.final_x_plus_y[1] - self.final_x_plus_y[0])
            / (self.sampled_x_plus_y[1] - self.sampled_x_plus_y[0])
    }
}

fn iv(x: Interval) -> [f64; 2] {
    [x.lo, x.hi]
}

fn initial_leaf(init_all: &[(f64, f64)]) -> Leaf {
    // The sets hold the six physical states (E never acts on them).
    let init = &init_all[..6];
    let params: Vec<usize> = (0..init.len()).filter(|&i| init[i].1 > init[i].0).collect();
    let c: Vec<f64> = init.iter().map(|(a, b)| 0.5 * (a + b)).collect();
    let mut gens = Vec::new();
    let mut err = vec![0.0; init.len()];
    for &p in &params {
        let mut g = vec![0.0; init.len()];
        g[p] = 0.5 * (init[p].1 - init[p].0);
        // c +- g covers [a, b] up to rounding; cover that with a tiny box.
        err[p] = ((init[p].0.abs() + init[p].1.abs()) * f64::EPSILON).next_up();
        gens.push(g);
    }
    let mut z = Zonotope {
        c,
        gens,
        n_param: params.len(),
    };
    z.add_box(&err);
    Leaf {
        init: init_all.iter().map(|&(a, b)| [a, b]).collect(),
        params,
        steps: Vec::new(),
        failure: None,
        flow_steps: (0, 0),
        max_dev: 0.0,
        z,
        h: f64::INFINITY,
    }
}

/// Split a leaf (current zonotope included) along parameter `j` (index into `params`).
fn split_leaf(l: &Leaf, j: usize) -> (Leaf, Leaf) {
    let (za, zb) = l.z.split(j);
    let p = l.params[j];
    let mid = 0.5 * (l.init[p][0] + l.init[p][1]);
    let mut a = l.clone();
    let mut b = l.clone();
    a.init[p][1] = mid;
    b.init[p][0] = mid;
    a.z = za;
    b.z = zb;
    (a, b)
}

struct Ctx<'a> {
    plant: &'a Plant,
    ctrl: SetController,
    s: &'a ReachSettings,
    min_width: Vec<f64>,
}

impl Ctx<'_> {
    fn can_split(&self, l: &Leaf, j: usize) -> bool {
        let p = l.params[j];
        l.init[p][1] - l.init[p][0] > 2.0 * self.min_width[p]
    }

    /// The parameter along which the flown sub-box `l` is most worth splitting.
    fn split_dir(&self, l: &Leaf) -> Option<usize> {
        (0..l.params.len())
            .filter(|&j| self.can_split(l, j))
            .max_by(|&a, &b| {
                // A sub-box that lost its enclosure splits along the parameter that
                // moves the dynamics' states (v_xp, v_yp, omega, theta) most; otherwise
                // along the one that moves x + y most.
                let w = |j: usize| match l.failure {
                    Some(_) => l.z.gens[j][..4].iter().map(|v| v.abs()).sum::<f64>(),
                    None => (l.z.gens[j][4] + l.z.gens[j][5]).abs(),
                };
                w(a).total_cmp(&w(b))
            })
    }

    /// Advance `l` by one period from instant `k` (a failure is recorded in the leaf).
    fn advance(&self, l: &mut Leaf, k: usize) {
        let t = k as f64 * self.s.period;
        let u = self.ctrl.over(&l.z);
        l.max_dev = l.max_dev.max(u.dev);
        // The control held over the period starting at t.
        let spread = u.coef.iter().map(|c| c.abs()).sum::<f64>();
        let ex = Some([
            (u.cst - u.dev - spread).max(u.range.lo),
            (u.cst + u.dev + spread).min(u.range.hi),
        ]);
        match l.steps.last_mut() {
            // The record at t was made at the end of the previous period.
            Some(last) if k > 0 => last.ex = ex,
            _ => {
                let xy = iv(l.z.x_plus_y());
                l.steps.push(StepSet {
                    t,
                    bbox: l.z.bbox().iter().map(|x| iv(*x)).collect(),
                    x_plus_y: xy,
                    x_plus_y_period: xy,
                    ex,
                    set: self.s.keep_sets.then(|| l.z.clone()),
                });
            }
        }
        // Augment with the control row.
        let d = l.z.dim();
        let mut za = Zonotope {
            c: l.z.c.clone(),
            gens: Vec::with_capacity(l.z.gens.len() + 1),
            n_param: l.z.n_param,
        };
        za.c.push(u.cst);
        for (g, a) in l.z.gens.iter().zip(&u.coef) {
            let mut ng = g.clone();
            ng.push(*a);
            za.gens.push(ng);
        }
        let mut dg = vec![0.0; d + 1];
        dg[d] = u.dev;
        za.gens.push(dg);
        match flow_period(self.plant, &za, self.s.period, &self.s.flow, &mut l.h) {
            Ok((nz, xyp, st)) => {
                l.flow_steps.0 += st.taylor_steps;
                l.flow_steps.1 += st.fallback_steps;
                let mut z = Zonotope {
                    c: nz.c[..d].to_vec(),
                    gens: nz.gens.iter().map(|g| g[..d].to_vec()).collect(),
                    n_param: nz.n_param,
                };
                // Drop noise generators that only acted on the control row.
                let np = z.n_param;
                let mut idx = 0;
                z.gens.retain(|g| {
                    idx += 1;
                    idx <= np || g.iter().any(|v| *v != 0.0)
                });
                let bb = z.bbox();
                let xy = z.x_plus_y();
                l.steps.push(StepSet {
                    t: (k + 1) as f64 * self.s.period,
                    bbox: bb.iter().map(|x| iv(*x)).collect(),
                    x_plus_y: iv(xy),
                    x_plus_y_period: iv(xyp.hull(&xy)),
                    ex: None,
                    set: self.s.keep_sets.then(|| z.clone()),
                });
                l.z = z;
            }
            Err(flow::FlowFailure::NoEnclosure { t: tf }) => {
                l.failure = Some(format!(
                    "no validated enclosure at t = {:.4} (set too wide or the flow leaves the model's domain)",
                    t + tf
                ));
            }
        }
    }

    /// Whether a flown sub-box is worth splitting: it failed, its final `x + y` carries
    /// more than `tol_noise` of noise, or the goal is undecided on it.
    fn needs_refinement(&self, l: &Leaf, tol_noise: f64) -> bool {
        if l.failure.is_some() {
            return true;
        }
        let nr = l.z.noise_radius();
        if nr[4] + nr[5] > tol_noise {
            return true;
        }
        match &self.s.goal {
            Some(g) => leaf_goal(l, g, self.s).is_none(),
            None => false,
        }
    }

    /// Fly one sub-box over the whole horizon.
    fn run(&self, mut l: Leaf, steps: usize) -> Leaf {
        for k in 0..steps {
            self.advance(&mut l, k);
            if l.failure.is_some() {
                break;
            }
        }
        l
    }
}

/// The goal on one sub-box: `Some(true)` every enclosure inside the band, `Some(false)`
/// some enclosure entirely outside it, `None` undecided.
fn leaf_goal(l: &Leaf, g: &Goal, s: &ReachSettings) -> Option<bool> {
    let mut all_in = true;
    for st in &l.steps {
        let r = match g.from {
            None if st.t >= s.horizon - 1e-9 => st.x_plus_y,
            None => continue,
            Some(f) if st.t >= f + s.period - 1e-9 => st.x_plus_y_period,
            Some(f) if st.t >= f - 1e-9 => st.x_plus_y,
            Some(_) => continue,
        };
        if r[0] > g.ystar || r[1] < -g.ystar {
            return Some(false);
        }
        if !(-g.ystar <= r[0] && r[1] <= g.ystar) {
            all_in = false;
        }
    }
    if l.failure.is_some() {
        return None;
    }
    if all_in {
        Some(true)
    } else {
        None
    }
}

/// Simulate `n` trajectories from the initial box (end points of every parameter
/// first, then uniform random points) with the tight integrator.
pub fn simulate_samples(plant: &Plant, net: &Network, s: &ReachSettings, n: usize) -> Vec<Sample> {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(s.seed);
    let params: Vec<usize> = (0..s.init.len())
        .filter(|&i| s.init[i].1 > s.init[i].0)
        .collect();
    let mut starts: Vec<Vec<f64>> = Vec::new();
    for corner in 0..(1usize << params.len().min(6)).min(n) {
        starts.push(
            (0..s.init.len())
                .map(|i| match params.iter().position(|&p| p == i) {
                    Some(j) => {
                        if corner >> j & 1 == 1 {
                            s.init[i].1
                        } else {
                            s.init[i].0
                        }
                    }
                    None => s.init[i].0,
                })
                .collect(),
        );
    }
    while starts.len() < n {
        starts.push(
            s.init
                .iter()
                .map(|&(a, b)| if b > a { rng.gen_range(a..=b) } else { a })
                .collect(),
        );
    }
    let ls = LoopSettings {
        period: s.period,
        horizon: s.horizon,
        integrator: Integrator::from_name("tight").expect("tight integrator"),
        reset_filter: s.reset_filter,
        output_step: Some(0.05),
    };
    starts
        .par_iter()
        .filter_map(|x0| {
            let mut c = NetworkController::new(net.clone(), s.clip, "net");
            let f = fly(plant, &mut c, x0, &ls).ok()?;
            let mut states = vec![x0.clone()];
            states.extend(f.steps.iter().map(|r| r.state_end.clone()));
            let xy = f.dense.iter().map(|(_, st, _)| (st[4], st[5])).collect();
            let txy = f
                .dense
                .iter()
                .map(|(t, st, _)| (t, st[4] + st[5]))
                .collect();
            Some(Sample {
                initial: x0.clone(),
                states,
                xy,
                txy,
            })
        })
        .collect()
}

/// Compute the reachable sets of the closed loop `plant` + `net` from `s.init`, and
/// decide `s.goal`.
pub fn reach(net: &Network, s: &ReachSettings) -> Result<ReachResult, ReachError> {
    let t0 = Instant::now();
    let steps = s.validate(net)?;
    let plant = Plant::new(s.model);
    // Falsification first: it is cheap and gives the figure its trajectories.
    let samples = simulate_samples(&plant, net, s, s.samples);
    let mut violation: Option<Verdict> = None;
    if let Some(g) = &s.goal {
        for smp in &samples {
            let bad = match g.from {
                None => {
                    let x = smp.states.last().expect("states");
                    ((x[4] + x[5]).abs() > g.ystar).then_some((s.horizon, x[4] + x[5]))
                }
                Some(f) => smp
                    .txy
                    .iter()
                    .find(|(t, v)| *t >= f - 1e-12 && v.abs() > g.ystar)
                    .map(|&(t, v)| (t, v)),
            };
            if let Some((t, v)) = bad {
                violation = Some(Verdict::Violated {
                    initial: smp.initial.clone(),
                    t,
                    x_plus_y: v,
                });
                break;
            }
        }
    }
    let ctx = Ctx {
        plant: &plant,
        ctrl: SetController::new(net, s.clip),
        s,
        min_width: s
            .init
            .iter()
            .map(|(a, b)| (b - a) * s.min_fraction)
            .collect(),
    };
    // Initial partition along the widest parameter.
    let root = initial_leaf(&s.init);
    let mut leaves = vec![root];
    let pieces = if s.initial_splits > 0 {
        s.initial_splits
    } else {
        let w = s.init[..6]
            .iter()
            .map(|(a, b)| b - a)
            .fold(0.0f64, f64::max);
        // Leave room in the budget for one split of every other parameter.
        let others = s.init[..6]
            .iter()
            .filter(|(a, b)| b > a)
            .count()
            .saturating_sub(1);
        ((w / s.auto_piece).ceil().max(1.0) as usize)
            .next_power_of_two()
            .min((s.max_leaves >> others.min(20)).max(1))
    };
    for _ in 0..pieces.max(1).ilog2() {
        leaves = leaves
            .into_iter()
            .flat_map(|l| {
                let j = (0..l.params.len()).max_by(|&a, &b| {
                    let w = |j: usize| l.init[l.params[j]][1] - l.init[l.params[j]][0];
                    w(a).total_cmp(&w(b))
                });
                match j {
                    Some(j) => {
                        let (a, b) = split_leaf(&l, j);
                        vec![a, b]
                    }
                    None => vec![l],
                }
            })
            .collect();
    }
    let sampled_width = samples
        .iter()
        .map(|smp| {
            let x = smp.states.last().expect("states");
            x[4] + x[5]
        })
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
            (a.min(v), b.max(v))
        });
    let sampled_width = (sampled_width.1 - sampled_width.0).max(0.0);
    // Noise allowed in a sub-box's final x + y: a tenth of the sampled spread, capped.
    let tol_noise = s.max_noise.min(0.1 * sampled_width).max(1e-6);
    let mut done: Vec<Leaf> = Vec::new();
    let mut pending = leaves;
    while !pending.is_empty() {
        let results: Vec<Leaf> = pending.into_par_iter().map(|l| ctx.run(l, steps)).collect();
        pending = Vec::new();
        let mut total = done.len() + results.len();
        for l in results {
            let want = ctx.needs_refinement(&l, tol_noise);
            match ctx.split_dir(&l) {
                // A sub-box that lost its enclosure may still be split when the budget
                // is spent, up to a quarter more: better a few more sub-boxes than an
                // unknown.
                Some(j)
                    if want
                        && (total < s.max_leaves
                            || l.failure.is_some() && total < s.max_leaves + s.max_leaves / 4) =>
                {
                    let mut init: Vec<(f64, f64)> = l.init.iter().map(|r| (r[0], r[1])).collect();
                    let p = l.params[j];
                    let mid = 0.5 * (init[p].0 + init[p].1);
                    let mut a = init.clone();
                    a[p].1 = mid;
                    init[p].0 = mid;
                    pending.push(initial_leaf(&a));
                    pending.push(initial_leaf(&init));
                    total += 1;
                }
                _ => done.push(l),
            }
        }
    }
    let any_failed = done.iter().any(|l| l.failure.is_some());
    done.sort_by(|a, b| {
        a.init
            .iter()
            .map(|x| x[0])
            .collect::<Vec<_>>()
            .partial_cmp(&b.init.iter().map(|x| x[0]).collect::<Vec<_>>())
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    let mut fin = Interval {
        lo: f64::INFINITY,
        hi: f64::NEG_INFINITY,
    };
    for l in &done {
        if l.failure.is_none() {
            let r = l.steps.last().expect("final record").x_plus_y;
            fin = fin.hull(&Interval { lo: r[0], hi: r[1] });
        }
    }
    if any_failed {
        fin = Interval::entire();
    }
    let sampled = samples.iter().fold(
        Interval {
            lo: f64::INFINITY,
            hi: f64::NEG_INFINITY,
        },
        |acc, smp| {
            let x = smp.states.last().expect("states");
            acc.hull(&Interval::point(x[4] + x[5]))
        },
    );
    let verdict = match (&s.goal, violation) {
        (None, _) => Verdict::NoGoal,
        (Some(_), Some(v)) => v,
        (Some(g), None) => {
            if any_failed {
                let why = done
                    .iter()
                    .find_map(|l| l.failure.clone())
                    .unwrap_or_default();
                Verdict::Unknown { reason: why }
            } else {
                let ok = done.iter().all(|l| leaf_goal(l, g, s) == Some(true));
                if ok {
                    Verdict::Proved
                } else {
                    Verdict::Unknown {
                        reason: format!(
                            "the enclosure of x + y ({:.4}, {:.4}) is not inside the goal band and no simulated trajectory violates it; refine with more sub-boxes (--max-leaves) or smaller thresholds",
                            fin.lo, fin.hi
                        ),
                    }
                }
            }
        }
    };
    Ok(ReachResult {
        verdict,
        final_x_plus_y: iv(fin),
        sampled_x_plus_y: iv(sampled),
        leaves: done,
        seconds: t0.elapsed().as_secs_f64(),
        samples,
    })
}

/// Whether the result's enclosures contain a simulated trajectory at every control
/// instant: the trajectory's initial state selects the sub-box, and the state must lie
/// in that sub-box's zonotope (parameters exact, noise as a box; needs `keep_sets`) or
/// its box, with tolerance `tol` for the simulation's own error. Returns the first
/// instant where containment fails.
pub fn check_containment(res: &ReachResult, smp: &Sample, tol: f64) -> Result<(), String> {
    let leaf = res
        .leaves
        .iter()
        .find(|l| {
            l.init
                .iter()
                .zip(&smp.initial)
                .all(|(r, x)| r[0] <= *x && *x <= r[1])
        })
        .ok_or("no sub-box contains the initial state")?;
    for (k, st) in leaf.steps.iter().enumerate() {
        let x = &smp.states[k];
        for (i, b) in st.bbox.iter().enumerate() {
            if !(b[0] - tol <= x[i] && x[i] <= b[1] + tol) {
                return Err(format!(
                    "t = {}: state {} = {} outside [{}, {}]",
                    st.t, i, x[i], b[0], b[1]
                ));
            }
        }
        if let Some(z) = &st.set {
            let xi: Vec<f64> = leaf
                .params
                .iter()
                .map(|&p| {
                    let (a, b) = (leaf.init[p][0], leaf.init[p][1]);
                    (smp.initial[p] - 0.5 * (a + b)) / (0.5 * (b - a))
                })
                .collect();
            if !z.contains_with_params(x, &xi, tol) {
                return Err(format!("t = {}: state outside the zonotope", st.t));
            }
        }
    }
    Ok(())
}

/// Largest number of boxes drawn in a figure; beyond it neighbouring sub-boxes are
/// merged (interval hull, still an over-approximation).
const MAX_FIGURE_BOXES: usize = 20_000;

/// Sampled trajectories drawn on top of the sets.
const MAX_FIGURE_SAMPLES: usize = 24;

/// The x-y boxes of every sub-box at every control instant, merged across neighbouring
/// sub-boxes (sorted by their initial box) if there are too many to draw.
fn figure_boxes(res: &ReachResult) -> Vec<(f64, f64, f64, f64)> {
    let total: usize = res.leaves.iter().map(|l| l.steps.len()).sum();
    let group = total.div_ceil(MAX_FIGURE_BOXES).max(1);
    let mut out = Vec::new();
    for chunk in res.leaves.chunks(group) {
        let steps = chunk.iter().map(|l| l.steps.len()).max().unwrap_or(0);
        for k in 0..steps {
            let mut b = (
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
            );
            for l in chunk {
                if let Some(st) = l.steps.get(k) {
                    let (x, y) = (st.bbox[4], st.bbox[5]);
                    b = (b.0.min(x[0]), b.1.max(x[1]), b.2.min(y[0]), b.3.max(y[1]));
                }
            }
            if b.0.is_finite() && b.1.is_finite() && b.2.is_finite() && b.3.is_finite() {
                out.push(b);
            }
        }
    }
    out
}

/// The x-y figure of a run: every sub-box's set at every control instant (as boxes),
/// the target line, the goal band `|x + y| <= band` and a few sampled trajectories on
/// top, equal axes (the layout of the published reachability figure).
pub fn figure(res: &ReachResult, title: &str, band: Option<f64>) -> TrajectoryFigure {
    // A few trajectories only (the extremes come first in the samples, then random
    // starts), so the sets under them stay visible.
    let n = res.samples.len();
    let step = n.div_ceil(MAX_FIGURE_SAMPLES).max(1);
    let curves: Vec<Curve> = res
        .samples
        .iter()
        .enumerate()
        .filter(|(i, _)| *i < 2 || i % step == 0)
        .take(MAX_FIGURE_SAMPLES)
        .map(|(_, smp)| Curve {
            label: format!("y0 = {:.4}", smp.initial[5]),
            points: smp.xy.clone(),
        })
        .collect();
    let shown = curves.len();
    let mut fig = TrajectoryFigure::new(
        format!(
            "{title}: {} ({} sub-boxes; sets at control instants)",
            res.verdict.name(),
            res.subproblems()
        ),
        curves,
    );
    fig.boxes = figure_boxes(res);
    fig.band = band;
    fig.legend = false;
    fig.group_label = Some(format!("sampled trajectories ({shown} of {n})"));
    fig
}

//! Closed-loop training with counterexample-guided rounds (issue 18 item 2,
//! `samara train --method closed-loop`).
//!
//! 1. The network is first trained on the PID data alone ([`crate::train`](mod@crate::train), the plain
//!    method, restarts included), so every round starts from a controller that imitates
//!    the PID.
//! 2. Each round takes `steps_per_round` full-batch Adam steps on
//!    `data_weight * MSE(data) + mean over the starts of the closed-loop penalty`
//!    ([`ClosedLoopLoss`]: |x + y| above the training bound at T, or over a window),
//!    differentiated through the sample-and-hold loop, warm-started from the previous
//!    round's weights and optimiser state. A round stops early once the penalty is 0 on
//!    every start.
//! 3. The network in raw units (normalisation layers in the IR) goes to
//!    [`samara_reach::reach`] with the small sub-box budget. `proved` ends the rounds;
//!    otherwise the start of a violating simulated trajectory and the midpoints of every
//!    refuted or undecided sub-box join the flight set, and the next round retrains.
//!    A round whose small-budget verdict is `unknown` without a violation, and the last
//!    round, try the full budget too before giving up.
//!
//! Everything is a function of the options and the data (same seed, same network).

use crate::closed_loop::ClosedLoopLoss;
use crate::data::{MinMax, Table};
use crate::mlp::{Adam, Mlp};
use crate::train::{train, Metrics, Restart, TrainError, TrainOptions};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rand::SeedableRng;
use samara_nn::{Affine, Layer, Network};
use samara_plant::Model;
use samara_reach::GliderViolation;
use samara_reach::{reach, Goal, ReachResult, ReachSettings, Verdict};
use std::time::Instant;

/// Settings of closed-loop training.
#[derive(Clone, Debug)]
pub struct CegisOptions {
    /// The data-only training that gives the first network (its method must be plain;
    /// seed, epochs, architecture and restarts come from here).
    pub pretrain: TrainOptions,
    /// The flights: plant (reduced), horizon, period, RK4 step, clip, window. Its `bound`
    /// is the training bound (the goal less a margin, so that the enclosures have room);
    /// its `y0` is replaced by the flight set of each round.
    pub loss: ClosedLoopLoss,
    /// The goal `|x + y| <= goal` that reach must prove (at T, or over `loss.from..T`).
    pub goal: f64,
    /// The interval of initial y (chords).
    pub y0: (f64, f64),
    /// Evenly spaced interior starts of the first flight set (the two ends are added).
    pub initial_starts: usize,
    /// Adam steps per round.
    pub steps_per_round: usize,
    /// Adam learning rate of the rounds.
    pub lr: f64,
    /// Weight of the data MSE (normalised units) against the mean closed-loop penalty.
    pub data_weight: f64,
    /// Most rounds (reach runs with the small budget).
    pub max_rounds: usize,
    /// Sub-box budget and simulated samples of reach in a round.
    pub round_reach: (usize, usize),
    /// Sub-box budget and samples of the full reach (undecided rounds and the last).
    pub final_reach: (usize, usize),
    /// Most starts added per round (the worst sub-boxes first).
    pub max_added: usize,
    /// A progress line per round on stderr.
    pub progress: bool,
}

impl Default for CegisOptions {
    /// The published case: reduced model, y0 in [0.1/0.07, 0.3/0.07], T = 20, goal
    /// |x + y| <= 2 at T, training bound 1.25, 9 interior starts plus the ends, 150 Adam
    /// steps of lr 0.005 per round, data weight 100, at most 6 rounds, reach budgets
    /// 16 sub-boxes / 50 samples (the reproduction's quick setting) and 64 / 200.
    fn default() -> Self {
        CegisOptions {
            pretrain: TrainOptions::default(),
            loss: ClosedLoopLoss {
                bound: 1.25,
                step: 0.05,
                ..Default::default()
            },
            goal: 2.0,
            y0: (0.1 / 0.07, 0.3 / 0.07),
            initial_starts: 9,
            steps_per_round: 150,
            lr: 0.005,
            data_weight: 100.0,
            max_rounds: 6,
            round_reach: (16, 50),
            final_reach: (64, 200),
            max_added: 8,
            progress: false,
        }
    }
}

/// One round.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Round {
    /// 1-based.
    pub round: usize,
    /// Adam steps taken (fewer than the budget when the penalty reached 0).
    pub steps: usize,
    /// Total loss after the round's last step (data_weight * MSE + mean penalty).
    pub loss: f64,
    /// Data MSE (normalised units).
    pub mse: f64,
    /// Mean closed-loop penalty over the flight set.
    pub penalty: f64,
    /// R^2 against every PID data row (raw units).
    pub r2: f64,
    /// Flights in the set this round trained on.
    pub starts: usize,
    /// Reach's verdict (`proved`, `violated`, `unknown`).
    pub verdict: String,
    /// Reach's reason for `unknown` or the violating trajectory.
    pub reason: String,
    /// Enclosure of x + y at T (hull over the sub-boxes; infinite if one lost it).
    pub enclosure: [f64; 2],
    /// Sampled range of x + y at T.
    pub sampled: [f64; 2],
    /// Sub-box budget of the reach run that gave the verdict.
    pub max_leaves: usize,
    /// Starts added to the flight set after this round.
    pub added: Vec<f64>,
    /// Seconds of training in the round.
    pub train_seconds: f64,
    /// Seconds of reach in the round.
    pub reach_seconds: f64,
}

/// The result of closed-loop training.
#[derive(Clone, Debug)]
pub struct CegisOutcome {
    /// The trained network, raw units (normalisation layers in the IR).
    pub network: Network,
    /// Every round.
    pub rounds: Vec<Round>,
    /// Whether reach proved the goal for the returned network.
    pub proved: bool,
    /// The last reach run (on the returned network).
    pub reach: ReachResult,
    /// R^2 of the returned network against every data row.
    pub r2: f64,
    /// RMSE against every data row (raw output units).
    pub rmse: f64,
    /// The data-only training's test metrics and restarts.
    pub pretrain_metrics: Metrics,
    /// Restarts of the data-only training.
    pub restarts: Vec<Restart>,
    /// The seed the network was initialised from.
    pub init_seed: u64,
    /// Seconds of the data-only training.
    pub pretrain_seconds: f64,
    /// Wall time of everything.
    pub seconds: f64,
}

impl CegisOptions {
    /// The defaults flown on a spec's closed loop ([`samara_spec::LoopDecl`]): its
    /// interval of initial heights, period, horizon, clip and goal (with the training
    /// bound `max(goal - 0.75, goal / 2)`: the defaults' 1.25 for the published goal 2).
    /// The flights of closed-loop training start at `(1, 0, 0, 0, 0, y0)` on the reduced
    /// model, so a loop with another model or another initial set is refused (the error
    /// names the loop and says what to write).
    pub fn from_loop(l: &samara_spec::LoopDecl) -> Result<Self, TrainError> {
        let bad = |m: String| Err(TrainError::Settings(format!("loop `{}`: {m}", l.name)));
        if samara_reach::plant_model(l.model) != Model::Reduced {
            return bad(format!(
                "closed-loop training flies the reduced model, not {}: write `model reduced`",
                l.model.name()
            ));
        }
        let fixed = [1.0, 0.0, 0.0, 0.0, 0.0];
        if l.start.len() != 6 || l.start[..5].iter().zip(fixed).any(|(s, v)| *s != (v, v)) {
            return bad(
                "closed-loop training starts at v_xp = 1, v_yp = 0, omega = 0, theta = 0, x = 0 with y in an interval: write the start so"
                    .into(),
            );
        }
        let Some(goal) = &l.goal else {
            return bad(
                "closed-loop training needs the loop's goal: add `goal NAME: |x + y| <= 2 at 20`"
                    .into(),
            );
        };
        let d = CegisOptions::default();
        Ok(CegisOptions {
            y0: l.start[5],
            goal: goal.bound,
            loss: ClosedLoopLoss {
                bound: (goal.bound - 0.75).max(0.5 * goal.bound),
                from: goal.from,
                horizon: l.horizon,
                period: l.period,
                clip: l.clip,
                ..d.loss.clone()
            },
            ..d
        })
    }

    /// Check the settings (the pretraining's and the loss's are checked where used).
    pub fn validate(&self) -> Result<(), TrainError> {
        let bad = |m: String| Err(TrainError::Settings(m));
        if !(self.goal.is_finite() && self.goal > 0.0) {
            return bad(format!(
                "--goal-ystar {}: the goal bound must be a positive number, e.g. 2",
                self.goal
            ));
        }
        if !(self.loss.bound.is_finite() && self.loss.bound >= 0.0 && self.loss.bound <= self.goal)
        {
            return bad(format!(
                "the closed-loop training bound {} must be in [0, goal = {}] (--margin in [0, goal])",
                self.loss.bound, self.goal
            ));
        }
        let (a, b) = self.y0;
        if !(a.is_finite() && b.is_finite() && a <= b) {
            return bad(format!("--y0 {a}:{b}: give A:B with finite A <= B"));
        }
        if self.max_rounds == 0 || self.max_rounds > 100 {
            return bad(format!(
                "--rounds {}: give 1 to 100 rounds",
                self.max_rounds
            ));
        }
        if self.steps_per_round > 100_000 {
            return bad(format!(
                "--steps-per-round {}: give 0 to 100000",
                self.steps_per_round
            ));
        }
        if !(self.lr > 0.0 && self.lr <= crate::train::MAX_LR) {
            return bad(format!(
                "--cl-lr {}: the learning rate of the rounds must be in (0, {}]",
                self.lr,
                crate::train::MAX_LR
            ));
        }
        if !(self.data_weight.is_finite() && self.data_weight >= 0.0) {
            return bad(format!(
                "--data-weight {}: must be a finite number >= 0",
                self.data_weight
            ));
        }
        if self.initial_starts > 10_000 {
            return bad(format!("--starts {}: give 0 to 10000", self.initial_starts));
        }
        for (name, (l, s)) in [("round", self.round_reach), ("final", self.final_reach)] {
            if l == 0 || s == 0 {
                return bad(format!(
                    "the {name} reach budget needs >= 1 sub-box and sample"
                ));
            }
        }
        if self.pretrain.arch.first() != Some(&6) || self.pretrain.arch.last() != Some(&1) {
            return bad(format!(
                "--arch {:?}: the closed loop needs 6 inputs (the states) and 1 output (ex)",
                self.pretrain.arch
            ));
        }
        Ok(())
    }

    /// The first flight set: the interval's ends and `initial_starts` evenly spaced
    /// interior points.
    pub fn initial_set(&self) -> Vec<f64> {
        let (a, b) = self.y0;
        let n = self.initial_starts;
        let mut v = vec![a];
        v.extend((1..=n).map(|i| a + (b - a) * i as f64 / (n + 1) as f64));
        if b > a {
            v.push(b);
        }
        v
    }

    /// Reach settings for the trained network with a budget.
    pub fn reach_settings(&self, (leaves, samples): (usize, usize)) -> ReachSettings {
        let mut rs = ReachSettings::published(self.loss.plant.model);
        rs.init[5] = self.y0;
        rs.period = self.loss.period;
        rs.horizon = self.loss.horizon;
        rs.clip = self.loss.clip;
        rs.goal = Some(Goal {
            ystar: self.goal,
            from: self.loss.from,
        });
        rs.max_leaves = leaves;
        rs.samples = samples;
        rs.seed = self.pretrain.seed;
        rs
    }
}

/// Starts worth adding after a reach run: the start of the violating trajectory, then
/// the starts of reach's other simulated trajectories that miss the goal (worst first),
/// then the midpoints of the sub-boxes whose enclosure is not inside the goal band (lost,
/// then refuted or undecided, worst first); at most `max`, and none closer than 1e-9 to
/// a start already in `set`.
pub fn counterexamples(
    res: &ReachResult,
    goal: &Goal,
    horizon: f64,
    set: &[f64],
    max: usize,
) -> Vec<f64> {
    // (tier, excess, y0): tier 0 the violation, 1 other simulated counterexamples,
    // 2 lost sub-boxes, 3 refuted or undecided ones; worst first within a tier.
    let mut cands: Vec<(u8, f64, f64)> = Vec::new();
    if let Verdict::Violated(GliderViolation { initial, .. }) = &res.verdict {
        cands.push((0, 0.0, initial[5]));
    }
    for smp in &res.samples {
        let worst = match goal.from {
            None => smp
                .states
                .last()
                .map(|x| (x[4] + x[5]).abs())
                .unwrap_or(0.0),
            Some(f) => smp
                .txy
                .iter()
                .filter(|(t, _)| *t >= f - 1e-12)
                .map(|(_, v)| v.abs())
                .fold(0.0, f64::max),
        };
        if worst > goal.ystar {
            cands.push((1, worst - goal.ystar, smp.initial[5]));
        }
    }
    for l in &res.leaves {
        let y = 0.5 * (l.init[5][0] + l.init[5][1]);
        if l.failure.is_some() {
            cands.push((2, 0.0, y));
            continue;
        }
        let excess = l
            .steps
            .iter()
            .filter(|st| match goal.from {
                None => st.t >= horizon - 1e-9,
                Some(f) => st.t >= f - 1e-9,
            })
            .map(|st| {
                let r = if goal.from.is_some() && st.t > 0.0 {
                    st.x_plus_y_period
                } else {
                    st.x_plus_y
                };
                (r[1] - goal.ystar).max(-goal.ystar - r[0])
            })
            .fold(f64::NEG_INFINITY, f64::max);
        if excess > 0.0 {
            cands.push((3, excess, y));
        }
    }
    cands.sort_by(|a, b| {
        a.0.cmp(&b.0)
            .then(b.1.total_cmp(&a.1))
            .then(a.2.total_cmp(&b.2))
    });
    let mut out: Vec<f64> = Vec::new();
    for (_, _, y) in cands {
        if out.len() >= max {
            break;
        }
        if set.iter().chain(&out).all(|s| (s - y).abs() > 1e-9) {
            out.push(y);
        }
    }
    out
}

/// The IR network of an [`Mlp`] in the units of `mm` (6 states, then ex).
pub fn raw_network(net: &Mlp, mm: &MinMax) -> Network {
    Network {
        input_names: samara_nn::STATE_INPUTS
            .iter()
            .map(|s| s.to_string())
            .collect(),
        output_names: vec!["ex".into()],
        input_norm: Some(Affine::normalise(&mm.min[..6], &mm.range[..6])),
        layers: net.to_layers(),
        output_denorm: Some(Affine::denormalise(&mm.min[6..7], &mm.range[6..7])),
    }
}

/// The [`Mlp`] with the weights of a trained IR network's layers.
fn mlp_of(net: &Network, arch: &[usize], relu_output: bool) -> Mlp {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    let mut m = Mlp::new(arch, relu_output, &mut rng);
    m.params = net
        .layers
        .iter()
        .filter_map(|l| match l {
            Layer::Affine(a) => Some(a.to_dense().into_owned().into_iter().chain(a.b.clone())),
            _ => None,
        })
        .flatten()
        .collect();
    m
}

/// Data MSE (normalised units) and its gradient, over every row.
fn data_term(net: &Mlp, z: &[Vec<f64>], t: &[f64], grad: &mut [f64]) -> f64 {
    let mut c = net.cache();
    let n = z.len() as f64;
    let mut mse = 0.0;
    for (x, &y) in z.iter().zip(t) {
        let p = net.forward(x, &mut c)[0];
        mse += (p - y).powi(2) / n;
        net.backward(&mut c, &[2.0 * (p - y)], 1.0 / n, grad, None);
    }
    mse
}

/// R^2 and RMSE in raw units against every row.
fn fit(net: &Mlp, z: &[Vec<f64>], t: &[f64], mm: &MinMax) -> (f64, f64) {
    let mut c = net.cache();
    let (s, m) = (mm.range[6], mm.min[6]);
    let n = t.len() as f64;
    let mean = t.iter().map(|v| m + s * v).sum::<f64>() / n;
    let (mut sse, mut sst) = (0.0, 0.0);
    for (x, &y) in z.iter().zip(t) {
        let p = m + s * net.forward(x, &mut c)[0];
        sse += (p - (m + s * y)).powi(2);
        sst += (m + s * y - mean).powi(2);
    }
    (1.0 - sse / sst, (sse / n).sqrt())
}

/// `in [lo, hi]`, or `not enclosed` when a sub-box lost its enclosure.
pub fn enclosure_text(e: [f64; 2]) -> String {
    if e[0].is_finite() && e[1].is_finite() {
        format!("in [{:.4}, {:.4}]", e[0], e[1])
    } else {
        "not enclosed (a sub-box lost validation)".into()
    }
}

/// Train a controller for the closed-loop goal on `data` (6 state columns, then ex; raw
/// units) with min-max constants `mm` (from the data when `None`). See the module
/// documentation for the rounds.
pub fn train_closed_loop(
    data: &Table,
    mm: Option<&MinMax>,
    o: &CegisOptions,
) -> Result<CegisOutcome, TrainError> {
    let t0 = Instant::now();
    o.validate()?;
    if !matches!(o.pretrain.method, crate::Method::Plain) {
        return Err(TrainError::Settings(
            "the closed-loop method starts from the plain method's data-only training".into(),
        ));
    }
    let computed;
    let mm = match mm {
        Some(m) => m,
        None => {
            computed = MinMax::of(data);
            &computed
        }
    };
    // Check the loss's settings before the (longer) pretraining.
    let mut cl = o.loss.clone();
    cl.y0 = o.initial_set();
    let probe = probe_network(&o.pretrain);
    cl.periods(&probe, mm)?;
    o.reach_settings(o.round_reach)
        .validate(&raw_network(&probe, mm))
        .map_err(|e| TrainError::Settings(e.to_string()))?;

    let pre = train(data, Some(mm), &o.pretrain)?;
    let pretrain_seconds = t0.elapsed().as_secs_f64();
    let mut net = mlp_of(&pre.network, &o.pretrain.arch, o.pretrain.relu_output);
    let z: Vec<Vec<f64>> = (0..data.rows())
        .map(|i| {
            (0..6)
                .map(|j| (data.row(i)[j] - mm.min[j]) / mm.range[j])
                .collect()
        })
        .collect();
    let t: Vec<f64> = (0..data.rows())
        .map(|i| (data.row(i)[6] - mm.min[6]) / mm.range[6])
        .collect();

    let pb = if o.progress {
        let pb =
            ProgressBar::with_draw_target(Some(o.max_rounds as u64), ProgressDrawTarget::stderr());
        pb.set_style(
            ProgressStyle::with_template(
                "closed-loop rounds [{bar:20}] {pos}/{len} {msg} {elapsed}",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
        );
        pb
    } else {
        ProgressBar::hidden()
    };
    let goal = Goal {
        ystar: o.goal,
        from: o.loss.from,
    };
    let mut adam = Adam::new(net.params.len(), o.lr);
    let mut rounds = Vec::new();
    let mut last: Option<ReachResult> = None;
    let mut proved = false;
    for round in 1..=o.max_rounds {
        pb.set_message(format!(
            "round {round}: training on {} flights",
            cl.y0.len()
        ));
        let tr = Instant::now();
        let (mut loss, mut mse, mut penalty) = (f64::NAN, f64::NAN, f64::NAN);
        let mut steps = 0;
        let scale = 1.0 / cl.y0.len() as f64;
        for step in 0..=o.steps_per_round {
            let (p, gp) = cl.loss_and_gradient(&net, mm)?;
            let mut grad = vec![0.0; net.params.len()];
            let m = data_term(&net, &z, &t, &mut grad);
            (loss, mse, penalty) = (o.data_weight * m + scale * p, m, scale * p);
            if !loss.is_finite() {
                return Err(TrainError::Degenerate {
                    restarts: vec![Restart {
                        attempt: 0,
                        seed: pre.init_seed,
                        epoch: round,
                        reason: crate::Degeneracy::Diverged,
                    }],
                });
            }
            // The last evaluation only measures; so does a penalty of 0.
            if step == o.steps_per_round || p == 0.0 {
                break;
            }
            for (g, q) in grad.iter_mut().zip(&gp) {
                *g = o.data_weight * *g + scale * q;
            }
            adam.step(&mut net.params, &grad);
            steps += 1;
        }
        let train_seconds = tr.elapsed().as_secs_f64();
        let (r2, _) = fit(&net, &z, &t, mm);
        let raw = raw_network(&net, mm);
        pb.set_message(format!("round {round}: reach"));
        let rt = Instant::now();
        let mut budget = o.round_reach;
        let mut res = reach(&raw, &o.reach_settings(budget))
            .map_err(|e| TrainError::Settings(e.to_string()))?;
        let undecided = matches!(res.verdict, Verdict::Unknown { .. });
        if (undecided || round == o.max_rounds)
            && !matches!(
                res.verdict,
                Verdict::Proved | Verdict::Violated(GliderViolation { .. })
            )
            && o.final_reach != o.round_reach
        {
            budget = o.final_reach;
            res = reach(&raw, &o.reach_settings(budget))
                .map_err(|e| TrainError::Settings(e.to_string()))?;
        }
        let reach_seconds = rt.elapsed().as_secs_f64();
        proved = res.verdict == Verdict::Proved;
        let added = if proved {
            Vec::new()
        } else {
            counterexamples(&res, &goal, o.loss.horizon, &cl.y0, o.max_added)
        };
        let r = Round {
            round,
            steps,
            loss,
            mse,
            penalty,
            r2,
            starts: cl.y0.len(),
            verdict: res.verdict.name().into(),
            reason: Verdict::reason(&res.verdict),
            enclosure: res.final_x_plus_y,
            sampled: res.sampled_x_plus_y,
            max_leaves: budget.0,
            added: added.clone(),
            train_seconds,
            reach_seconds,
        };
        let line = format!(
            "round {round}: {steps} steps, loss {:.4e} (mse {:.3e}, penalty {:.3e}), R^2 {r2:.4}, {} flights; reach ({} sub-boxes): {}, x + y at T {}; +{} starts; {:.1} s + {:.1} s",
            r.loss, r.mse, r.penalty, r.starts, budget.0, r.verdict, enclosure_text(r.enclosure), added.len(), train_seconds, reach_seconds
        );
        if o.progress {
            pb.suspend(|| eprintln!("{line}"));
        }
        pb.inc(1);
        rounds.push(r);
        cl.y0.extend(added);
        last = Some(res);
        if proved {
            break;
        }
    }
    pb.finish_and_clear();
    let (r2, rmse) = fit(&net, &z, &t, mm);
    Ok(CegisOutcome {
        network: raw_network(&net, mm),
        rounds,
        proved,
        reach: last.expect("at least one round"),
        r2,
        rmse,
        pretrain_metrics: pre.metrics,
        restarts: pre.restarts,
        init_seed: pre.init_seed,
        pretrain_seconds,
        seconds: t0.elapsed().as_secs_f64(),
    })
}

/// A network of the pretraining's shape (for checking settings before training).
fn probe_network(o: &TrainOptions) -> Mlp {
    Mlp::new(
        &o.arch,
        o.relu_output,
        &mut rand_chacha::ChaCha8Rng::seed_from_u64(0),
    )
}

/// The figure of the rounds: per round, the enclosure of x + y at T from reach (bar;
/// a lost enclosure is drawn to the chart's edge in red), the sampled range (black) and
/// the goal band `|x + y| <= goal` (green); PNG and SVG, each written to a temporary
/// sibling and renamed.
pub fn rounds_figure(
    rounds: &[Round],
    goal: f64,
    title: &str,
    png: &std::path::Path,
    svg: &std::path::Path,
) -> Result<(), String> {
    use plotters::prelude::*;
    fn draw<DB: DrawingBackend>(
        area: DrawingArea<DB, plotters::coord::Shift>,
        rounds: &[Round],
        goal: f64,
        title: &str,
    ) -> Result<(), String>
    where
        DB::ErrorType: 'static,
    {
        let e = |x: &dyn std::fmt::Display| x.to_string();
        area.fill(&WHITE).map_err(|x| e(&x))?;
        let finite = rounds
            .iter()
            .flat_map(|r| r.enclosure.iter().chain(&r.sampled))
            .copied()
            .filter(|v| v.is_finite());
        let lim = finite.fold(goal, |a, v| a.max(v.abs())).min(4.0 * goal) * 1.15;
        let n = rounds.len().max(1) as f64;
        let mut chart = ChartBuilder::on(&area)
            .caption(title, ("sans-serif", 24))
            .margin(20)
            .x_label_area_size(50)
            .y_label_area_size(60)
            .build_cartesian_2d(0.5..n + 0.5, -lim..lim)
            .map_err(|x| e(&x))?;
        chart
            .configure_mesh()
            .x_desc("round")
            .y_desc("x + y at t = T")
            .x_labels(rounds.len().clamp(2, 20))
            .x_label_formatter(&|v| format!("{v:.0}"))
            .label_style(("sans-serif", 18))
            .axis_desc_style(("sans-serif", 20))
            .draw()
            .map_err(|x| e(&x))?;
        chart
            .draw_series(std::iter::once(Rectangle::new(
                [(0.5, -goal), (n + 0.5, goal)],
                RGBColor(120, 200, 120).mix(0.25).filled(),
            )))
            .map_err(|x| e(&x))?
            .label(format!("goal |x + y| <= {goal}"))
            .legend(|(x, y)| {
                Rectangle::new(
                    [(x, y - 5), (x + 20, y + 5)],
                    RGBColor(120, 200, 120).mix(0.4).filled(),
                )
            });
        let bar = |r: &Round| {
            let lost = !(r.enclosure[0].is_finite() && r.enclosure[1].is_finite());
            let (lo, hi) = if lost {
                (-lim, lim)
            } else {
                (r.enclosure[0].max(-lim), r.enclosure[1].min(lim))
            };
            let x = r.round as f64;
            (x, lo, hi, lost)
        };
        chart
            .draw_series(rounds.iter().map(|r| {
                let (x, lo, hi, lost) = bar(r);
                let c = if lost {
                    RGBColor(220, 60, 40)
                } else if r.verdict == "proved" {
                    RGBColor(90, 120, 220)
                } else {
                    RGBColor(230, 150, 40)
                };
                Rectangle::new([(x - 0.25, lo), (x + 0.25, hi)], c.mix(0.6).filled())
            }))
            .map_err(|x| e(&x))?
            .label("reach enclosure (blue proved, orange not, red lost)")
            .legend(|(x, y)| {
                Rectangle::new(
                    [(x, y - 5), (x + 20, y + 5)],
                    RGBColor(90, 120, 220).mix(0.6).filled(),
                )
            });
        chart
            .draw_series(rounds.iter().filter(|r| r.sampled[0].is_finite()).map(|r| {
                let x = r.round as f64;
                PathElement::new(
                    vec![(x, r.sampled[0].max(-lim)), (x, r.sampled[1].min(lim))],
                    BLACK.stroke_width(4),
                )
            }))
            .map_err(|x| e(&x))?
            .label("sampled range")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(4)));
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 16))
            .draw()
            .map_err(|x| e(&x))?;
        area.present().map_err(|x| e(&x))?;
        Ok(())
    }
    let tmp = |p: &std::path::Path| {
        let name = p
            .file_name()
            .map(|n| n.to_string_lossy().to_string())
            .unwrap_or_default();
        p.with_file_name(format!(".{name}.{}.tmp", std::process::id()))
    };
    let (tp, ts) = (
        tmp(png).with_extension("png"),
        tmp(svg).with_extension("svg"),
    );
    let r = draw(
        BitMapBackend::new(&tp, (900, 600)).into_drawing_area(),
        rounds,
        goal,
        title,
    )
    .and_then(|_| {
        draw(
            SVGBackend::new(&ts, (900, 600)).into_drawing_area(),
            rounds,
            goal,
            title,
        )
    })
    .and_then(|_| {
        std::fs::rename(&tp, png).map_err(|x| format!("{}: {x}", png.display()))?;
        std::fs::rename(&ts, svg).map_err(|x| format!("{}: {x}", svg.display()))
    });
    if r.is_err() {
        let _ = std::fs::remove_file(&tp);
        let _ = std::fs::remove_file(&ts);
    }
    r
}

/// Simulated flights of a raw-unit controller from sampled starts: the worst |x + y| at
/// the horizon and how many exceed the goal.
#[derive(Clone, Debug, PartialEq)]
pub struct FlightCheck {
    /// Flights.
    pub flights: usize,
    /// Largest |x + y| at the horizon.
    pub worst: f64,
    /// Its initial y.
    pub worst_y0: f64,
    /// Flights with |x + y| > goal at the horizon.
    pub violations: usize,
}

/// Fly `net` (raw units, output clipped to `clip`) in `model` from `n` starts
/// `(1, 0, 0, 0, 0, y0[, 0])`, y0 uniform in `y0` (seeded ChaCha8; the two ends first),
/// with samara-sim's tight integrator (DOP853), and compare |x + y| at `horizon` with
/// `goal` (a NaN counts as a violation).
#[allow(clippy::too_many_arguments)]
pub fn check_flights(
    net: &Network,
    model: samara_plant::Model,
    y0: (f64, f64),
    n: usize,
    seed: u64,
    clip: Option<(f64, f64)>,
    horizon: f64,
    goal: f64,
) -> Result<FlightCheck, String> {
    use rand::Rng;
    use samara_sim::{fly, initial_state, Integrator, LoopSettings, NetworkController};
    let plant = samara_plant::Plant::new(model);
    let settings = LoopSettings {
        horizon,
        integrator: Integrator::Tight(Default::default()),
        output_step: None,
        ..Default::default()
    };
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let mut ctl = NetworkController::new(net.clone(), clip, "checked");
    let mut out = FlightCheck {
        flights: 0,
        worst: 0.0,
        worst_y0: y0.0,
        violations: 0,
    };
    for i in 0..n {
        let y = match i {
            0 => y0.0,
            1 => y0.1,
            _ if y0.1 > y0.0 => rng.gen_range(y0.0..=y0.1),
            _ => y0.0,
        };
        let f = fly(&plant, &mut ctl, &initial_state(&plant, y), &settings)
            .map_err(|e| e.to_string())?;
        let s = &f.steps.last().ok_or("no steps")?.state_end;
        let v = (s[4] + s[5]).abs();
        if v.is_nan() || v > goal {
            out.violations += 1;
        }
        if v.is_nan() || v > out.worst {
            out.worst = v;
            out.worst_y0 = y;
        }
        out.flights += 1;
    }
    Ok(out)
}

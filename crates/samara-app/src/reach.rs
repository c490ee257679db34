//! Reachability results as typed documents (`samara reach`, `samara merge reach`,
//! `samara.reach`): the zonotope run's `reach.json` ([`ReachReport`]) and its `--json`
//! summary ([`ReachSummary`]), the settings echo, and the reach shard file of the
//! zonotope path ([`ZonotopeRun`], [`ZonotopeShard`]) with its merge
//! ([`merge_zonotope`]). The Taylor-model path (system files) is in
//! [`system`].
//!
//! Every document goes through `serde_json::Value` when printed (keys sorted), which is
//! the layout the CLI has always written. Shards store numbers as [`Exact`] text so that
//! the merge rebuilds the one-process run bit for bit, non-finite numbers included.

pub mod adaptive;
pub mod args;
pub mod discrete;
pub mod glider;
pub mod system;

use crate::shard::{pair, unpair, Exact, ExactPair, Shard};
use crate::AppError;
use samara_plant::{Model, STATE_NAMES};
use samara_reach::parts::{self, Flown, LeafRecord, Prepared};
use samara_reach::GliderViolation;
use samara_reach::Sample;
use samara_reach::{Goal, ReachResult, ReachSettings, StepSet, Verdict};
use samara_report::reach::{Trajectory, XyBox};
use samara_report::Curve;
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};

type Result<T> = std::result::Result<T, AppError>;

fn bad<T>(m: String) -> Result<T> {
    Err(AppError::Input(m))
}

/// Serde adapter for an interval whose ends serde_json writes as `null` when they are
/// not finite (an unbounded enclosure): `null` reads back as NaN.
pub mod pair_nan_as_null {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    /// Write the pair (serde_json: `null` for a non-finite end).
    pub fn serialize<S: Serializer>(x: &[f64; 2], s: S) -> Result<S::Ok, S::Error> {
        x.serialize(s)
    }

    /// Read a pair, `null` ends as NaN.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<[f64; 2], D::Error> {
        let [a, b] = <[Option<f64>; 2]>::deserialize(d)?;
        Ok([a.unwrap_or(f64::NAN), b.unwrap_or(f64::NAN)])
    }
}

/// The settings of a zonotope run as `reach.json` records them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SettingsEcho {
    /// The `--network` path as given.
    pub network: String,
    /// The model's name.
    pub model: String,
    /// The initial interval of each state, by name.
    pub init: BTreeMap<String, [f64; 2]>,
    /// Horizon.
    pub horizon: f64,
    /// Control period.
    pub period: f64,
    /// The controller's output clip, if any.
    pub clip: Option<[f64; 2]>,
    /// Whether the filter state restarts every period.
    pub reset_filter: bool,
    /// The goal, if any.
    pub goal: Option<GoalEcho>,
    /// Sub-box budget.
    pub max_leaves: usize,
    /// Initial pieces (0: automatic).
    pub initial_splits: usize,
    /// Simulated trajectories.
    pub samples: usize,
    /// Sampling seed.
    pub seed: u64,
    /// Worker threads.
    pub threads: usize,
}

/// The goal `|x + y| <= ystar` (at the horizon, or on `[from, horizon]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GoalEcho {
    /// Half-width of the band.
    pub ystar: f64,
    /// Start of the window, if any.
    pub from: Option<f64>,
}

impl SettingsEcho {
    /// The echo of `s` for a run of the network named `network` on `threads` workers.
    pub fn new(network: &str, threads: usize, s: &ReachSettings) -> Self {
        SettingsEcho {
            network: network.to_string(),
            model: s.model.name().to_string(),
            init: s
                .init
                .iter()
                .enumerate()
                .map(|(i, &(lo, hi))| (STATE_NAMES[i].to_string(), [lo, hi]))
                .collect(),
            horizon: s.horizon,
            period: s.period,
            clip: s.clip.map(|(lo, hi)| [lo, hi]),
            reset_filter: s.reset_filter,
            goal: s.goal.as_ref().map(|g| GoalEcho {
                ystar: g.ystar,
                from: g.from,
            }),
            max_leaves: s.max_leaves,
            initial_splits: s.initial_splits,
            samples: s.samples,
            seed: s.seed,
            threads,
        }
    }
}

/// A simulated trajectory that misses the goal.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Counterexample {
    /// Its initial state.
    pub initial: Vec<f64>,
    /// Time of the miss.
    pub t: f64,
    /// Its `x + y` there.
    pub x_plus_y: f64,
}

/// The verdict with its reason, as `reach.json` and the summary give it
/// (`{"verdict": "violated", "reason": ..., "counterexample": ...}`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "verdict", rename_all = "lowercase")]
pub enum VerdictReport {
    /// Every trajectory meets the goal (sound enclosure).
    Proved,
    /// A simulated trajectory misses the goal.
    Violated {
        /// Where, in words.
        reason: String,
        /// The trajectory.
        counterexample: Counterexample,
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

impl From<&Verdict> for VerdictReport {
    fn from(v: &Verdict) -> Self {
        match v {
            Verdict::Proved => VerdictReport::Proved,
            Verdict::NoGoal => VerdictReport::NoGoal,
            Verdict::Unknown { reason } => VerdictReport::Unknown {
                reason: reason.clone(),
            },
            Verdict::Violated(GliderViolation {
                initial,
                t,
                x_plus_y,
            }) => VerdictReport::Violated {
                reason: format!("the simulated trajectory from {initial:?} has x + y = {x_plus_y} at t = {t}, outside the goal band"),
                counterexample: Counterexample {
                    initial: initial.clone(),
                    t: *t,
                    x_plus_y: *x_plus_y,
                },
            },
        }
    }
}

/// What the report, the summary and the human line say of a zonotope run (one process,
/// or merged shards).
#[derive(Clone, Debug)]
pub struct Outcome {
    /// The verdict.
    pub verdict: Verdict,
    /// Enclosure of `x + y` at the horizon.
    pub final_x_plus_y: [f64; 2],
    /// Range of `x + y` at the horizon over the samples.
    pub sampled_x_plus_y: [f64; 2],
    /// Sub-boxes of the final partition.
    pub subproblems: usize,
    /// Wall time (merged: the sum of the shards').
    pub seconds: f64,
    /// Simulated trajectories.
    pub sampled_trajectories: usize,
    /// Where a sub-box lost its enclosure, if one did
    /// (`samara_reach::verdict::lost_enclosure`).
    pub lost: Option<String>,
    /// Warnings on the inputs (a network in the wrong units).
    pub warnings: Vec<String>,
}

impl Outcome {
    /// The outcome of a one-process run.
    pub fn of(res: &ReachResult, s: &ReachSettings, warnings: Vec<String>) -> Self {
        Outcome {
            warnings,
            lost: samara_reach::verdict::lost_enclosure(&res.leaves, s),
            verdict: res.verdict.clone(),
            final_x_plus_y: res.final_x_plus_y,
            sampled_x_plus_y: res.sampled_x_plus_y,
            subproblems: res.subproblems(),
            seconds: res.seconds,
            sampled_trajectories: res.samples.len(),
        }
    }

    /// Width of the enclosure over the sampled width (as `ReachResult::width_ratio`).
    pub fn width_ratio(&self) -> f64 {
        width(self.final_x_plus_y) / width(self.sampled_x_plus_y)
    }

    /// Whether the run has no result: the goal is unknown, or there is no goal and a
    /// sub-box lost its enclosure.
    pub fn no_result(&self) -> bool {
        matches!(self.verdict, Verdict::Unknown { .. }) || self.lost.is_some()
    }

    /// Whether the run succeeded (the CLI's exit 0): proved, or no goal and enclosed
    /// to the horizon.
    pub fn success(&self) -> bool {
        match self.verdict {
            Verdict::NoGoal => self.lost.is_none(),
            Verdict::Proved => true,
            Verdict::Violated(GliderViolation { .. }) | Verdict::Unknown { .. } => false,
        }
    }

    /// The one-line verdict the CLI prints (`s`: the run's settings).
    pub fn human_line(&self, s: &ReachSettings) -> String {
        let f = self.final_x_plus_y;
        let sm = self.sampled_x_plus_y;
        let goal = match &s.goal {
            Some(g) => match g.from {
                Some(t0) => format!(" (goal |x + y| <= {} on [{t0}, {}])", g.ystar, s.horizon),
                None => format!(" (goal |x + y| <= {} at t = {})", g.ystar, s.horizon),
            },
            None => String::new(),
        };
        let detail = match &self.verdict {
            Verdict::Unknown { reason } => format!("; reason: {reason}"),
            Verdict::NoGoal => match &self.lost {
                Some(why) => format!("; no result: {why}"),
                None => String::new(),
            },
            Verdict::Violated(GliderViolation {
                initial,
                t,
                x_plus_y,
            }) => format!("; counterexample: from {initial:?}, x + y = {x_plus_y} at t = {t}"),
            _ => String::new(),
        };
        // No finite sampled trajectory (e.g. a state where the model is singular): say
        // so instead of printing the empty range [inf, -inf].
        let sampled = if sm[0] <= sm[1] {
            format!(
                "sampled [{:.6}, {:.6}] (width {:.6}); ratio {:.3}",
                sm[0],
                sm[1],
                width(sm),
                self.width_ratio()
            )
        } else {
            "sampled: none (no simulated trajectory stayed finite); ratio n/a".to_string()
        };
        format!(
            "{}{goal}: x + y at t = {} in [{:.6}, {:.6}] (width {:.6}); {sampled}; {} sub-boxes; {:.2} s{detail}",
            self.verdict.name(),
            s.horizon,
            f[0],
            f[1],
            width(f),
            self.subproblems,
            self.seconds
        )
    }
}

fn width(iv: [f64; 2]) -> f64 {
    iv[1] - iv[0]
}

/// `reach.json` of a zonotope run.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ReachReport {
    /// The settings.
    pub settings: SettingsEcho,
    /// The verdict and its reason.
    pub verdict: VerdictReport,
    /// Enclosure of `x + y` at the horizon (`null` ends: unbounded).
    #[serde(with = "pair_nan_as_null")]
    pub final_x_plus_y: [f64; 2],
    /// Range of `x + y` at the horizon over the samples.
    #[serde(with = "pair_nan_as_null")]
    pub sampled_x_plus_y: [f64; 2],
    /// Enclosure width over sampled width.
    #[serde(with = "crate::nan_as_null")]
    pub width_ratio: f64,
    /// Sub-boxes of the final partition.
    pub subproblems: usize,
    /// Wall time.
    pub seconds: f64,
    /// Simulated trajectories.
    pub sampled_trajectories: usize,
    /// Where a sub-box lost its enclosure, if one did.
    pub enclosure_lost: Option<String>,
    /// Warnings on the inputs.
    pub warnings: Vec<String>,
    /// The model's state names.
    pub state_names: Vec<String>,
    /// The sub-boxes and their enclosures (unbounded ends written as `null`, read back
    /// as NaN).
    #[serde(
        serialize_with = "Vec::<LeafRecord>::serialize",
        deserialize_with = "leaves_nan_as_null::deserialize"
    )]
    pub leaves: Vec<LeafRecord>,
}

/// Reading back the sub-boxes of `reach.json`, where serde_json wrote every non-finite
/// number as `null`: those read back as NaN (the sub-box types serialise only).
mod leaves_nan_as_null {
    use super::LeafRecord;
    use samara_reach::StepSet;
    use serde::{Deserialize, Deserializer};

    /// A number, `null` as NaN.
    struct N(f64);

    impl<'de> Deserialize<'de> for N {
        fn deserialize<D: Deserializer<'de>>(d: D) -> Result<N, D::Error> {
            Ok(N(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN)))
        }
    }

    fn pair(p: [N; 2]) -> [f64; 2] {
        [p[0].0, p[1].0]
    }

    #[derive(Deserialize)]
    struct StepIn {
        t: N,
        bbox: Vec<[N; 2]>,
        x_plus_y: [N; 2],
        x_plus_y_period: [N; 2],
        ex: Option<[N; 2]>,
    }

    #[derive(Deserialize)]
    struct LeafIn {
        init: Vec<[N; 2]>,
        params: Vec<usize>,
        steps: Vec<StepIn>,
        failure: Option<String>,
        flow_steps: (usize, usize),
        max_dev: N,
    }

    /// Read the sub-boxes.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<LeafRecord>, D::Error> {
        let leaves = Vec::<LeafIn>::deserialize(d)?;
        Ok(leaves
            .into_iter()
            .map(|l| LeafRecord {
                init: l.init.into_iter().map(pair).collect(),
                params: l.params,
                steps: l
                    .steps
                    .into_iter()
                    .map(|st| StepSet {
                        t: st.t.0,
                        bbox: st.bbox.into_iter().map(pair).collect(),
                        x_plus_y: pair(st.x_plus_y),
                        x_plus_y_period: pair(st.x_plus_y_period),
                        ex: st.ex.map(pair),
                        set: None,
                    })
                    .collect(),
                failure: l.failure,
                flow_steps: l.flow_steps,
                max_dev: l.max_dev.0,
            })
            .collect())
    }
}

impl ReachReport {
    /// The report of a run (`leaves`: its final sub-boxes).
    pub fn new(
        settings: SettingsEcho,
        s: &ReachSettings,
        o: &Outcome,
        leaves: Vec<LeafRecord>,
    ) -> Self {
        ReachReport {
            settings,
            verdict: (&o.verdict).into(),
            final_x_plus_y: o.final_x_plus_y,
            sampled_x_plus_y: o.sampled_x_plus_y,
            width_ratio: o.width_ratio(),
            subproblems: o.subproblems,
            seconds: o.seconds,
            sampled_trajectories: o.sampled_trajectories,
            enclosure_lost: o.lost.clone(),
            warnings: o.warnings.clone(),
            state_names: STATE_NAMES[..s.model.dim()]
                .iter()
                .map(|n| n.to_string())
                .collect(),
            leaves,
        }
    }
}

/// The `--json` summary of a zonotope run.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ReachSummary {
    /// The verdict and its reason.
    #[serde(flatten)]
    pub verdict: VerdictReport,
    /// Enclosure of `x + y` at the horizon.
    #[serde(with = "pair_nan_as_null")]
    pub final_x_plus_y: [f64; 2],
    /// Its width.
    #[serde(with = "crate::nan_as_null")]
    pub final_width: f64,
    /// Range of `x + y` over the samples.
    #[serde(with = "pair_nan_as_null")]
    pub sampled_x_plus_y: [f64; 2],
    /// Its width.
    #[serde(with = "crate::nan_as_null")]
    pub sampled_width: f64,
    /// Enclosure width over sampled width.
    #[serde(with = "crate::nan_as_null")]
    pub width_ratio: f64,
    /// Sub-boxes.
    pub subproblems: usize,
    /// Wall time.
    pub seconds: f64,
    /// Where a sub-box lost its enclosure, if one did.
    pub enclosure_lost: Option<String>,
    /// Warnings on the inputs.
    pub warnings: Vec<String>,
    /// The output folder.
    pub out: String,
}

impl ReachSummary {
    /// The summary of `o`, written to the folder `out`.
    pub fn new(o: &Outcome, out: &Path) -> Self {
        ReachSummary {
            verdict: (&o.verdict).into(),
            final_x_plus_y: o.final_x_plus_y,
            final_width: width(o.final_x_plus_y),
            sampled_x_plus_y: o.sampled_x_plus_y,
            sampled_width: width(o.sampled_x_plus_y),
            width_ratio: o.width_ratio(),
            subproblems: o.subproblems,
            seconds: o.seconds,
            enclosure_lost: o.lost.clone(),
            warnings: o.warnings.clone(),
            out: out.display().to_string(),
        }
    }
}

/// The goal of a [`ZonotopeRun`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GoalText {
    /// Half-width of the band.
    pub ystar: Exact,
    /// Start of the window.
    pub from: Option<Exact>,
}

/// `run` of a zonotope reach shard: the inputs (content digests of `--network` and
/// `--spec`) and the settings every shard of one run shares, numbers as exact text so
/// that the merge rebuilds the settings bit for bit.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ZonotopeRun {
    /// Content digests by flag.
    pub inputs: BTreeMap<String, String>,
    /// The samara version that wrote the shard.
    pub samara: String,
    /// Model name.
    pub model: String,
    /// Initial box.
    pub init: Vec<ExactPair>,
    /// Horizon.
    pub horizon: Exact,
    /// Period.
    pub period: Exact,
    /// Output clip.
    pub clip: Option<ExactPair>,
    /// Filter reset.
    pub reset_filter: bool,
    /// Goal.
    pub goal: Option<GoalText>,
    /// Sub-box budget.
    pub max_leaves: usize,
    /// Initial pieces setting.
    pub initial_splits: usize,
    /// Simulated trajectories.
    pub samples: usize,
    /// Sampling seed.
    pub seed: u64,
    /// Initial pieces of the run.
    pub pieces: usize,
}

impl ZonotopeRun {
    /// The record of settings `s` (`pieces`: the run's initial pieces).
    pub fn new(s: &ReachSettings, inputs: BTreeMap<String, String>, pieces: usize) -> Self {
        ZonotopeRun {
            inputs,
            samara: env!("CARGO_PKG_VERSION").to_string(),
            model: s.model.name().to_string(),
            init: s.init.iter().map(|&(lo, hi)| pair([lo, hi])).collect(),
            horizon: Exact(s.horizon),
            period: Exact(s.period),
            clip: s.clip.map(|(lo, hi)| pair([lo, hi])),
            reset_filter: s.reset_filter,
            goal: s.goal.as_ref().map(|g| GoalText {
                ystar: Exact(g.ystar),
                from: g.from.map(Exact),
            }),
            max_leaves: s.max_leaves,
            initial_splits: s.initial_splits,
            samples: s.samples,
            seed: s.seed,
            pieces,
        }
    }

    /// The settings the record was made from.
    pub fn settings(&self) -> Result<ReachSettings> {
        let Some(model) = Model::from_name(&self.model) else {
            return bad(format!("shard files: bad `run.model` ({:?})", self.model));
        };
        let mut s = ReachSettings::published(model);
        if self.init.len() != model.dim() {
            return bad(format!(
                "shard files: bad `run.init` ({} intervals for the {} model)",
                self.init.len(),
                model.name()
            ));
        }
        s.init = self
            .init
            .iter()
            .map(|p| {
                let [a, b] = unpair(*p);
                (a, b)
            })
            .collect();
        s.horizon = self.horizon.0;
        s.period = self.period.0;
        s.clip = self.clip.map(|p| {
            let [a, b] = unpair(p);
            (a, b)
        });
        s.reset_filter = self.reset_filter;
        s.goal = self.goal.as_ref().map(|g| Goal {
            ystar: g.ystar.0,
            from: g.from.map(|f| f.0),
        });
        s.max_leaves = self.max_leaves;
        s.initial_splits = self.initial_splits;
        s.samples = self.samples;
        s.seed = self.seed;
        Ok(s)
    }
}

/// A sampled counterexample in a shard.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ViolationText {
    /// Initial state.
    pub initial: Vec<Exact>,
    /// Time of the miss.
    pub t: Exact,
    /// `x + y` there.
    pub x_plus_y: Exact,
}

/// What every shard computes alike from the samples; the merge checks they agree.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SharedSamples {
    /// Simulated trajectories.
    pub sampled_trajectories: usize,
    /// Range of `x + y` at the horizon over them.
    pub sampled_x_plus_y: ExactPair,
    /// Noise allowed in a sub-box's final `x + y`.
    pub tol_noise: Exact,
    /// The first sampled trajectory that misses the goal.
    pub violation: Option<ViolationText>,
}

impl SharedSamples {
    fn of(p: &Prepared) -> Self {
        SharedSamples {
            sampled_trajectories: p.samples.len(),
            sampled_x_plus_y: pair(p.sampled_x_plus_y),
            tol_noise: Exact(p.tol_noise),
            violation: match &p.violation {
                Some(Verdict::Violated(GliderViolation {
                    initial,
                    t,
                    x_plus_y,
                })) => Some(ViolationText {
                    initial: initial.iter().map(|x| Exact(*x)).collect(),
                    t: Exact(*t),
                    x_plus_y: Exact(*x_plus_y),
                }),
                _ => None,
            },
        }
    }
}

/// One control instant of a sub-box in a shard (a [`StepSet`] as exact text).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StepText {
    /// Time.
    pub t: Exact,
    /// Interval hull of the states.
    pub bbox: Vec<ExactPair>,
    /// `x + y` at `t`.
    pub x_plus_y: ExactPair,
    /// `x + y` over the period ending at `t`.
    pub x_plus_y_period: ExactPair,
    /// Control held from `t`.
    pub ex: Option<ExactPair>,
}

/// A sub-box's enclosures in a shard (a [`LeafRecord`] as exact text).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LeafText {
    /// The sub-box.
    pub init: Vec<ExactPair>,
    /// The parameter states.
    pub params: Vec<usize>,
    /// One record per control instant reached.
    pub steps: Vec<StepText>,
    /// Why the enclosure stopped early.
    pub failure: Option<String>,
    /// Validated steps taken (Taylor, fallback).
    pub flow_steps: (usize, usize),
    /// Largest deviation of the network enclosure.
    pub max_dev: Exact,
}

/// A flown sub-box in a shard (a [`Flown`] as exact text).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FlownText {
    /// Its name ([`parts::piece_key`], one digit per split).
    pub key: String,
    /// Whether it is worth splitting.
    pub want: bool,
    /// The parameter it is split along.
    pub split: Option<usize>,
    /// The goal on it.
    pub goal: Option<bool>,
    /// Its sub-box and enclosures.
    pub leaf: LeafText,
}

impl From<&Flown> for FlownText {
    fn from(f: &Flown) -> Self {
        let l = &f.leaf;
        FlownText {
            key: f.key.clone(),
            want: f.want,
            split: f.split,
            goal: f.goal,
            leaf: LeafText {
                init: l.init.iter().map(|b| pair(*b)).collect(),
                params: l.params.clone(),
                steps: l
                    .steps
                    .iter()
                    .map(|st| StepText {
                        t: Exact(st.t),
                        bbox: st.bbox.iter().map(|b| pair(*b)).collect(),
                        x_plus_y: pair(st.x_plus_y),
                        x_plus_y_period: pair(st.x_plus_y_period),
                        ex: st.ex.map(pair),
                    })
                    .collect(),
                failure: l.failure.clone(),
                flow_steps: l.flow_steps,
                max_dev: Exact(l.max_dev),
            },
        }
    }
}

impl FlownText {
    /// The flown sub-box, checked (`file` names its shard in messages).
    pub fn flown(&self, file: &Path) -> Result<Flown> {
        let what = format!("{}: sub-box {}", file.display(), self.key);
        let l = &self.leaf;
        if self.split.is_some_and(|j| j >= l.params.len()) {
            return bad(format!("{what}: bad `split` ({:?})", self.split));
        }
        if l.failure.is_none() && l.steps.is_empty() {
            return bad(format!("{what}: no enclosure recorded"));
        }
        let leaf = LeafRecord {
            init: l.init.iter().map(|p| unpair(*p)).collect(),
            params: l.params.clone(),
            steps: l
                .steps
                .iter()
                .map(|st| StepSet {
                    t: st.t.0,
                    bbox: st.bbox.iter().map(|p| unpair(*p)).collect(),
                    x_plus_y: unpair(st.x_plus_y),
                    x_plus_y_period: unpair(st.x_plus_y_period),
                    ex: st.ex.map(unpair),
                    set: None,
                })
                .collect(),
            failure: l.failure.clone(),
            flow_steps: l.flow_steps,
            max_dev: l.max_dev.0,
        };
        Ok(Flown {
            key: self.key.clone(),
            want: self.want,
            split: self.split,
            goal: self.goal,
            leaf,
        })
    }
}

/// One curve of the figure in a shard.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CurveText {
    /// Legend label.
    pub label: String,
    /// Points.
    pub points: Vec<ExactPair>,
}

/// The figure's sampled trajectories (the same in every shard: kept once, in shard 0).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FigureText {
    /// The legend label of the group of curves.
    pub group_label: Option<String>,
    /// The curves.
    pub curves: Vec<CurveText>,
}

/// `result` of a zonotope reach shard: the shard's pieces flown, with what the merge
/// needs to write what one process writes.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ZonotopeShard {
    /// The shard's range of initial pieces.
    pub pieces: (usize, usize),
    /// What every shard computes alike.
    pub shared: SharedSamples,
    /// `--network` as given.
    pub network: String,
    /// Where the merge reads the controller back to re-check a counterexample.
    pub network_file: String,
    /// Where the merge reads `--spec` back.
    pub spec_file: Option<String>,
    /// `--loop`.
    #[serde(rename = "loop")]
    pub loop_name: Option<String>,
    /// Warnings on the inputs.
    pub warnings: Vec<String>,
    /// Worker threads.
    pub threads: usize,
    /// Wall time.
    pub seconds: f64,
    /// The flown sub-boxes.
    pub subboxes: Vec<FlownText>,
    /// Shard 0: the figure's curves.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub figure: Option<FigureText>,
}

/// Where and how a shard was run: the fields of [`ZonotopeShard`] the flight does not
/// give.
#[derive(Clone, Debug)]
pub struct ShardSource {
    /// `--network` as given.
    pub network: String,
    /// `--network` resolved.
    pub network_file: String,
    /// `--spec` resolved.
    pub spec_file: Option<String>,
    /// `--loop`.
    pub loop_name: Option<String>,
    /// Warnings on the inputs.
    pub warnings: Vec<String>,
    /// Worker threads.
    pub threads: usize,
}

impl ZonotopeShard {
    /// The result of shard `sh`: the pieces `range` of `prep` flown (`flown`) in
    /// `seconds`.
    pub fn new(
        sh: Shard,
        prep: &Prepared,
        range: std::ops::Range<usize>,
        flown: &[Flown],
        seconds: f64,
        src: ShardSource,
    ) -> Self {
        let figure = (sh.i == 0).then(|| {
            let (curves, group_label) =
                samara_report::reach::sample_curves(&figure_samples(&prep.samples));
            FigureText {
                group_label,
                curves: curves
                    .iter()
                    .map(|c| CurveText {
                        label: c.label.clone(),
                        points: c.points.iter().map(|&(x, y)| pair([x, y])).collect(),
                    })
                    .collect(),
            }
        });
        ZonotopeShard {
            pieces: (range.start, range.end),
            shared: SharedSamples::of(prep),
            network: src.network,
            network_file: src.network_file,
            spec_file: src.spec_file,
            loop_name: src.loop_name,
            warnings: src.warnings,
            threads: src.threads,
            seconds,
            subboxes: flown.iter().map(FlownText::from).collect(),
            figure,
        }
    }
}

/// The merged run: what one process of the same run writes.
#[derive(Clone, Debug)]
pub struct Merged {
    /// The run's settings.
    pub settings: ReachSettings,
    /// Its outcome.
    pub outcome: Outcome,
    /// Its final sub-boxes, in the one-process order.
    pub leaves: Vec<LeafRecord>,
    /// `--network` of shard 0.
    pub network: String,
    /// Worker threads of shard 0.
    pub threads: usize,
    /// The figure's curves.
    pub curves: Vec<Curve>,
    /// Their legend label.
    pub group_label: Option<String>,
}

impl Merged {
    /// `reach.json` of the merged run.
    pub fn report(&self) -> ReachReport {
        ReachReport::new(
            SettingsEcho::new(&self.network, self.threads, &self.settings),
            &self.settings,
            &self.outcome,
            self.leaves.clone(),
        )
    }
}

/// The error of a merge that needs sub-box `key`, which its shard did not fly.
fn missing(key: &str, files: &[&Path], n_pieces: usize, max_leaves: usize) -> AppError {
    let n = files.len();
    let (piece, path) = key.split_once(':').unwrap_or((key, ""));
    let p: usize = piece.parse().unwrap_or(0);
    let i = (0..n)
        .find(|&i| Shard { i, n }.range(n_pieces).contains(&p))
        .unwrap_or(0);
    let file = files[i].display();
    if path.is_empty() {
        return AppError::Input(format!("{file}: piece {key} of shard {i}/{n} is missing (a damaged shard file?); run that shard again"));
    }
    let parent = &key[..key.len() - 1];
    AppError::Input(format!(
        "the run splits sub-box {parent} into {key}, which shard {i}/{n} ({file}) did not fly: the sub-box budget (--max-leaves {max_leaves}) ran out during the refinement, and that shard, which cannot see the other shards' sub-boxes, spent part of the budget's extra quarter (for sub-boxes that lost their enclosure) on sub-boxes the run does not split; this run cannot be merged exactly: run it without --shard, or with a larger --max-leaves"
    ))
}

/// The counterexample of a merge to re-check, and where shard 0 found the controller.
pub struct Recheck<'a> {
    /// The run's settings.
    pub settings: &'a ReachSettings,
    /// The counterexample.
    pub verdict: &'a Verdict,
    /// Shard 0's result (`network_file`, `spec_file`, `loop`).
    pub shard0: &'a ZonotopeShard,
    /// Shard 0's file, for messages.
    pub file0: &'a Path,
}

impl Recheck<'_> {
    /// The shards' counterexample flown again under the controller `load` reads back
    /// (`load(network, spec, loop)`): the controller's files must be the ones the
    /// shards digested (`run.inputs`), and the trajectory must miss the goal as the
    /// verdict says ([`samara_reach::verdict::recheck_violation`]).
    pub fn run(
        &self,
        run: &ZonotopeRun,
        load: impl FnOnce(&Path, Option<&Path>, Option<&str>) -> Result<samara_nn::Network>,
    ) -> Result<()> {
        let at = format!("{}: the counterexample", self.file0.display());
        let network = PathBuf::from(&self.shard0.network_file);
        let spec = self.shard0.spec_file.as_ref().map(PathBuf::from);
        for (flag, p) in [("--network", Some(&network)), ("--spec", spec.as_ref())] {
            let Some(p) = p else { continue };
            let now = crate::shard::digest_file(p, &format!("{at}: re-checking it needs {flag}"))?;
            let then = run.inputs.get(flag);
            if then != Some(&now) {
                return bad(format!(
                    "{at}: input `{flag}` ({}) changed since the shards ran (content digest {} then, {now} now); run every shard again",
                    p.display(),
                    then.map_or_else(|| "null".to_string(), |t| format!("\"{t}\""))
                ));
            }
        }
        let net = load(&network, spec.as_deref(), self.shard0.loop_name.as_deref())?;
        samara_reach::verdict::recheck_violation(&net, self.settings, self.verdict).or_else(|e| {
            bad(format!(
                "{at} does not hold: {e}; the shard is damaged or tampered with, run the shards again"
            ))
        })
    }
}

/// `samara merge reach` of zonotope shards: the N shards' flown sub-boxes, the run's
/// refinement replayed over them (`samara_reach::parts::refine`: the same rounds and
/// sub-box budget as one process), and the outcome one process gives. The verdict, the
/// enclosures, the sub-boxes and the counterexample (a sampled trajectory, the same in
/// every shard, re-checked by `recheck`) are the one-process run's; `seconds` is the sum
/// of the shards', `network` and `threads` are shard 0's. Refused when a sub-box the run
/// flies was not flown by its shard (rare; see `samara_reach::parts`).
pub fn merge_zonotope(
    run: &ZonotopeRun,
    shards: &[(PathBuf, ZonotopeShard)],
    recheck: impl FnOnce(&Recheck) -> Result<()>,
) -> Result<Merged> {
    let s = run.settings()?;
    let n_pieces = run.pieces;
    let n = shards.len();
    let (file0, r0) = &shards[0];
    let files: Vec<&Path> = shards.iter().map(|(p, _)| p.as_path()).collect();
    let mut nodes: HashMap<String, Flown> = HashMap::new();
    let mut seconds = 0.0;
    for (i, (file, r)) in shards.iter().enumerate() {
        let range = Shard { i, n }.range(n_pieces);
        if r.pieces != (range.start, range.end) {
            return bad(format!(
                "{}: pieces [{},{}], expected {}..{} of {n_pieces} for shard {i}/{n}",
                file.display(),
                r.pieces.0,
                r.pieces.1,
                range.start,
                range.end
            ));
        }
        if r.shared != r0.shared {
            return bad(format!(
                "{} and {}: the shards' simulated samples differ (different samara builds?): {} vs {}",
                file0.display(),
                file.display(),
                serde_json::to_value(&r0.shared).unwrap_or_default(),
                serde_json::to_value(&r.shared).unwrap_or_default()
            ));
        }
        seconds += r.seconds;
        for v in &r.subboxes {
            let f = v.flown(file)?;
            let piece = f
                .key
                .split_once(':')
                .and_then(|(p, _)| p.parse::<usize>().ok());
            if !piece.is_some_and(|p| range.contains(&p)) {
                return bad(format!(
                    "{}: sub-box {} is not of this shard's pieces {}..{}",
                    file.display(),
                    f.key,
                    range.start,
                    range.end
                ));
            }
            if nodes.contains_key(&f.key) {
                return bad(format!("{}: sub-box {} given twice", file.display(), f.key));
            }
            nodes.insert(f.key.clone(), f);
        }
    }
    // The one-process rounds over the recorded flights.
    let start: Vec<String> = (0..n_pieces).map(parts::piece_key).collect();
    let mut done = parts::refine(
        start,
        0,
        s.max_leaves,
        |keys: Vec<String>| {
            keys.iter()
                .map(|k| {
                    nodes
                        .get(k)
                        .ok_or_else(|| missing(k, &files, n_pieces, s.max_leaves))
                })
                .collect::<Result<Vec<&Flown>>>()
        },
        |f| (parts::child_key(&f.key, 0), parts::child_key(&f.key, 1)),
    )?;
    let sh = &r0.shared;
    let violation = sh.violation.as_ref().map(|v| {
        Verdict::Violated(GliderViolation {
            initial: v.initial.iter().map(|x| x.0).collect(),
            t: v.t.0,
            x_plus_y: v.x_plus_y.0,
        })
    });
    if let Some(v) = &violation {
        recheck(&Recheck {
            settings: &s,
            verdict: v,
            shard0: r0,
            file0,
        })?;
    }
    let (verdict, fin) = parts::finish(&s, violation, &mut done);
    let leaves: Vec<LeafRecord> = done.iter().map(|f| f.leaf.clone()).collect();
    let outcome = Outcome {
        lost: samara_reach::verdict::lost_enclosure(&leaves, &s),
        warnings: r0.warnings.clone(),
        verdict,
        final_x_plus_y: fin,
        sampled_x_plus_y: unpair(sh.sampled_x_plus_y),
        subproblems: done.len(),
        seconds,
        sampled_trajectories: sh.sampled_trajectories,
    };
    let Some(fig) = &r0.figure else {
        return bad(format!(
            "{}: no `figure` (shard 0 keeps it)",
            file0.display()
        ));
    };
    let curves = fig
        .curves
        .iter()
        .map(|c| Curve {
            label: c.label.clone(),
            points: c
                .points
                .iter()
                .map(|p| {
                    let [x, y] = unpair(*p);
                    (x, y)
                })
                .collect(),
        })
        .collect();
    Ok(Merged {
        settings: s,
        outcome,
        leaves,
        network: r0.network.clone(),
        threads: r0.threads,
        curves,
        group_label: fig.group_label.clone(),
    })
}

/// The `--json` line of a zonotope reach shard.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct ShardLine {
    /// `[I, N]`.
    pub shard: (usize, usize),
    /// The shard's range of initial pieces.
    pub pieces: (usize, usize),
    /// Sub-boxes flown.
    pub subboxes: usize,
    /// The shard file.
    pub out: PathBuf,
}

/// A glider run's final sub-boxes as its figure draws them (`samara_report::reach`):
/// each sub-box's set at every control instant, projected onto x and y (states 4 and 5).
pub fn figure_sets(leaves: &[LeafRecord]) -> Vec<Vec<XyBox>> {
    leaves
        .iter()
        .map(|l| l.steps.iter().map(|st| [st.bbox[4], st.bbox[5]]).collect())
        .collect()
}

/// A glider run's sampled trajectories as its figure draws them, labelled by `y0`
/// (state 5).
pub fn figure_samples(samples: &[Sample]) -> Vec<Trajectory<'_>> {
    samples
        .iter()
        .map(|s| Trajectory {
            y0: s.initial[5],
            xy: &s.xy,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shard::{document, read_shards};

    /// A flown sub-box that lost its enclosure: infinite ends and a NaN, as a real
    /// blown-up enclosure carries.
    fn lost_subbox(key: &str) -> Flown {
        Flown {
            key: key.into(),
            want: false,
            split: None,
            goal: None,
            leaf: LeafRecord {
                init: vec![
                    [1.0, 1.0],
                    [0.0, 0.0],
                    [0.0, 0.0],
                    [0.0, 0.0],
                    [0.0, 0.0],
                    [2.0, 2.5],
                ],
                params: vec![5],
                steps: vec![StepSet {
                    t: 0.5,
                    bbox: vec![[f64::NEG_INFINITY, f64::INFINITY]; 6],
                    x_plus_y: [f64::NEG_INFINITY, 0.1],
                    x_plus_y_period: [-0.0, f64::INFINITY],
                    ex: Some([f64::NAN, 0.19]),
                    set: None,
                }],
                failure: Some("the enclosure blew up".into()),
                flow_steps: (3, 1),
                max_dev: f64::INFINITY,
            },
        }
    }

    fn bits(v: &[[f64; 2]]) -> Vec<[u64; 2]> {
        v.iter().map(|p| [p[0].to_bits(), p[1].to_bits()]).collect()
    }

    #[test]
    fn shards_keep_non_finite_numbers_through_the_merge() {
        let s = ReachSettings::published(Model::Reduced);
        let run = ZonotopeRun::new(&s, BTreeMap::new(), 2);
        let shared = SharedSamples {
            sampled_trajectories: 3,
            sampled_x_plus_y: pair([f64::INFINITY, f64::NEG_INFINITY]),
            tol_noise: Exact(1e-6),
            violation: None,
        };
        let dir = std::env::temp_dir().join(format!("samara-app-merge-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut files = Vec::new();
        for i in 0..2 {
            let f = lost_subbox(&parts::piece_key(i));
            let result = ZonotopeShard {
                pieces: (i, i + 1),
                shared: shared.clone(),
                network: "n.onnx".into(),
                network_file: "/x/n.onnx".into(),
                spec_file: None,
                loop_name: None,
                warnings: vec![],
                threads: 1,
                seconds: 0.25,
                subboxes: vec![FlownText::from(&f)],
                figure: (i == 0).then(|| FigureText {
                    group_label: None,
                    curves: vec![CurveText {
                        label: "a".into(),
                        points: vec![pair([f64::NAN, f64::INFINITY])],
                    }],
                }),
            };
            let text = document("reach", Shard { i, n: 2 }, &run, &result).unwrap();
            // Exact text, never a JSON null, for every non-finite number.
            assert!(
                text.contains("\"inf\"") && text.contains("\"-inf\"") && text.contains("\"NaN\"")
            );
            assert!(!text.contains("null,") || text.contains("\"spec_file\": null"));
            let p = dir.join(format!("s{i}.json"));
            std::fs::write(&p, text).unwrap();
            files.push(p);
        }
        let shards = read_shards("reach", &files).unwrap();
        let back_run: ZonotopeRun = shards.run_as().unwrap();
        assert_eq!(back_run, run);
        let results = shards.results_as::<ZonotopeShard>().unwrap();
        let f0 = results[0].1.subboxes[0].flown(&files[0]).unwrap();
        let want = lost_subbox("0");
        assert_eq!(f0.leaf.max_dev, f64::INFINITY);
        assert_eq!(bits(&f0.leaf.steps[0].bbox), bits(&want.leaf.steps[0].bbox));
        assert_eq!(
            bits(&[f0.leaf.steps[0].x_plus_y, f0.leaf.steps[0].x_plus_y_period]),
            bits(&[
                want.leaf.steps[0].x_plus_y,
                want.leaf.steps[0].x_plus_y_period
            ])
        );
        assert!(f0.leaf.steps[0].ex.unwrap()[0].is_nan());
        let merged = merge_zonotope(&back_run, &results, |_| panic!("no counterexample")).unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        // A lost enclosure: the hull at the horizon is the whole line, no result.
        assert_eq!(
            merged.outcome.final_x_plus_y,
            [f64::NEG_INFINITY, f64::INFINITY]
        );
        assert!(merged.outcome.no_result());
        assert_eq!(merged.outcome.seconds, 0.5);
        assert_eq!(merged.leaves.len(), 2);
        assert_eq!(merged.leaves[0].max_dev, f64::INFINITY);
        assert!(merged.curves[0].points[0].0.is_nan());
        assert_eq!(
            unpair(merged.report().settings.init["y"].map(Exact)),
            [s.init[5].0, s.init[5].1]
        );
        // reach.json writes the unbounded ends as null, and reads them back as NaN.
        let report = serde_json::to_value(merged.report()).unwrap();
        assert_eq!(report["final_x_plus_y"], serde_json::json!([null, null]));
        assert_eq!(report["leaves"][0]["max_dev"], serde_json::Value::Null);
        let back: ReachReport = serde_json::from_value(report).unwrap();
        assert!(back.final_x_plus_y[0].is_nan() && back.width_ratio.is_nan());
        assert!(back.leaves[0].max_dev.is_nan());
        assert_eq!(back.leaves[1].steps[0].x_plus_y[1], 0.1);
    }
}

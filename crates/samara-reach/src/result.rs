//! What a glider reachability run returns: the verdict, every sub-box of the initial
//! set with its enclosures at each control instant, and the check that simulated
//! trajectories lie inside them.

use crate::sampling::Sample;
use crate::zonotope::Zonotope;
use samara_num::Status;
use serde::{Deserialize, Serialize};

/// The verdict of a reachability run on its goal, in samara's answer vocabulary
/// ([`samara_num::Status`]: proved, violated, unknown, and `none` when no goal was
/// stated), generic over what a counterexample is: a glider trajectory
/// ([`GliderViolation`]) or a system-file flight
/// ([`crate::taylor::SystemViolation`]). Serialised as `{"verdict": "violated", ...}`
/// with the counterexample's fields beside the tag.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "verdict", rename_all = "lowercase")]
pub enum ReachVerdict<V> {
    /// Every trajectory from the initial set meets the goal (sound enclosure).
    Proved,
    /// A simulated trajectory misses the goal.
    Violated(V),
    /// Not settled.
    Unknown {
        /// Why.
        reason: String,
    },
    /// No goal was given.
    #[serde(rename = "none")]
    NoGoal,
}

impl<V> ReachVerdict<V> {
    /// The verdict's status.
    pub fn status(&self) -> Status {
        match self {
            ReachVerdict::Proved => Status::Proved,
            ReachVerdict::Violated(_) => Status::Violated,
            ReachVerdict::Unknown { .. } => Status::Unknown,
            ReachVerdict::NoGoal => Status::NoGoal,
        }
    }

    /// `proved`, `violated`, `unknown` or `none`.
    pub fn name(&self) -> &'static str {
        self.status().name()
    }
}

/// A glider trajectory that misses the goal.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GliderViolation {
    /// Its initial state.
    pub initial: Vec<f64>,
    /// Time of the violation.
    pub t: f64,
    /// Its `x + y` there.
    pub x_plus_y: f64,
}

/// The verdict of a glider run.
pub type Verdict = ReachVerdict<GliderViolation>;

impl Verdict {
    /// Why the goal is not proved, in words: the unknown reason, or where the
    /// simulated counterexample misses the goal; empty when proved or without a goal.
    pub fn reason(&self) -> String {
        match self {
            Verdict::Unknown { reason } => reason.clone(),
            Verdict::Violated(GliderViolation {
                initial,
                t,
                x_plus_y,
            }) => format!(
                "simulated from y0 = {:.4}: x + y = {:.4} at t = {}",
                initial[5], x_plus_y, t
            ),
            _ => String::new(),
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

/// A flown sub-box: one node of a piece's refinement tree, and how the driver judges it.
#[derive(Clone, Debug)]
pub struct Flown {
    /// Its name: `piece_key` of its piece, then one digit per split (see
    /// `child_key`).
    pub key: String,
    /// Whether it is worth splitting: it lost its enclosure, its final `x + y` carries
    /// too much noise, or the goal is undecided on it.
    pub want: bool,
    /// The parameter (index into `leaf.params`) it is split along, if it can be.
    pub split: Option<usize>,
    /// The goal on it: `Some(true)` every enclosure inside the band, `Some(false)` one
    /// entirely outside, `None` undecided or no goal.
    pub goal: Option<bool>,
    /// Its sub-box and enclosures.
    pub leaf: Leaf,
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

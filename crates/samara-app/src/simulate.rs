//! Simulation results as typed documents (`samara simulate --json`): the flights of
//! the built-in glider ([`SimulateSummary`]) and of a system file ([`SystemSimSummary`]).

use samara_plant::STATE_NAMES;
use samara_sim::Flight;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Largest magnitude of an initial state value of `simulate` and `reach`: the model is
/// nondimensional and the published states are O(1) (heights 1.43 to 4.29).
pub const MAX_STATE: f64 = 1000.0;

/// One flight of the glider: its start height and where it ends.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StartSummary {
    /// Initial height.
    pub y0: f64,
    /// The state at the horizon, by name.
    pub final_state: BTreeMap<String, f64>,
    /// `x + y` at the horizon.
    pub final_x_plus_y: f64,
    /// Right-hand-side evaluations the integrator made.
    pub rhs_evals: usize,
}

impl StartSummary {
    /// The summary of a flight of a model with `dim` states.
    pub fn of(f: &Flight, dim: usize) -> Self {
        let last = &f.steps.last().expect("at least one step").state_end;
        StartSummary {
            y0: f.initial[5],
            final_state: last
                .iter()
                .enumerate()
                .take(dim)
                .map(|(i, v)| (STATE_NAMES[i].to_string(), *v))
                .collect(),
            final_x_plus_y: last[4] + last[5],
            rhs_evals: f.evals,
        }
    }
}

/// The `--json` summary of `samara simulate` on the built-in glider.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SimulateSummary {
    /// Model name.
    pub model: String,
    /// `--controller` as given.
    pub controller: String,
    /// `--integrator` as given.
    pub integrator: String,
    /// Control period.
    pub period: f64,
    /// Horizon.
    pub horizon: f64,
    /// One entry per start.
    pub starts: Vec<StartSummary>,
    /// Wall time.
    pub wall_seconds: f64,
    /// Output folder.
    pub out: String,
    /// Warnings on the inputs.
    pub warnings: Vec<String>,
}

/// A flight of a system file that misses a goal.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GoalViolation {
    /// The start's number.
    pub start: usize,
    /// Its initial state.
    pub initial: Vec<f64>,
    /// The goal's text.
    pub goal: String,
}

/// The `--json` summary of `samara simulate --system`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SystemSimSummary {
    /// The system's name.
    pub system: String,
    /// Number of flights.
    pub starts: usize,
    /// The goals' texts.
    pub goals: Vec<String>,
    /// The flights that miss a goal.
    pub violations: Vec<GoalViolation>,
    /// Wall time.
    pub wall_seconds: f64,
}

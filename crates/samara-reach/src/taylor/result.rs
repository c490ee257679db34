//! What a system-file reachability run returns: its verdict, every sub-box of the
//! initial set with its sets, and the run's summary.

use super::settings::{MeasureRange, NetworkError};

use samara_system::sim::SystemFlight;
use samara_system::{System, When};
use serde::{Deserialize, Serialize};

/// A system-file flight that misses a goal.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SystemViolation {
    /// Its initial state.
    pub initial: Vec<f64>,
    /// The goal it misses (its text in the file).
    pub goal: String,
}

/// The verdict of a system run (the one reach verdict, [`crate::ReachVerdict`], with a
/// system-file flight as its counterexample).
pub type SystemVerdict = crate::result::ReachVerdict<SystemViolation>;

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
    pub(crate) fn settled(&self) -> bool {
        self.failure.is_none() && self.decided.iter().all(|d| *d == Some(true))
    }
}

/// Whether a goal that must hold over a window (or at the end) has already failed to
/// be proved on the sets: flying on cannot prove it.
pub(crate) fn undecidable(sys: &System, ok: &[bool]) -> bool {
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

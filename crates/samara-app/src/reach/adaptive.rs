//! Adaptive splitting's documents (`samara reach ... --target-ratio R`,
//! [`samara_reach::adaptive`]): `reach.json` ([`AdaptiveReport`]: the system run's report
//! plus an `adaptive` object) and the `--json` summary ([`AdaptiveSummary`]), and the
//! human line's adaptive part ([`adaptive_text`]).

use crate::reach::system::{SystemSettingsEcho, SystemSummary};
use samara_reach::adaptive::{AdaptiveCell, AdaptiveReach};
use samara_reach::system::SystemReach;
use serde::Serialize;

/// The settings `reach.json` records of an adaptive run: the Taylor-model settings and
/// the target.
#[derive(Clone, Debug, Serialize)]
pub struct AdaptiveSettingsEcho {
    /// The Taylor-model run's settings.
    #[serde(flatten)]
    pub run: SystemSettingsEcho,
    /// `--target-ratio`.
    pub target_ratio: f64,
}

/// The `adaptive` object: the target, whether it was met and how the cells came about.
#[derive(Clone, Debug, Serialize)]
pub struct AdaptiveEcho {
    /// `--target-ratio`.
    pub target_ratio: f64,
    /// Whether the target was met.
    pub met: bool,
    /// The hull's width over the flights' spread, when every cell reached the horizon.
    pub ratio: Option<f64>,
    /// Why the target was not met, if it was not.
    pub reason: Option<String>,
    /// Why the run stopped early (time, budget), if it did.
    pub stopped: Option<String>,
    /// Cells of the final partition.
    pub leaves: usize,
    /// Of those, the cells accepted (sets in the band).
    pub accepted: usize,
    /// Cells flown, parents of cut cells included.
    pub flown: usize,
    /// Rounds.
    pub rounds: usize,
    /// The flights' range of the measure.
    pub sampled: [f64; 2],
    /// The band the cells' enclosures had to lie in.
    pub band: [f64; 2],
    /// The cells (in `reach.json` only: thousands of lines on a large set).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cells: Option<Vec<AdaptiveCell>>,
}

impl AdaptiveEcho {
    /// The echo of `r`, with its cells when `cells`.
    pub fn new(r: &AdaptiveReach, cells: bool) -> Self {
        AdaptiveEcho {
            target_ratio: r.target_ratio,
            met: r.met,
            ratio: r.ratio,
            reason: r.reason.clone(),
            stopped: r.stopped.clone(),
            leaves: r.cells.len(),
            accepted: r.cells.iter().filter(|c| c.accepted).count(),
            flown: r.flown,
            rounds: r.rounds,
            sampled: r.sampled,
            band: r.band,
            cells: cells.then(|| r.cells.clone()),
        }
    }
}

/// `reach.json` of an adaptive run.
#[derive(Clone, Debug, Serialize)]
pub struct AdaptiveReport {
    /// The system file (or the built-in setting).
    pub system: String,
    /// `--network` as given.
    pub network: String,
    /// The settings.
    pub settings: AdaptiveSettingsEcho,
    /// The Taylor-model result over the final cells.
    pub result: SystemReach,
    /// The adaptive run's record.
    pub adaptive: AdaptiveEcho,
}

/// The `--json` summary of an adaptive run.
#[derive(Clone, Debug, Serialize)]
pub struct AdaptiveSummary {
    /// The Taylor-model summary.
    #[serde(flatten)]
    pub run: SystemSummary,
    /// The adaptive record, without the cells.
    pub adaptive: AdaptiveEcho,
}

/// `adaptive: N leaves (K cells flown in R rounds); ratio q against the flights
/// (target R): met`.
pub fn adaptive_text(r: &AdaptiveReach) -> String {
    let ratio = r.ratio.map_or_else(
        || "no ratio (not every cell has sets at the horizon)".to_string(),
        |q| format!("ratio {q:.3}"),
    );
    let verdict = match &r.reason {
        None if r.met => "target met".to_string(),
        None => "target not met".to_string(),
        Some(why) => format!("target not met: {why}"),
    };
    format!(
        "adaptive: {} leaves ({} cells flown in {} rounds); {ratio} against the flights (target {}): {verdict}",
        r.cells.len(),
        r.flown,
        r.rounds,
        r.target_ratio
    )
}

/// Whether an adaptive run succeeded (exit 0): the width target met and every goal
/// proved, or no goal.
pub fn adaptive_success(r: &AdaptiveReach) -> bool {
    use samara_reach::system::SystemVerdict;
    r.met
        && matches!(
            r.reach.verdict,
            SystemVerdict::Proved | SystemVerdict::NoGoal
        )
}

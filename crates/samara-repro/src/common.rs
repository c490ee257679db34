//! What the reproduction's stages and report sections share: the training methods and
//! the spec's global properties in table order, the stage error, the plain CSV reader,
//! and the flights figure. A module of its own so that the
//! stages (`stages`, `*_stage`, `sections`) import it and not each other.

use crate::ReproError;
use samara_report::{Curve, TrajectoryFigure};
use samara_sim::Flight;

/// samara's training methods, in the order of the train stage's table.
pub(crate) const METHODS: [&str; 6] = [
    "plain",
    "adversarial",
    "lipschitz",
    "dl2",
    "goedel",
    "closed-loop",
];
/// The spec's global properties, verified by critical values and trained for by DL2 and
/// Goedel.
pub(crate) const P1_TO_P4: [&str; 4] = ["p1", "p2", "p3", "p4"];

/// A stage's error: the stage's name and the message.
pub(crate) fn stage_err(stage: &str, e: impl std::fmt::Display) -> ReproError {
    ReproError::Stage {
        stage: stage.into(),
        message: e.to_string(),
    }
}

/// The rows of a headerless CSV file of numbers (blank lines skipped); the error names
/// the file, the line and the value.
pub(crate) fn read_plain_csv(path: &std::path::Path) -> Result<Vec<Vec<f64>>, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("{}: {e}", path.display()))?;
    text.lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
        .map(|(i, l)| {
            l.split(',')
                .map(|v| {
                    v.trim()
                        .parse::<f64>()
                        .map_err(|_| format!("{}:{}: not a number: {v:?}", path.display(), i + 1))
                })
                .collect()
        })
        .collect()
}

/// Figure of flights.
pub fn flights_figure(title: &str, flights: &[Flight], band: Option<f64>) -> TrajectoryFigure {
    let curves = flights
        .iter()
        .map(|f| Curve {
            label: format!("y0 = {:.4}", f.initial[5]),
            points: std::iter::once((f.initial[4], f.initial[5]))
                .chain(f.dense.iter().map(|(_, s, _)| (s[4], s[5])))
                .collect(),
        })
        .collect();
    let mut fig = TrajectoryFigure::new(title, curves);
    fig.band = band;
    fig
}

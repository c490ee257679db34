//! The x-y figure of a reachability run of the glider (`samara_reach`): the sets as
//! boxes, the goal band and sampled trajectories. It lives here, not in `samara-reach`,
//! so that the reachability library does not depend on drawing.

use crate::{Curve, TrajectoryFigure};
use samara_reach::{Leaf, ReachResult, Sample, Verdict};
use std::borrow::Borrow;

/// Largest number of boxes drawn in a figure; beyond it neighbouring sub-boxes are
/// merged (interval hull, still an over-approximation).
const MAX_FIGURE_BOXES: usize = 20_000;

/// Sampled trajectories drawn on top of the sets.
const MAX_FIGURE_SAMPLES: usize = 24;

/// The x-y boxes of every sub-box at every control instant, merged across neighbouring
/// sub-boxes (sorted by their initial box) if there are too many to draw.
fn figure_boxes<L: Borrow<Leaf>>(leaves: &[L]) -> Vec<(f64, f64, f64, f64)> {
    let total: usize = leaves.iter().map(|l| l.borrow().steps.len()).sum();
    let group = total.div_ceil(MAX_FIGURE_BOXES).max(1);
    let mut out = Vec::new();
    for chunk in leaves.chunks(group) {
        let steps = chunk
            .iter()
            .map(|l| l.borrow().steps.len())
            .max()
            .unwrap_or(0);
        for k in 0..steps {
            let mut b = (
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
            );
            for l in chunk {
                if let Some(st) = l.borrow().steps.get(k) {
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

/// The sampled trajectories drawn in the figure and their legend entry: a few only (the
/// extremes come first in the samples, then random starts), so the sets under them stay
/// visible.
pub fn sample_curves(samples: &[Sample]) -> (Vec<Curve>, Option<String>) {
    let n = samples.len();
    let step = n.div_ceil(MAX_FIGURE_SAMPLES).max(1);
    let curves: Vec<Curve> = samples
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
    (
        curves,
        Some(format!("sampled trajectories ({shown} of {n})")),
    )
}

/// The figure of the final sub-boxes `leaves` (in order) with the trajectories `curves`
/// (legend entry `group_label`) on top, the layout of [`figure`]: a merged shard run
/// (`samara_reach::parts`) draws its sub-boxes with the curves [`sample_curves`] picks
/// from the run's samples.
pub fn draw<L: Borrow<Leaf>>(
    title: &str,
    verdict: &Verdict,
    leaves: &[L],
    curves: Vec<Curve>,
    group_label: Option<String>,
    band: Option<f64>,
) -> TrajectoryFigure {
    let mut fig = TrajectoryFigure::new(
        format!(
            "{title}: {} ({} sub-boxes; sets at control instants)",
            verdict.name(),
            leaves.len()
        ),
        curves,
    );
    fig.boxes = figure_boxes(leaves);
    fig.band = band;
    fig.legend = false;
    fig.group_label = group_label;
    fig
}

/// The x-y figure of a run: every sub-box's set at every control instant (as boxes),
/// the target line, the goal band `|x + y| <= band` and a few sampled trajectories on
/// top, equal axes (the layout of the published reachability figure).
pub fn figure(res: &ReachResult, title: &str, band: Option<f64>) -> TrajectoryFigure {
    let (curves, group_label) = sample_curves(&res.samples);
    draw(title, &res.verdict, &res.leaves, curves, group_label, band)
}

//! The x-y figure of a reachability run of the glider: the sets as boxes, the goal band
//! and sampled trajectories. It takes plain boxes and trajectories ([`XyBox`],
//! [`Trajectory`]), not the reachability library's types, so that drawing depends on no
//! engine: the caller (`samara-app`, the reproduction) projects its run onto them.

use crate::{Curve, TrajectoryFigure};

/// Largest number of boxes drawn in a figure; beyond it neighbouring sub-boxes are
/// merged (interval hull, still an over-approximation).
const MAX_FIGURE_BOXES: usize = 20_000;

/// Sampled trajectories drawn on top of the sets.
const MAX_FIGURE_SAMPLES: usize = 24;

/// One set projected to the x-y plane: `[[x_lo, x_hi], [y_lo, y_hi]]`.
pub type XyBox = [[f64; 2]; 2];

/// One sampled trajectory as the figure draws it.
#[derive(Clone, Copy, Debug)]
pub struct Trajectory<'a> {
    /// The initial value of `y` (the curve's legend label).
    pub y0: f64,
    /// Dense `(x, y)` points.
    pub xy: &'a [(f64, f64)],
}

/// The x-y boxes of every sub-box (`sets[i]`: sub-box `i`'s set at each control instant,
/// sub-boxes in order), merged across neighbouring sub-boxes if there are too many to
/// draw. Boxes with a non-finite side are left out.
fn figure_boxes(sets: &[Vec<XyBox>]) -> Vec<(f64, f64, f64, f64)> {
    let total: usize = sets.iter().map(Vec::len).sum();
    let group = total.div_ceil(MAX_FIGURE_BOXES).max(1);
    let mut out = Vec::new();
    for chunk in sets.chunks(group) {
        let steps = chunk.iter().map(Vec::len).max().unwrap_or(0);
        for k in 0..steps {
            let mut b = (
                f64::INFINITY,
                f64::NEG_INFINITY,
                f64::INFINITY,
                f64::NEG_INFINITY,
            );
            for s in chunk {
                if let Some([x, y]) = s.get(k) {
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
pub fn sample_curves(samples: &[Trajectory]) -> (Vec<Curve>, Option<String>) {
    let n = samples.len();
    let step = n.div_ceil(MAX_FIGURE_SAMPLES).max(1);
    let curves: Vec<Curve> = samples
        .iter()
        .enumerate()
        .filter(|(i, _)| *i < 2 || i % step == 0)
        .take(MAX_FIGURE_SAMPLES)
        .map(|(_, smp)| Curve {
            label: format!("y0 = {:.4}", smp.y0),
            points: smp.xy.to_vec(),
        })
        .collect();
    let shown = curves.len();
    (
        curves,
        Some(format!("sampled trajectories ({shown} of {n})")),
    )
}

/// The figure of the final sub-boxes' sets `sets` (in order; see [`figure`]) under the
/// verdict named `verdict`, with the trajectories `curves` (legend entry `group_label`)
/// on top, the layout of [`figure`]: a merged shard run draws its sub-boxes with the
/// curves [`sample_curves`] picked from the run's samples.
pub fn draw(
    title: &str,
    verdict: &str,
    sets: &[Vec<XyBox>],
    curves: Vec<Curve>,
    group_label: Option<String>,
    band: Option<f64>,
) -> TrajectoryFigure {
    let mut fig = TrajectoryFigure::new(
        format!(
            "{title}: {verdict} ({} sub-boxes; sets at control instants)",
            sets.len()
        ),
        curves,
    );
    fig.boxes = figure_boxes(sets);
    fig.band = band;
    fig.legend = false;
    fig.group_label = group_label;
    fig
}

/// The x-y figure of a run: every sub-box's set at every control instant (`sets`, as
/// boxes), the target line, the goal band `|x + y| <= band` and a few of the sampled
/// trajectories `samples` on top, equal axes (the layout of the published reachability
/// figure); `verdict` is the verdict's name.
pub fn figure(
    title: &str,
    verdict: &str,
    sets: &[Vec<XyBox>],
    samples: &[Trajectory],
    band: Option<f64>,
) -> TrajectoryFigure {
    let (curves, group_label) = sample_curves(samples);
    draw(title, verdict, sets, curves, group_label, band)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn merged_boxes_are_the_hull_of_each_group_and_skip_unbounded_sets() {
        // Two sub-boxes, two instants each; few enough that nothing is merged.
        let sets = vec![
            vec![[[0.0, 1.0], [2.0, 3.0]], [[1.0, 2.0], [3.0, 4.0]]],
            vec![
                [[5.0, 6.0], [7.0, 8.0]],
                [[f64::NEG_INFINITY, 0.0], [0.0, 1.0]],
            ],
        ];
        let b = figure_boxes(&sets);
        assert_eq!(
            b,
            vec![
                (0.0, 1.0, 2.0, 3.0),
                (1.0, 2.0, 3.0, 4.0),
                (5.0, 6.0, 7.0, 8.0)
            ]
        );
        // Past the limit, neighbours merge into their interval hull.
        let many: Vec<Vec<XyBox>> = (0..MAX_FIGURE_BOXES + 1)
            .map(|i| vec![[[i as f64, i as f64 + 1.0], [0.0, 1.0]]])
            .collect();
        let b = figure_boxes(&many);
        assert_eq!(b.len(), MAX_FIGURE_BOXES / 2 + 1);
        assert_eq!(b[0], (0.0, 2.0, 0.0, 1.0));
    }

    #[test]
    fn sample_curves_keep_the_extremes_and_say_how_many_are_shown() {
        let pts = [(0.0, 1.0), (1.0, 0.5)];
        let samples: Vec<Trajectory> = (0..50)
            .map(|i| Trajectory {
                y0: 2.0 + i as f64 * 1e-3,
                xy: &pts,
            })
            .collect();
        let (curves, label) = sample_curves(&samples);
        // Step 3 (50 / 24 rounded up): indices 0, 1, then 3, 6, ... up to 24 curves.
        assert_eq!(curves.len(), 18);
        assert_eq!(curves[0].label, "y0 = 2.0000");
        assert_eq!(curves[1].label, "y0 = 2.0010");
        assert_eq!(curves[2].label, "y0 = 2.0030");
        assert_eq!(label.as_deref(), Some("sampled trajectories (18 of 50)"));
    }
}

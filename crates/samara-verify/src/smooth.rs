//! Queries on networks that are not piecewise linear (sigmoid, tanh, the step `Sign`):
//! a front over the one input-split engine for them, [`samara_bounds::smooth`] (CROWN
//! bounds intersected with interval bounds, the interval rule alone after a layer of
//! steps, the inputs fixed in every disjunct folded into the first layer's bias, an
//! attack with the straight-through gradient through `Sign` first). A query of several
//! applications is one network of them side by side ([`samara_bounds::smooth::Apps`]),
//! and a constraint over inputs as well as outputs is one over that network's outputs
//! with those inputs carried through, so every query without free variables is one the
//! engine states as cases ([`crate::boxq::cases_side_by_side`]).
//!
//! Contract, as for every verdict of this crate: `Proved` only from the engine's sound
//! bounds having closed every piece; a point only when its f64 outputs satisfy the
//! disjunct beyond rounding ([`Point::robustly_satisfies`]); anything cut short is
//! `Unknown` with its reason.

use crate::boxq::{cases_side_by_side, BoxUnknown};
use crate::point::Point;
use crate::route::box_reason;
use crate::{Counterexample, UnknownReason, Verdict};
use samara_bounds::search::{Case, CasePoint, Outcome, Settings};
use samara_bounds::smooth::Apps;
use samara_nn::{Activation, Layer, Network};
use samara_num::Timeout;
use samara_spec::normal::Query;

/// Whether a network has a step (`Sign`) layer.
pub fn has_steps(net: &Network) -> bool {
    net.layers
        .iter()
        .any(|l| matches!(l, Layer::Act(Activation::Sign)))
}

/// Decide `q` over `nets` (the applications' networks, in order) with
/// [`samara_bounds::smooth::solve_apps`] within `timeout`; `None` when the query is not
/// one the engine states ([`cases_side_by_side`]). Networks with a step give the first attack
/// half the time (their gradient is the straight-through estimator's, a direction
/// only, and an image-sized binarised network is rarely proved by bounds).
pub fn prove(q: &Query, nets: &[&Network], timeout: Timeout) -> Option<Verdict> {
    let (through, cases) = cases_side_by_side(q)?;
    if cases.is_empty() {
        return Some(Verdict::Proved);
    }
    let apps = Apps {
        nets: nets.to_vec(),
        through,
    };
    let mut settings = Settings {
        timeout,
        ..Default::default()
    };
    let half = 0.5 * timeout.secs();
    if nets.iter().any(|n| has_steps(n)) && half.is_finite() {
        settings.attack_seconds = settings.attack_seconds.max(half);
    }
    // The point of the concatenated inputs `x`, evaluated by every network.
    let point = |x: &[f64]| {
        let mut inputs = Vec::new();
        let mut at = 0;
        for n in nets {
            inputs.push(x[at..at + n.n_inputs()].to_vec());
            at += n.n_inputs();
        }
        Point {
            outputs: nets
                .iter()
                .zip(&inputs)
                .map(|(n, x)| n.eval_f64(x))
                .collect(),
            inputs,
            free: vec![],
        }
    };
    let plain: Vec<Case> = cases.iter().map(|c| c.1.clone()).collect();
    let (outcome, stats) = samara_bounds::smooth::solve_apps(&apps, &plain, &settings);
    let nodes = stats.pieces as usize;
    Some(match outcome {
        Outcome::Proved => Verdict::Proved,
        Outcome::Violated(CasePoint { case, x, .. }) => {
            let d = cases[case].0;
            let pt = point(&x);
            match pt.robustly_satisfies(&q.region[d]) {
                Ok(()) => Verdict::Violated(Counterexample {
                    margin: pt.margin(&q.region[d]),
                    point: pt,
                    exact: None,
                    disjunct: d,
                }),
                Err((margin, tolerance)) => {
                    Verdict::Unknown(UnknownReason::Rounding { margin, tolerance })
                }
            }
        }
        Outcome::Unknown(r) => Verdict::Unknown(match box_reason(BoxUnknown::Stopped(r)) {
            UnknownReason::Timeout { .. } => UnknownReason::Timeout { nodes },
            UnknownReason::NodeLimit { .. } => UnknownReason::NodeLimit { nodes },
            other => other,
        }),
    })
}

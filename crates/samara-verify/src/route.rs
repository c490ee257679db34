//! Engine routing for single-network queries (the VNN-COMP shape): a box-shaped query
//! ([`crate::boxq`]) goes to the input-split branch and bound with CROWN bounds; anything
//! else, and a box-shaped query that engine leaves undecided while time remains (a piece
//! too thin to split in f64, or a point exact arithmetic did not confirm), goes to
//! [`crate::prove`], the exact optimiser with the query's constraints as rows
//! ([`crate::single`]; input and ReLU splitting). The tags `phase` and
//! `input_split+phase` name that route (they are kept as they were when it was a ReLU-phase
//! search, so that result files written before still read).
//!
//! The contract is [`crate::prove`]'s: `Proved` only from a completed sound argument,
//! `Violated` only with a point re-checked in exact rational arithmetic (input-split
//! route) or beyond rounding (optimiser route), `Unknown` with a typed reason otherwise.

use crate::boxq::{prove_boxes, BoxAnswer, BoxUnknown};
use crate::{out_of_range, prove, Prepared, Settings, UnknownReason, Verdict, VerifyError};
use samara_bounds::search::StopReason;
use samara_spec::normal::Query;
use std::time::Instant;

/// Which engine decided.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Engine {
    /// The input-split branch and bound ([`crate::boxq`]).
    InputSplit,
    /// The exact optimiser ([`crate::prove`]), the query not being box-shaped.
    Phase,
    /// The input-split engine gave no verdict with time left; the optimiser ran after.
    InputSplitThenPhase,
}

impl Engine {
    /// A short tag: `input_split`, `phase` or `input_split+phase`.
    pub fn tag(self) -> &'static str {
        match self {
            Engine::InputSplit => "input_split",
            Engine::Phase => "phase",
            Engine::InputSplitThenPhase => "input_split+phase",
        }
    }
}

/// The input-split engine's reason for no verdict, in the crate's terms.
pub fn box_reason(u: BoxUnknown) -> UnknownReason {
    match u {
        BoxUnknown::Stopped(StopReason::Timeout) => UnknownReason::Timeout { nodes: 0 },
        BoxUnknown::Stopped(StopReason::PieceLimit) => UnknownReason::NodeLimit { nodes: 0 },
        BoxUnknown::Stopped(StopReason::Unsplittable) => UnknownReason::Numerical {
            what: "an input box became too small to split in floating point and was neither closed nor refuted by its bounds".into(),
        },
        // The bound of the thin piece's slack is 0 up to rounding.
        BoxUnknown::Stopped(StopReason::ThinRegion) => UnknownReason::ThinRegion { bound: 0.0 },
        BoxUnknown::NotConfirmed => UnknownReason::Rounding {
            margin: 0.0,
            tolerance: 0.0,
        },
    }
}

/// Decide a `Prove` query, routing it as the module doc says. `s.timeout` bounds the
/// whole call (both engines); `s.max_nodes` applies to the optimiser.
pub fn prove_routed(
    q: &Query,
    prep: &Prepared,
    s: &Settings,
) -> Result<(Verdict, Engine), VerifyError> {
    prep.check(q)?;
    let t0 = Instant::now();
    let pwl = match q.applications.as_slice() {
        [a] => prep.pwl.get(&a.network).and_then(|p| p.as_ref().ok()),
        _ => None,
    };
    // Values the encoding cannot take are reported by `prove` (out_of_range).
    let Some(pwl) = pwl.filter(|_| out_of_range(q).is_none()) else {
        return Ok((prove(q, prep, s)?, Engine::Phase));
    };
    let Some(answer) = prove_boxes(q, pwl, s.timeout) else {
        return Ok((prove(q, prep, s)?, Engine::Phase));
    };
    let reason = match answer {
        BoxAnswer::Proved => return Ok((Verdict::Proved, Engine::InputSplit)),
        BoxAnswer::Violated(c) => return Ok((Verdict::Violated(c), Engine::InputSplit)),
        BoxAnswer::Unknown(u) => box_reason(u),
    };
    let left = s.timeout.left(t0);
    if matches!(reason, UnknownReason::Timeout { .. }) || left.is_zero() {
        return Ok((Verdict::Unknown(reason), Engine::InputSplit));
    }
    let v = prove(
        q,
        prep,
        &Settings {
            timeout: left,
            ..*s
        },
    )?;
    Ok((v, Engine::InputSplitThenPhase))
}

//! Closed loops: a variant of the plate (`samara_system::plate`, a system file compiled
//! from its `.sys` source) flown by a declared network under sample and hold, its
//! initial set and the goal `samara reach` decides. [`LoopDecl::system`] lowers a loop
//! to that [`System`] with the loop's period, horizon, initial set and clip.
//!
//! ```text
//! loop published of f: model reduced, period 0.5, horizon 20, clip ex in [0.181, 0.193]
//! start published: v_xp = 1, v_yp = 0, omega = 0, theta = 0, x = 0, y in [1.43, 4.29]
//! goal published: |x + y| <= 2 at 20
//! ```
//!
//! The network reads the plate's six states (its inputs carry their names, in the
//! plant's order, in raw units: the spec's `normalise` lines are composed by the
//! consumer) and its single output is the actuation `ex`. The checks here give each
//! mistake its `file:line:col`; what they let through is what `samara_reach` and
//! closed-loop training accept.

use super::suggest::nearest;
use super::Spec;
use crate::syntax::{Expr, LoopValue, Pos, SpecError};
use samara_system::plate::{self, Variant};
use samara_system::System;

/// The band goal `|x + y| <= bound` around the line `y = -x` (the one goal `samara
/// reach` decides for the built-in plate), at the horizon or over `[from, horizon]`.
#[derive(Clone, Debug, PartialEq)]
pub struct BandGoal {
    /// Half-width of the band.
    pub bound: f64,
    /// Start of the time window; `None`: at the horizon only.
    pub from: Option<f64>,
    /// Where it was declared.
    pub pos: Pos,
}

/// A checked closed loop.
#[derive(Clone, Debug, PartialEq)]
pub struct LoopDecl {
    /// Name.
    pub name: String,
    /// The controller network (a declared network; its raw-unit composition flies).
    pub net: String,
    /// The plate variant (its system file: [`LoopDecl::system`]).
    pub model: Variant,
    /// Control period (sample and hold).
    pub period: f64,
    /// Horizon, a positive multiple of the period.
    pub horizon: f64,
    /// Clip of the controller's output, if any.
    pub clip: Option<(f64, f64)>,
    /// Initial set, one interval per state of `model` in the plant's order (empty until
    /// its `start` statement is read; the filter state `E` starts at 0 unless given).
    pub start: Vec<(f64, f64)>,
    /// The goal, if stated.
    pub goal: Option<BandGoal>,
    /// Where it was declared.
    pub pos: Pos,
}

impl LoopDecl {
    /// The loop as a system: its variant's system file with the loop's period, horizon,
    /// initial set (once its `start` is read) and clip of the actuation. The file's own
    /// goals are dropped: the loop's goal is [`LoopDecl::goal`].
    pub fn system(&self) -> System {
        let mut s = self.model.system();
        s.period = self.period;
        s.horizon = self.horizon;
        if !self.start.is_empty() {
            s.init = self.start.clone();
        }
        s.clips = vec![self.clip; s.inputs.len()];
        s.goals.clear();
        s
    }
}

/// Most control periods a loop may have (as `samara_reach::MAX_PERIODS`).
const MAX_PERIODS: f64 = 100_000.0;

impl Spec {
    /// The loop named `name`.
    pub fn closed_loop(&self, name: &str) -> Option<&LoopDecl> {
        self.loops.iter().find(|l| l.name == name)
    }

    fn loop_index(&self, name: &str, pos: Pos) -> Result<usize, SpecError> {
        let names: Vec<&str> = self.loops.iter().map(|l| l.name.as_str()).collect();
        self.index_named(
            &names,
            name,
            pos,
            (
                "loop",
                "declare it first: loop NAME of f: model reduced, period 0.5, horizon 20",
            ),
        )
    }

    /// Check a `loop` statement and record it.
    pub(super) fn add_loop(
        &mut self,
        name: String,
        net: String,
        clauses: Vec<(String, LoopValue, Pos)>,
        pos: Pos,
    ) -> Result<(), SpecError> {
        if self.loops.iter().any(|l| l.name == name) {
            return Err(self.error(
                pos,
                format!("loop `{name}` is declared twice"),
                "rename one of them",
            ));
        }
        let k = self.net_index(&net, pos)?;
        let (mut model, mut period, mut horizon, mut clip) = (None, None, None, None);
        for (key, value, p) in clauses {
            let seen = match key.as_str() {
                "model" => model.is_some(),
                "period" => period.is_some(),
                "horizon" => horizon.is_some(),
                _ => clip.is_some(),
            };
            if seen {
                return Err(self.error(
                    p,
                    format!("clause `{key}` is given twice"),
                    "give each clause once",
                ));
            }
            match value {
                LoopValue::Name(m) => {
                    let names: Vec<&str> = Variant::ALL.iter().map(|m| m.name()).collect();
                    let Some(found) = Variant::from_name(&m) else {
                        return Err(self.error(
                            p,
                            format!("unknown model `{m}`"),
                            format!("the plate models are {}", names.join(", ")),
                        ));
                    };
                    model = Some(found);
                }
                LoopValue::Number(v) => {
                    if !(v.is_finite() && v > 0.0) {
                        return Err(self.error(
                            p,
                            format!("{key} {v} must be a positive number"),
                            "e.g. period 0.5, horizon 20",
                        ));
                    }
                    if key == "period" {
                        period = Some(v);
                    } else {
                        horizon = Some(v);
                    }
                }
                LoopValue::Clip(out, a, b) => {
                    let outs = &self.networks[k].outputs;
                    if !outs.contains(&out) {
                        return Err(self.error(
                            p,
                            format!("`{out}` is not an output of network `{net}`"),
                            format!("outputs of `{net}`: {}", outs.join(", ")),
                        ));
                    }
                    if !(a.is_finite() && b.is_finite() && a <= b) {
                        return Err(self.error(
                            p,
                            format!("clip interval [{a}, {b}] is empty or not finite"),
                            "write clip OUT in [lo, hi] with finite lo <= hi",
                        ));
                    }
                    clip = Some((a, b));
                }
            }
        }
        let missing = |what: &str| {
            self.error(
                pos,
                format!("loop `{name}` has no {what}"),
                "loop NAME of f: model reduced, period 0.5, horizon 20",
            )
        };
        let model = model.ok_or_else(|| missing("model"))?;
        let period = period.ok_or_else(|| missing("period"))?;
        let horizon = horizon.ok_or_else(|| missing("horizon"))?;
        let periods = horizon / period;
        if !(periods.round() >= 1.0
            && periods <= MAX_PERIODS + 0.5
            && (periods - periods.round()).abs() <= 1e-9 * periods.max(1.0))
        {
            return Err(self.error(
                pos,
                format!("horizon {horizon} is not a multiple of the period {period} (at most 100000 periods)"),
                "choose e.g. period 0.5, horizon 20",
            ));
        }
        let d = &self.networks[k];
        let reads = plate::controller_inputs();
        if d.inputs != reads || d.outputs.len() != 1 {
            return Err(self.error(
                pos,
                format!(
                    "network `{net}` reads ({}) and gives ({}); a closed loop of the plate feeds it the states ({}) and takes one output, the actuation",
                    d.inputs.join(", "),
                    d.outputs.join(", "),
                    reads.join(", ")
                ),
                "declare the controller as network f(v_xp, v_yp, omega, theta, x, y) -> (ex)",
            ));
        }
        self.loops.push(LoopDecl {
            name,
            net,
            model,
            period,
            horizon,
            clip,
            start: Vec::new(),
            goal: None,
            pos,
        });
        Ok(())
    }

    /// Check a `start` statement and record it in its loop.
    pub(super) fn add_start(
        &mut self,
        lp: &str,
        states: Vec<(String, f64, f64, Pos)>,
        pos: Pos,
    ) -> Result<(), SpecError> {
        let k = self.loop_index(lp, pos)?;
        if !self.loops[k].start.is_empty() {
            return Err(self.error(
                pos,
                format!("loop `{lp}` has two start statements"),
                "state its initial set once",
            ));
        }
        let model = self.loops[k].model;
        let names = plate::states(model);
        let mut start: Vec<Option<(f64, f64)>> = vec![None; names.len()];
        for (n, a, b, p) in states {
            let Some(j) = names.iter().position(|s| *s == n) else {
                let hint = nearest(&n, names.iter().map(String::as_str))
                    .map(|s| format!("did you mean `{s}`?"))
                    .unwrap_or_else(|| {
                        format!("the {} model's states: {}", model.name(), names.join(", "))
                    });
                return Err(self.error(
                    p,
                    format!("`{n}` is not a state of the {} model", model.name()),
                    hint,
                ));
            };
            if start[j].is_some() {
                return Err(self.error(
                    p,
                    format!("state `{n}` is given twice"),
                    "give each state once",
                ));
            }
            if !(a.is_finite() && b.is_finite() && a <= b && a >= -1e3 && b <= 1e3) {
                return Err(self.error(
                    p,
                    format!(
                        "initial interval [{a}, {b}] of `{n}` is empty or outside [-1000, 1000]"
                    ),
                    "write `name = v` or `name in [lo, hi]` with finite lo <= hi",
                ));
            }
            start[j] = Some((a, b));
        }
        // The filter state starts at rest unless given.
        if let Some(e) = names.iter().position(|s| s == "E") {
            start[e].get_or_insert((0.0, 0.0));
        }
        let absent: Vec<&str> = names
            .iter()
            .zip(&start)
            .filter(|(_, s)| s.is_none())
            .map(|(n, _)| n.as_str())
            .collect();
        if !absent.is_empty() {
            return Err(self.error(
                pos,
                format!(
                    "the initial set of loop `{lp}` leaves out {}",
                    absent.join(", ")
                ),
                "give every state: `name = v` or `name in [lo, hi]`",
            ));
        }
        self.loops[k].start = start.into_iter().flatten().collect();
        Ok(())
    }

    /// Check a `goal` statement and record it in its loop.
    pub(super) fn add_goal(
        &mut self,
        lp: &str,
        expr: &Expr,
        bound: f64,
        (from, time): (bool, f64),
        pos: Pos,
    ) -> Result<(), SpecError> {
        let k = self.loop_index(lp, pos)?;
        if self.loops[k].goal.is_some() {
            return Err(self.error(
                pos,
                format!("loop `{lp}` has two goals"),
                "state one goal per loop",
            ));
        }
        if !is_band(expr) {
            return Err(self.error(
                pos,
                "the goal of a plate loop bounds |x + y|, the distance to the line y = -x",
                "write goal NAME: |x + y| <= 2 at 20",
            ));
        }
        if !(bound.is_finite() && bound >= 0.0) {
            return Err(self.error(
                pos,
                format!("the goal's bound {bound} must be a finite number >= 0"),
                "e.g. |x + y| <= 2",
            ));
        }
        let horizon = self.loops[k].horizon;
        if !from && time != horizon {
            return Err(self.error(
                pos,
                format!("the goal is decided at the horizon {horizon}, not at {time}"),
                format!("write `at {horizon}`, `from {time}` for the window [{time}, {horizon}], or change the horizon"),
            ));
        }
        if from && !(time >= 0.0 && time <= horizon) {
            return Err(self.error(
                pos,
                format!("the goal's window starts at {time}, outside [0, {horizon}]"),
                format!("write from T with 0 <= T <= {horizon}"),
            ));
        }
        self.loops[k].goal = Some(BandGoal {
            bound,
            from: from.then_some(time),
            pos,
        });
        Ok(())
    }

    /// Every loop has its initial set (called once all statements are read).
    pub(super) fn check_loops(&self) -> Result<(), SpecError> {
        match self.loops.iter().find(|l| l.start.is_empty()) {
            Some(l) => Err(self.error(
                l.pos,
                format!("loop `{}` has no initial set", l.name),
                format!(
                    "add `start {}: v_xp = 1, v_yp = 0, omega = 0, theta = 0, x = 0, y in [1.4, 4.3]`",
                    l.name
                ),
            )),
            None => Ok(()),
        }
    }
}

/// `|x + y|` or `|y + x|`.
fn is_band(e: &Expr) -> bool {
    let Expr::Abs(inner) = e else { return false };
    let Expr::Sum(terms) = inner.as_ref() else {
        return false;
    };
    let name = |t: &(bool, Expr)| match t {
        (false, Expr::Name(None, n, _)) => Some(n.clone()),
        _ => None,
    };
    let names: Vec<Option<String>> = terms.iter().map(name).collect();
    names.len() == 2
        && (names == [Some("x".into()), Some("y".into())]
            || names == [Some("y".into()), Some("x".into())])
}

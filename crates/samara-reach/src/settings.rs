//! Settings of a reachability run, the goal, input errors and their validation.

use crate::zonotope::flow::FlowSettings;
use samara_nn::Network;
use samara_plant::Model;
use serde::Serialize;

/// Largest magnitude of an initial interval's end: the model is nondimensional and the
/// published states are O(1); beyond this the enclosures mean nothing and the sampling
/// would overflow.
pub const MAX_INIT: f64 = 1e3;

/// Largest number of control periods (`horizon / period`) `reach` accepts.
pub const MAX_PERIODS: usize = 100_000;

/// Errors of bad input (verdicts are values, see `Verdict`).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ReachError {
    /// The network does not read the six raw states or does not give one output.
    #[error("the network has {inputs} inputs and {outputs} outputs; the closed loop needs 6 inputs (v_xp, v_yp, omega, theta, x, y in raw units) and 1 output (ex): pass a raw-unit controller such as *_denorm.onnx")]
    NetworkShape {
        /// Inputs found.
        inputs: usize,
        /// Outputs found.
        outputs: usize,
    },
    /// An initial interval is empty, inverted or not finite.
    #[error("initial interval for {name} is [{lo}, {hi}]: give A:B with finite A <= B inside [-1000, 1000]")]
    BadInterval {
        /// State name.
        name: String,
        /// Lower end.
        lo: f64,
        /// Upper end.
        hi: f64,
    },
    /// The initial box has the wrong number of states.
    #[error("the {model} model has {expected} states; the initial set gives {found}")]
    InitDim {
        /// Model name.
        model: &'static str,
        /// Expected.
        expected: usize,
        /// Found.
        found: usize,
    },
    /// Horizon and period do not fit (or give more than [`MAX_PERIODS`] periods).
    #[error("horizon {horizon} is not a positive multiple of the period {period} with at most 100000 periods: choose e.g. --horizon 20 --period 0.5")]
    Horizon {
        /// Horizon.
        horizon: f64,
        /// Period.
        period: f64,
    },
    /// A goal bound that is not a positive finite number, or a start time outside the flight.
    #[error("goal: {0}")]
    Goal(String),
}

/// The goal `|x + y| <= ystar` at `t = T`, or for all `t` in `[from, T]`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Goal {
    /// Half-width of the band around the line `y = -x`.
    pub ystar: f64,
    /// Start of the time window (`None`: only at the horizon).
    pub from: Option<f64>,
}

/// Settings of a reachability run. Defaults: the published CORA setting (reduced model,
/// `y0 ∈ [1.4286, 4.2857]`, horizon 20, period 0.5) with the clip of the simulation.
#[derive(Clone, Debug)]
pub struct ReachSettings {
    /// Model variant.
    pub model: Model,
    /// Initial box, one interval per state (`Model::dim` entries).
    pub init: Vec<(f64, f64)>,
    /// Control period (0.5).
    pub period: f64,
    /// Horizon (20).
    pub horizon: f64,
    /// Output clip of the controller (`Some((0.181, 0.193))`; `None` as in CORA).
    pub clip: Option<(f64, f64)>,
    /// Restart the filter state E at 0 every period, as the simulation (true).
    pub reset_filter: bool,
    /// Goal to decide, if any.
    pub goal: Option<Goal>,
    /// Sub-boxes to start from, along the widest parameter; 0 (the default) picks one per
    /// `auto_piece` of its width, rounded up to a power of two and capped by `max_leaves`
    /// (32 on the published interval, whose CORA runs used 8-16 pieces cut by hand).
    pub initial_splits: usize,
    /// Width per initial sub-box when `initial_splits` is 0 (0.1: with 24 noise
    /// generators per row, 32 pieces of the published interval are as tight as 64 were
    /// with 4, in half the time; the budget left splits the noisiest).
    pub auto_piece: f64,
    /// Largest number of sub-boxes (64); sub-boxes that lost their enclosure may use a
    /// quarter more.
    pub max_leaves: usize,
    /// Split a sub-box when the noise part of its `x + y` enclosure exceeds this (0.01).
    pub max_noise: f64,
    /// Sub-boxes narrower than this fraction of the initial width are not split (1e-4).
    pub min_fraction: f64,
    /// Simulated trajectories for falsification and the figure (200).
    pub samples: usize,
    /// Seed of the sampling.
    pub seed: u64,
    /// Keep every sub-box's zonotope at every control instant (tests; memory).
    pub keep_sets: bool,
    /// Validated integrator settings.
    pub flow: FlowSettings,
}

/// How many actuator-range widths outside the range a network's raw output must lie,
/// at most of the sample states, for [`units_warning`] to suspect its units. A raw-unit
/// controller of the glider stays within about one width of the range (the published
/// `_denorm` networks: 0.1818 to 0.1936 over the nine published flights, range [0.181,
/// 0.193]); a normalised one read with raw states gives 0.5 to 100.
pub const UNITS_FACTOR: f64 = 10.0;

/// A suspected units mismatch, in words (`None` when none is seen): the network's raw
/// output (before any clip) at `states` (the controller reads their first
/// `net.n_inputs()` values) lies more than [`UNITS_FACTOR`] widths of the actuator range
/// `range` outside it at more than half of them. The likely cause is a network in
/// normalised units (inputs in [0, 1], a normalised output) flown where physical units
/// are expected; the clip would then pin every control to an end of the range, and the
/// flight or the sets would be the clip's, not the network's.
pub fn units_warning(net: &Network, states: &[Vec<f64>], range: (f64, f64)) -> Option<String> {
    let n = net.n_inputs();
    let outs: Vec<f64> = states
        .iter()
        .filter(|x| x.len() >= n && net.n_outputs() == 1)
        .map(|x| net.eval_f64(&x[..n])[0])
        .collect();
    let width = (range.1 - range.0).max(f64::MIN_POSITIVE);
    let far = outs
        .iter()
        .filter(|y| {
            let d = if **y < range.0 {
                range.0 - **y
            } else {
                **y - range.1
            };
            // NaN counts as far: no control at all.
            d.is_nan() || d > UNITS_FACTOR * width
        })
        .count();
    if outs.is_empty() || 2 * far <= outs.len() {
        return None;
    }
    let lo = outs.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = outs.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let layers = if net.input_norm.is_none() && net.output_denorm.is_none() {
        " and the file carries no normalisation layers"
    } else {
        ""
    };
    Some(format!(
        "the network's output at {far} of {} initial states lies more than {UNITS_FACTOR} times the actuator range's width outside [{}, {}] (from {lo:.4} to {hi:.4}){layers}: it looks like a network in normalised units (inputs in [0, 1], a normalised output) where physical units are expected, and every control would be pinned to the clip; pass the raw-unit network (the `_denorm` file, e.g. base_model_denorm.onnx), or declare the normalisation in a spec (`normalise NAME input/output`, with --spec)",
        outs.len(),
        range.0,
        range.1
    ))
}

/// The built-in plant model of a plate variant (a spec loop's `model`; the same name):
/// what the published glider engine flies.
pub fn plant_model(v: samara_system::plate::Variant) -> Model {
    use samara_system::plate::Variant;
    match v {
        Variant::Plate6 => Model::Plate6,
        Variant::Reduced => Model::Reduced,
        Variant::Full => Model::Full,
    }
}

impl ReachSettings {
    /// The corners of the initial box over its first six parameters (the states with a
    /// non-zero width; at most 64 corners, the other states at their single value),
    /// corner `c` taking the upper end of parameter `j` where bit `j` of `c` is set. The
    /// falsification flights start here first ([`crate::sampling::simulate_samples`]),
    /// and [`ReachSettings::units_warning`] evaluates the network here.
    pub fn corners(&self) -> Vec<Vec<f64>> {
        let params: Vec<usize> = (0..self.init.len())
            .filter(|&i| self.init[i].1 > self.init[i].0)
            .take(6)
            .collect();
        (0..1usize << params.len())
            .map(|corner| {
                let mut x: Vec<f64> = self.init.iter().map(|b| b.0).collect();
                for (j, &i) in params.iter().enumerate() {
                    if corner >> j & 1 == 1 {
                        x[i] = self.init[i].1;
                    }
                }
                x
            })
            .collect()
    }

    /// [`units_warning`] at the initial set's [corners](ReachSettings::corners) and
    /// centre, against the run's clip (the actuator range `samara_plant::EX_RANGE`
    /// without one).
    pub fn units_warning(&self, net: &Network) -> Option<String> {
        let mut states = self.corners();
        states.push(self.init.iter().map(|b| 0.5 * (b.0 + b.1)).collect());
        units_warning(net, &states, self.clip.unwrap_or(samara_plant::EX_RANGE))
    }

    /// The published setting for `model`: `y0 ∈ [1.4286, 4.2857]`, start `(1,0,0,0,0,y0)`.
    pub fn published(model: Model) -> Self {
        let mut init = vec![(1.0, 1.0), (0.0, 0.0), (0.0, 0.0), (0.0, 0.0), (0.0, 0.0)];
        init.push((0.1 / 0.07, 0.3 / 0.07));
        if model.has_filter() {
            init.push((0.0, 0.0));
        }
        ReachSettings {
            model,
            init,
            period: 0.5,
            horizon: 20.0,
            clip: Some(samara_plant::EX_RANGE),
            reset_filter: true,
            goal: None,
            initial_splits: 0,
            auto_piece: 0.1,
            max_leaves: 64,
            max_noise: 0.01,
            min_fraction: 1e-4,
            samples: 200,
            seed: 1,
            keep_sets: false,
            flow: FlowSettings::default(),
        }
    }

    /// The settings of a spec's closed loop ([`samara_spec::LoopDecl`]: model, initial
    /// set, period, horizon, clip, goal); the budgets are [`ReachSettings::published`]'s.
    /// The shipped case-study spec's loop `published` gives exactly
    /// `ReachSettings::published(Model::Reduced)` with the goal `|x + y| <= 2` at `t = 20`.
    pub fn from_loop(l: &samara_spec::LoopDecl) -> Self {
        let mut s = ReachSettings::published(plant_model(l.model));
        s.init = l.start.clone();
        s.period = l.period;
        s.horizon = l.horizon;
        s.clip = l.clip;
        s.goal = l.goal.as_ref().map(|g| Goal {
            ystar: g.bound,
            from: g.from,
        });
        s
    }

    fn steps(&self) -> Result<usize, ReachError> {
        let err = ReachError::Horizon {
            horizon: self.horizon,
            period: self.period,
        };
        if !(self.period > 0.0 && self.horizon > 0.0 && self.period.is_finite()) {
            return Err(err);
        }
        let k = self.horizon / self.period;
        if !k.is_finite()
            || k > MAX_PERIODS as f64 + 0.5
            || (k - k.round()).abs() > 1e-9 * k.max(1.0)
            || k.round() < 1.0
        {
            return Err(err);
        }
        Ok(k.round() as usize)
    }

    /// Check the settings against the model and network.
    pub fn validate(&self, net: &Network) -> Result<usize, ReachError> {
        if net.n_inputs() != 6 || net.n_outputs() != 1 {
            return Err(ReachError::NetworkShape {
                inputs: net.n_inputs(),
                outputs: net.n_outputs(),
            });
        }
        if self.init.len() != self.model.dim() {
            return Err(ReachError::InitDim {
                model: self.model.name(),
                expected: self.model.dim(),
                found: self.init.len(),
            });
        }
        for (i, &(lo, hi)) in self.init.iter().enumerate() {
            if !(lo.is_finite() && hi.is_finite() && lo <= hi && lo >= -MAX_INIT && hi <= MAX_INIT)
            {
                return Err(ReachError::BadInterval {
                    name: samara_plant::STATE_NAMES[i].into(),
                    lo,
                    hi,
                });
            }
        }
        if let Some(g) = &self.goal {
            if !(g.ystar.is_finite() && g.ystar >= 0.0) {
                return Err(ReachError::Goal(format!(
                    "ystar {} must be a finite number >= 0",
                    g.ystar
                )));
            }
            if let Some(f) = g.from {
                if !(f >= 0.0 && f <= self.horizon) {
                    return Err(ReachError::Goal(format!(
                        "--goal-from {f} must lie in [0, horizon = {}]",
                        self.horizon
                    )));
                }
            }
        }
        self.steps()
    }
}

#[cfg(test)]
mod units_tests {
    use super::*;
    use samara_nn::{Affine, Layer};

    /// `ex = w * y + b` over the six states (only y, the sixth, weighs).
    fn net(w: f64, b: f64) -> Network {
        Network {
            input_names: (0..6).map(|i| format!("s{i}")).collect(),
            output_names: vec!["ex".into()],
            input_norm: None,
            layers: vec![Layer::Affine(Affine::new(
                6,
                1,
                vec![0.0, 0.0, 0.0, 0.0, 0.0, w],
                vec![b],
            ))],
            output_denorm: None,
        }
    }

    #[test]
    fn units_warning_needs_most_outputs_far_outside_the_range() {
        let states: Vec<Vec<f64>> = [1.0, 2.0, 3.0]
            .iter()
            .map(|&y| vec![1.0, 0.0, 0.0, 0.0, 0.0, y])
            .collect();
        let range = (0.181, 0.193);
        // Ten widths of the range is 0.12 on either side.
        assert!(units_warning(&net(0.0, 0.187), &states, range).is_none());
        assert!(units_warning(&net(0.0, 0.193 + 0.119), &states, range).is_none());
        assert!(units_warning(&net(0.0, 0.193 + 0.121), &states, range).is_some());
        assert!(units_warning(&net(0.0, 0.181 - 0.121), &states, range).is_some());
        // 0.1 y + 0.1 = 0.2, 0.3, 0.4: one state of three far out, not most of them.
        assert!(units_warning(&net(0.1, 0.1), &states, range).is_none());
        // 0.2 y - 0.01 = 0.19, 0.39, 0.59: two of three.
        let w = units_warning(&net(0.2, -0.01), &states, range).unwrap();
        assert!(w.contains("at 2 of 3 initial states"), "{w}");
        assert!(w.contains("no normalisation layers"), "{w}");
        let w = units_warning(&net(0.0, f64::NAN), &states, range).unwrap();
        assert!(w.contains("3 of 3 initial states"), "{w}");
    }
}

//! Controllers of the sample-and-hold loop: the published PID law (docs/model.md section 4),
//! a constant input, and a neural network.

use samara_nn::Network;
use samara_plant::EX_RANGE;

/// A controller sampled at each control instant; its output is held for one period.
pub trait Controller: Send {
    /// A short name for reports.
    fn name(&self) -> String;
    /// Forget any memory (called at the start of every flight).
    fn reset(&mut self);
    /// The control input `ex` for the plant state at a control instant. The state has
    /// the filter state `E` (end value of the previous period) as component 6 when the
    /// model carries it.
    fn act(&mut self, state: &[f64]) -> f64;
}

/// The PID law of the published data generation, with its quirks kept: the "error" is
/// the filter state E at the end of the previous period, the derivative is the backward
/// difference `e_prev - err` per control step (gain -0.5), the integral gain is 0, and
/// the result is clipped to [0.181, 0.193]. In closed form
/// `ex_k = clip(0.19 + 0.55 E_{k-1} - 0.5 E_{k-2})`.
#[derive(Clone, Debug)]
pub struct PidController {
    /// Offset (0.19).
    pub offset: f64,
    /// Proportional gain (0.05).
    pub kp: f64,
    /// Derivative gain (-0.5), applied to `e_prev - err`.
    pub kd: f64,
    /// Integral gain (0.0).
    pub ki: f64,
    /// Output clip.
    pub clip: (f64, f64),
    e_prev: f64,
    sum: f64,
}

impl Default for PidController {
    fn default() -> Self {
        PidController {
            offset: 0.19,
            kp: 0.05,
            kd: -0.5,
            ki: 0.0,
            clip: EX_RANGE,
            e_prev: 0.0,
            sum: 0.0,
        }
    }
}

impl Controller for PidController {
    fn name(&self) -> String {
        "pid".into()
    }
    fn reset(&mut self) {
        self.e_prev = 0.0;
        self.sum = 0.0;
    }
    fn act(&mut self, state: &[f64]) -> f64 {
        let err = state.get(6).copied().unwrap_or(0.0);
        let deriv = self.e_prev - err;
        // MATLAB's sum(errors) includes the errors of all previous steps (times ki = 0).
        let ex = self.offset + err * self.kp + deriv * self.kd + self.sum * self.ki;
        let ex = ex.max(self.clip.0).min(self.clip.1);
        self.sum += err;
        self.e_prev = err;
        ex
    }
}

/// A constant input.
#[derive(Clone, Debug)]
pub struct ConstantController(pub f64);

impl Controller for ConstantController {
    fn name(&self) -> String {
        format!("constant:{}", self.0)
    }
    fn reset(&mut self) {}
    fn act(&mut self, _state: &[f64]) -> f64 {
        self.0
    }
}

/// A network controller in raw units: `ex = clip(net(v_xp, v_yp, omega, theta, x, y))`,
/// as in the published NN simulation (clip once per step), or unclipped as in the
/// published CORA model.
#[derive(Clone, Debug)]
pub struct NetworkController {
    /// The network (6 raw inputs, 1 raw output).
    pub net: Network,
    /// Output clip, `None` for none.
    pub clip: Option<(f64, f64)>,
    /// Name for reports.
    pub label: String,
}

impl NetworkController {
    /// Wrap a network; the caller has checked it has 6 inputs and 1 output.
    pub fn new(net: Network, clip: Option<(f64, f64)>, label: impl Into<String>) -> Self {
        NetworkController {
            net,
            clip,
            label: label.into(),
        }
    }
}

impl Controller for NetworkController {
    fn name(&self) -> String {
        self.label.clone()
    }
    fn reset(&mut self) {}
    fn act(&mut self, state: &[f64]) -> f64 {
        let ex = self.net.eval_f64(&state[..6])[0];
        match self.clip {
            Some((lo, hi)) => ex.max(lo).min(hi),
            None => ex,
        }
    }
}

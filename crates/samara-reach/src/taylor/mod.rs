//! Sound reachable sets of any closed loop written as a system file (`samara-system`):
//! Taylor-model sets in the initial-set parameters, the plant integrated by the
//! validated Taylor-model flowpipe ([`flow`]), the network bounded over each
//! set by CROWN with the set's linear part kept symbolic ([`samara_bounds::linset`]).
//!
//! Data flow of one sub-box `B` of the initial set (states with a non-zero width are
//! the parameters `xi in [-1, 1]^n`, `x_i = mid_i + rad_i xi_i`):
//! 1. at each control instant but the horizon: the resets (when they fire and what the
//!    set at an instant is come from `samara_system::System::begin_period`); the
//!    network's inputs `observe(x)` as Taylor models; their linear part `c + G xi`
//!    goes to CROWN, the rest (higher-order terms and remainders) as a noise box; the
//!    network's outputs come back as `coef . xi + cst +- dev` (Taylor models of
//!    order 1 with an interval remainder) —
//!    or, for networks without ReLU, the network evaluated on the Taylor models
//!    themselves (Taylor expansion of tanh / sigmoid), whichever is narrower;
//! 2. the inputs `actuate(outputs)` then the clips, on Taylor models (a clip that is
//!    inactive over the set stays exact);
//! 3. one control period of the plant by the flowpipe, which also returns the boxes of
//!    every step inside the period (for goals over time windows);
//! 4. the goals decided on the sets: a band with an affine `g(x)` on the Taylor models
//!    themselves (the dependence kept), boxes on the interval hull.
//!
//! Sub-boxes whose enclosure is lost or whose goal is undecided are cut in two along the
//! widest parameter (relative to the initial set) and flown again from `t = 0`, within a
//! budget; the frontier is flown in parallel (`rayon`). Before any of it, simulated
//! flights (the initial box's corners, its centre and random starts) look for a
//! counterexample.
//!
//! Verdicts: `proved` only when every sub-box's sets decide every goal true; `violated`
//! only with a simulated flight that misses a goal; `unknown` with the reason otherwise.//!
//! Files: [`settings`] (settings, measures, errors), `result` (verdict,
//! sub-boxes, summary), `driver` (the run), `refine` (splitting), `flight` (one sub-box
//! over the horizon), `network` (the controller over Taylor models), [`flow`] (the
//! flowpipe of one period), `standin` (polynomial stand-ins for non-smooth operations);
//! the Taylor-model reduction is `samara_num`'s.

pub(crate) mod driver;
pub(crate) mod flight;
pub mod flow;
pub(crate) mod network;
pub(crate) mod refine;
pub(crate) mod result;
pub mod settings;
pub(crate) mod standin;

pub use driver::{reach_system, starts};
pub use network::network_over;
pub use result::{SystemLeaf, SystemReach, SystemVerdict, SystemViolation};
pub use samara_num::tm_reduce::{precondition, reduce, reduce_with};
pub use settings::{
    end_band_measures, Measure, MeasureRange, NetworkError, SystemReachError, SystemReachSettings,
    NETWORK_ERROR_LADDER,
};

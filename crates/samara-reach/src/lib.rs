//! Sound reachable sets of network-controlled closed loops: the Alsomitra glider and any
//! plant written as a system file.
//!
//! The closed loop is the same as in simulation (`samara-sim`): at each control instant
//! the network reads the state, its (clipped) output is held for one period while the
//! plant flies. Here both halves run on sets, by one of two engines, each in its own
//! folder, beside what they share:
//! - [`zonotope`]: the glider's engine, on zonotopes ([`zonotope::netstep`] the
//!   controller output over a zonotope, kept affine in its generators by CROWN;
//!   [`zonotope::flow`] validated Taylor integration of the plant, Lohner-style, with the
//!   plant's own equations run on Taylor series of intervals; [`zonotope::driver`] the
//!   initial set as a box of parameters, cut into sub-boxes along the widest parameter,
//!   each flown over the whole horizon in parallel with `rayon`, and a sub-box that lost
//!   its enclosure, carries too much noise in its final `x + y` or leaves the goal
//!   undecided cut in two and flown again from `t = 0`, within the sub-box budget);
//! - [`taylor`]: any closed loop written as a system file, on Taylor models in the
//!   initial-set parameters (settings, driver, refinement, one sub-box's flight, the
//!   network over Taylor models, the flowpipe);
//! - shared: [`taylor_step`] (the validated Taylor step both engines take: a-priori
//!   enclosure, time coefficients, Lagrange remainder), [`settings`] (the glider run's settings, the goal, their validation), [`result`]
//!   and [`verdict`] (what a glider run returns and how the goal is decided on it),
//!   [`sampling`] (simulated trajectories: falsification first, figures), [`parts`]
//!   (a glider run cut into shards and merged), [`grid`] and [`adaptive`] (the system
//!   run over a grid of cells, and adaptively);
//! - [`discrete`]: discrete-time system files (`next` updates, a mode set by `argmax`,
//!   networks switched by the mode) on boxes, with the sound argmax.
//!
//! Verdicts: `Proved` only when every sub-box's enclosure satisfies the goal; `Violated`
//! only with a concrete simulated trajectory; `Unknown` with the reason otherwise.

#![warn(missing_docs)]

pub mod adaptive;
pub mod discrete;
pub mod grid;
pub mod parts;
pub mod result;
pub mod sampling;
pub mod settings;
pub mod taylor;
pub mod taylor_step;
pub mod verdict;
pub mod zonotope;

pub use result::{
    check_containment, GliderViolation, Leaf, ReachResult, ReachVerdict, StepSet, Verdict,
};
pub use sampling::{simulate_samples, Sample};
pub use settings::{plant_model, Goal, ReachError, ReachSettings, MAX_INIT, MAX_PERIODS};
pub use zonotope::driver::reach;
pub use zonotope::Zonotope;

/// The system-file (Taylor-model) engine under its former path, `samara_reach::system`.
pub use taylor as system;
/// The Taylor-model flowpipe under its former path, `samara_reach::tmflow`.
pub use taylor::flow as tmflow;

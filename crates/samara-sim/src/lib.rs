//! Simulation for samara: integrators, controllers and the sample-and-hold closed loop.
//!
//! - [`explicit_rk`]: the one adaptive explicit Runge-Kutta driver, running a Butcher
//!   tableau ([`tableau`]: DP5(4), DOP853) under a step-control policy: the standard
//!   control of Hairer, Norsett & Wanner (*Solving ODEs I*, II.4 and II.10), or
//! - [`ode45`]: a clone of MATLAB's `ode45` step control (Dormand-Prince 5(4), Shampine &
//!   Reichelt 1997), exactly as `docs/model.md` section 5, so the published data are
//!   regenerated bit-faithfully.
//! - [`dop853`]: DOP853 (order 8) under the standard control, by default at rtol 1e-10,
//!   atol 1e-12 (the CLI's `dop853`, alias `tight`).
//! - [`dopri`]: DP5(4) under the standard control (the CLI's `dp5`).
//! - [`rk4`]: classical fixed-step Runge-Kutta, over any `Scalar` (dual numbers too).
//! - [`dynamics`]: the [`Dynamics`] trait, one description of `x' = f(x, u)` that the
//!   built-in plant and a system file implement.
//! - [`control`]: the [`Controller`] trait, the published PID law, constant and network
//!   controllers.
//! - [`closed_loop`]: the sample-and-hold loop ([`sample_and_hold`], written once for
//!   the glider, system files and training; [`Integrator::hold`], one period of any
//!   [`Dynamics`]) and the data-generation protocol.
#![warn(missing_docs)]
// Numeric kernels index several arrays by the same stage/component index, and the
// `!(err <= 1.0)` tests deliberately treat NaN as a rejected step.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

pub mod closed_loop;
pub mod control;
pub mod dataset;
pub mod dop853;
mod dop853_tableau;
pub mod dopri;
pub mod dynamics;
pub mod explicit_rk;
pub mod ode45;
pub mod rk4;
pub mod tableau;

pub use closed_loop::{
    fly, initial_state, minmax, published_starts, sample_and_hold, training_rows, Dense, Flight,
    Integrator, LoopSettings, SimError, StepRecord,
};
pub use control::{ConstantController, Controller, NetworkController, PidController};
pub use dynamics::Dynamics;
pub use explicit_rk::{Collapse, Stats, Tolerances};
pub use rk4::Rk4;

/// Largest state dimension handled by the fixed-size integrator buffers.
pub const MAX_DIM: usize = 12;

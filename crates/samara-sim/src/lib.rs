//! Simulation for samara: integrators, controllers and the sample-and-hold closed loop.
//!
//! - [`ode45`]: a clone of MATLAB's `ode45` step control (Dormand-Prince 5(4), Shampine &
//!   Reichelt 1997), exactly as `docs/MODEL.md` section 5, so the published data are
//!   regenerated bit-faithfully.
//! - [`dop853`]: the tight mode, DOP853 (order 8) at rtol 1e-10, atol 1e-12.
//! - [`dopri`]: tight-tolerance Dormand-Prince integration with standard (Hairer,
//!   Norsett & Wanner, *Solving ODEs I*, II.4) error control.
//! - [`rk4`]: classical fixed-step Runge-Kutta.
//! - [`control`]: the [`Controller`] trait, the published PID law, constant and network
//!   controllers.
//! - [`closed_loop`]: the sample-and-hold loop and the data-generation protocol.

// Numeric kernels index several arrays by the same stage/component index, and the
// `!(err <= 1.0)` tests deliberately treat NaN as a rejected step.
#![allow(clippy::needless_range_loop, clippy::neg_cmp_op_on_partial_ord)]

pub mod closed_loop;
mod common;
pub mod control;
pub mod dataset;
pub mod dop853;
mod dop853_tableau;
pub mod dopri;
pub mod ode45;
pub mod rk4;

pub use closed_loop::{
    fly, initial_state, minmax, published_starts, training_rows, Dense, Flight, Integrator,
    LoopSettings, SimError, StepRecord,
};
pub use control::{ConstantController, Controller, NetworkController, PidController};

/// Largest state dimension handled by the fixed-size integrator buffers.
pub const MAX_DIM: usize = 8;

//! The one description of a plant's continuous dynamics that the simulator, training
//! and the reachability code share: the built-in glider ([`Plant`]) and a system file
//! (`samara_system::System`) both implement [`Dynamics`], and the sample-and-hold loop
//! ([`crate::closed_loop::sample_and_hold`]) runs over either.

use samara_num::Scalar;
use samara_plant::Plant;

/// A plant's continuous dynamics `x' = f(x, u)`, evaluable over any [`Scalar`] (`f64` to
/// simulate, dual numbers to differentiate a flight, intervals and Taylor models to
/// enclose one).
pub trait Dynamics {
    /// Number of states.
    fn dim(&self) -> usize;
    /// Number of inputs (held constant over a control period).
    fn n_inputs(&self) -> usize;
    /// `out = f(x, u)`; `x` has [`Dynamics::dim`] entries, `u` [`Dynamics::n_inputs`].
    fn rhs<S: Scalar>(&self, x: &[S], u: &[S], out: &mut [S]);
    /// As [`Dynamics::rhs`], with a caller-owned value buffer that an interpreted
    /// implementation reuses between calls (the default ignores it).
    fn rhs_buffered<S: Scalar>(&self, scratch: &mut Vec<S>, x: &[S], u: &[S], out: &mut [S]) {
        let _ = scratch;
        self.rhs(x, u, out)
    }
}

/// The built-in glider: its one input is the control `ex`.
impl Dynamics for Plant {
    fn dim(&self) -> usize {
        Plant::dim(self)
    }
    fn n_inputs(&self) -> usize {
        1
    }
    fn rhs<S: Scalar>(&self, x: &[S], u: &[S], out: &mut [S]) {
        Plant::rhs(self, x, &u[0], out)
    }
}

//! DOP853, the order-8 pair of Dormand & Prince with error estimators of orders 5 and 3,
//! under the standard step control (Hairer, Norsett & Wanner, *Solving ODEs I*, II.10):
//! the [`DOP853`] tableau on the one adaptive driver ([`crate::explicit_rk`]). samara's
//! tight mode: about 40% fewer right-hand-side evaluations than the 5(4) pair at rtol
//! 1e-10. Output points use a cubic Hermite interpolant between accepted steps (used
//! only for trajectories and figures; the states at control instants are exact
//! integrator states).

use crate::explicit_rk::{Stats, Tolerances};
use crate::tableau::DOP853;

/// Integrate `y' = f(y)` from `t0` to `tf` (`tf > t0`), landing exactly on `tf`. If
/// `out` is given, pushes the state at each of `out_times` in `(t0, tf]`.
pub fn integrate<F>(
    f: F,
    y: &mut [f64],
    t0: f64,
    tf: f64,
    tol: Tolerances,
    out_times: &[f64],
    out: Option<&mut Vec<f64>>,
) -> Stats
where
    F: FnMut(&[f64], &mut [f64]),
{
    integrate_from(f, y, t0, tf, tol, None, out_times, out)
}

/// As [`integrate`], starting with step `h_init` when given (e.g. the [`Stats::h_next`]
/// of the previous control period, which saves the start-up steps of a restart).
#[allow(clippy::too_many_arguments)]
pub fn integrate_from<F>(
    f: F,
    y: &mut [f64],
    t0: f64,
    tf: f64,
    tol: Tolerances,
    h_init: Option<f64>,
    out_times: &[f64],
    out: Option<&mut Vec<f64>>,
) -> Stats
where
    F: FnMut(&[f64], &mut [f64]),
{
    assert!(tf > t0);
    crate::explicit_rk::integrate(&DOP853, f, y, t0, tf, tol, h_init, out_times, out)
}

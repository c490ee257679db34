//! Dormand-Prince 5(4) at tight tolerances under the standard step control: the
//! [`DP54`] tableau on the one adaptive driver ([`crate::explicit_rk`]).

use crate::explicit_rk::Stats;
use crate::tableau::DP54;

pub use crate::explicit_rk::Tolerances;

/// Integrate `y' = f(y)` from `t0` to `tf` (either direction), landing exactly on `tf`.
/// If `out` is given, pushes the state at each of `out_times` in `(t0, tf]` (cubic
/// Hermite between accepted steps, exact at `tf`).
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
    crate::explicit_rk::integrate(&DP54, f, y, t0, tf, tol, None, out_times, out)
}

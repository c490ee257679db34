//! DOP853: the explicit Runge-Kutta pair of order 8 with 5th- and 3rd-order error
//! estimators of Dormand & Prince, with the step control of Hairer, Norsett & Wanner
//! (*Solving ODEs I*, section II.10: combined error norm
//! `|h| err5^2 / sqrt((err5^2 + 0.01 err3^2) n)`, exponent 1/8, safety 0.9, factor
//! limits 0.2..10). The tight mode of samara: about 40% fewer right-hand-side
//! evaluations than the 5(4) pair at rtol 1e-10. Output points use a cubic Hermite
//! interpolant between accepted steps (used only for trajectories and figures; the
//! states at control instants are exact integrator states).

use crate::dop853_tableau::{A, B, E3, E5};
use crate::dopri::Tolerances;
use crate::ode45::Stats;
use crate::MAX_DIM;

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
    mut f: F,
    y: &mut [f64],
    t0: f64,
    tf: f64,
    tol: Tolerances,
    h_init: Option<f64>,
    out_times: &[f64],
    mut out: Option<&mut Vec<f64>>,
) -> Stats
where
    F: FnMut(&[f64], &mut [f64]),
{
    let n = y.len();
    assert!(n <= MAX_DIM && tf > t0);
    let mut stats = Stats::default();
    let mut k = [[0.0f64; MAX_DIM]; 12];
    let mut fnew = [0.0f64; MAX_DIM];
    f(&y[..n], &mut k[0][..n]);
    stats.evals += 1;
    let mut h = crate::common::initial_step(&y[..n], &k[0][..n], tol);
    if let Some(hi) = h_init.filter(|v| v.is_finite() && *v > 0.0) {
        h = hi;
    }
    h = h.min(tf - t0);
    let mut h_proposed = h;
    let mut t = t0;
    let mut ys = [0.0f64; MAX_DIM];
    let mut ynew = [0.0f64; MAX_DIM];
    let mut next_out = out_times
        .iter()
        .position(|&to| to > t0)
        .unwrap_or(out_times.len());
    let mut last_rejected = false;
    let inv_n = 1.0 / n as f64;
    loop {
        let last = t + h >= tf;
        if last {
            h_proposed = h_proposed.max(h);
            h = tf - t;
        }
        for s in 1..12 {
            let row = &A[s];
            for i in 0..n {
                let mut acc = 0.0;
                for j in 0..s {
                    acc += row[j] * k[j][i];
                }
                ys[i] = y[i] + h * acc;
            }
            f(&ys[..n], &mut k[s][..n]);
        }
        stats.evals += 11;
        let (mut e5, mut e3) = (0.0, 0.0);
        for i in 0..n {
            let (mut acc, mut a5, mut a3) = (0.0, 0.0, 0.0);
            for j in 0..12 {
                acc += B[j] * k[j][i];
                a5 += E5[j] * k[j][i];
                a3 += E3[j] * k[j][i];
            }
            ynew[i] = y[i] + h * acc;
            let sc = tol.atol + tol.rtol * y[i].abs().max(ynew[i].abs());
            e5 += (a5 / sc).powi(2);
            e3 += (a3 / sc).powi(2);
        }
        let den = e5 + 0.01 * e3;
        let err = if den > 0.0 {
            h.abs() * e5 * (inv_n / den).sqrt()
        } else {
            0.0
        };
        if !(err <= 1.0) {
            stats.rejected += 1;
            h *= crate::common::reject_factor(err, 0.125);
            last_rejected = true;
            continue;
        }
        stats.accepted += 1;
        f(&ynew[..n], &mut fnew[..n]);
        stats.evals += 1;
        let tnew = if last { tf } else { t + h };
        if let Some(o) = out.as_deref_mut() {
            crate::common::hermite_outputs(
                o,
                out_times,
                &mut next_out,
                t,
                tnew,
                &y[..n],
                &k[0][..n],
                &ynew[..n],
                &fnew[..n],
            );
        }
        t = tnew;
        y[..n].copy_from_slice(&ynew[..n]);
        k[0] = fnew;
        let fac = crate::common::accept_factor(err, 0.125, last_rejected);
        last_rejected = false;
        if last {
            // The final step was shortened to land on tf: propose what the controller
            // would have taken next from the unshortened step.
            stats.h_next = if h < h_proposed { h_proposed } else { h * fac };
            break;
        }
        h *= fac;
        h_proposed = h;
    }
    stats
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kepler_orbit_closes_to_tight_tolerance() {
        // Circular two-body orbit: period 2 pi, returns to its start.
        let mut y = [1.0, 0.0, 0.0, 1.0];
        let tf = 2.0 * std::f64::consts::PI;
        let stats = integrate(
            |y, d| {
                let r3 = (y[0] * y[0] + y[1] * y[1]).powf(1.5);
                d[0] = y[2];
                d[1] = y[3];
                d[2] = -y[0] / r3;
                d[3] = -y[1] / r3;
            },
            &mut y,
            0.0,
            tf,
            Tolerances::default(),
            &[],
            None,
        );
        assert!((y[0] - 1.0).abs() < 1e-8 && y[1].abs() < 1e-8, "{y:?}");
        assert!(stats.evals < 3000);
    }

    #[test]
    fn eighth_order_beats_fifth_order_on_evaluations() {
        let rhs = |y: &[f64], d: &mut [f64]| {
            d[0] = y[1];
            d[1] = -y[0];
        };
        let mut a = [1.0, 0.0];
        let mut b = [1.0, 0.0];
        let s8 = integrate(rhs, &mut a, 0.0, 20.0, Tolerances::default(), &[], None);
        let s5 = crate::dopri::integrate(rhs, &mut b, 0.0, 20.0, Tolerances::default(), &[], None);
        assert!(s8.evals < s5.evals, "{} vs {}", s8.evals, s5.evals);
        assert!((a[0] - 20f64.cos()).abs() < 1e-8);
    }
}

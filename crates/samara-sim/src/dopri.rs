//! Tight-tolerance Dormand-Prince 5(4) integration with the standard step-size control
//! of Hairer, Norsett & Wanner (*Solving ODEs I*, section II.4: RMS error norm with
//! `atol + rtol * max(|y|, |ynew|)` scaling, safety 0.9, factor limits 0.2..10), the
//! FSAL property and a cubic Hermite interpolant for output points.

use crate::ode45::{Stats, E};
use crate::MAX_DIM;

/// Tolerances of the tight mode.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tolerances {
    /// Relative tolerance.
    pub rtol: f64,
    /// Absolute tolerance.
    pub atol: f64,
}

impl Default for Tolerances {
    /// rtol 1e-10, atol 1e-12: the published reference tolerances of the scipy peer.
    fn default() -> Self {
        Tolerances {
            rtol: 1e-10,
            atol: 1e-12,
        }
    }
}

/// Integrate `y' = f(y)` from `t0` to `tf`, landing exactly on `tf`. If `out` is given,
/// pushes the state at each of `out_times` in `(t0, tf]` (cubic Hermite between accepted
/// steps, exact at `tf`).
pub fn integrate<F>(
    mut f: F,
    y: &mut [f64],
    t0: f64,
    tf: f64,
    tol: Tolerances,
    out_times: &[f64],
    mut out: Option<&mut Vec<f64>>,
) -> Stats
where
    F: FnMut(&[f64], &mut [f64]),
{
    let n = y.len();
    assert!(n <= MAX_DIM);
    let mut stats = Stats::default();
    let mut k = [[0.0f64; MAX_DIM]; 7];
    f(&y[..n], &mut k[0][..n]);
    stats.evals += 1;
    let span = tf - t0;
    let mut h = crate::common::initial_step(&y[..n], &k[0][..n], tol);
    h = h.min(span.abs()) * span.signum();
    let mut t = t0;
    let mut ynew = [0.0f64; MAX_DIM];
    let mut next_out = out_times
        .iter()
        .position(|&to| to > t0)
        .unwrap_or(out_times.len());
    let mut last_rejected = false;
    loop {
        let last = (t + h - tf) * span.signum() >= 0.0;
        if last {
            h = tf - t;
        }
        crate::common::dp5_stages(&mut f, &y[..n], &mut k, h);
        crate::common::dp5_solution(&mut f, &y[..n], &mut k, h, &mut ynew);
        stats.evals += 6;
        let mut err = 0.0;
        for i in 0..n {
            let mut fe = 0.0;
            for (j, kj) in k.iter().enumerate() {
                fe += kj[i] * E[j];
            }
            let sc = tol.atol + tol.rtol * y[i].abs().max(ynew[i].abs());
            err += (h * fe / sc).powi(2);
        }
        let err = (err / n as f64).sqrt();
        if !(err <= 1.0) {
            stats.rejected += 1;
            h *= crate::common::reject_factor(err, 0.2);
            last_rejected = true;
            continue;
        }
        stats.accepted += 1;
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
                &k[6][..n],
            );
        }
        t = tnew;
        y[..n].copy_from_slice(&ynew[..n]);
        k[0] = k[6];
        if last {
            break;
        }
        let fac = crate::common::accept_factor(err, 0.2, last_rejected);
        last_rejected = false;
        h *= fac;
    }
    stats
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn harmonic_oscillator_to_tight_tolerance() {
        let mut y = [1.0, 0.0];
        let tf = 10.0;
        integrate(
            |y, d| {
                d[0] = y[1];
                d[1] = -y[0];
            },
            &mut y,
            0.0,
            tf,
            Tolerances::default(),
            &[],
            None,
        );
        assert!((y[0] - tf.cos()).abs() < 1e-8);
        assert!((y[1] + tf.sin()).abs() < 1e-8);
    }
}

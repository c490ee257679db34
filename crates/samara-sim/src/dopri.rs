//! Tight-tolerance Dormand-Prince 5(4) integration with the standard step-size control
//! of Hairer, Norsett & Wanner (*Solving ODEs I*, section II.4: RMS error norm with
//! `atol + rtol * max(|y|, |ynew|)` scaling, safety 0.9, factor limits 0.2..10), the
//! FSAL property and a cubic Hermite interpolant for output points.

use crate::ode45::{Stats, A, E};
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
    mut out: Option<&mut Vec<(f64, Vec<f64>)>>,
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
    // Initial step (Hairer's heuristic, simplified): h = 0.01 * ||y|| / ||f||.
    let mut d0 = 0.0;
    let mut d1 = 0.0;
    for i in 0..n {
        let sc = tol.atol + tol.rtol * y[i].abs();
        d0 += (y[i] / sc).powi(2);
        d1 += (k[0][i] / sc).powi(2);
    }
    let (d0, d1) = ((d0 / n as f64).sqrt(), (d1 / n as f64).sqrt());
    let mut h = if d0 < 1e-5 || d1 < 1e-5 {
        1e-6
    } else {
        0.01 * d0 / d1
    };
    h = h.min(span.abs()) * span.signum();
    let mut t = t0;
    let mut ys = [0.0f64; MAX_DIM];
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
        for s in 0..5 {
            for i in 0..n {
                let mut acc = 0.0;
                for (j, kj) in k.iter().enumerate().take(s + 1) {
                    acc += A[s][j] * kj[i];
                }
                ys[i] = y[i] + h * acc;
            }
            let (_, tail) = k.split_at_mut(s + 1);
            f(&ys[..n], &mut tail[0][..n]);
        }
        for i in 0..n {
            let mut acc = 0.0;
            for (j, kj) in k.iter().enumerate().take(6) {
                acc += A[5][j] * kj[i];
            }
            ynew[i] = y[i] + h * acc;
        }
        {
            let (_, tail) = k.split_at_mut(6);
            f(&ynew[..n], &mut tail[0][..n]);
        }
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
            let fac = if err.is_finite() {
                (0.9 * err.powf(-0.2)).max(0.2)
            } else {
                0.2
            };
            h *= fac;
            last_rejected = true;
            continue;
        }
        stats.accepted += 1;
        let tnew = if last { tf } else { t + h };
        if let Some(o) = out.as_deref_mut() {
            while next_out < out_times.len() && out_times[next_out] <= tnew {
                let to = out_times[next_out];
                if to == tnew {
                    o.push((to, ynew[..n].to_vec()));
                } else {
                    // Cubic Hermite on [t, tnew] with end slopes k[0], k[6].
                    let s = (to - t) / h;
                    let h00 = 2.0 * s * s * s - 3.0 * s * s + 1.0;
                    let h10 = s * s * s - 2.0 * s * s + s;
                    let h01 = -2.0 * s * s * s + 3.0 * s * s;
                    let h11 = s * s * s - s * s;
                    let yi = (0..n)
                        .map(|i| h00 * y[i] + h10 * h * k[0][i] + h01 * ynew[i] + h11 * h * k[6][i])
                        .collect();
                    o.push((to, yi));
                }
                next_out += 1;
            }
        }
        t = tnew;
        y[..n].copy_from_slice(&ynew[..n]);
        k[0] = k[6];
        if last {
            break;
        }
        let mut fac = if err == 0.0 {
            10.0
        } else {
            0.9 * err.powf(-0.2)
        };
        fac = fac.clamp(0.2, 10.0);
        if last_rejected {
            fac = fac.min(1.0);
        }
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

//! Pieces shared by the Runge-Kutta integrators.

use crate::dopri::Tolerances;
use crate::ode45::A;
use crate::MAX_DIM;

/// Stages 2..6 of the Dormand-Prince 5(4) pair into `k[1..6]`, each stage computed as
/// `y + h * (sum_j a_sj k_j)` (MATLAB's arithmetic order).
pub(crate) fn dp5_stages<F: FnMut(&[f64], &mut [f64])>(
    f: &mut F,
    y: &[f64],
    k: &mut [[f64; MAX_DIM]; 7],
    h: f64,
) {
    let n = y.len();
    let mut ys = [0.0f64; MAX_DIM];
    for (s, row) in A.iter().enumerate().take(5) {
        for i in 0..n {
            let mut acc = 0.0;
            for (j, kj) in k.iter().enumerate().take(s + 1) {
                acc += row[j] * kj[i];
            }
            ys[i] = y[i] + h * acc;
        }
        let (_, tail) = k.split_at_mut(s + 1);
        f(&ys[..n], &mut tail[0][..n]);
    }
}

/// The 5th-order solution `y + h * (sum_j b_j k_j)` into `ynew`, and its derivative
/// (the FSAL stage) into `k[6]`.
pub(crate) fn dp5_solution<F: FnMut(&[f64], &mut [f64])>(
    f: &mut F,
    y: &[f64],
    k: &mut [[f64; MAX_DIM]; 7],
    h: f64,
    ynew: &mut [f64; MAX_DIM],
) {
    let n = y.len();
    for i in 0..n {
        let mut acc = 0.0;
        for (j, kj) in k.iter().enumerate().take(6) {
            acc += A[5][j] * kj[i];
        }
        ynew[i] = y[i] + h * acc;
    }
    let (_, tail) = k.split_at_mut(6);
    f(&ynew[..n], &mut tail[0][..n]);
}

/// Hairer's starting step `0.01 ||y|| / ||f||` in the scaled RMS norm (1e-6 when either
/// norm is tiny), *Solving ODEs I*, II.4.
pub(crate) fn initial_step(y: &[f64], f0: &[f64], tol: Tolerances) -> f64 {
    let n = y.len() as f64;
    let (mut d0, mut d1) = (0.0, 0.0);
    for (yi, fi) in y.iter().zip(f0) {
        let sc = tol.atol + tol.rtol * yi.abs();
        d0 += (yi / sc).powi(2);
        d1 += (fi / sc).powi(2);
    }
    let (d0, d1) = ((d0 / n).sqrt(), (d1 / n).sqrt());
    if d0 < 1e-5 || d1 < 1e-5 {
        1e-6
    } else {
        0.01 * d0 / d1
    }
}

/// Push the states at the output times in `(t, tnew]` (cubic Hermite inside the step,
/// exact at `tnew`), advancing `next_out`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn hermite_outputs(
    out: &mut Vec<f64>,
    out_times: &[f64],
    next_out: &mut usize,
    t: f64,
    tnew: f64,
    y: &[f64],
    f0: &[f64],
    ynew: &[f64],
    f1: &[f64],
) {
    let h = tnew - t;
    while *next_out < out_times.len() && out_times[*next_out] <= tnew {
        let to = out_times[*next_out];
        if to == tnew {
            out.push(to);
            out.extend_from_slice(ynew);
        } else {
            let s = (to - t) / h;
            let (s2, s3) = (s * s, s * s * s);
            let h00 = 2.0 * s3 - 3.0 * s2 + 1.0;
            let h10 = s3 - 2.0 * s2 + s;
            let h01 = -2.0 * s3 + 3.0 * s2;
            let h11 = s3 - s2;
            out.push(to);
            out.extend(
                (0..y.len())
                    .map(|i| h00 * y[i] + h10 * h * f0[i] + h01 * ynew[i] + h11 * h * f1[i]),
            );
        }
        *next_out += 1;
    }
}

/// Step-size factor after a rejected step with error `err` (scaled so 1 is the
/// tolerance) for a method whose error exponent is `expo` (1/5 for 5(4), 1/8 for 8(5,3)):
/// `max(0.2, 0.9 err^-expo)`, 0.2 on a non-finite error.
pub(crate) fn reject_factor(err: f64, expo: f64) -> f64 {
    if err.is_finite() {
        (0.9 * err.powf(-expo)).max(0.2)
    } else {
        0.2
    }
}

/// Step-size factor after an accepted step: `0.9 err^-expo` within [0.2, 10], never a
/// growth right after a rejection (Hairer, Norsett & Wanner, II.4).
pub(crate) fn accept_factor(err: f64, expo: f64, after_rejection: bool) -> f64 {
    let fac = if err == 0.0 {
        10.0
    } else {
        (0.9 * err.powf(-expo)).clamp(0.2, 10.0)
    };
    if after_rejection {
        fac.min(1.0)
    } else {
        fac
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn hermite_is_exact_for_cubics() {
        // y = t^3 on [1, 2]: values 1, 8 and slopes 3, 12.
        let mut out = Vec::new();
        let mut next = 0;
        super::hermite_outputs(
            &mut out,
            &[1.5, 2.0],
            &mut next,
            1.0,
            2.0,
            &[1.0],
            &[3.0],
            &[8.0],
            &[12.0],
        );
        assert_eq!(out.len(), 4); // rows (t, y)
        assert!((out[1] - 3.375).abs() < 1e-14);
        assert_eq!((out[2], out[3]), (2.0, 8.0));
        assert_eq!(next, 2);
    }
}

//! A clone of MATLAB's `ode45` (Dormand-Prince 5(4) pair, Shampine & Reichelt, "The
//! MATLAB ODE suite", SIAM J. Sci. Comput. 18(1), 1997) with MATLAB's default options:
//! RelTol 1e-3, AbsTol 1e-6 (scalar), MaxStep 0.1 |tf - t0|, mixed relative/absolute
//! infinity-norm error test, and the 4th-order `ntrp45` interpolant for output points.
//! Every rule follows `docs/MODEL.md` section 5; the arithmetic order of the stages
//! (`y + h * (sum b_ij f_j)`) is kept.

use crate::MAX_DIM;

/// Dormand-Prince stage coefficients (row i: b_{i+1, j}).
pub(crate) const A: [[f64; 6]; 6] = [
    [1.0 / 5.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [3.0 / 40.0, 9.0 / 40.0, 0.0, 0.0, 0.0, 0.0],
    [44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0, 0.0, 0.0, 0.0],
    [
        19372.0 / 6561.0,
        -25360.0 / 2187.0,
        64448.0 / 6561.0,
        -212.0 / 729.0,
        0.0,
        0.0,
    ],
    [
        9017.0 / 3168.0,
        -355.0 / 33.0,
        46732.0 / 5247.0,
        49.0 / 176.0,
        -5103.0 / 18656.0,
        0.0,
    ],
    [
        35.0 / 384.0,
        0.0,
        500.0 / 1113.0,
        125.0 / 192.0,
        -2187.0 / 6784.0,
        11.0 / 84.0,
    ],
];

/// Error weights E (5th minus 4th order).
pub(crate) const E: [f64; 7] = [
    71.0 / 57600.0,
    0.0,
    -71.0 / 16695.0,
    71.0 / 1920.0,
    -17253.0 / 339200.0,
    22.0 / 525.0,
    -1.0 / 40.0,
];

/// `ntrp45` interpolation matrix (rows: stages, columns: powers s, s^2, s^3, s^4).
pub(crate) const BI: [[f64; 4]; 7] = [
    [1.0, -183.0 / 64.0, 37.0 / 12.0, -145.0 / 128.0],
    [0.0, 0.0, 0.0, 0.0],
    [0.0, 1500.0 / 371.0, -1000.0 / 159.0, 1000.0 / 371.0],
    [0.0, -125.0 / 32.0, 125.0 / 12.0, -375.0 / 64.0],
    [0.0, 9477.0 / 3392.0, -729.0 / 106.0, 25515.0 / 6784.0],
    [0.0, -11.0 / 7.0, 11.0 / 3.0, -55.0 / 28.0],
    [0.0, 3.0 / 2.0, -4.0, 5.0 / 2.0],
];

/// MATLAB `eps(t)`: the spacing of doubles at `t`.
fn eps_of(t: f64) -> f64 {
    let a = t.abs();
    if a < f64::MIN_POSITIVE {
        return f64::from_bits(1); // smallest subnormal
    }
    let e = ((a.to_bits() >> 52) & 0x7ff) as i32 - 1023;
    2f64.powi(e - 52)
}

/// Options of the MATLAB clone (MATLAB defaults).
#[derive(Clone, Debug)]
pub struct Ode45Options {
    /// Relative tolerance (MATLAB default 1e-3).
    pub rel_tol: f64,
    /// Absolute tolerance (MATLAB default 1e-6).
    pub abs_tol: f64,
}

impl Default for Ode45Options {
    fn default() -> Self {
        Ode45Options {
            rel_tol: 1e-3,
            abs_tol: 1e-6,
        }
    }
}

/// Statistics of one integration.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stats {
    /// Accepted steps.
    pub accepted: usize,
    /// Rejected steps.
    pub rejected: usize,
    /// Right-hand-side evaluations.
    pub evals: usize,
    /// Step size proposed for a continuation (0 if not provided by the method).
    pub h_next: f64,
}

/// Integrate `y' = f(y)` (autonomous) from `t0` to `tf` with MATLAB's `ode45` rules, as
/// if called with `tspan = out_times` (`out_times[0] = t0`, last = `tf`, at least two
/// entries). Returns the end state in `y` and, if `out` is given, pushes the state at
/// every entry of `out_times` after the first (interpolated by `ntrp45`, the last one
/// exact) as flat rows `t, y...`. `hmax` = 0.1 |tf - t0| and the first step uses `|tspan(2) - tspan(1)|`
/// exactly as MATLAB.
pub fn integrate<F>(
    mut f: F,
    y: &mut [f64],
    out_times: &[f64],
    opts: &Ode45Options,
    mut out: Option<&mut Vec<f64>>,
) -> Stats
where
    F: FnMut(&[f64], &mut [f64]),
{
    let n = y.len();
    assert!(n <= MAX_DIM && out_times.len() >= 2);
    let t0 = out_times[0];
    let tf = *out_times.last().unwrap();
    let rtol = opts.rel_tol;
    let threshold = opts.abs_tol / rtol;
    let pow = 1.0 / 5.0;
    let hmax = 0.1 * (tf - t0).abs();
    let htspan = (out_times[1] - out_times[0]).abs();
    let mut stats = Stats::default();

    let mut k = [[0.0f64; MAX_DIM]; 7];
    f(&y[..n], &mut k[0][..n]);
    stats.evals += 1;

    let mut t = t0;
    let mut hmin = 16.0 * eps_of(t);
    let mut absh = hmax.min(htspan);
    let mut rh = 0.0f64;
    for i in 0..n {
        rh = rh.max(k[0][i].abs() / y[i].abs().max(threshold));
    }
    rh /= 0.8 * rtol.powf(pow);
    if absh * rh > 1.0 {
        absh = 1.0 / rh;
    }
    absh = absh.max(hmin);

    let mut next_out = 1usize;
    let mut ynew = [0.0f64; MAX_DIM];
    let mut done = false;
    while !done {
        hmin = 16.0 * eps_of(t);
        absh = hmax.min(hmin.max(absh));
        let mut h = absh;
        if 1.1 * absh >= (tf - t).abs() {
            h = tf - t;
            absh = h.abs();
            done = true;
        }
        let mut nofailed = true;
        let tnew;
        loop {
            crate::common::dp5_stages(&mut f, &y[..n], &mut k, h);
            stats.evals += 5;
            let mut tn = t + h;
            if done {
                tn = tf;
            }
            h = tn - t;
            crate::common::dp5_solution(&mut f, &y[..n], &mut k, h, &mut ynew);
            stats.evals += 1;
            let mut err = 0.0f64;
            for i in 0..n {
                let mut fe = 0.0;
                for (j, kj) in k.iter().enumerate() {
                    fe += kj[i] * E[j];
                }
                let den = y[i].abs().max(ynew[i].abs()).max(threshold);
                err = err.max((fe / den).abs());
            }
            err *= absh;
            if err > rtol || err.is_nan() {
                stats.rejected += 1;
                if absh <= hmin {
                    // MATLAB warns and stops; we accept to avoid an infinite loop.
                    tnew = tn;
                    break;
                }
                if nofailed {
                    nofailed = false;
                    let r = if err.is_nan() {
                        0.1
                    } else {
                        0.1f64.max(0.8 * (rtol / err).powf(pow))
                    };
                    absh = hmin.max(absh * r);
                } else {
                    absh = hmin.max(0.5 * absh);
                }
                h = absh;
                done = false;
                continue;
            }
            if nofailed {
                let temp = 1.25 * (err / rtol).powf(pow);
                if temp > 0.2 {
                    absh /= temp;
                } else {
                    absh *= 5.0;
                }
            }
            tnew = tn;
            break;
        }
        stats.accepted += 1;
        // Output points inside (t, tnew].
        if let Some(o) = out.as_deref_mut() {
            while next_out < out_times.len() && out_times[next_out] <= tnew {
                let to = out_times[next_out];
                if to == tnew {
                    o.push(to);
                    o.extend_from_slice(&ynew[..n]);
                } else {
                    let s = (to - t) / h;
                    let pw = [s, s * s, s * s * s, s * s * s * s];
                    o.push(to);
                    o.extend((0..n).map(|i| {
                        let mut acc = 0.0;
                        for (j, kj) in k.iter().enumerate() {
                            let c = BI[j][0] * pw[0]
                                + BI[j][1] * pw[1]
                                + BI[j][2] * pw[2]
                                + BI[j][3] * pw[3];
                            acc += kj[i] * c;
                        }
                        y[i] + h * acc
                    }));
                }
                next_out += 1;
            }
        }
        t = tnew;
        y[..n].copy_from_slice(&ynew[..n]);
        k[0] = k[6];
    }
    stats
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eps_matches_matlab() {
        assert_eq!(eps_of(1.0), f64::EPSILON);
        assert_eq!(eps_of(0.5), f64::EPSILON / 2.0);
        assert_eq!(eps_of(0.0), f64::from_bits(1));
    }

    #[test]
    fn exponential_decay_is_accurate_to_tolerance() {
        // y' = -y, y(0) = 1: compare with exp(-t) at the output points.
        let times: Vec<f64> = (0..=50).map(|i| i as f64 * 0.01).collect();
        let mut y = [1.0];
        let mut out = Vec::new();
        integrate(
            |y, d| d[0] = -y[0],
            &mut y,
            &times,
            &Ode45Options::default(),
            Some(&mut out),
        );
        assert_eq!(out.len(), 100);
        for row in out.chunks_exact(2) {
            let (t, v) = (row[0], row[1]);
            assert!((v - (-t).exp()).abs() < 1e-5, "t={t}");
        }
        assert!((y[0] - (-0.5f64).exp()).abs() < 1e-6);
    }
}

//! A clone of MATLAB's `ode45` (Dormand-Prince 5(4) pair, Shampine & Reichelt, "The
//! MATLAB ODE suite", SIAM J. Sci. Comput. 18(1), 1997) with MATLAB's default options:
//! RelTol 1e-3, AbsTol 1e-6 (scalar), MaxStep 0.1 |tf - t0|, mixed relative/absolute
//! infinity-norm error test, and the 4th-order `ntrp45` interpolant for output points.
//! Every rule follows `docs/model.md` section 5; the arithmetic order of the stages
//! (`y + h * (sum b_ij f_j)`) is kept. The step control is a policy on the one adaptive
//! Runge-Kutta driver ([`crate::explicit_rk`]) running the [`DP54`] tableau.

use crate::explicit_rk::{drive, OutputPoints, Rejection, Stages, StepControl, MAX_STEPS};
use crate::tableau::{ErrorEstimator, Tableau, DP54};
use crate::MAX_DIM;

pub use crate::explicit_rk::Stats;

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

/// Integrate `y' = f(y)` (autonomous) from `t0` to `tf` with MATLAB's `ode45` rules, as
/// if called with `tspan = out_times` (`out_times[0] = t0`, last = `tf`, at least two
/// entries). Returns the end state in `y` and, if `out` is given, pushes the state at
/// every entry of `out_times` after the first (interpolated by `ntrp45`, the last one
/// exact) as flat rows `t, y...`. `hmax` = 0.1 |tf - t0| and the first step uses `|tspan(2) - tspan(1)|`
/// exactly as MATLAB.
pub fn integrate<F>(
    f: F,
    y: &mut [f64],
    out_times: &[f64],
    opts: &Ode45Options,
    out: Option<&mut Vec<f64>>,
) -> Stats
where
    F: FnMut(&[f64], &mut [f64]),
{
    assert!(y.len() <= MAX_DIM && out_times.len() >= 2);
    let t0 = out_times[0];
    let tf = *out_times.last().unwrap();
    let mut ctl = Matlab {
        tf,
        rtol: opts.rel_tol,
        threshold: opts.abs_tol / opts.rel_tol,
        pow: 1.0 / 5.0,
        hmax: 0.1 * (tf - t0).abs(),
        htspan: (out_times[1] - out_times[0]).abs(),
        t0,
        hmin: 0.0,
        absh: 0.0,
        retry: false,
        nofailed: true,
        forced: false,
        outputs: OutputPoints {
            times: out_times,
            next: 1,
            out,
        },
    };
    drive(&DP54, &mut ctl, f, y, t0)
}

/// MATLAB's `ode45` step control as a policy on the driver: mixed relative/absolute
/// infinity-norm error test, step `absh` within `[16 eps(t), hmax]`, the end reached
/// once `1.1 absh` covers it, the first failure rescaling by `0.8 (rtol/err)^(1/5)`
/// (at least 0.1) and later ones halving, and output points from the pair's continuous
/// extension (`ntrp45`).
struct Matlab<'a> {
    tf: f64,
    rtol: f64,
    /// `AbsTol / RelTol`.
    threshold: f64,
    pow: f64,
    hmax: f64,
    htspan: f64,
    t0: f64,
    hmin: f64,
    absh: f64,
    /// The next attempt retries a failed step (MATLAB's inner loop).
    retry: bool,
    /// No failure yet in this step.
    nofailed: bool,
    /// This step was taken at the minimum step size despite its error.
    forced: bool,
    outputs: OutputPoints<'a>,
}

impl StepControl for Matlab<'_> {
    fn start(&mut self, y: &[f64], f0: &[f64]) {
        self.hmin = 16.0 * eps_of(self.t0);
        let mut absh = self.hmax.min(self.htspan);
        let mut rh = 0.0f64;
        for i in 0..y.len() {
            rh = rh.max(f0[i].abs() / y[i].abs().max(self.threshold));
        }
        rh /= 0.8 * self.rtol.powf(self.pow);
        if absh * rh > 1.0 {
            absh = 1.0 / rh;
        }
        self.absh = absh.max(self.hmin);
    }

    fn attempt(&mut self, t: f64) -> (f64, bool) {
        if self.retry {
            self.retry = false;
            return (self.absh, false);
        }
        self.hmin = 16.0 * eps_of(t);
        self.absh = self.hmax.min(self.hmin.max(self.absh));
        self.nofailed = true;
        self.forced = false;
        if 1.1 * self.absh >= (self.tf - t).abs() {
            let h = self.tf - t;
            self.absh = h.abs();
            (h, true)
        } else {
            (self.absh, false)
        }
    }

    fn solution_step(&self, t: f64, h: f64, last: bool) -> (f64, f64) {
        let tn = if last { self.tf } else { t + h };
        (tn - t, tn)
    }

    fn error(&self, tab: &Tableau, y: &[f64], ynew: &[f64], k: &Stages, _h: f64) -> (f64, bool) {
        let ErrorEstimator::Embedded(e) = &tab.error else {
            unreachable!("the ode45 control runs the DP5(4) pair");
        };
        let mut err = 0.0f64;
        for i in 0..y.len() {
            let mut fe = 0.0;
            for j in 0..tab.stages {
                fe += k[j][i] * e[j];
            }
            let den = y[i].abs().max(ynew[i].abs()).max(self.threshold);
            err = err.max((fe / den).abs());
        }
        err *= self.absh;
        (err, !(err > self.rtol || err.is_nan()))
    }

    fn rejected(&mut self, _t: f64, err: f64, ynew: &[f64], stats: &Stats) -> Rejection {
        if self.absh <= self.hmin {
            if err.is_nan()
                || ynew.iter().any(|v| !v.is_finite())
                || stats.accepted + stats.rejected > MAX_STEPS
            {
                // No step can meet the tolerance any more (NaN, or steps of 16 eps(t)
                // that would take ~1e14 iterations): stop with a NaN state instead of
                // hanging (issue 17).
                return Rejection::GiveUp;
            }
            // MATLAB warns and stops; we accept to avoid an infinite loop.
            self.forced = true;
            return Rejection::AcceptAnyway;
        }
        if self.nofailed {
            self.nofailed = false;
            let r = if err.is_nan() {
                0.1
            } else {
                0.1f64.max(0.8 * (self.rtol / err).powf(self.pow))
            };
            self.absh = self.hmin.max(self.absh * r);
        } else {
            self.absh = self.hmin.max(0.5 * self.absh);
        }
        self.retry = true;
        Rejection::Retry
    }

    fn output(
        &mut self,
        tab: &Tableau,
        t: f64,
        tnew: f64,
        h: f64,
        y: &[f64],
        ynew: &[f64],
        k: &Stages,
        _f1: &[f64],
    ) {
        let op = &mut self.outputs;
        let Some(o) = op.out.as_deref_mut() else {
            return;
        };
        let bi = tab.interpolant.as_ref().expect("DP5(4) has ntrp45");
        while op.next < op.times.len() && op.times[op.next] <= tnew {
            let to = op.times[op.next];
            if to == tnew {
                o.push(to);
                o.extend_from_slice(ynew);
            } else {
                let s = (to - t) / h;
                let pw = [s, s * s, s * s * s, s * s * s * s];
                o.push(to);
                o.extend((0..y.len()).map(|i| {
                    let mut acc = 0.0;
                    for j in 0..tab.stages {
                        let c = bi[j][0] * pw[0]
                            + bi[j][1] * pw[1]
                            + bi[j][2] * pw[2]
                            + bi[j][3] * pw[3];
                        acc += k[j][i] * c;
                    }
                    y[i] + h * acc
                }));
            }
            op.next += 1;
        }
    }

    fn accepted(&mut self, err: f64, _last: bool, _stats: &mut Stats) {
        if self.nofailed && !self.forced {
            let temp = 1.25 * (err / self.rtol).powf(self.pow);
            if temp > 0.2 {
                self.absh /= temp;
            } else {
                self.absh *= 5.0;
            }
        }
    }
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

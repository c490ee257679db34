//! The one adaptive explicit Runge-Kutta driver: any [`Tableau`] (DP5(4), DOP853) under a
//! step-control policy (`StepControl`): the standard control of Hairer, Norsett &
//! Wanner ([`integrate`]), or the clone of MATLAB's `ode45` ([`crate::ode45`]).
//!
//! The driver owns the stages, the solution, the FSAL bookkeeping, the accept/reject
//! sequence, the state update and the statistics; a policy owns the step size, the error
//! norm, the acceptance test and the output points. The arithmetic order of every stage
//! (`y + h * (sum_j a_ij k_j)`, `j` ascending) is that of the codes it replaced, so the
//! results are bit-identical to them (`tests/integrator_pin.rs`).

use crate::tableau::{ErrorEstimator, Tableau, MAX_STAGES};
use crate::MAX_DIM;

/// Tolerances of the standard step control.
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

/// Statistics of one integration.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stats {
    /// Accepted steps.
    pub accepted: usize,
    /// Rejected steps.
    pub rejected: usize,
    /// Right-hand-side evaluations.
    pub evals: usize,
    /// Step size proposed for a continuation (0 if not provided by the step control).
    pub h_next: f64,
    /// Where the step size collapsed, if it did (the state is then NaN, as for any
    /// failed integration, so callers that only check finiteness still stop).
    pub collapse: Option<Collapse>,
}

/// Where and how an integration's step size collapsed: [`COLLAPSE_STEPS`] attempted
/// steps shorter than [`COLLAPSE_REL`] of the integration span with no accepted step of
/// normal length between them, [`COLLAPSE_MAX_STEPS`] attempts in all, or a step that
/// vanished against `t` with a finite error. A right-hand side that switches where its field
/// points at the switch from both sides (a sliding mode: `if x < 0 then 1 else -1`)
/// makes any explicit integrator chatter there with steps of ~1e-11; a transversal
/// switch costs a few dozen short steps, far below the count.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Collapse {
    /// Time of the last accepted state.
    pub t: f64,
    /// The step size last attempted.
    pub h: f64,
    /// The last accepted state (its first `n` entries, `n` the system's dimension).
    pub state: [f64; MAX_DIM],
}

/// A step shorter than this share of the integration span counts toward a collapse.
pub const COLLAPSE_REL: f64 = 1e-7;

/// Attempted steps shorter than [`COLLAPSE_REL`] of the span, in a row (no accepted
/// step of normal length between them), after which an integration stops as collapsed.
pub const COLLAPSE_STEPS: usize = 1000;

/// Attempted steps of one integration call after which it stops as collapsed whatever
/// their lengths: a chattering whose steps alternate between short and normal ones (a
/// `sign` term whose stages all fall on one side of the switch now and then) never
/// makes [`COLLAPSE_STEPS`] short ones in a row. An average step under 1e-5 of the span:
/// the published closed loops take about ten steps per period, and an explicit
/// integrator this far below its accuracy step is following a discontinuity (or a
/// stiffness it is not made for).
pub const COLLAPSE_MAX_STEPS: usize = 100_000;

/// Stage derivatives `k_j` of one step.
pub(crate) type Stages = [[f64; MAX_DIM]; MAX_STAGES];

/// What a policy decides about a step whose error failed its test.
pub(crate) enum Rejection {
    /// Try again (the policy has shrunk its step).
    Retry,
    /// No step can meet the tolerance any more: stop with a NaN state.
    GiveUp,
    /// Take the step anyway (MATLAB's behaviour at the minimum step).
    AcceptAnyway,
}

/// A step-size control policy on the driver.
pub(crate) trait StepControl {
    /// Before the first step, with the initial state and its derivative.
    fn start(&mut self, y: &[f64], f0: &[f64]);
    /// The step to attempt from `t`, and whether it lands on the end time.
    fn attempt(&mut self, t: f64) -> (f64, bool);
    /// The step the solution is formed with, and the time it reaches, after the stages
    /// were computed with `h`.
    fn solution_step(&self, t: f64, h: f64, last: bool) -> (f64, f64);
    /// The step's scaled error and whether it passes.
    fn error(&self, tab: &Tableau, y: &[f64], ynew: &[f64], k: &Stages, h: f64) -> (f64, bool);
    /// A failed step (`stats.rejected` already counts it).
    fn rejected(&mut self, t: f64, err: f64, ynew: &[f64], stats: &Stats) -> Rejection;
    /// The output points in `(t, tnew]` of an accepted step (`f1` = `f(ynew)`).
    #[allow(clippy::too_many_arguments)]
    fn output(
        &mut self,
        tab: &Tableau,
        t: f64,
        tnew: f64,
        h: f64,
        y: &[f64],
        ynew: &[f64],
        k: &Stages,
        f1: &[f64],
    );
    /// After an accepted step (and its output): the next step size; `last` ends the run.
    fn accepted(&mut self, err: f64, last: bool, stats: &mut Stats);
    /// Whether the step size has collapsed ([`Collapse`]); checked before every attempt.
    fn collapsed(&self) -> bool {
        false
    }
}

/// `sum_j w_j k_j[i]` over stages `0..m`, `j` ascending.
fn weighted(w: &[f64; MAX_STAGES], k: &Stages, i: usize, m: usize) -> f64 {
    let mut acc = 0.0;
    for j in 0..m {
        acc += w[j] * k[j][i];
    }
    acc
}

/// Run `tab` under `ctl` from `y` (whose derivative is evaluated first) until the policy
/// ends the run. Returns the statistics; `y` holds the end state (NaN if the policy gave
/// up).
pub(crate) fn drive<F, C>(tab: &Tableau, ctl: &mut C, mut f: F, y: &mut [f64], t0: f64) -> Stats
where
    F: FnMut(&[f64], &mut [f64]),
    C: StepControl,
{
    let n = y.len();
    assert!(n <= MAX_DIM);
    let s = tab.stages;
    // The stages computed with the attempted step; the last one of an FSAL pair is the
    // solution's derivative.
    let explicit = if tab.fsal { s - 1 } else { s };
    let mut stats = Stats::default();
    let mut k: Stages = [[0.0; MAX_DIM]; MAX_STAGES];
    let mut ys = [0.0f64; MAX_DIM];
    let mut ynew = [0.0f64; MAX_DIM];
    let mut fnew = [0.0f64; MAX_DIM];
    f(&y[..n], &mut k[0][..n]);
    stats.evals += 1;
    ctl.start(&y[..n], &k[0][..n]);
    let mut t = t0;
    loop {
        let (h, last) = ctl.attempt(t);
        if ctl.collapsed() {
            let mut state = [0.0; MAX_DIM];
            state[..n].copy_from_slice(&y[..n]);
            stats.collapse = Some(Collapse { t, h, state });
            y[..n].fill(f64::NAN);
            return stats;
        }
        for st in 1..explicit {
            for i in 0..n {
                ys[i] = y[i] + h * weighted(&tab.a[st], &k, i, st);
            }
            f(&ys[..n], &mut k[st][..n]);
        }
        let (h, tnew) = ctl.solution_step(t, h, last);
        for i in 0..n {
            ynew[i] = y[i] + h * weighted(&tab.b, &k, i, explicit);
        }
        if tab.fsal {
            f(&ynew[..n], &mut k[s - 1][..n]);
        }
        stats.evals += s - 1;
        let (err, pass) = ctl.error(tab, &y[..n], &ynew[..n], &k, h);
        if !pass {
            stats.rejected += 1;
            match ctl.rejected(t, err, &ynew[..n], &stats) {
                Rejection::Retry => continue,
                Rejection::GiveUp => {
                    // The error stays above tolerance (e.g. NaN) however small the step:
                    // give up with a NaN state instead of looping forever (issue 17).
                    y[..n].fill(f64::NAN);
                    return stats;
                }
                Rejection::AcceptAnyway => {}
            }
        }
        stats.accepted += 1;
        if tab.fsal {
            fnew = k[s - 1];
        } else {
            f(&ynew[..n], &mut fnew[..n]);
            stats.evals += 1;
        }
        ctl.output(tab, t, tnew, h, &y[..n], &ynew[..n], &k, &fnew[..n]);
        t = tnew;
        y[..n].copy_from_slice(&ynew[..n]);
        k[0] = fnew;
        ctl.accepted(err, last, &mut stats);
        if last {
            return stats;
        }
    }
}

/// Hairer's starting step `0.01 ||y|| / ||f||` in the scaled RMS norm (1e-6 when either
/// norm is tiny), *Solving ODEs I*, II.4.
fn initial_step(y: &[f64], f0: &[f64], tol: Tolerances) -> f64 {
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

/// The requested output points of one integration and where the next one is.
pub(crate) struct OutputPoints<'a> {
    /// Requested times.
    pub(crate) times: &'a [f64],
    /// Index of the next time not yet written.
    pub(crate) next: usize,
    /// Flat rows `t, y...`, if outputs are wanted.
    pub(crate) out: Option<&'a mut Vec<f64>>,
}

/// Most steps (accepted and rejected) of one integration call before it gives up with
/// a NaN state: far above what any meaningful period needs (the published runs take
/// about ten per period), far below a hang.
pub(crate) const MAX_STEPS: usize = 10_000_000;

/// The standard step control (Hairer, Norsett & Wanner, *Solving ODEs I*, II.4 and
/// II.10): error scaled by `atol + rtol * max(|y|, |ynew|)`, accepted at most 1, step
/// factor `0.9 err^-exponent` within [0.2, 10] (no growth right after a rejection),
/// cubic Hermite output points.
struct Standard<'a> {
    tf: f64,
    /// `tf - t0` and its sign.
    span: f64,
    dir: f64,
    h_init: Option<f64>,
    tol: Tolerances,
    exponent: f64,
    h: f64,
    /// The step the control proposed before the last step was shortened to land on
    /// `tf` (for [`Stats::h_next`]).
    h_proposed: f64,
    last_rejected: bool,
    outputs: OutputPoints<'a>,
    /// Attempts shorter than [`COLLAPSE_REL`] of the span so far.
    tiny: usize,
    /// Attempts so far (for [`COLLAPSE_MAX_STEPS`]).
    attempts: usize,
    /// Set when the step vanished with a finite error, or after [`COLLAPSE_STEPS`]
    /// tiny attempts.
    collapsed: bool,
}

impl StepControl for Standard<'_> {
    fn start(&mut self, y: &[f64], f0: &[f64]) {
        let h = match self.h_init.filter(|v| v.is_finite() && *v > 0.0) {
            Some(hi) => hi,
            None => initial_step(y, f0, self.tol),
        };
        self.h = h.min(self.span.abs()) * self.dir;
        self.h_proposed = self.h;
    }

    fn attempt(&mut self, t: f64) -> (f64, bool) {
        let last = (t + self.h - self.tf) * self.dir >= 0.0;
        if last {
            self.h_proposed = self.h_proposed.max(self.h);
            self.h = self.tf - t;
        }
        if !last && self.h.abs() < COLLAPSE_REL * self.span.abs() {
            self.tiny += 1;
            if self.tiny > COLLAPSE_STEPS {
                self.collapsed = true;
            }
        }
        self.attempts += 1;
        if self.attempts > COLLAPSE_MAX_STEPS {
            self.collapsed = true;
        }
        (self.h, last)
    }

    fn collapsed(&self) -> bool {
        self.collapsed
    }

    fn solution_step(&self, t: f64, h: f64, last: bool) -> (f64, f64) {
        (h, if last { self.tf } else { t + h })
    }

    fn error(&self, tab: &Tableau, y: &[f64], ynew: &[f64], k: &Stages, h: f64) -> (f64, bool) {
        let n = y.len();
        let sc = |i: usize| self.tol.atol + self.tol.rtol * y[i].abs().max(ynew[i].abs());
        let err = match &tab.error {
            ErrorEstimator::Embedded(e) => {
                let mut err = 0.0;
                for i in 0..n {
                    let fe = weighted(e, k, i, tab.stages);
                    err += (h * fe / sc(i)).powi(2);
                }
                (err / n as f64).sqrt()
            }
            ErrorEstimator::FifthAndThird { e5, e3 } => {
                let (mut s5, mut s3) = (0.0, 0.0);
                for i in 0..n {
                    s5 += (weighted(e5, k, i, tab.stages) / sc(i)).powi(2);
                    s3 += (weighted(e3, k, i, tab.stages) / sc(i)).powi(2);
                }
                let den = s5 + 0.01 * s3;
                if den > 0.0 {
                    h.abs() * s5 * ((1.0 / n as f64) / den).sqrt()
                } else {
                    0.0
                }
            }
        };
        // `!(err <= 1)`: a NaN error is a failed step.
        (err, err <= 1.0)
    }

    fn rejected(&mut self, t: f64, err: f64, _ynew: &[f64], stats: &Stats) -> Rejection {
        // max(0.2, 0.9 err^-exponent), 0.2 on a non-finite error.
        self.h *= if err.is_finite() {
            (0.9 * err.powf(-self.exponent)).max(0.2)
        } else {
            0.2
        };
        self.last_rejected = true;
        let vanished = !(self.h.abs() > 16.0 * f64::EPSILON * t.abs().max(self.tf.abs()));
        if vanished && err.is_finite() {
            // A finite error that no step can meet: the step collapsed (reported with
            // the state, before the next attempt).
            self.collapsed = true;
            Rejection::Retry
        } else if vanished || stats.accepted + stats.rejected > MAX_STEPS {
            Rejection::GiveUp
        } else {
            Rejection::Retry
        }
    }

    fn output(
        &mut self,
        _tab: &Tableau,
        t: f64,
        tnew: f64,
        _h: f64,
        y: &[f64],
        ynew: &[f64],
        k: &Stages,
        f1: &[f64],
    ) {
        let op = &mut self.outputs;
        if let Some(o) = op.out.as_deref_mut() {
            let f0 = &k[0][..y.len()];
            hermite_outputs(o, op.times, &mut op.next, t, tnew, y, f0, ynew, f1);
        }
    }

    fn accepted(&mut self, err: f64, last: bool, stats: &mut Stats) {
        // A step of normal length ends a run of short ones (a switch crossed): only
        // short steps in a row, as on a sliding mode, add up to a collapse.
        if self.h.abs() >= COLLAPSE_REL * self.span.abs() {
            self.tiny = 0;
        }
        let fac = if err == 0.0 {
            10.0
        } else {
            (0.9 * err.powf(-self.exponent)).clamp(0.2, 10.0)
        };
        let fac = if self.last_rejected {
            fac.min(1.0)
        } else {
            fac
        };
        self.last_rejected = false;
        if last {
            // The final step was shortened to land on tf: propose what the controller
            // would have taken next from the unshortened step.
            stats.h_next = if self.h < self.h_proposed {
                self.h_proposed
            } else {
                self.h * fac
            };
            return;
        }
        self.h *= fac;
        self.h_proposed = self.h;
    }
}

/// Integrate `y' = f(y)` with the pair `tab` under the standard step control from `t0` to
/// `tf` (either direction), landing exactly on `tf`, starting with step `h_init` when
/// given (positive and finite; e.g. the [`Stats::h_next`] of the previous control period,
/// which saves the start-up steps of a restart), else with Hairer's starting step. If
/// `out` is given, pushes the state at each of `out_times` in `(t0, tf]` as flat rows
/// `t, y...` (cubic Hermite between accepted steps, exact at `tf`: used only for
/// trajectories and figures).
#[allow(clippy::too_many_arguments)]
pub fn integrate<F>(
    tab: &Tableau,
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
    let span = tf - t0;
    let mut ctl = Standard {
        tf,
        span,
        dir: span.signum(),
        h_init,
        tol,
        exponent: tab.exponent,
        h: 0.0,
        h_proposed: 0.0,
        last_rejected: false,
        tiny: 0,
        attempts: 0,
        collapsed: false,
        outputs: OutputPoints {
            times: out_times,
            next: out_times
                .iter()
                .position(|&to| to > t0)
                .unwrap_or(out_times.len()),
            out,
        },
    };
    drive(tab, &mut ctl, f, y, t0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tableau::{DOP853, DP54};

    #[test]
    fn hermite_is_exact_for_cubics() {
        // y = t^3 on [1, 2]: values 1, 8 and slopes 3, 12.
        let mut out = Vec::new();
        let mut next = 0;
        hermite_outputs(
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

    fn oscillator(y: &[f64], d: &mut [f64]) {
        d[0] = y[1];
        d[1] = -y[0];
    }

    /// A sliding mode (`x' = 1` left of 0.3, `-1` right of it: the field points at the
    /// switch from both sides) collapses the step: reported at once (not after ten
    /// million steps) with the time the flight reaches the switch (0.3 from x = 0, up to
    /// the chattering's width) and the state there; a transversal switch (`x' = 1` then
    /// `0.5`) does not, and lands on the closed form 0.3 + 0.5 (1 - 0.3) = 0.65.
    #[test]
    fn sliding_mode_collapses_and_transversal_switch_does_not() {
        let tol = Tolerances::default();
        let slide = |y: &[f64], d: &mut [f64]| d[0] = if y[0] < 0.3 { 1.0 } else { -1.0 };
        let mut y = [0.0];
        let st = integrate(&DOP853, slide, &mut y, 0.0, 1.0, tol, None, &[], None);
        let c = st.collapse.expect("collapse reported");
        assert!(y[0].is_nan(), "a collapsed integration ends NaN");
        assert!((c.t - 0.3).abs() < 1e-6, "{c:?}");
        assert!((c.state[0] - 0.3).abs() < 1e-6, "{c:?}");
        assert!(c.h.abs() < COLLAPSE_REL, "{c:?}");
        assert!(st.accepted + st.rejected < 10 * COLLAPSE_STEPS, "{st:?}");
        let cross = |y: &[f64], d: &mut [f64]| d[0] = if y[0] < 0.3 { 1.0 } else { 0.5 };
        let mut y = [0.0];
        let st = integrate(&DOP853, cross, &mut y, 0.0, 1.0, tol, None, &[], None);
        assert_eq!(st.collapse, None);
        assert!((y[0] - 0.65).abs() < 1e-9, "{}", y[0]);
        // Many crossings in one call (a relay switching up to 400 times, more short
        // steps in all than COLLAPSE_STEPS) are not a collapse: each crossing ends
        // with steps of normal length. y' = 1 on [0, 0.1) mod 0.2 of x = t, 0.5
        // elsewhere (the value is not checked: a step may straddle a whole cycle
        // unseen, which no error estimate detects).
        let relay = |y: &[f64], d: &mut [f64]| {
            d[0] = 1.0;
            d[1] = if y[0].rem_euclid(0.2) < 0.1 { 1.0 } else { 0.5 };
        };
        let mut y = [0.0, 0.0];
        let st = integrate(&DOP853, relay, &mut y, 0.0, 40.0, tol, None, &[], None);
        assert_eq!(st.collapse, None, "{st:?}");
        assert!(
            y[1].is_finite() && st.accepted + st.rejected > COLLAPSE_STEPS,
            "{st:?}"
        );
    }

    /// The chattering of a `sign` term found by the differential plant test (issue 35):
    /// `x' = -0.48 x - 0.29 sign(x - 0.32) - 0.13`, sliding at x = 0.32, ran ten million
    /// steps (44 s) because normal steps now and then broke the run of short ones; it is
    /// now stopped as collapsed after [`COLLAPSE_MAX_STEPS`] attempts, at the switch.
    #[test]
    fn sign_chattering_collapses_within_the_step_budget() {
        let tol = Tolerances::default();
        let f = |y: &[f64], d: &mut [f64]| {
            let s = (y[0] - 0.3196429523991142).signum();
            d[0] = -0.4778242883048819 * y[0] - 0.9665913621863802 * 0.3 * s - 0.1335;
        };
        let mut y = [0.3847310974746946];
        let st = integrate(&DOP853, f, &mut y, 0.0, 0.2, tol, None, &[], None);
        let c = st.collapse.expect("collapse reported");
        assert!((c.state[0] - 0.3196429523991142).abs() < 1e-6, "{c:?}");
        // Caught by the step budget, not by a run of short steps.
        assert_eq!(st.accepted + st.rejected, COLLAPSE_MAX_STEPS, "{st:?}");
    }

    #[test]
    fn both_pairs_reach_tight_tolerance() {
        for tab in [&DP54, &DOP853] {
            let mut y = [1.0, 0.0];
            let tol = Tolerances::default();
            integrate(tab, oscillator, &mut y, 0.0, 10.0, tol, None, &[], None);
            assert!((y[0] - 10f64.cos()).abs() < 1e-8, "{}", tab.name);
            assert!((y[1] + 10f64.sin()).abs() < 1e-8, "{}", tab.name);
        }
    }

    #[test]
    fn eighth_order_beats_fifth_order_on_evaluations() {
        let tol = Tolerances::default();
        let (mut a, mut b) = ([1.0, 0.0], [1.0, 0.0]);
        let s8 = integrate(&DOP853, oscillator, &mut a, 0.0, 20.0, tol, None, &[], None);
        let s5 = integrate(&DP54, oscillator, &mut b, 0.0, 20.0, tol, None, &[], None);
        assert!(s8.evals < s5.evals, "{} vs {}", s8.evals, s5.evals);
        assert!((a[0] - 20f64.cos()).abs() < 1e-8);
    }

    #[test]
    fn kepler_orbit_closes_to_tight_tolerance() {
        // Circular two-body orbit: period 2 pi, returns to its start.
        let mut y = [1.0, 0.0, 0.0, 1.0];
        let tf = 2.0 * std::f64::consts::PI;
        let kepler = |y: &[f64], d: &mut [f64]| {
            let r3 = (y[0] * y[0] + y[1] * y[1]).powf(1.5);
            d[0] = y[2];
            d[1] = y[3];
            d[2] = -y[0] / r3;
            d[3] = -y[1] / r3;
        };
        let tol = Tolerances::default();
        let stats = integrate(&DOP853, kepler, &mut y, 0.0, tf, tol, None, &[], None);
        assert!((y[0] - 1.0).abs() < 1e-8 && y[1].abs() < 1e-8, "{y:?}");
        assert!(stats.evals < 3000);
    }
}

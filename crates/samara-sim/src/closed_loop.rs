//! The sample-and-hold closed loop (docs/model.md section 4): at each control instant the
//! controller reads the state, its output is held for one period while the plant is
//! integrated, and (published protocol) the filter state E restarts at 0 every period.

use crate::control::Controller;
use crate::dopri;
use crate::dynamics::Dynamics;
use crate::explicit_rk::{Stats, Tolerances};
use crate::ode45::{self, Ode45Options};
use crate::rk4::Rk4;
use samara_num::Scalar;
use samara_plant::Plant;

/// Which integrator advances the plant over one period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Integrator {
    /// MATLAB-ode45 clone with default tolerances (reproduces the published data).
    Ode45,
    /// DOP853 under the standard step control (CLI `dop853`, alias `tight`; by default
    /// at rtol 1e-10, atol 1e-12), continuing each period with the step the previous
    /// one proposed.
    Dop853(Tolerances),
    /// Dormand-Prince 5(4) under the standard step control (CLI `dp5`).
    Dp5(Tolerances),
    /// Fixed-step RK4 with the given step.
    Rk4(f64),
}

impl Integrator {
    /// Parse a CLI name (`ode45`, `dop853` or its older name `tight`, `dp5`, `rk4`).
    pub fn from_name(s: &str) -> Option<Integrator> {
        match s {
            "ode45" => Some(Integrator::Ode45),
            "dop853" | "tight" => Some(Integrator::Dop853(Tolerances::default())),
            "dp5" => Some(Integrator::Dp5(Tolerances::default())),
            "rk4" => Some(Integrator::Rk4(1e-3)),
            _ => None,
        }
    }

    /// The older name of [`Integrator::Dop853`] (it named the method by a property, its
    /// tight default tolerances), kept as a constructor so existing callers compile.
    #[allow(non_snake_case)]
    pub const fn Tight(tol: Tolerances) -> Integrator {
        Integrator::Dop853(tol)
    }

    /// Advance `x` over one control period `[0, out_times.last()]` of `x' = f(x, u)`
    /// with the input `u` held. `out_times` is the output grid of the period (from 0;
    /// the ode45 clone reads its first step from it even when nothing is recorded, and
    /// RK4 steps each of its intervals); with `dense`, each output time `t` and the
    /// state there are appended as one row `t, x...`. `h_prev` is the step the previous
    /// period proposed (DOP853 continues with it; 0 for none); `scratch` the value
    /// buffer of an interpreted right-hand side.
    #[allow(clippy::too_many_arguments)]
    pub fn hold<D: Dynamics>(
        self,
        d: &D,
        x: &mut [f64],
        u: &[f64],
        out_times: &[f64],
        h_prev: f64,
        scratch: &mut Vec<f64>,
        dense: Option<&mut Vec<f64>>,
    ) -> Stats {
        let period = *out_times.last().expect("an output grid ends at the period");
        let rhs = |y: &[f64], out: &mut [f64]| d.rhs_buffered(scratch, y, u, out);
        match self {
            Integrator::Ode45 => {
                ode45::integrate(rhs, x, out_times, &Ode45Options::default(), dense)
            }
            Integrator::Dop853(tol) => crate::dop853::integrate_from(
                rhs,
                x,
                0.0,
                period,
                tol,
                (h_prev > 0.0).then_some(h_prev),
                out_times,
                dense,
            ),
            Integrator::Dp5(tol) => dopri::integrate(rhs, x, 0.0, period, tol, out_times, dense),
            Integrator::Rk4(h) => {
                let mut rhs = rhs;
                let mut rk = Rk4::new(x.len());
                let mut st = Stats::default();
                let mut t = 0.0;
                let mut dense = dense;
                for &to in &out_times[1..] {
                    st.evals += 4 * rk.integrate(&mut rhs, x, t, to, h);
                    t = to;
                    if let Some(buf) = dense.as_deref_mut() {
                        buf.push(to);
                        buf.extend_from_slice(x);
                    }
                }
                st
            }
        }
    }
}

/// Settings of a closed-loop flight. Defaults: the published protocol.
#[derive(Clone, Debug)]
pub struct LoopSettings {
    /// Control period (0.5).
    pub period: f64,
    /// Horizon (20); must be a positive multiple of the period.
    pub horizon: f64,
    /// Integrator (ode45 clone).
    pub integrator: Integrator,
    /// Restart the filter state E at 0 every period (true, as the published code).
    pub reset_filter: bool,
    /// Output spacing inside each period for trajectories (0.01, as `0:0.01:0.5`);
    /// `None` records control instants only.
    pub output_step: Option<f64>,
}

impl Default for LoopSettings {
    fn default() -> Self {
        LoopSettings {
            period: 0.5,
            horizon: 20.0,
            integrator: Integrator::Ode45,
            reset_filter: true,
            output_step: Some(0.01),
        }
    }
}

/// Largest number of control periods of one flight (`horizon / period`): a guard against
/// settings that would allocate without bound (the published protocol has 40).
pub const MAX_PERIODS: usize = 1_000_000;

/// Largest number of output points per control period (`period / output_step`).
pub const MAX_OUTPUTS_PER_PERIOD: usize = 1_000_000;

/// Invalid settings or states.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SimError {
    /// The period is not a positive finite number.
    #[error("the control period must be a positive number, got {0}; pass e.g. --period 0.5")]
    Period(f64),
    /// The horizon is not positive or not a multiple of the period.
    #[error("the horizon must be a positive multiple of the period ({period}), got {horizon}; pass e.g. --horizon 20")]
    Horizon {
        /// Horizon given.
        horizon: f64,
        /// Period given.
        period: f64,
    },
    /// More control periods than [`MAX_PERIODS`].
    #[error("the horizon {horizon} is {periods:e} control periods of {period}; at most {max} are allowed (memory grows with every period): pass a shorter --horizon or a longer --period")]
    TooManyPeriods {
        /// Horizon given.
        horizon: f64,
        /// Period given.
        period: f64,
        /// `horizon / period`.
        periods: f64,
        /// The limit.
        max: usize,
    },
    /// The output step does not divide the period.
    #[error("the output step {0} must be positive, divide the period, and give at most 1000000 points per period")]
    OutputStep(f64),
    /// The integrator's step size collapsed ([`crate::Collapse`]): the right-hand side
    /// switches at the state faster than any step can follow (the quadrant masks of the
    /// plate and full models where the field points at a switch from both sides).
    #[error("the integrator's step size collapsed at t = {t} (state {state:?}, held input ex = {ex}): the right-hand side switches there (a quadrant mask of the model) faster than any step can follow; try another start or the reduced model, whose right-hand side is smooth")]
    StepCollapse {
        /// Time where the step collapsed.
        t: f64,
        /// The state there.
        state: Vec<f64>,
        /// Input held during the period.
        ex: f64,
    },
    /// The state became NaN or infinite (the model left its valid range).
    #[error("the state became NaN or infinite in the control period ending at t = {t} (held input ex = {ex}): the model left its valid range; clip the controller's output (drop --no-clip) or start nearer the published heights")]
    NonFinite {
        /// End of the period.
        t: f64,
        /// Input held during it.
        ex: f64,
    },
    /// State of the wrong size.
    #[error("the initial state has {found} components but model `{model}` has {expected}")]
    StateDim {
        /// Model name.
        model: &'static str,
        /// Expected.
        expected: usize,
        /// Found.
        found: usize,
    },
}

impl LoopSettings {
    /// Number of control steps; validates the settings.
    pub fn steps(&self) -> Result<usize, SimError> {
        if !(self.period.is_finite() && self.period > 0.0) {
            return Err(SimError::Period(self.period));
        }
        let r = self.horizon / self.period;
        let steps = r.round();
        if self.horizon.is_finite() && r > MAX_PERIODS as f64 + 0.5 {
            return Err(SimError::TooManyPeriods {
                horizon: self.horizon,
                period: self.period,
                periods: r,
                max: MAX_PERIODS,
            });
        }
        if !(self.horizon.is_finite() && self.horizon > 0.0)
            || steps < 1.0
            || (r - steps).abs() > 1e-9 * r.max(1.0)
        {
            return Err(SimError::Horizon {
                horizon: self.horizon,
                period: self.period,
            });
        }
        if let Some(o) = self.output_step {
            let q = self.period / o;
            if !(o > 0.0)
                || !q.is_finite()
                || q > MAX_OUTPUTS_PER_PERIOD as f64 + 0.5
                || (q - q.round()).abs() > 1e-9 * q.max(1.0)
            {
                return Err(SimError::OutputStep(o));
            }
        }
        Ok(steps as usize)
    }
}

/// One control step of a flight.
#[derive(Clone, Debug, PartialEq)]
pub struct StepRecord {
    /// Time at the end of the period.
    pub t_end: f64,
    /// State at the end of the period.
    pub state_end: Vec<f64>,
    /// Control input held during the period.
    pub ex: f64,
}

/// Dense output of a flight, stored flat (one allocation per flight): rows of
/// `t, ex, state...`.
#[derive(Clone, Debug, PartialEq, Default)]
pub struct Dense {
    /// State dimension.
    pub dim: usize,
    /// Flat rows.
    pub data: Vec<f64>,
}

impl Dense {
    /// Append a row.
    pub fn push(&mut self, t: f64, state: &[f64], ex: f64) {
        self.data.push(t);
        self.data.push(ex);
        self.data.extend_from_slice(state);
    }

    /// Number of rows.
    pub fn len(&self) -> usize {
        self.data.len() / (self.dim + 2)
    }

    /// Whether there are no rows.
    pub fn is_empty(&self) -> bool {
        self.data.is_empty()
    }

    /// Rows as `(t, state, ex)`.
    pub fn iter(&self) -> impl Iterator<Item = (f64, &[f64], f64)> {
        self.data
            .chunks_exact(self.dim + 2)
            .map(|r| (r[0], &r[2..], r[1]))
    }
}

/// A simulated flight.
#[derive(Clone, Debug, PartialEq)]
pub struct Flight {
    /// Initial state.
    pub initial: Vec<f64>,
    /// One record per control step.
    pub steps: Vec<StepRecord>,
    /// Dense output at the output times (including t = 0).
    pub dense: Dense,
    /// Integration statistics summed over the flight.
    pub evals: usize,
}

/// The sample-and-hold loop, written once for every closed loop in samara (the
/// glider's flights, a system file's, training's differentiable flights), over any
/// [`Scalar`]: for each of `periods` control periods `k`, `control(ctx, k, x)` reads the
/// state (and applies what happens at a control instant: the published filter restart,
/// a system file's resets) and returns the input; `hold(ctx, x, u)` advances the plant
/// over the period with that input held (by [`Integrator::hold`] over a [`Dynamics`], or
/// [`Rk4`] on dual numbers); `after(ctx, k, x, u, held)` sees the state at the period's
/// end with what `hold` returned (records it, checks it). `ctx` is the flight's own
/// record, shared by the three steps. The first error stops the flight.
pub fn sample_and_hold<S, C, H, E>(
    ctx: &mut C,
    x: &mut [S],
    periods: usize,
    mut control: impl FnMut(&mut C, usize, &mut [S]) -> Result<Vec<S>, E>,
    mut hold: impl FnMut(&mut C, &mut [S], &[S]) -> H,
    mut after: impl FnMut(&mut C, usize, &[S], &[S], H) -> Result<(), E>,
) -> Result<(), E> {
    for k in 0..periods {
        let u = control(ctx, k, x)?;
        let held = hold(ctx, x, &u);
        after(ctx, k, x, &u, held)?;
    }
    Ok(())
}

/// Fly `plant` under `controller` from `initial` with the given settings.
pub fn fly(
    plant: &Plant,
    controller: &mut dyn Controller,
    initial: &[f64],
    settings: &LoopSettings,
) -> Result<Flight, SimError> {
    let n_steps = settings.steps()?;
    let dim = plant.dim();
    if initial.len() != dim {
        return Err(SimError::StateDim {
            model: plant.model.name(),
            expected: dim,
            found: initial.len(),
        });
    }
    controller.reset();
    let period = settings.period;
    // Output times within a period, as MATLAB's tspan 0:0.01:0.5 (t = i * 0.01). The
    // ode45 clone reads its first step from tspan(2) - tspan(1), so the grid is passed
    // even when nothing is recorded.
    let grid = settings.output_step.unwrap_or(0.01);
    let m = ((period / grid).round() as usize).max(1);
    let out_times: Vec<f64> = (0..=m)
        .map(|i| if i == m { period } else { i as f64 * grid })
        .collect();
    let want = settings.output_step.is_some();
    /// What the flight records, shared by the loop's steps.
    struct Record {
        flight: Flight,
        buf: Vec<f64>,
        scratch: Vec<f64>,
        h_next: f64,
    }
    let mut rec = Record {
        flight: Flight {
            initial: initial.to_vec(),
            steps: Vec::with_capacity(n_steps),
            dense: Dense {
                dim,
                data: Vec::new(),
            },
            evals: 0,
        },
        buf: Vec::new(),
        scratch: Vec::new(),
        h_next: 0.0,
    };
    let mut s = initial.to_vec();
    sample_and_hold(
        &mut rec,
        &mut s,
        n_steps,
        |rec, k, s| {
            let ex = controller.act(s);
            if k == 0 && want {
                rec.flight.dense.push(0.0, s, ex);
            }
            if settings.reset_filter && plant.model.has_filter() {
                s[6] = 0.0;
            }
            Ok(vec![ex])
        },
        |rec, s, u| {
            rec.buf.clear();
            settings.integrator.hold(
                plant,
                s,
                u,
                &out_times,
                rec.h_next,
                &mut rec.scratch,
                want.then_some(&mut rec.buf),
            )
        },
        |rec, k, s, u, stats: Stats| {
            let ex = u[0];
            rec.flight.evals += stats.evals;
            rec.h_next = stats.h_next;
            let t0 = k as f64 * period;
            for row in rec.buf.chunks_exact(dim + 1) {
                rec.flight.dense.push(t0 + row[0], &row[1..], ex);
            }
            if let Some(c) = stats.collapse {
                // A step that collapses while the state runs off to huge values is a
                // divergence (the model left its valid range), not a switching surface:
                // report it as such, with the fix that applies.
                if c.state[..dim]
                    .iter()
                    .any(|v| !v.is_finite() || v.abs() > DIVERGED)
                {
                    return Err(SimError::NonFinite {
                        t: (k + 1) as f64 * period,
                        ex,
                    });
                }
                return Err(SimError::StepCollapse {
                    t: k as f64 * period + c.t,
                    state: c.state[..dim].to_vec(),
                    ex,
                });
            }
            if s.iter().any(|v| !v.is_finite()) {
                return Err(SimError::NonFinite {
                    t: (k + 1) as f64 * period,
                    ex,
                });
            }
            rec.flight.steps.push(StepRecord {
                t_end: (k + 1) as f64 * period,
                state_end: s.to_vec(),
                ex,
            });
            Ok(())
        },
    )?;
    Ok(rec.flight)
}

/// A state component beyond this magnitude counts as diverged: the glider's states are
/// of order 100 over every published flight, so 1e12 is far outside the model's range.
const DIVERGED: f64 = 1e12;

/// The published starts: y0 = n / 0.07 for n = 0.1:0.025:0.3 (nine values). MATLAB's
/// colon operator computes `0.1 + i * 0.025`.
pub fn published_starts() -> Vec<f64> {
    (0..9).map(|i| (0.1 + i as f64 * 0.025) / 0.07).collect()
}

/// The initial state (1, 0, 0, 0, 0, y0 [, 0]) of a flight.
pub fn initial_state(plant: &Plant, y0: f64) -> Vec<f64> {
    let mut s = vec![1.0, 0.0, 0.0, 0.0, 0.0, y0];
    if plant.model.has_filter() {
        s.push(0.0);
    }
    s
}

/// Training rows `(v_xp, v_yp, omega, theta, x, y, ex)`: one per control step, state at
/// the END of the step and the input applied during it (the published row layout).
pub fn training_rows(flights: &[Flight]) -> Vec<[f64; 7]> {
    flights
        .iter()
        .flat_map(|f| {
            f.steps.iter().map(|r| {
                let s = &r.state_end;
                [s[0], s[1], s[2], s[3], s[4], s[5], r.ex]
            })
        })
        .collect()
}

/// Min-max normalisation constants of rows: `(min, range)` per column.
pub fn minmax(rows: &[[f64; 7]]) -> ([f64; 7], [f64; 7]) {
    let mut lo = [f64::INFINITY; 7];
    let mut hi = [f64::NEG_INFINITY; 7];
    for r in rows {
        for j in 0..7 {
            lo[j] = lo[j].min(r[j]);
            hi[j] = hi[j].max(r[j]);
        }
    }
    let mut range = [0.0; 7];
    for j in 0..7 {
        range[j] = hi[j] - lo[j];
    }
    (lo, range)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings(horizon: f64, period: f64) -> LoopSettings {
        LoopSettings {
            horizon,
            period,
            ..LoopSettings::default()
        }
    }

    #[test]
    fn sizes_are_checked_before_anything_is_allocated() {
        assert_eq!(settings(20.0, 0.5).steps(), Ok(40));
        assert!(matches!(
            settings(1e12, 0.5).steps(),
            Err(SimError::TooManyPeriods { .. })
        ));
        assert!(matches!(
            settings(1e308, 0.5).steps(),
            Err(SimError::TooManyPeriods { .. })
        ));
        // Less than one period is no flight at all.
        assert!(matches!(
            settings(1e-20, 0.5).steps(),
            Err(SimError::Horizon { .. })
        ));
        for p in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(
                settings(20.0, p).steps(),
                Err(SimError::Period(_))
            ));
        }
        let mut s = settings(0.5, 0.5);
        s.output_step = Some(1e-12);
        assert!(matches!(s.steps(), Err(SimError::OutputStep(_))));
    }

    /// A right-hand side that turns NaN: every adaptive integrator stops with a NaN state
    /// (dp5 used to shrink its step forever).
    #[test]
    fn nan_right_hand_sides_end_the_integration() {
        let nan_after = |y: &[f64], d: &mut [f64]| {
            for (di, yi) in d.iter_mut().zip(y) {
                *di = if *yi > 1.2 { f64::NAN } else { 1.0 };
            }
        };
        let tol = crate::dopri::Tolerances::default();
        let times = [0.0, 0.25, 0.5];
        let mut y = [1.0, 1.0];
        crate::dopri::integrate(nan_after, &mut y, 0.0, 0.5, tol, &times, None);
        assert!(y.iter().all(|v| v.is_nan()), "{y:?}");
        let mut y = [1.0, 1.0];
        crate::dop853::integrate(nan_after, &mut y, 0.0, 0.5, tol, &times, None);
        assert!(y.iter().any(|v| !v.is_finite()), "{y:?}");
        let mut y = [1.0, 1.0];
        crate::ode45::integrate(nan_after, &mut y, &times, &Default::default(), None);
        assert!(y.iter().any(|v| !v.is_finite()), "{y:?}");
    }

    /// The RK4 integrator through the shared loop ([`sample_and_hold`],
    /// [`Integrator::hold`]) gives the flight of a hand-written sample-and-hold loop
    /// that steps RK4 over each output interval with the PID law's `ex` held and the
    /// filter restarted every period, bit for bit, dense rows included.
    #[test]
    fn rk4_flights_are_the_hand_written_loop() {
        use crate::control::PidController;
        let plant = Plant::new(samara_plant::Model::Full);
        let ls = LoopSettings {
            horizon: 3.0,
            period: 0.5,
            integrator: Integrator::Rk4(1e-3),
            reset_filter: true,
            output_step: Some(0.1),
        };
        let x0 = initial_state(&plant, 3.0);
        let f = fly(&plant, &mut PidController::default(), &x0, &ls).unwrap();
        let mut pid = PidController::default();
        pid.reset();
        let mut s = x0.clone();
        let mut rows: Vec<(f64, Vec<f64>, f64)> = Vec::new();
        for k in 0..6 {
            let ex = pid.act(&s);
            if k == 0 {
                rows.push((0.0, s.clone(), ex));
            }
            s[6] = 0.0;
            let mut t = 0.0;
            for i in 1..=5 {
                let to = if i == 5 { 0.5 } else { i as f64 * 0.1 };
                crate::rk4::integrate(|y, d| plant.rhs(y, &ex, d), &mut s, t, to, 1e-3);
                rows.push((k as f64 * 0.5 + to, s.clone(), ex));
                t = to;
            }
            assert_eq!(f.steps[k].state_end, s, "period {k}");
            assert_eq!(f.steps[k].ex, ex);
        }
        let dense: Vec<(f64, Vec<f64>, f64)> = f
            .dense
            .iter()
            .map(|(t, x, ex)| (t, x.to_vec(), ex))
            .collect();
        assert_eq!(dense, rows);
    }
}

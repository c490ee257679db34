//! Closed-loop simulation of a system file, with the semantics of
//! [`System::initial_state`] and [`System::begin_period`] (docs/system.md, "Semantics of
//! a closed loop"): at each control instant but the horizon the resets are applied, the
//! network reads the observed states, its outputs are mapped to the plant's
//! inputs (affine map, then clip) and held for one period, over which the equations are
//! integrated by samara-sim's DOP853 (rtol 1e-10, atol 1e-12, the step carried over from
//! period to period as the built-in closed loop does). The same sample-and-hold protocol
//! as `samara_sim::closed_loop::fly`, so the Alsomitra system files reproduce the
//! built-in model's flights.

use crate::{System, When};
use samara_sim::closed_loop::sample_and_hold;
use samara_sim::{Integrator, Stats, Tolerances};

/// A simulated flight of a system.
#[derive(Clone, Debug, PartialEq)]
pub struct SystemFlight {
    /// Output times.
    pub t: Vec<f64>,
    /// States at the output times (one row per time).
    pub states: Vec<Vec<f64>>,
    /// Plant inputs held over the stretch that ends at each output time (row 0: the
    /// first period's).
    pub inputs: Vec<Vec<f64>>,
}

/// Why a flight could not be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SimError {
    /// The initial state has the wrong length.
    #[error("the initial state has {found} entries; the system has {expected} states")]
    StateDim {
        /// States of the system.
        expected: usize,
        /// Entries given.
        found: usize,
    },
    /// The controller gave the wrong number of outputs.
    #[error("the network gives {found} outputs; the system reads {expected} (net[0..{expected}])")]
    NetOutputs {
        /// Outputs the system reads.
        expected: usize,
        /// Outputs given.
        found: usize,
    },
    /// The system is discrete-time (`next` updates): it has no flow to integrate.
    #[error("the system is discrete-time (`next` updates), with no flow to integrate: analyse it with `samara reach --system` (samara_reach::discrete)")]
    Discrete,
    /// More states than the integrators' fixed buffers hold.
    #[error("the system has {0} states; the closed-loop integrator handles at most {max} (samara_sim::MAX_DIM)", max = samara_sim::MAX_DIM)]
    TooManyStates(usize),
    /// The integrator's step size collapsed (`samara_sim::Collapse`): the right-hand
    /// side switches at the state faster than any step can follow, typically an `if`
    /// whose field points at its switch from both sides (a sliding mode).
    #[error("the integrator's step size collapsed at t = {t} (state {state:?}, step {h:.1e}): {}; smooth the switch (blend the branches with 0.5 * (1 + tanh(k * (a - b))) for a large k) or give the `if` hysteresis (a state that remembers the branch, so that it changes only past a margin)", switch_text(switches))]
    StepCollapse {
        /// Time where the step collapsed.
        t: f64,
        /// The state there.
        state: Vec<f64>,
        /// The step size last tried.
        h: f64,
        /// The `if`s whose condition changes sign at that state, as `file:line:col:
        /// source line` (empty: none found, e.g. an `abs`, `min`, `max` or `sign`).
        switches: Vec<String>,
    },
    /// The time budget given to [`fly_until`] was spent.
    #[error("the time budget was spent before the control period ending at t = {t}")]
    Timeout {
        /// End of the period not flown.
        t: f64,
    },
    /// The state left the finite numbers.
    #[error("the state became NaN or infinite in the control period ending at t = {t}")]
    NonFinite {
        /// End of the period.
        t: f64,
    },
}

/// The switches of a [`SimError::StepCollapse`] message.
fn switch_text(switches: &[String]) -> String {
    if switches.is_empty() {
        "the right-hand side is not smooth there (no `if` of the file flips at that state: look at abs, sign, min or max)".to_string()
    } else {
        format!(
            "the right-hand side switches there, at {}",
            switches
                .iter()
                .map(|w| format!("`if` {w}"))
                .collect::<Vec<_>>()
                .join(" and ")
        )
    }
}

/// Fly `sys` under the controller `net` (network inputs -> outputs) from `x0`, with
/// `per_period` output times per control period (at least 1: the control instants).
pub fn fly(
    sys: &System,
    net: &dyn Fn(&[f64]) -> Vec<f64>,
    x0: &[f64],
    per_period: usize,
) -> Result<SystemFlight, SimError> {
    fly_until(sys, net, x0, per_period, None)
}

/// [`fly`] within a time budget: the clock is read before every control period, and a
/// flight still going at `deadline` stops with [`SimError::Timeout`] (a period itself
/// is bounded by the integrator's collapse detection, `samara_sim::Collapse`).
pub fn fly_until(
    sys: &System,
    net: &dyn Fn(&[f64]) -> Vec<f64>,
    x0: &[f64],
    per_period: usize,
    deadline: Option<std::time::Instant>,
) -> Result<SystemFlight, SimError> {
    if sys.is_discrete() {
        return Err(SimError::Discrete);
    }
    let n = sys.dim();
    if x0.len() != n {
        return Err(SimError::StateDim {
            expected: n,
            found: x0.len(),
        });
    }
    if n > samara_sim::MAX_DIM {
        return Err(SimError::TooManyStates(n));
    }
    let m = per_period.max(1);
    let period = sys.period;
    let out_times: Vec<f64> = (0..=m)
        .map(|i| {
            if i == m {
                period
            } else {
                i as f64 * period / m as f64
            }
        })
        .collect();
    let mut x = x0.to_vec();
    /// What the flight records, shared by the loop's steps.
    struct Record {
        flight: SystemFlight,
        obs: Vec<f64>,
        scratch: Vec<f64>,
        buf: Vec<f64>,
        h_next: f64,
    }
    let mut rec = Record {
        flight: SystemFlight {
            t: Vec::new(),
            states: Vec::new(),
            inputs: Vec::new(),
        },
        obs: vec![0.0; sys.n_observed()],
        scratch: Vec::new(),
        buf: Vec::new(),
        h_next: 0.0,
    };
    sys.initial_state(&mut x);
    sample_and_hold(
        &mut rec,
        &mut x,
        sys.steps(),
        |rec, k, x| {
            if deadline.is_some_and(|d| std::time::Instant::now() > d) {
                return Err(SimError::Timeout {
                    t: (k + 1) as f64 * period,
                });
            }
            sys.begin_period(k, x);
            sys.observe(x, &mut rec.obs);
            let y = net(&rec.obs);
            if y.len() < sys.n_net_outputs {
                return Err(SimError::NetOutputs {
                    expected: sys.n_net_outputs,
                    found: y.len(),
                });
            }
            let mut u = vec![0.0; sys.n_inputs()];
            sys.actuate(&y, &mut u);
            if k == 0 {
                rec.flight.t.push(0.0);
                rec.flight.states.push(x.to_vec());
                rec.flight.inputs.push(u.clone());
            }
            Ok(u)
        },
        |rec, x, u| {
            rec.buf.clear();
            Integrator::Dop853(Tolerances::default()).hold(
                sys,
                x,
                u,
                &out_times,
                rec.h_next,
                &mut rec.scratch,
                Some(&mut rec.buf),
            )
        },
        |rec, k, x, u, stats: Stats| {
            rec.h_next = stats.h_next;
            if let Some(c) = stats.collapse {
                let state = c.state[..n].to_vec();
                let file = &sys.file;
                let switches = sys
                    .switches_at(&state, u, 1e-6)
                    .into_iter()
                    .map(|w| format!("{file}:{}:{}: {}", w.pos.line, w.pos.col, w.text))
                    .collect();
                return Err(SimError::StepCollapse {
                    t: k as f64 * period + c.t,
                    state,
                    h: c.h,
                    switches,
                });
            }
            if x.iter().any(|v| !v.is_finite()) {
                return Err(SimError::NonFinite {
                    t: (k + 1) as f64 * period,
                });
            }
            let t0 = k as f64 * period;
            for row in rec.buf.chunks_exact(n + 1) {
                rec.flight.t.push(t0 + row[0]);
                rec.flight.states.push(row[1..].to_vec());
                rec.flight.inputs.push(u.to_vec());
            }
            Ok(())
        },
    )?;
    Ok(rec.flight)
}

/// Whether every goal of `sys` holds along the flight (at its output times: a window
/// goal is checked at the recorded times inside the window).
pub fn goals_hold(sys: &System, f: &SystemFlight) -> Vec<bool> {
    let eps = 1e-9 * sys.horizon.max(1.0);
    sys.goals
        .iter()
        .map(|g| {
            let at = |i: usize| g.holds(&f.states[i]);
            let inside = |t1: f64, t2: f64| {
                (0..f.t.len()).filter(move |&i| f.t[i] >= t1 - eps && f.t[i] <= t2 + eps)
            };
            match g.when {
                When::End => f.t.last().map(|_| at(f.t.len() - 1)).unwrap_or(false),
                When::Always(t1, t2) => inside(t1, t2).all(at),
                When::Eventually(t1, t2) => inside(t1, t2).any(at),
            }
        })
        .collect()
}

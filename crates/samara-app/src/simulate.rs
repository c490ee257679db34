//! Simulation results as typed documents (`samara simulate --json`): the flights of
//! the built-in glider ([`SimulateSummary`]) and of a system file ([`SystemSimSummary`]).

use crate::args::SimulateArgs;
use crate::bind::{check_horizon_period, check_period_count, num};
use crate::{input, AppError, Front};
use samara_plant::{Model, STATE_NAMES};
use samara_sim::Flight;
use samara_sim::{published_starts, Integrator, LoopSettings};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Largest magnitude of an initial state value of `simulate` and `reach`: the model is
/// nondimensional and the published states are O(1) (heights 1.43 to 4.29).
pub const MAX_STATE: f64 = 1000.0;

/// One flight of the glider: its start height and where it ends.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StartSummary {
    /// Initial height.
    pub y0: f64,
    /// The state at the horizon, by name.
    pub final_state: BTreeMap<String, f64>,
    /// `x + y` at the horizon.
    pub final_x_plus_y: f64,
    /// Right-hand-side evaluations the integrator made.
    pub rhs_evals: usize,
}

impl StartSummary {
    /// The summary of a flight of a model with `dim` states.
    pub fn of(f: &Flight, dim: usize) -> Self {
        let last = &f.steps.last().expect("at least one step").state_end;
        StartSummary {
            y0: f.initial[5],
            final_state: last
                .iter()
                .enumerate()
                .take(dim)
                .map(|(i, v)| (STATE_NAMES[i].to_string(), *v))
                .collect(),
            final_x_plus_y: last[4] + last[5],
            rhs_evals: f.evals,
        }
    }
}

/// The `--json` summary of `samara simulate` on the built-in glider.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SimulateSummary {
    /// Model name.
    pub model: String,
    /// `--controller` as given.
    pub controller: String,
    /// `--integrator` as given.
    pub integrator: String,
    /// Control period.
    pub period: f64,
    /// Horizon.
    pub horizon: f64,
    /// One entry per start.
    pub starts: Vec<StartSummary>,
    /// Wall time.
    pub wall_seconds: f64,
    /// Output folder.
    pub out: String,
    /// Warnings on the inputs.
    pub warnings: Vec<String>,
}

/// A flight of a system file that misses a goal.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct GoalViolation {
    /// The start's number.
    pub start: usize,
    /// Its initial state.
    pub initial: Vec<f64>,
    /// The goal's text.
    pub goal: String,
}

/// The `--json` summary of `samara simulate --system`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SystemSimSummary {
    /// The system's name.
    pub system: String,
    /// Number of flights.
    pub starts: usize,
    /// The goals' texts.
    pub goals: Vec<String>,
    /// The flights that miss a goal.
    pub violations: Vec<GoalViolation>,
    /// Wall time.
    pub wall_seconds: f64,
}

/// Limits of the numbers `simulate` and `reach` accept (documented in `--help` and
/// docs/simulation.md): beyond them a run would only exhaust memory or leave the range in
/// which the (nondimensional) glider model means anything.
pub mod limits {
    /// Most control periods (`horizon / period`) of `simulate` (the published run has
    /// 40): the closed loop's own limit, `samara_sim::MAX_PERIODS`.
    pub const MAX_PERIODS: f64 = samara_sim::closed_loop::MAX_PERIODS as f64;
    /// Most starts of `simulate --y0`.
    pub const MAX_STARTS: usize = 100_000;
    /// Most rows of `trajectories.csv` (built in memory, about 200 bytes a row).
    pub const MAX_ROWS: f64 = 2_000_000.0;
    /// Largest magnitude of an initial state value.
    pub const MAX_STATE: f64 = crate::simulate::MAX_STATE;
}

/// Parse `START:END:COUNT` or `V,V,...`.
pub fn parse_y0(s: &str) -> Result<Vec<f64>, AppError> {
    let bad = || {
        AppError::Input(format!("--y0 {s:?}: expected START:END:COUNT (e.g. 1.4286:4.2857:9) or a list V,V,... of finite numbers"))
    };
    let v = parse_y0_values(s, &bad)?;
    if v.len() > limits::MAX_STARTS {
        return input(format!(
            "--y0 {s:?}: {} starts; at most {} are allowed (each start is a full flight kept in memory); use fewer starts or several runs",
            v.len(),
            limits::MAX_STARTS
        ));
    }
    if let Some(y) = v.iter().find(|y| y.abs() > limits::MAX_STATE) {
        return input(format!(
            "--y0 {s:?}: the height {} is outside [-{m}, {m}], the range in which the nondimensional model means anything (published starts: 1.43 to 4.29); give heights inside it",
            num(*y),
            m = limits::MAX_STATE
        ));
    }
    Ok(v)
}

fn parse_y0_values(s: &str, bad: &dyn Fn() -> AppError) -> Result<Vec<f64>, AppError> {
    if s.contains(':') {
        let parts: Vec<&str> = s.split(':').collect();
        if parts.len() != 3 {
            return Err(bad());
        }
        let a: f64 = parts[0].trim().parse().map_err(|_| bad())?;
        let b: f64 = parts[1].trim().parse().map_err(|_| bad())?;
        let n: usize = parts[2].trim().parse().map_err(|_| bad())?;
        if n == 0 || !a.is_finite() || !b.is_finite() {
            return Err(bad());
        }
        if n > limits::MAX_STARTS {
            return input(format!(
                "--y0 {s:?}: COUNT {n} is more than {} starts (each start is a full flight kept in memory); use fewer starts or several runs",
                limits::MAX_STARTS
            ));
        }
        if n == 1 {
            return Ok(vec![a]);
        }
        Ok((0..n)
            .map(|i| a + (b - a) * i as f64 / (n - 1) as f64)
            .collect())
    } else {
        let v: Vec<f64> = s
            .split(',')
            .map(|x| x.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|_| bad())?;
        if v.is_empty() || v.iter().any(|x| !x.is_finite()) {
            return Err(bad());
        }
        Ok(v)
    }
}

/// The checked inputs of a `samara simulate` run of the built-in glider.
#[derive(Clone, Debug)]
pub struct SimPlan {
    /// The plant variant.
    pub model: samara_plant::Model,
    /// Period, horizon, integrator and output step of the loop.
    pub settings: samara_sim::LoopSettings,
    /// The initial heights.
    pub starts: Vec<f64>,
}

impl SimulateArgs {
    /// The model, loop settings and starts of a built-in glider run (`--model`,
    /// `--integrator`, `--horizon`, `--period`, `--y0`), every limit checked.
    pub fn plan(&self) -> Result<SimPlan, AppError> {
        let a = self;
        let model = Model::from_name(&a.model).ok_or_else(|| {
            AppError::Input(format!(
                "--model {:?}: unknown model; choose one of plate6, reduced, full",
                a.model
            ))
        })?;
        let integrator = Integrator::from_name(&a.integrator).ok_or_else(|| {
            AppError::Input(format!(
            "--integrator {:?}: unknown integrator; choose ode45, dop853 (or tight), dp5 or rk4",
            a.integrator
        ))
        })?;
        check_horizon_period(Front::Cli, a.horizon, a.period)?;
        check_period_count(Front::Cli, a.horizon, a.period, limits::MAX_PERIODS)?;
        let output_step = if (a.period / 0.01 - (a.period / 0.01).round()).abs() < 1e-9 {
            Some(0.01)
        } else {
            Some(a.period / 50.0)
        };
        let settings = LoopSettings {
            period: a.period,
            horizon: a.horizon,
            integrator,
            reset_filter: true,
            output_step,
        };
        settings
            .steps()
            .map_err(|e| AppError::Input(e.to_string()))?;
        let starts = match &a.y0 {
            Some(s) => parse_y0(s)?,
            None => published_starts(),
        };
        // Rows of trajectories.csv: t = 0 and every output point of every period.
        let per_period = output_step.map_or(1.0, |o| (a.period / o).round().max(1.0));
        let rows = starts.len() as f64 * (1.0 + (a.horizon / a.period).round() * per_period);
        if rows > limits::MAX_ROWS {
            return input(format!(
            "--y0/--horizon/--period: {} start(s) x {} period(s) x {per_period} output points give {rows:e} trajectory rows; at most {:e} are allowed (trajectories.csv is built in memory): use fewer starts, a shorter --horizon or a longer --period",
            starts.len(),
            (a.horizon / a.period).round(),
            limits::MAX_ROWS
        ));
        }
        Ok(SimPlan {
            model,
            settings,
            starts,
        })
    }

    /// The flags of `simulate --system`: no `--y0`, `--samples` from 1 to
    /// [`limits::MAX_STARTS`].
    pub fn check_system_flags(&self) -> Result<(), AppError> {
        let a = self;
        if a.y0.is_some() {
            return input("--y0 does not apply with --system: the system file's `init` lines give the initial set; use --samples N");
        }
        if a.samples == 0 || a.samples > limits::MAX_STARTS {
            return input(format!(
                "--samples {}: give 1 to {} starts",
                a.samples,
                limits::MAX_STARTS
            ));
        }
        Ok(())
    }

    /// The trajectory rows of `simulate --system` on `sys`, at most [`limits::MAX_ROWS`].
    pub fn check_system_rows(&self, sys: &samara_system::System) -> Result<(), AppError> {
        let a = self;
        let rows = (a.samples as f64) * (sys.steps() as f64 * 10.0 + 1.0);
        if rows > limits::MAX_ROWS {
            return input(format!(
            "--samples {} x {} periods x 10 output points = {rows:e} trajectory rows; at most {:e} are allowed: use fewer --samples",
            a.samples,
            sys.steps(),
            limits::MAX_ROWS
        ));
        }
        Ok(())
    }
}

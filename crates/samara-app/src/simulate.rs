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

pub use crate::bind::MAX_STATE;

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

/// The plant variant and the sample-and-hold loop of a glider simulation (`samara
/// simulate`, `samara.simulate`): the model and integrator by name, the horizon and period
/// (at most `max_periods` periods, a whole number of them), and dense output every 0.01
/// when it divides the period, else 50 points a period.
pub fn glider_loop(
    front: Front,
    model: &str,
    integrator: &str,
    horizon: f64,
    period: f64,
    max_periods: f64,
) -> Result<(Model, LoopSettings), AppError> {
    let Some(m) = Model::from_name(model) else {
        return input(format!(
            "{} {model:?}: unknown model; choose one of plate6, reduced, full",
            front.arg("model")
        ));
    };
    let Some(integrator) = Integrator::from_name(integrator) else {
        return input(format!(
            "{} {integrator:?}: unknown integrator; choose ode45, dop853 (or tight), dp5 or rk4",
            front.arg("integrator")
        ));
    };
    check_horizon_period(front, horizon, period)?;
    check_period_count(front, horizon, period, max_periods)?;
    let output_step = if (period / 0.01 - (period / 0.01).round()).abs() < 1e-9 {
        Some(0.01)
    } else {
        Some(period / 50.0)
    };
    let settings = LoopSettings {
        period,
        horizon,
        integrator,
        reset_filter: true,
        output_step,
    };
    settings
        .steps()
        .map_err(|e| AppError::Input(front.words(&e.to_string())))?;
    Ok((m, settings))
}

/// The controller of a glider simulation for model `model`, checked: the PID needs the
/// filter state, a constant must lie in the actuator's range, a network must have the
/// glider's 6 raw inputs and 1 output ([`check_glider_network`]).
/// `label` names the controller in messages (`--controller "constant:0.5":`, a file, or
/// `controller`), `name` the network in figures.
pub fn glider_controller(
    front: Front,
    c: ControllerRequest,
    model: Model,
    label: &str,
    name: &str,
) -> Result<Box<dyn samara_sim::Controller + Send>, AppError> {
    use samara_plant::EX_RANGE;
    use samara_sim::{ConstantController, NetworkController, PidController};
    use ControllerRequest as C;
    let q = |s: &str| match front {
        Front::Cli => s.to_string(),
        Front::Python => format!("'{s}'"),
    };
    Ok(match c {
        C::Pid => {
            if !model.has_filter() {
                return input(format!(
                    "{label} {} needs the filter state E, which model `reduced` does not have; use {} or {}, or another controller",
                    q("pid"),
                    front.eg("model", &q("plate6")),
                    q("full")
                ));
            }
            Box::new(PidController::default())
        }
        C::Constant(ex) => {
            if !(EX_RANGE.0..=EX_RANGE.1).contains(&ex) {
                return input(format!(
                    "{label} ex = {ex} is outside the allowed range [{}, {}]; choose a value inside it",
                    EX_RANGE.0, EX_RANGE.1
                ));
            }
            Box::new(ConstantController(ex))
        }
        C::Network { net, clip } => {
            let net = check_glider_network(label, &net)?;
            let c = if clip { Some(EX_RANGE) } else { None };
            Box::new(NetworkController::new(net, c, name))
        }
    })
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
        let (model, settings) = glider_loop(
            Front::Cli,
            &a.model,
            &a.integrator,
            a.horizon,
            a.period,
            limits::MAX_PERIODS,
        )?;
        let output_step = settings.output_step;
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

/// The files a built-in glider run writes into `--out`.
pub const WRITES: [&str; 5] = [
    "trajectories.csv",
    "training_data.csv",
    "normalisation.csv",
    "trajectories.png",
    "trajectories.svg",
];

impl SimulateArgs {
    /// A built-in glider run, checked ([`SimulateArgs::plan`], then `--controller`: `pid`,
    /// `constant:EX` or a network file, never under a name the run writes into
    /// `--out`), with the warnings on a network in the wrong units
    /// (`samara_reach::settings::units_warning`, the check `samara reach` makes).
    pub fn prepare(&self) -> anyhow::Result<(SimulatePlan, Vec<String>)> {
        use anyhow::{bail, Context};
        use samara_plant::EX_RANGE;
        use ControllerRequest as C;
        let a = self;
        let p = a.plan()?;
        let spec = a.controller.as_str();
        let mut label = "--controller".to_string();
        let mut name = String::new();
        let mut warnings = Vec::new();
        let request = if spec == "pid" {
            C::Pid
        } else if let Some(v) = spec.strip_prefix("constant:") {
            let ex: f64 = v.trim().parse().map_err(|_| {
                anyhow::anyhow!(
                    "--controller {spec:?}: {v:?} is not a number; use e.g. constant:0.187"
                )
            })?;
            label = format!("--controller {spec:?}:");
            C::Constant(ex)
        } else {
            let path = std::path::Path::new(spec);
            // Never write over the controller file (an input), before anything is computed.
            samara_report::guard::check_output_dir(
                "--out",
                &a.out,
                &WRITES,
                &[("--controller", path)],
            )?;
            if path.extension().and_then(|e| e.to_str()) != Some("onnx") && !path.exists() {
                bail!("--controller {spec:?}: expected `pid`, `constant:EX` or the path of an .onnx network");
            }
            if !path.exists() {
                bail!(
                    "--controller {}: no such file; give the path of an .onnx network",
                    path.display()
                );
            }
            let net = samara_nn::load(path).with_context(|| {
                format!(
                    "--controller {}: cannot load the network; give an ONNX file samara can read",
                    path.display()
                )
            })?;
            label = path.display().to_string();
            name = path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| "network".into());
            if net.n_inputs() == 6 && net.n_outputs() == 1 {
                let plant = samara_plant::Plant::new(p.model);
                let starts: Vec<Vec<f64>> = p
                    .starts
                    .iter()
                    .map(|&y0| samara_sim::initial_state(&plant, y0))
                    .collect();
                warnings.extend(
                    samara_reach::settings::units_warning(&net, &starts, EX_RANGE)
                        .map(|w| format!("--controller {}: {w}", a.controller)),
                );
            }
            C::Network {
                net,
                clip: !a.no_clip,
            }
        };
        let controller = glider_controller(Front::Cli, request, p.model, &label, &name)?;
        let plan = SimulatePlan {
            plant: samara_plant::Plant::new(p.model),
            controller,
            settings: p.settings,
            starts: p.starts,
        };
        Ok((plan, warnings))
    }
}

/// Write a built-in glider run's data into `out`: `trajectories.csv` (every start's
/// dense output), the training data set and its normalisation constants.
pub fn write_data(out: &std::path::Path, dim: usize, flights: &[Flight]) -> anyhow::Result<()> {
    use samara_report::write_atomic;
    use samara_sim::dataset::{normalisation_csv, training_csv};
    use std::fmt::Write as _;
    let mut traj = format!("start,y0,t,{},ex\n", STATE_NAMES[..dim].join(","));
    for (i, f) in flights.iter().enumerate() {
        for (t, s, ex) in f.dense.iter() {
            let _ = write!(traj, "{},{:?},{:?}", i + 1, f.initial[5], t);
            for v in s {
                let _ = write!(traj, ",{v:?}");
            }
            let _ = writeln!(traj, ",{ex:?}");
        }
    }
    write_atomic(&out.join("trajectories.csv"), traj.as_bytes())?;
    let rows = samara_sim::training_rows(flights);
    write_atomic(
        &out.join("training_data.csv"),
        training_csv(&rows).as_bytes(),
    )?;
    let (lo, range) = samara_sim::minmax(&rows);
    write_atomic(
        &out.join("normalisation.csv"),
        normalisation_csv(&lo, &range).as_bytes(),
    )?;
    Ok(())
}

impl SimulateSummary {
    /// The `--json` summary of a built-in glider run of `a` that flew `flights` in
    /// `wall` seconds.
    pub fn of(
        a: &SimulateArgs,
        model: Model,
        settings: &LoopSettings,
        flights: &[Flight],
        wall: f64,
        warnings: Vec<String>,
    ) -> Self {
        SimulateSummary {
            model: model.name().to_string(),
            controller: a.controller.clone(),
            integrator: a.integrator.clone(),
            period: settings.period,
            horizon: settings.horizon,
            starts: flights
                .iter()
                .map(|f| StartSummary::of(f, model.dim()))
                .collect(),
            wall_seconds: wall,
            out: a.out.display().to_string(),
            warnings,
        }
    }
}

/// A finished `samara simulate --system` run: its trajectories written.
#[derive(Clone, Debug, PartialEq)]
pub struct SystemSimDone {
    /// The `--json` summary.
    pub summary: SystemSimSummary,
    /// The human lines (stdout).
    pub human: Vec<String>,
}

/// Run `samara simulate --system FILE`: fly the system under the network
/// `--controller` from `--samples` starts (the initial box's lower and upper corners,
/// its centre, then seeded uniform samples), write `trajectories.csv` and check the
/// file's goals along every flight.
pub fn run_system(a: &SimulateArgs, path: &std::path::Path) -> anyhow::Result<SystemSimDone> {
    use anyhow::{anyhow, bail, Context};
    use rand::{Rng, SeedableRng};
    a.check_system_flags()?;
    let sys = samara_system::System::from_file(path).map_err(|e| anyhow!("{e}"))?;
    if a.controller == "pid" || a.controller.starts_with("constant:") {
        bail!("--system needs a network controller: --controller NET.onnx (inputs: the file's `observe` list, outputs: its net[i])");
    }
    let net_path = std::path::Path::new(&a.controller);
    let net = samara_nn::load(net_path)
        .with_context(|| format!("--controller {}", net_path.display()))?;
    crate::reach::args::check_fits(
        &format!("--controller {}", net_path.display()),
        &net,
        &sys,
        &path.display().to_string(),
    )?;
    a.check_system_rows(&sys)?;
    samara_report::guard::check_output_dir(
        "--out",
        &a.out,
        &["trajectories.csv"],
        &[("--system", path), ("--controller", net_path)],
    )?;
    let out = samara_report::guard::OutDir::prepare(&a.out)?;
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
    let starts: Vec<Vec<f64>> = (0..a.samples)
        .map(|k| {
            sys.init
                .iter()
                .map(|&(lo, hi)| match k {
                    0 => lo,
                    1 => hi,
                    2 => 0.5 * (lo + hi),
                    _ if lo < hi => rng.gen_range(lo..=hi),
                    _ => lo,
                })
                .collect()
        })
        .collect();
    let t0 = std::time::Instant::now();
    let eval = |o: &[f64]| net.eval_f64(o);
    let mut csv = String::from("start,t");
    for n in sys.states.iter().chain(&sys.inputs) {
        csv.push(',');
        csv.push_str(n);
    }
    csv.push('\n');
    let mut violations = Vec::new();
    for (k, x0) in starts.iter().enumerate() {
        let f = samara_system::sim::fly(&sys, &eval, x0, 10)
            .map_err(|e| anyhow!("{}: start {k} {x0:?}: {e}", path.display()))?;
        for ((t, x), u) in f.t.iter().zip(&f.states).zip(&f.inputs) {
            csv.push_str(&format!("{k},{}", samara_report::fmt_f64(*t)));
            for v in x.iter().chain(u) {
                csv.push(',');
                csv.push_str(&samara_report::fmt_f64(*v));
            }
            csv.push('\n');
        }
        let holds = samara_system::sim::goals_hold(&sys, &f);
        for (g, ok) in sys.goals.iter().zip(holds) {
            if !ok {
                violations.push(GoalViolation {
                    start: k,
                    initial: x0.clone(),
                    goal: g.text.clone(),
                });
            }
        }
    }
    samara_report::write_atomic(&a.out.join("trajectories.csv"), csv.as_bytes())?;
    out.keep();
    let wall = t0.elapsed().as_secs_f64();
    let mut human = vec![format!(
        "{}: {} flights, {} goal violations ({wall:.2} s); trajectories in {}",
        path.display(),
        starts.len(),
        violations.len(),
        a.out.join("trajectories.csv").display()
    )];
    if let Some(v) = violations.first() {
        human.push(format!("first violation: {}", serde_json::to_value(v)?));
    }
    Ok(SystemSimDone {
        summary: SystemSimSummary {
            system: sys.name.clone(),
            starts: starts.len(),
            goals: sys.goals.iter().map(|g| g.text.clone()).collect(),
            violations,
            wall_seconds: wall,
        },
        human,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use ControllerRequest as C;

    fn message(front: Front, c: C, model: Model, label: &str) -> String {
        match glider_controller(front, c, model, label, "n") {
            Ok(_) => String::new(),
            Err(e) => e.to_string(),
        }
    }

    /// One check serves `samara simulate` and `samara.simulate`, each in its own words
    /// (the texts both printed before the two copies became one).
    #[test]
    fn one_controller_check_speaks_each_front() {
        assert_eq!(
            message(Front::Cli, C::Pid, Model::Reduced, "--controller"),
            "--controller pid needs the filter state E, which model `reduced` does not have; use --model plate6 or full, or another controller"
        );
        assert_eq!(
            message(Front::Python, C::Pid, Model::Reduced, "controller"),
            "controller 'pid' needs the filter state E, which model `reduced` does not have; use model='plate6' or 'full', or another controller"
        );
        assert_eq!(
            message(
                Front::Cli,
                C::Constant(0.5),
                Model::Plate6,
                "--controller \"constant:0.5\":"
            ),
            "--controller \"constant:0.5\": ex = 0.5 is outside the allowed range [0.181, 0.193]; choose a value inside it"
        );
        assert_eq!(
            message(
                Front::Python,
                C::Constant(0.5),
                Model::Plate6,
                "controller constant"
            ),
            "controller constant ex = 0.5 is outside the allowed range [0.181, 0.193]; choose a value inside it"
        );
        assert_eq!(message(Front::Cli, C::Pid, Model::Plate6, "x"), "");
        assert_eq!(
            message(Front::Python, C::Constant(0.187), Model::Reduced, "x"),
            ""
        );
    }

    #[test]
    fn one_loop_check_names_each_fronts_argument() {
        let cli = glider_loop(Front::Cli, "plate6", "euler", 20.0, 0.5, 1e6).unwrap_err();
        assert_eq!(
            cli.to_string(),
            "--integrator \"euler\": unknown integrator; choose ode45, dop853 (or tight), dp5 or rk4"
        );
        let py = glider_loop(Front::Python, "plate7", "ode45", 20.0, 0.5, 1e6).unwrap_err();
        assert_eq!(
            py.to_string(),
            "model \"plate7\": unknown model; choose one of plate6, reduced, full"
        );
        let (m, s) = glider_loop(Front::Python, "reduced", "rk4", 2.0, 0.25, 1e6).unwrap();
        assert_eq!(
            (m, s.period, s.horizon, s.output_step),
            (Model::Reduced, 0.25, 2.0, Some(0.01))
        );
        assert_eq!(s.steps().unwrap(), 8);
    }
}

/// A glider controller: a network of 6 raw inputs (v_xp, v_yp, omega, theta, x, y) and
/// 1 output (ex), named so; `label` names it in the message.
pub fn check_glider_network(
    label: &str,
    n: &samara_nn::Network,
) -> Result<samara_nn::Network, AppError> {
    if n.n_inputs() != 6 || n.n_outputs() != 1 {
        return input(format!(
            "{label}: the network has {} inputs and {} outputs; a controller needs 6 raw inputs (v_xp, v_yp, omega, theta, x, y) and 1 output (ex)",
            n.n_inputs(),
            n.n_outputs()
        ));
    }
    n.clone()
        .with_names(&samara_nn::STATE_INPUTS, &["ex"])
        .map_err(|e| AppError::Input(e.to_string()))
}

/// The controller of a simulation (`samara.simulate`).
#[derive(Clone, Debug)]
pub enum ControllerRequest {
    /// The published PID controller (needs the filter state E).
    Pid,
    /// A constant control `ex`.
    Constant(f64),
    /// A network in raw units, clipped to the actuator's range if `clip`.
    Network {
        /// The network.
        net: samara_nn::Network,
        /// Whether its output is clipped.
        clip: bool,
    },
}

/// A checked [`crate::python_front::SimulateRequest`]: the plant, the controller, the loop's settings and
/// the starts.
pub struct SimulatePlan {
    /// The plant.
    pub plant: samara_plant::Plant,
    /// The controller.
    pub controller: Box<dyn samara_sim::Controller + Send>,
    /// The sample-and-hold loop's settings.
    pub settings: samara_sim::LoopSettings,
    /// The initial heights.
    pub starts: Vec<f64>,
}

impl SimulatePlan {
    /// Fly every start; the error is the integrator's message.
    pub fn fly(mut self) -> std::result::Result<Vec<samara_sim::Flight>, String> {
        let mut out = Vec::with_capacity(self.starts.len());
        for &y in &self.starts {
            let init = samara_sim::initial_state(&self.plant, y);
            let f = samara_sim::fly(&self.plant, self.controller.as_mut(), &init, &self.settings)
                .map_err(|e| e.to_string())?;
            out.push(f);
        }
        Ok(out)
    }
}

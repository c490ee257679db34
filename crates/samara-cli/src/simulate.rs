//! `samara simulate`.

use anyhow::{anyhow, bail, Context, Result};
use samara_app::bind::{check_horizon_period, check_period_count, num};
use samara_app::simulate::{GoalViolation, SimulateSummary, StartSummary, SystemSimSummary};
use samara_app::Front;
use samara_plant::{Model, Plant, EX_RANGE, STATE_NAMES};
use samara_report::write_atomic;
use samara_sim::dataset::{normalisation_csv, training_csv};
use samara_sim::{
    fly, initial_state, minmax, published_starts, training_rows, ConstantController, Controller,
    Flight, Integrator, LoopSettings, NetworkController, PidController,
};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

/// Flags of `samara simulate`. The defaults reproduce the published protocol (plate6,
/// PID, nine starts y0 = n/0.07 for n = 0.1:0.025:0.3, ode45 clone, period 0.5,
/// horizon 20).
#[derive(clap::Args, Debug)]
pub struct SimulateArgs {
    /// Plant variant: plate6 (simulation model), reduced (reachability model), full
    /// (four-quadrant model).
    #[arg(long, default_value = "plate6")]
    pub model: String,
    /// Controller: `pid`, `constant:EX` (EX in [0.181, 0.193]) or a network file
    /// (`.onnx`, raw units in, raw ex out).
    #[arg(long, default_value = "pid")]
    pub controller: String,
    /// Do not clip a network controller's output to [0.181, 0.193].
    #[arg(long)]
    pub no_clip: bool,
    /// Initial heights: `START:END:COUNT` (evenly spaced, ends included) or a
    /// comma-separated list, each in [-1000, 1000], at most 100000 starts (negative
    /// values work as `--y0 -1:2:3`). Default: the nine published starts.
    #[arg(long, allow_hyphen_values = true)]
    pub y0: Option<String>,
    /// Integrator: `ode45` (MATLAB clone, reproduces the published data), `dop853`
    /// (also `tight`: DOP853, rtol 1e-10, atol 1e-12), `dp5` (Dormand-Prince 5(4) at the
    /// same tolerances) or `rk4` (fixed step 1e-3).
    #[arg(long, default_value = "ode45")]
    pub integrator: String,
    /// Horizon (a positive multiple of the period, at most 1000000 periods).
    #[arg(long, default_value_t = 20.0, allow_hyphen_values = true)]
    pub horizon: f64,
    /// Control period (sample and hold), in [0.001, 100].
    #[arg(long, default_value_t = 0.5, allow_hyphen_values = true)]
    pub period: f64,
    /// Output directory (created if missing; removed again if the run fails and
    /// created it). It may not hold the --controller file under a name the run writes.
    #[arg(long)]
    pub out: PathBuf,
    /// Print a JSON summary (final state per start, wall time) on stdout.
    #[arg(long)]
    pub json: bool,
    /// Skip the figures (useful for thousands of starts).
    #[arg(long)]
    pub no_plot: bool,
    /// A system file (`docs/system.md`, e.g. `examples/archcomp/tora.sys`): fly it under
    /// the network `--controller NET.onnx` from `--samples` starts in its initial set, with
    /// its own period and horizon, and check its goals along every flight. `--model`,
    /// `--y0`, `--integrator`, `--horizon` and `--period` do not apply (the file states
    /// them; DOP853 integrates). Exit 1 when a flight violates a goal.
    #[arg(long)]
    pub system: Option<PathBuf>,
    /// With `--system`: number of starts (the initial box's lower and upper corners, its
    /// centre, then seeded uniform samples), 1 to 100000.
    #[arg(long, default_value_t = 9)]
    pub samples: usize,
}

/// Limits of the numbers `simulate` and `reach` accept (documented in `--help` and
/// docs/simulation.md): beyond them a run would only exhaust memory or leave the range in
/// which the (nondimensional) glider model means anything.
pub(crate) mod limits {
    /// Most control periods (`horizon / period`) of `simulate` (the published run has
    /// 40): the closed loop's own limit, `samara_sim::MAX_PERIODS`.
    pub const MAX_PERIODS: f64 = samara_sim::closed_loop::MAX_PERIODS as f64;
    /// Most starts of `simulate --y0`.
    pub const MAX_STARTS: usize = 100_000;
    /// Most rows of `trajectories.csv` (built in memory, about 200 bytes a row).
    pub const MAX_ROWS: f64 = 2_000_000.0;
    /// Largest magnitude of an initial state value.
    pub const MAX_STATE: f64 = samara_app::simulate::MAX_STATE;
}

/// Parse `START:END:COUNT` or `V,V,...`.
pub fn parse_y0(s: &str) -> Result<Vec<f64>> {
    let bad = || {
        anyhow!("--y0 {s:?}: expected START:END:COUNT (e.g. 1.4286:4.2857:9) or a list V,V,... of finite numbers")
    };
    let v = parse_y0_values(s, &bad)?;
    if v.len() > limits::MAX_STARTS {
        bail!(
            "--y0 {s:?}: {} starts; at most {} are allowed (each start is a full flight kept in memory); use fewer starts or several runs",
            v.len(),
            limits::MAX_STARTS
        );
    }
    if let Some(y) = v.iter().find(|y| y.abs() > limits::MAX_STATE) {
        bail!(
            "--y0 {s:?}: the height {} is outside [-{m}, {m}], the range in which the nondimensional model means anything (published starts: 1.43 to 4.29); give heights inside it",
            num(*y),
            m = limits::MAX_STATE
        );
    }
    Ok(v)
}

fn parse_y0_values(s: &str, bad: &dyn Fn() -> anyhow::Error) -> Result<Vec<f64>> {
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
            bail!(
                "--y0 {s:?}: COUNT {n} is more than {} starts (each start is a full flight kept in memory); use fewer starts or several runs",
                limits::MAX_STARTS
            );
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

/// Build the controller named by `--controller`.
pub fn make_controller(spec: &str, no_clip: bool) -> Result<Box<dyn Controller>> {
    if spec == "pid" {
        return Ok(Box::new(PidController::default()));
    }
    if let Some(v) = spec.strip_prefix("constant:") {
        let ex: f64 = v.trim().parse().map_err(|_| {
            anyhow!("--controller {spec:?}: {v:?} is not a number; use e.g. constant:0.187")
        })?;
        if !(EX_RANGE.0..=EX_RANGE.1).contains(&ex) {
            bail!(
                "--controller {spec:?}: ex = {ex} is outside the allowed range [{}, {}]; choose a value inside it",
                EX_RANGE.0,
                EX_RANGE.1
            );
        }
        return Ok(Box::new(ConstantController(ex)));
    }
    let path = Path::new(spec);
    if path.extension().and_then(|e| e.to_str()) == Some("onnx") || path.exists() {
        if !path.exists() {
            bail!(
                "--controller {}: no such file; give the path of an .onnx network",
                path.display()
            );
        }
        let net = glider_network(path).with_context(|| {
            format!(
                "--controller {}: cannot load the network; give an ONNX file samara can read",
                path.display()
            )
        })?;
        if net.n_inputs() != 6 || net.n_outputs() != 1 {
            bail!(
                "{}: the network has {} inputs and {} outputs; a controller needs 6 raw inputs (v_xp, v_yp, omega, theta, x, y) and 1 output (ex)",
                path.display(),
                net.n_inputs(),
                net.n_outputs()
            );
        }
        let clip = if no_clip { None } else { Some(EX_RANGE) };
        let label = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "network".into());
        return Ok(Box::new(NetworkController::new(net, clip, label)));
    }
    bail!("--controller {spec:?}: expected `pid`, `constant:EX` or the path of an .onnx network")
}

/// A glider controller file (`samara_nn::load`: ONNX or `.nnet`); a 6-input, 1-output
/// network gets the case study's state names (v_xp, v_yp, omega, theta, x, y) and `ex`.
pub(crate) fn glider_network(path: &Path) -> Result<samara_nn::Network> {
    let net = samara_nn::load(path)?;
    if net.n_inputs() == 6 && net.n_outputs() == 1 {
        return Ok(net.with_names(&samara_nn::STATE_INPUTS, &["ex"])?);
    }
    Ok(net)
}

/// Validated inputs of a run.
struct Plan {
    plant: Plant,
    settings: LoopSettings,
    starts: Vec<f64>,
}

fn plan(a: &SimulateArgs) -> Result<Plan> {
    let model = Model::from_name(&a.model).ok_or_else(|| {
        anyhow!(
            "--model {:?}: unknown model; choose one of plate6, reduced, full",
            a.model
        )
    })?;
    let integrator = Integrator::from_name(&a.integrator).ok_or_else(|| {
        anyhow!(
            "--integrator {:?}: unknown integrator; choose ode45, dop853 (or tight), dp5 or rk4",
            a.integrator
        )
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
    settings.steps().map_err(|e| anyhow!("{e}"))?;
    let starts = match &a.y0 {
        Some(s) => parse_y0(s)?,
        None => published_starts(),
    };
    // Rows of trajectories.csv: t = 0 and every output point of every period.
    let per_period = output_step.map_or(1.0, |o| (a.period / o).round().max(1.0));
    let rows = starts.len() as f64 * (1.0 + (a.horizon / a.period).round() * per_period);
    if rows > limits::MAX_ROWS {
        bail!(
            "--y0/--horizon/--period: {} start(s) x {} period(s) x {per_period} output points give {rows:e} trajectory rows; at most {:e} are allowed (trajectories.csv is built in memory): use fewer starts, a shorter --horizon or a longer --period",
            starts.len(),
            (a.horizon / a.period).round(),
            limits::MAX_ROWS
        );
    }
    Ok(Plan {
        plant: Plant::new(model),
        settings,
        starts,
    })
}

/// The files a run writes into `--out`.
const WRITES: [&str; 5] = [
    "trajectories.csv",
    "training_data.csv",
    "normalisation.csv",
    "trajectories.png",
    "trajectories.svg",
];

/// Run `samara simulate`.
pub fn run(a: &SimulateArgs) -> Result<ExitCode> {
    if let Some(sys) = &a.system {
        return run_system(a, sys);
    }
    let plan = plan(a)?;
    if a.controller == "pid" && !plan.plant.model.has_filter() {
        bail!("--controller pid needs the filter state E, which model `reduced` does not have; use --model plate6 or full, or another controller");
    }
    // Never write over the controller file (an input), before anything is computed.
    if a.controller != "pid" && !a.controller.starts_with("constant:") {
        samara_report::guard::check_output_dir(
            "--out",
            &a.out,
            &WRITES,
            &[("--controller", Path::new(&a.controller))],
        )?;
    }
    let mut controller = make_controller(&a.controller, a.no_clip)?;
    let warnings = units_warnings(a, &plan)?;
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    // Output directory: create and probe before simulating, so a bad path fails fast;
    // a failed run removes the folders it created.
    let out = samara_report::guard::OutDir::prepare(&a.out)?;

    let t0 = Instant::now();
    let mut flights = Vec::with_capacity(plan.starts.len());
    for &y0 in &plan.starts {
        let init = initial_state(&plan.plant, y0);
        flights.push(
            fly(&plan.plant, controller.as_mut(), &init, &plan.settings)
                .map_err(|e| anyhow!("{e}"))?,
        );
    }
    let wall = t0.elapsed().as_secs_f64();
    write_outputs(a, &plan, &flights, controller.name())?;
    if a.json {
        let s = summary(a, &plan, &flights, wall, warnings);
        println!("{}", crate::json_text(&s, true)?);
    } else {
        eprintln!(
            "simulated {} flight(s) of model {} in {:.3} s; wrote {}",
            flights.len(),
            plan.plant.model.name(),
            wall,
            a.out.display()
        );
    }
    out.keep();
    Ok(ExitCode::SUCCESS)
}

/// A network controller in the wrong units: its outputs at the starts far outside the
/// actuator range (`samara_reach::settings::units_warning`, the check `samara reach`
/// makes), as a warning naming the flag. None for `pid` and `constant:`.
fn units_warnings(a: &SimulateArgs, plan: &Plan) -> Result<Vec<String>> {
    if a.controller == "pid" || a.controller.starts_with("constant:") {
        return Ok(Vec::new());
    }
    let net = glider_network(Path::new(&a.controller))?;
    let starts: Vec<Vec<f64>> = plan
        .starts
        .iter()
        .map(|&y0| initial_state(&plan.plant, y0))
        .collect();
    Ok(
        samara_reach::settings::units_warning(&net, &starts, EX_RANGE)
            .map(|w| format!("--controller {}: {w}", a.controller))
            .into_iter()
            .collect(),
    )
}

fn state_header(dim: usize) -> String {
    STATE_NAMES[..dim].join(",")
}

fn write_outputs(a: &SimulateArgs, plan: &Plan, flights: &[Flight], cname: String) -> Result<()> {
    let dim = plan.plant.dim();
    let mut traj = format!("start,y0,t,{},ex\n", state_header(dim));
    for (i, f) in flights.iter().enumerate() {
        for (t, s, ex) in f.dense.iter() {
            let _ = write!(traj, "{},{:?},{:?}", i + 1, f.initial[5], t);
            for v in s {
                let _ = write!(traj, ",{v:?}");
            }
            let _ = writeln!(traj, ",{ex:?}");
        }
    }
    write_atomic(&a.out.join("trajectories.csv"), traj.as_bytes())?;

    let rows = training_rows(flights);
    write_atomic(
        &a.out.join("training_data.csv"),
        training_csv(&rows).as_bytes(),
    )?;
    let (lo, range) = minmax(&rows);
    write_atomic(
        &a.out.join("normalisation.csv"),
        normalisation_csv(&lo, &range).as_bytes(),
    )?;

    if !a.no_plot {
        let mut fig = samara_repro::stages::flights_figure(
            &format!(
                "Alsomitra glider, {} model, {} controller",
                plan.plant.model.name(),
                cname
            ),
            flights,
            None,
        );
        fig.legend = flights.len() <= 12;
        fig.render(
            &a.out.join("trajectories.png"),
            &a.out.join("trajectories.svg"),
        )?;
    }
    Ok(())
}

/// The `--json` summary of a run.
fn summary(
    a: &SimulateArgs,
    plan: &Plan,
    flights: &[Flight],
    wall: f64,
    warnings: Vec<String>,
) -> SimulateSummary {
    let dim = plan.plant.dim();
    SimulateSummary {
        model: plan.plant.model.name().to_string(),
        controller: a.controller.clone(),
        integrator: a.integrator.clone(),
        period: plan.settings.period,
        horizon: plan.settings.horizon,
        starts: flights.iter().map(|f| StartSummary::of(f, dim)).collect(),
        wall_seconds: wall,
        out: a.out.display().to_string(),
        warnings,
    }
}

/// Files `simulate --system` writes.
const SYSTEM_WRITES: [&str; 1] = ["trajectories.csv"];

fn run_system(a: &SimulateArgs, path: &Path) -> Result<ExitCode> {
    use rand::{Rng, SeedableRng};
    if a.y0.is_some() {
        bail!("--y0 does not apply with --system: the system file's `init` lines give the initial set; use --samples N");
    }
    if a.samples == 0 || a.samples > limits::MAX_STARTS {
        bail!(
            "--samples {}: give 1 to {} starts",
            a.samples,
            limits::MAX_STARTS
        );
    }
    let sys = samara_system::System::from_file(path).map_err(|e| anyhow!("{e}"))?;
    if a.controller == "pid" || a.controller.starts_with("constant:") {
        bail!("--system needs a network controller: --controller NET.onnx (inputs: the file's `observe` list, outputs: its net[i])");
    }
    let net_path = Path::new(&a.controller);
    let net = samara_nn::load(net_path)
        .with_context(|| format!("--controller {}", net_path.display()))?;
    samara_app::reach::args::check_fits("--controller", net_path, &net, &sys, path)?;
    let rows = (a.samples as f64) * (sys.steps() as f64 * 10.0 + 1.0);
    if rows > limits::MAX_ROWS {
        bail!(
            "--samples {} x {} periods x 10 output points = {rows:e} trajectory rows; at most {:e} are allowed: use fewer --samples",
            a.samples,
            sys.steps(),
            limits::MAX_ROWS
        );
    }
    samara_report::guard::check_output_dir(
        "--out",
        &a.out,
        &SYSTEM_WRITES,
        &[("--system", path), ("--controller", net_path)],
    )?;
    let out = samara_report::guard::OutDir::prepare(&a.out)?;
    // Starts: lower corner, upper corner, centre, then seeded uniform samples.
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
    let t0 = Instant::now();
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
        for (g, ok) in sys
            .goals
            .iter()
            .zip(samara_system::sim::goals_hold(&sys, &f))
        {
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
    let all_hold = violations.is_empty();
    if a.json {
        let s = SystemSimSummary {
            system: sys.name.clone(),
            starts: starts.len(),
            goals: sys.goals.iter().map(|g| g.text.clone()).collect(),
            violations,
            wall_seconds: wall,
        };
        println!("{}", crate::json_text(&s, false)?);
    } else {
        println!(
            "{}: {} flights, {} goal violations ({wall:.2} s); trajectories in {}",
            path.display(),
            starts.len(),
            violations.len(),
            a.out.join("trajectories.csv").display()
        );
        if let Some(v) = violations.first() {
            println!("first violation: {}", crate::json_text(v, false)?);
        }
    }
    Ok(if all_hold {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

//! `samara simulate`.

use anyhow::{anyhow, bail, Context, Result};
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
    /// comma-separated list. Default: the nine published starts.
    #[arg(long)]
    pub y0: Option<String>,
    /// Integrator: `ode45` (MATLAB clone, reproduces the published data), `tight`
    /// (DOP853, rtol 1e-10, atol 1e-12), `dp5` (Dormand-Prince 5(4) at the same tolerances) or `rk4` (fixed step 1e-3).
    #[arg(long, default_value = "ode45")]
    pub integrator: String,
    /// Horizon (a positive multiple of the period).
    #[arg(long, default_value_t = 20.0, allow_negative_numbers = true)]
    pub horizon: f64,
    /// Control period (sample and hold).
    #[arg(long, default_value_t = 0.5, allow_negative_numbers = true)]
    pub period: f64,
    /// Output directory (created if missing).
    #[arg(long)]
    pub out: PathBuf,
    /// Print a JSON summary (final state per start, wall time) on stdout.
    #[arg(long)]
    pub json: bool,
    /// Skip the figures (useful for thousands of starts).
    #[arg(long)]
    pub no_plot: bool,
}

/// Parse `START:END:COUNT` or `V,V,...`.
pub fn parse_y0(s: &str) -> Result<Vec<f64>> {
    let bad = || {
        anyhow!("--y0 {s:?}: expected START:END:COUNT (e.g. 1.4286:4.2857:9) or a list V,V,... of finite numbers")
    };
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
        let net = crate_nn_load(path)?;
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

fn crate_nn_load(path: &Path) -> Result<samara_nn::Network> {
    crate::nnload::load_network(path)
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
            "--integrator {:?}: unknown integrator; choose ode45, tight, dp5 or rk4",
            a.integrator
        )
    })?;
    check_horizon_period(a.horizon, a.period)?;
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
    Ok(Plan {
        plant: Plant::new(model),
        settings,
        starts,
    })
}

/// Run `samara simulate`.
/// `--horizon` and `--period` must be positive finite numbers (shared by the commands
/// that fly the closed loop).
pub(crate) fn check_horizon_period(horizon: f64, period: f64) -> Result<()> {
    if !(horizon.is_finite() && horizon > 0.0) {
        bail!("--horizon {horizon}: the horizon must be positive (e.g. --horizon 20)");
    }
    if !(period.is_finite() && period > 0.0) {
        bail!("--period {period}: the period must be positive (e.g. --period 0.5)");
    }
    Ok(())
}

/// Create the output directory `out` and check that it is writable (a probe file), so a
/// bad `--out` fails before any long computation.
pub(crate) fn prepare_out_dir(out: &std::path::Path) -> Result<()> {
    std::fs::create_dir_all(out).with_context(|| {
        format!(
            "cannot create output directory {}; choose a writable --out",
            out.display()
        )
    })?;
    let probe = out.join(format!(".samara-probe-{}", std::process::id()));
    std::fs::write(&probe, b"").with_context(|| {
        format!(
            "output directory {} is not writable; choose a writable --out",
            out.display()
        )
    })?;
    let _ = std::fs::remove_file(&probe);
    Ok(())
}

pub fn run(a: &SimulateArgs) -> Result<ExitCode> {
    let plan = plan(a)?;
    let mut controller = make_controller(&a.controller, a.no_clip)?;
    if a.controller == "pid" && !plan.plant.model.has_filter() {
        bail!("--controller pid needs the filter state E, which model `reduced` does not have; use --model plate6 or full, or another controller");
    }
    // Output directory: create and probe before simulating, so a bad path fails fast.
    prepare_out_dir(&a.out)?;

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
        println!(
            "{}",
            serde_json::to_string_pretty(&summary(a, &plan, &flights, wall))?
        );
    } else {
        eprintln!(
            "simulated {} flight(s) of model {} in {:.3} s; wrote {}",
            flights.len(),
            plan.plant.model.name(),
            wall,
            a.out.display()
        );
    }
    Ok(ExitCode::SUCCESS)
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

fn summary(a: &SimulateArgs, plan: &Plan, flights: &[Flight], wall: f64) -> serde_json::Value {
    let dim = plan.plant.dim();
    let starts: Vec<serde_json::Value> = flights
        .iter()
        .map(|f| {
            let last = &f.steps.last().expect("at least one step").state_end;
            let mut st = serde_json::Map::new();
            for (i, v) in last.iter().enumerate().take(dim) {
                st.insert(STATE_NAMES[i].to_string(), serde_json::json!(v));
            }
            serde_json::json!({
                "y0": f.initial[5],
                "final_state": st,
                "final_x_plus_y": last[4] + last[5],
                "rhs_evals": f.evals,
            })
        })
        .collect();
    serde_json::json!({
        "model": plan.plant.model.name(),
        "controller": a.controller,
        "integrator": a.integrator,
        "period": plan.settings.period,
        "horizon": plan.settings.horizon,
        "starts": starts,
        "wall_seconds": wall,
        "out": a.out.display().to_string(),
    })
}

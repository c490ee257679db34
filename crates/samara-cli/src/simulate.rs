//! `samara simulate`.

use anyhow::{anyhow, bail, Context, Result};
pub use samara_app::args::SimulateArgs;
use samara_app::simulate::{GoalViolation, SimulateSummary, StartSummary, SystemSimSummary};
use samara_plant::{Plant, EX_RANGE, STATE_NAMES};
use samara_report::write_atomic;
use samara_sim::dataset::{normalisation_csv, training_csv};
use samara_sim::{
    fly, initial_state, minmax, training_rows, ConstantController, Controller, Flight,
    LoopSettings, NetworkController, PidController,
};
use std::fmt::Write as _;
use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

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
        let net = samara_nn::load(path).with_context(|| {
            format!(
                "--controller {}: cannot load the network; give an ONNX file samara can read",
                path.display()
            )
        })?;
        // The library's shape check and naming, as Python's `simulate` has them.
        let net = samara_app::python_front::glider_controller(&path.display().to_string(), &net)?;
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
    let p = a.plan()?;
    Ok(Plan {
        plant: Plant::new(p.model),
        settings: p.settings,
        starts: p.starts,
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
    a.check_system_flags()?;
    let sys = samara_system::System::from_file(path).map_err(|e| anyhow!("{e}"))?;
    if a.controller == "pid" || a.controller.starts_with("constant:") {
        bail!("--system needs a network controller: --controller NET.onnx (inputs: the file's `observe` list, outputs: its net[i])");
    }
    let net_path = Path::new(&a.controller);
    let net = samara_nn::load(net_path)
        .with_context(|| format!("--controller {}", net_path.display()))?;
    samara_app::reach::args::check_fits("--controller", net_path, &net, &sys, path)?;
    a.check_system_rows(&sys)?;
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

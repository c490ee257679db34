//! `samara reach`: sound reachable sets of the network-controlled glider (issue 6).
//!
//! Parses the flags into `samara_reach::ReachSettings`, checks everything (including
//! the network against the settings) before writing anything, runs
//! `samara_reach::reach`, then writes `DIR/reach.json`, `DIR/reach.png` and
//! `DIR/reach.svg` and prints the verdict.

use anyhow::{anyhow, bail, Context, Result};
use samara_plant::{Model, STATE_NAMES};
use samara_reach::{Goal, ReachResult, ReachSettings, Verdict};
use samara_report::{write_atomic, TrajectoryFigure};
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use crate::simulate::{limits, num as fmt_num};

/// Most control periods of a reachability run (the published run has 40; every period
/// costs a set-valued integration per sub-box).
const MAX_PERIODS: f64 = 10_000.0;
/// Longest control period of a reachability run.
const MAX_PERIOD: f64 = 10.0;
/// Most sub-boxes (`--max-leaves`).
const MAX_LEAVES: usize = 100_000;
/// Most simulated trajectories (`--samples`).
const MAX_SAMPLES: usize = 100_000;
/// Most sampled points kept in memory (samples x horizon / 0.05).
const MAX_SAMPLE_POINTS: f64 = 1e7;
/// Most worker threads.
const MAX_THREADS: usize = 1024;

/// The published initial heights: y0 in [0.1/0.07, 0.3/0.07].
const Y0_DEFAULT: (f64, f64) = (0.1 / 0.07, 0.3 / 0.07);

/// Flags of `samara reach`. The defaults are the published CORA setting: reduced
/// model, start (1, 0, 0, 0, 0, y0) with y0 in [1.4286, 4.2857], period 0.5, horizon 20.
#[derive(clap::Args, Debug)]
pub struct ReachArgs {
    /// The controller network (`.onnx`, 6 raw inputs v_xp, v_yp, omega, theta, x, y;
    /// 1 raw output ex), e.g. base_model_denorm.onnx.
    #[arg(long)]
    pub network: PathBuf,
    /// Plant variant: reduced (the published reachability model), plate6 (the
    /// simulation model) or full (four-quadrant model).
    #[arg(long, default_value = "reduced")]
    pub model: String,
    /// Initial interval of the height y: `A:B` (or a single value A), ends in
    /// [-1000, 1000]. Default 1.4285714285714286:4.285714285714286 (= 0.1/0.07 : 0.3/0.07).
    #[arg(long, allow_hyphen_values = true)]
    pub y0: Option<String>,
    /// Initial interval of one state, `NAME=A:B` or `NAME=A` (repeatable); NAME is one
    /// of v_xp, v_yp, omega, theta, x, y (and E for plate6/full). Other states start at
    /// (1, 0, 0, 0, 0, y0[, 0]). Ends in [-1000, 1000].
    #[arg(long = "init", value_name = "NAME=A:B", allow_hyphen_values = true)]
    pub init: Vec<String>,
    /// Horizon (a positive multiple of the period, at most 10000 periods).
    #[arg(long, default_value_t = 20.0, allow_hyphen_values = true)]
    pub horizon: f64,
    /// Control period (sample and hold), in [0.001, 10].
    #[arg(long, default_value_t = 0.5, allow_hyphen_values = true)]
    pub period: f64,
    /// Goal: |x + y| <= Y at the horizon (or on [T*, horizon] with --goal-from).
    #[arg(long, allow_hyphen_values = true)]
    pub goal_ystar: Option<f64>,
    /// Start T* of the goal's time window (needs --goal-ystar).
    #[arg(long, allow_hyphen_values = true)]
    pub goal_from: Option<f64>,
    /// Do not clip the controller's output to [0.181, 0.193] (as the CORA model).
    #[arg(long)]
    pub no_clip: bool,
    /// Worker threads, 1 to 1024 (default: all cores).
    #[arg(long, allow_hyphen_values = true)]
    pub threads: Option<usize>,
    /// Largest number of sub-boxes of the initial set, 1 to 100000 (default 64; more
    /// gives tighter sets, slower).
    #[arg(long, allow_hyphen_values = true)]
    pub max_leaves: Option<usize>,
    /// Simulated trajectories for falsification, the sampled range and the figure, 1 to
    /// 100000 and at most 10^7 sampled points (about samples x horizon / 0.05) (default 200).
    #[arg(long, allow_hyphen_values = true)]
    pub samples: Option<usize>,
    /// Output directory (created if missing; removed again if the run fails and created
    /// it). It may not be, or lie inside, the --network file.
    #[arg(long)]
    pub out: PathBuf,
    /// Print a JSON summary on stdout instead of the human line.
    #[arg(long)]
    pub json: bool,
    /// A system file (docs/system.md, e.g. examples/archcomp/tora.sys): any plant with
    /// its initial set, period, horizon, actuation and goals; the sets are Taylor models
    /// and --network is its controller (`.onnx` or `.nnet`).
    #[arg(long)]
    pub system: Option<PathBuf>,
    /// Order of the Taylor models with --system or --sets taylor, 1 to 8 (default 4).
    #[arg(long, allow_hyphen_values = true)]
    pub order: Option<usize>,
    /// Set representation of the built-in glider setting: `zonotope` (affine sets with
    /// interval remainders, the Lohner flow) or `taylor` (Taylor models in the initial-set
    /// parameters: the same setting run as the shipped system file). --system always uses
    /// Taylor models.
    #[arg(long, default_value = "zonotope")]
    pub sets: String,
    /// Wall-clock budget in seconds for Taylor-model runs (--system, --sets taylor),
    /// finite and positive: when spent, the run stops splitting and reports `unknown`
    /// with the reason (checked between splitting rounds).
    #[arg(long, allow_hyphen_values = true)]
    pub timeout: Option<f64>,
}

/// Parse `A:B` or `A` into a finite, non-inverted interval; `what` names the flag and
/// its value in messages (e.g. `--y0 "3:2"`).
pub fn parse_interval(s: &str, what: &str) -> Result<(f64, f64)> {
    let bad = || {
        anyhow!(
            "{what}: expected A:B (e.g. 1.4286:4.2857) or a single value A, with finite numbers"
        )
    };
    let parts: Vec<&str> = s.split(':').collect();
    let (a, b) = match parts.as_slice() {
        [a] => {
            let a: f64 = a.trim().parse().map_err(|_| bad())?;
            (a, a)
        }
        [a, b] => (
            a.trim().parse::<f64>().map_err(|_| bad())?,
            b.trim().parse::<f64>().map_err(|_| bad())?,
        ),
        _ => return Err(bad()),
    };
    if !(a.is_finite() && b.is_finite()) {
        bail!("{what}: the interval ends must be finite numbers");
    }
    if a > b {
        bail!("{what}: the interval is empty (inverted, {a} > {b}); give A:B with A <= B, e.g. {b}:{a}");
    }
    let m = limits::MAX_STATE;
    if a < -m || b > m {
        bail!("{what}: the interval ends must lie in [-{m}, {m}], the range in which the nondimensional model means anything (published: y0 in [1.43, 4.29], the other states 0 or 1); give a smaller interval");
    }
    Ok((a, b))
}

/// Validated inputs of a run.
struct Plan {
    settings: ReachSettings,
    net: samara_nn::Network,
}

fn build_settings(a: &ReachArgs) -> Result<ReachSettings> {
    let model = Model::from_name(&a.model).ok_or_else(|| {
        anyhow!(
            "--model {:?}: unknown model; choose one of reduced, plate6, full",
            a.model
        )
    })?;
    let mut s = ReachSettings::published(model);
    s.init[5] = Y0_DEFAULT;
    if let Some(y0) = &a.y0 {
        s.init[5] = parse_interval(y0, &format!("--y0 {y0:?}"))?;
    }
    let names = &STATE_NAMES[..model.dim()];
    let mut seen: Vec<usize> = Vec::new();
    for spec in &a.init {
        let (name, iv) = spec.split_once('=').ok_or_else(|| {
            anyhow!("--init {spec:?}: expected NAME=A:B (e.g. --init theta=-0.01:0.01)")
        })?;
        let name = name.trim();
        let i = names.iter().position(|n| *n == name).ok_or_else(|| {
            let extra = if name == "E" {
                format!(" (model {} has no filter state E)", model.name())
            } else {
                String::new()
            };
            anyhow!(
                "--init {spec:?}: unknown state {name:?}{extra}; choose one of {}",
                names.join(", ")
            )
        })?;
        if i == 5 && a.y0.is_some() {
            bail!("--init {spec:?}: y is also given by --y0; give it once");
        }
        if seen.contains(&i) {
            bail!("--init {spec:?}: state {name} is given twice; give it once");
        }
        seen.push(i);
        s.init[i] = parse_interval(iv, &format!("--init {spec:?}"))?;
    }
    crate::simulate::check_horizon_period(a.horizon, a.period)?;
    if a.period > MAX_PERIOD {
        bail!("--period {}: reach takes periods up to {MAX_PERIOD} (the validated integrator takes at most 400 steps of at most 0.0625 per period, so a longer hold cannot be enclosed); e.g. --period 0.5", a.period);
    }
    crate::simulate::check_period_count(a.horizon, a.period, MAX_PERIODS)?;
    s.horizon = a.horizon;
    s.period = a.period;
    let k = a.horizon / a.period;
    if (k - k.round()).abs() > 1e-9 * k.max(1.0) || k.round() < 1.0 {
        let n = k.floor().max(1.0);
        bail!(
            "--horizon {} is not a positive multiple of --period {}: choose e.g. --horizon {} (or another period)",
            a.horizon,
            a.period,
            n * a.period
        );
    }
    if a.no_clip {
        s.clip = None;
    }
    match (a.goal_ystar, a.goal_from) {
        (None, Some(f)) => {
            bail!(
                "--goal-from {}: needs a goal; add --goal-ystar Y (e.g. --goal-ystar 2)",
                fmt_num(f)
            )
        }
        (Some(y), from) => {
            if !(y.is_finite() && y >= 0.0) {
                bail!(
                    "--goal-ystar {}: the band half-width must be a finite number >= 0 (e.g. --goal-ystar 2)",
                    fmt_num(y)
                );
            }
            if let Some(f) = from {
                if !(f.is_finite() && f >= 0.0 && f <= a.horizon) {
                    bail!(
                        "--goal-from {}: the window start must lie in [0, horizon = {}]",
                        fmt_num(f),
                        a.horizon
                    );
                }
            }
            s.goal = Some(Goal { ystar: y, from });
        }
        (None, None) => {}
    }
    check_budget(a, s.max_leaves)?;
    if let Some(n) = a.max_leaves {
        s.max_leaves = n;
    }
    if let Some(n) = a.samples {
        s.samples = n;
    }
    // Sampled trajectories are recorded every 0.05 (or the finest step above that which
    // divides the period).
    let q = a.period / 0.05;
    let per_period = if (q - q.round()).abs() <= 1e-9 * q.max(1.0) && q.round() >= 1.0 {
        q.round()
    } else {
        q.ceil().max(1.0)
    };
    let points = s.samples as f64 * (a.horizon / a.period).round() * per_period;
    if points > MAX_SAMPLE_POINTS {
        bail!(
            "--samples {} with --horizon {}: {points:e} sampled points (one about every 0.05 time units per trajectory); at most {MAX_SAMPLE_POINTS:e} are kept in memory: pass fewer --samples or a shorter --horizon",
            s.samples,
            a.horizon
        );
    }
    Ok(s)
}

/// `--max-leaves`, `--samples` and `--threads`, checked the same way for both paths
/// (the built-in glider and system files); `default_leaves` is the path's sub-box
/// budget, named in the messages.
pub(crate) fn check_budget(a: &ReachArgs, default_leaves: usize) -> Result<()> {
    if let Some(n) = a.max_leaves {
        if n == 0 {
            bail!("--max-leaves 0: give at least 1 (default {default_leaves})");
        }
        if n > MAX_LEAVES {
            bail!("--max-leaves {n}: at most {MAX_LEAVES} sub-boxes are allowed (each is a full reachability run; the default is {default_leaves})");
        }
    }
    if let Some(n) = a.samples {
        if n == 0 {
            bail!("--samples 0: give at least 1 (default 200); falsification needs trajectories");
        }
        if n > MAX_SAMPLES {
            bail!("--samples {n}: at most {MAX_SAMPLES} trajectories are allowed (each is kept in memory; the default is 200)");
        }
    }
    match a.threads {
        Some(0) => bail!("--threads 0: give at least 1 (or leave it out to use all cores)"),
        Some(n) if n > MAX_THREADS => bail!(
            "--threads {n}: at most {MAX_THREADS} worker threads are allowed (more than the cores only costs memory); leave it out to use all cores"
        ),
        _ => Ok(()),
    }
}

/// Start the global worker pool with `--threads` workers (all cores without it).
pub(crate) fn start_threads(a: &ReachArgs) -> Result<()> {
    if let Some(n) = a.threads {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build_global()
            .map_err(|e| anyhow!("--threads {n}: cannot start the thread pool: {e}"))?;
    }
    Ok(())
}

/// The files a run writes into `--out`.
const WRITES: [&str; 3] = ["reach.json", "reach.png", "reach.svg"];

fn plan(a: &ReachArgs) -> Result<Plan> {
    let settings = build_settings(a)?;
    // Never write over the network file (an input), before anything is computed.
    samara_report::guard::check_output_dir("--out", &a.out, &WRITES, &[("--network", &a.network)])?;
    // The flags are checked; now the network, then the library's own check of the
    // settings against it.
    if !a.network.exists() {
        bail!(
            "--network {}: no such file; give the path of an .onnx controller with 6 raw inputs and 1 output (e.g. base_model_denorm.onnx)",
            a.network.display()
        );
    }
    let net = crate::nnload::load_network(&a.network).with_context(|| {
        format!(
            "--network {}: cannot load the network; give an ONNX file samara can read",
            a.network.display()
        )
    })?;
    settings.validate(&net).map_err(|e| match e {
        samara_reach::ReachError::NetworkShape { .. } => {
            anyhow!("--network {}: {e}", a.network.display())
        }
        samara_reach::ReachError::Horizon { .. } => anyhow!("--horizon/--period: {e}"),
        samara_reach::ReachError::BadInterval { .. } => anyhow!("--y0/--init: {e}"),
        _ => anyhow!("{e}"),
    })?;
    Ok(Plan { settings, net })
}

/// Run `samara reach`.
pub fn run(a: &ReachArgs) -> Result<ExitCode> {
    if let Some(sys) = &a.system {
        return crate::reach_system::run(a, sys);
    }
    match a.sets.as_str() {
        "zonotope" => {
            if a.order.is_some() {
                bail!("--order applies to Taylor-model sets (--sets taylor or --system); the zonotope sets have no order");
            }
            if a.timeout.is_some() {
                bail!("--timeout applies to Taylor-model sets (--sets taylor or --system); bound the zonotope run with --max-leaves");
            }
        }
        "taylor" => {
            let plan = plan(a)?;
            let sys = crate::reach_system::builtin_system(&plan.settings)?;
            return crate::reach_system::run_system(
                a,
                &sys,
                Path::new("built-in setting"),
                &plan.net,
            );
        }
        other => bail!("--sets {other}: give zonotope or taylor"),
    }
    let plan = plan(a)?;
    start_threads(a)?;
    // Output directory: create and probe before the (possibly long) analysis; a failed
    // run removes the folders it created.
    let out = samara_report::guard::OutDir::prepare(&a.out)?;

    let spinner = progress(&plan.settings);
    let res = samara_reach::reach(&plan.net, &plan.settings);
    if let Some(p) = spinner {
        p.finish_and_clear();
    }
    let res = res.map_err(|e| anyhow!("{e}"))?;

    let report = report_json(a, &plan.settings, &res)?;
    write_atomic(
        &a.out.join("reach.json"),
        serde_json::to_string_pretty(&report)?.as_bytes(),
    )?;
    figure(a, &plan.settings, &res).render(&a.out.join("reach.png"), &a.out.join("reach.svg"))?;

    if a.json {
        println!("{}", serde_json::to_string_pretty(&summary(&res, a))?);
    } else {
        println!("{}", human_line(&plan.settings, &res));
        eprintln!("wrote {}", a.out.display());
    }
    out.keep();
    Ok(match res.verdict {
        Verdict::Proved | Verdict::NoGoal => ExitCode::SUCCESS,
        Verdict::Violated { .. } | Verdict::Unknown { .. } => ExitCode::from(1),
    })
}

/// A spinner on stderr (only drawn when stderr is a terminal).
fn progress(s: &ReachSettings) -> Option<indicatif::ProgressBar> {
    use std::io::IsTerminal;
    if !std::io::stderr().is_terminal() {
        return None;
    }
    let p = indicatif::ProgressBar::new_spinner();
    p.set_message(format!(
        "reachable sets of the {} model over [0, {}] ...",
        s.model.name(),
        s.horizon
    ));
    p.enable_steady_tick(std::time::Duration::from_millis(120));
    Some(p)
}

fn width(iv: [f64; 2]) -> f64 {
    iv[1] - iv[0]
}

/// A number for JSON: non-finite values (an unbounded enclosure) become null.
fn num(v: f64) -> serde_json::Value {
    if v.is_finite() {
        serde_json::json!(v)
    } else {
        serde_json::Value::Null
    }
}

fn verdict_details(v: &Verdict) -> serde_json::Value {
    match v {
        Verdict::Proved => serde_json::json!({ "verdict": "proved" }),
        Verdict::NoGoal => serde_json::json!({ "verdict": "none" }),
        Verdict::Unknown { reason } => {
            serde_json::json!({ "verdict": "unknown", "reason": reason })
        }
        Verdict::Violated {
            initial,
            t,
            x_plus_y,
        } => serde_json::json!({
            "verdict": "violated",
            "reason": format!("the simulated trajectory from {initial:?} has x + y = {x_plus_y} at t = {t}, outside the goal band"),
            "counterexample": { "initial": initial, "t": t, "x_plus_y": x_plus_y },
        }),
    }
}

fn settings_json(a: &ReachArgs, s: &ReachSettings) -> serde_json::Value {
    let mut init = serde_json::Map::new();
    for (i, (lo, hi)) in s.init.iter().enumerate() {
        init.insert(STATE_NAMES[i].to_string(), serde_json::json!([lo, hi]));
    }
    serde_json::json!({
        "network": a.network.display().to_string(),
        "model": s.model.name(),
        "init": init,
        "horizon": s.horizon,
        "period": s.period,
        "clip": s.clip.map(|(lo, hi)| [lo, hi]),
        "reset_filter": s.reset_filter,
        "goal": s.goal,
        "max_leaves": s.max_leaves,
        "initial_splits": s.initial_splits,
        "samples": s.samples,
        "seed": s.seed,
        "threads": a.threads.unwrap_or_else(rayon::current_num_threads),
    })
}

fn report_json(a: &ReachArgs, s: &ReachSettings, res: &ReachResult) -> Result<serde_json::Value> {
    Ok(serde_json::json!({
        "settings": settings_json(a, s),
        "verdict": verdict_details(&res.verdict),
        "final_x_plus_y": [num(res.final_x_plus_y[0]), num(res.final_x_plus_y[1])],
        "sampled_x_plus_y": res.sampled_x_plus_y,
        "width_ratio": num(res.width_ratio()),
        "subproblems": res.subproblems(),
        "seconds": res.seconds,
        "sampled_trajectories": res.samples.len(),
        "state_names": &STATE_NAMES[..s.model.dim()],
        "leaves": serde_json::to_value(&res.leaves)?,
    }))
}

fn summary(res: &ReachResult, a: &ReachArgs) -> serde_json::Value {
    let mut v = verdict_details(&res.verdict);
    let m = v.as_object_mut().expect("object");
    m.insert(
        "final_x_plus_y".into(),
        serde_json::json!([num(res.final_x_plus_y[0]), num(res.final_x_plus_y[1])]),
    );
    m.insert("final_width".into(), num(width(res.final_x_plus_y)));
    m.insert(
        "sampled_x_plus_y".into(),
        serde_json::json!(res.sampled_x_plus_y),
    );
    m.insert("sampled_width".into(), num(width(res.sampled_x_plus_y)));
    m.insert("width_ratio".into(), num(res.width_ratio()));
    m.insert("subproblems".into(), serde_json::json!(res.subproblems()));
    m.insert("seconds".into(), serde_json::json!(res.seconds));
    m.insert("out".into(), serde_json::json!(a.out.display().to_string()));
    v
}

fn human_line(s: &ReachSettings, res: &ReachResult) -> String {
    let f = res.final_x_plus_y;
    let sm = res.sampled_x_plus_y;
    let goal = match &s.goal {
        Some(g) => match g.from {
            Some(t0) => format!(" (goal |x + y| <= {} on [{t0}, {}])", g.ystar, s.horizon),
            None => format!(" (goal |x + y| <= {} at t = {})", g.ystar, s.horizon),
        },
        None => String::new(),
    };
    let detail = match &res.verdict {
        Verdict::Unknown { reason } => format!("; reason: {reason}"),
        Verdict::Violated {
            initial,
            t,
            x_plus_y,
        } => format!("; counterexample: from {initial:?}, x + y = {x_plus_y} at t = {t}"),
        _ => String::new(),
    };
    // No finite sampled trajectory (e.g. a state where the model is singular): say so
    // instead of printing the empty range [inf, -inf].
    let sampled = if sm[0] <= sm[1] {
        format!(
            "sampled [{:.6}, {:.6}] (width {:.6}); ratio {:.3}",
            sm[0],
            sm[1],
            width(sm),
            res.width_ratio()
        )
    } else {
        "sampled: none (no simulated trajectory stayed finite); ratio n/a".to_string()
    };
    format!(
        "{}{goal}: x + y at t = {} in [{:.6}, {:.6}] (width {:.6}); {sampled}; {} sub-boxes; {:.2} s{detail}",
        res.verdict.name(),
        s.horizon,
        f[0],
        f[1],
        width(f),
        res.subproblems(),
        res.seconds
    )
}

fn figure(a: &ReachArgs, s: &ReachSettings, res: &ReachResult) -> TrajectoryFigure {
    let name = a
        .network
        .file_stem()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "network".into());
    samara_reach::figure(
        res,
        &format!("{name}, {} model", s.model.name()),
        s.goal.as_ref().map(|g| g.ystar),
    )
}

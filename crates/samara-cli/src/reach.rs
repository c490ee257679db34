//! `samara reach`: sound reachable sets of the network-controlled glider (issue 6).
//!
//! Parses the flags into `samara_reach::ReachSettings`, checks everything (including
//! the network against the settings) before writing anything, runs
//! `samara_reach::reach`, then writes `DIR/reach.json`, `DIR/reach.png` and
//! `DIR/reach.svg` and prints the verdict.
//!
//! With `--shard I/N` it computes only part I of N of the run (`samara_reach::parts`: a
//! contiguous range of the initial pieces, each refined on its own) and writes it to the
//! shard file `--out`; `samara merge reach` replays the run's refinement over the N parts
//! and writes what one process writes (see [`merge_reach`]).

use anyhow::{anyhow, bail, Context, Result};
use samara_plant::{Model, STATE_NAMES};
use samara_reach::parts::{self, Flown, LeafRecord};
use samara_reach::{Goal, ReachResult, ReachSettings, StepSet, Verdict};
use samara_report::{write_atomic, Curve};
use samara_spec::lower::NetDecl;
use serde_json::{json, Value};
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use crate::simulate::{limits, num as fmt_num};
use crate::verify::shard::{self, Shard};

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

/// The published initial heights: y0 in [0.1/0.07, 0.3/0.07].
const Y0_DEFAULT: (f64, f64) = (0.1 / 0.07, 0.3 / 0.07);

/// Flags of `samara reach`. The defaults are the published CORA setting: reduced
/// model, start (1, 0, 0, 0, 0, y0) with y0 in [1.4286, 4.2857], period 0.5, horizon 20.
#[derive(clap::Args, Debug, Clone)]
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
    /// it). It may not be, or lie inside, the --network file. With --shard: the shard's
    /// partial result (a JSON file, for `samara merge reach`).
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
    /// Order of the Taylor models with --system or --sets taylor, 1 to 8 (default 4; for
    /// the built-in glider, when neither this nor --network-error is given, 2 with
    /// --network-error symbolic:7, its measured best).
    #[arg(long, allow_hyphen_values = true)]
    pub order: Option<usize>,
    /// Set representation of the built-in glider setting: `zonotope` (affine sets with
    /// interval remainders, the Lohner flow), `taylor` (Taylor models in the initial-set
    /// parameters: the same setting run as the shipped system file) or `auto` (zonotope
    /// sets, the faster and tighter on every glider setting measured; where they leave
    /// the goal unknown, Taylor-model sets as well, written to OUT/taylor, with --order,
    /// --timeout and --network-error). --system always uses Taylor models.
    #[arg(long, default_value = "zonotope")]
    pub sets: String,
    /// Wall-clock budget in seconds for Taylor-model runs (--system, --sets taylor),
    /// finite and positive: when spent, the run stops splitting and reports `unknown`
    /// with the reason (checked between splitting rounds).
    #[arg(long, allow_hyphen_values = true)]
    pub timeout: Option<f64>,
    /// How the network step's error enters Taylor-model sets (--system, --sets taylor):
    /// `interval` (a remainder per input: cheapest), `symbolic` or `symbolic:N` (a fresh
    /// parameter per input and period, at most N beyond the state count, default 20:
    /// keeps the driven states correlated), or `auto` (default: tried on the whole
    /// initial set cheapest first, docs/reach.md; the built-in glider: see --order).
    #[arg(long)]
    pub network_error: Option<String>,
    /// With symbolic remainders (--network-error symbolic), the share of a state's width
    /// that the flow's interval remainders may reach inside a period before they become
    /// parameters, in (0, 1]. Smaller: tighter, more reductions. Default 0.05 for system
    /// files (ARCH-COMP's measured best); 0.001 for the built-in glider on Taylor-model
    /// sets (docs/reach.md).
    #[arg(long, allow_hyphen_values = true)]
    pub lift_at: Option<f64>,
    /// With symbolic remainders, how much each lifted parameter weighs toward --order:
    /// 1 (default) as much as an initial parameter; the order itself: lifted
    /// parameters enter linearly only (mixed-degree Taylor models, far fewer terms,
    /// so more of them can be kept; docs/reach.md).
    #[arg(long, allow_hyphen_values = true)]
    pub lifted_weight: Option<i64>,
    /// A spec file whose closed loop to fly (`loop`, `start`, `goal` statements; e.g.
    /// models/alsomitra/alsomitra.spec, loop `published`): model, initial set, period,
    /// horizon, clip and goal come from it, so the flags that set them are refused
    /// beside it. --network is then the loop's network as the spec declares it: the
    /// spec's `normalise` lines are composed into it (for the shipped spec, a
    /// normalised network such as base_model_norm.onnx).
    #[arg(long, conflicts_with_all = ["model", "y0", "init", "horizon", "period", "goal_ystar", "goal_from", "no_clip", "system"])]
    pub spec: Option<PathBuf>,
    /// The loop of --spec to fly (default: its first).
    #[arg(long = "loop", value_name = "NAME", requires = "spec")]
    pub loop_name: Option<String>,
    /// Compute only part I of N (0-based) of the run. Zonotope sets: the initial pieces
    /// (the initial set cut along its widest parameter, usually the height) in N
    /// contiguous ranges, each piece refined on its own. Taylor-model sets (--system,
    /// --sets taylor): the cells of --grid in N contiguous ranges. --out is then the
    /// shard file; `samara merge reach` puts the N files together into the one-process
    /// reach.json (and, for zonotope sets, the figures)
    #[arg(long, value_name = "I/N", allow_hyphen_values = true, value_parser = shard::parse_shard)]
    pub shard: Option<Shard>,
    /// With Taylor-model sets (--system, --sets taylor): cut the initial set into a fixed
    /// grid first, NAME=K cutting state NAME into K equal pieces (repeatable; other
    /// states uncut), and fly every cell as its own run, with its own --max-leaves
    /// budget (docs/reach.md, "Grids and shards"). What --shard divides
    #[arg(long, value_name = "NAME=K")]
    pub grid: Vec<String>,
    /// Adaptive splitting toward a width target (Taylor-model sets): cut the initial set
    /// where a cell's enclosure is lost or its x + y (a system file's first `goal band
    /// ... at end`) at the horizon leaves the band that keeps the hull within R times
    /// the spread of the --samples flights; --max-leaves bounds the cells, --grid gives
    /// the starting cells (docs/reach.md, "Adaptive splitting").
    #[arg(long, value_name = "R", allow_hyphen_values = true)]
    pub target_ratio: Option<f64>,
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

/// The settings of the loop of `--spec` (with `--loop`, or the first) and the
/// declaration of the network that flies it.
fn spec_settings(path: &Path, name: Option<&str>) -> Result<(ReachSettings, NetDecl)> {
    let spec = samara_spec::Spec::read(path).map_err(|e| anyhow!("{e}"))?;
    let names: Vec<&str> = spec.loops.iter().map(|l| l.name.as_str()).collect();
    let lp = match name {
        Some(n) => spec.closed_loop(n).ok_or_else(|| {
            anyhow!(
                "--loop {n}: {} states no loop `{n}`; its loops: {}",
                path.display(),
                if names.is_empty() { "none".into() } else { names.join(", ") }
            )
        })?,
        None => spec.loops.first().ok_or_else(|| {
            anyhow!(
                "--spec {}: states no closed loop; add `loop NAME of f: model reduced, period 0.5, horizon 20`, `start NAME: ...` and `goal NAME: |x + y| <= 2 at 20` (docs/spec.md, Closed loops)",
                path.display()
            )
        })?,
    };
    if lp.period > MAX_PERIOD {
        bail!(
            "{}:{}:{}: reach takes periods up to {MAX_PERIOD}; e.g. period 0.5",
            path.display(),
            lp.pos.line,
            lp.pos.col
        );
    }
    crate::simulate::check_period_count(lp.horizon, lp.period, MAX_PERIODS)?;
    let net = spec
        .networks
        .iter()
        .find(|n| n.name == lp.net)
        .cloned()
        .ok_or_else(|| anyhow!("loop `{}`: unknown network `{}`", lp.name, lp.net))?;
    Ok((ReachSettings::from_loop(lp), net))
}

/// The raw-unit controller of a loop: the file bound to the spec's network with the
/// spec's normalisation composed (`raw = C + S z`, `out_raw = offset + scale out`).
fn spec_controller(
    net: samara_nn::Network,
    d: &NetDecl,
    file: &Path,
) -> Result<samara_nn::Network> {
    if d.in_norm.is_none() && d.out_norm.is_none() {
        return Ok(net);
    }
    if net.input_norm.is_some() || net.output_denorm.is_some() {
        bail!(
            "--network {}: the file carries its own normalisation layers (it takes raw units), but the spec declares `normalise {}` (its network takes normalised units): pass the normalised file (e.g. base_model_norm.onnx), or fly the raw file without --spec",
            file.display(),
            d.name
        );
    }
    Ok(samara_nn::Network {
        input_norm: d
            .in_norm
            .as_ref()
            .map(|(c, s)| samara_nn::Affine::normalise(c, s)),
        output_denorm: d
            .out_norm
            .as_ref()
            .map(|(c, s)| samara_nn::Affine::denormalise(c, s)),
        ..net
    })
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
    crate::threads::check(a.threads)
}

/// Start the global worker pool with `--threads` workers (all cores without it).
pub(crate) fn start_threads(a: &ReachArgs) -> Result<()> {
    crate::threads::start(a.threads)
}

/// The files a run (and `samara merge reach`) writes into `--out`.
pub(crate) const WRITES: [&str; 3] = ["reach.json", "reach.png", "reach.svg"];

/// `as_file`: --out is a shard file (--shard), not the output folder.
fn plan(a: &ReachArgs, as_file: bool) -> Result<Plan> {
    let (settings, decl) = match &a.spec {
        Some(p) => {
            let (s, d) = spec_settings(p, a.loop_name.as_deref())?;
            (s, Some(d))
        }
        None => (build_settings(a)?, None),
    };
    // Never write over the network file (an input), before anything is computed.
    let inputs = [("--network", a.network.as_path())];
    if as_file {
        samara_report::guard::check_output_file("--out", &a.out, &inputs)?;
    } else {
        samara_report::guard::check_output_dir("--out", &a.out, &WRITES, &inputs)?;
    }
    // The flags are checked; now the network, then the library's own check of the
    // settings against it.
    let net = controller(&a.network, decl.as_ref())?;
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

/// A network in the wrong units (`ReachSettings::units_warning`: its outputs at the
/// initial set's corners far outside the actuator range), as a warning naming the flag.
fn units_warnings(a: &ReachArgs, plan: &Plan) -> Vec<String> {
    plan.settings
        .units_warning(&plan.net)
        .map(|w| format!("--network {}: {w}", a.network.display()))
        .into_iter()
        .collect()
}

/// The controller a run flies: the `--network` file, with the normalisation of `--spec`'s
/// network declaration composed (`decl`).
fn controller(network: &Path, decl: Option<&NetDecl>) -> Result<samara_nn::Network> {
    if !network.exists() {
        bail!(
            "--network {}: no such file; give the path of an .onnx controller with 6 raw inputs and 1 output (e.g. base_model_denorm.onnx)",
            network.display()
        );
    }
    let net = crate::nnload::load_network(network).with_context(|| {
        format!(
            "--network {}: cannot load the network; give an ONNX file samara can read",
            network.display()
        )
    })?;
    match decl {
        Some(d) => spec_controller(net, d, network),
        None => Ok(net),
    }
}

/// `--order` and `--timeout` do not apply to zonotope sets.
fn check_zonotope_flags(a: &ReachArgs) -> Result<()> {
    if a.order.is_some() {
        bail!("--order applies to Taylor-model sets (--sets taylor or --system); the zonotope sets have no order");
    }
    if a.timeout.is_some() {
        bail!("--timeout applies to Taylor-model sets (--sets taylor or --system); bound the zonotope run with --max-leaves");
    }
    if a.network_error.is_some() {
        bail!("--network-error applies to Taylor-model sets (--sets taylor or --system); the zonotope sets keep the network's error as generators already");
    }
    if a.lift_at.is_some() {
        bail!("--lift-at applies to Taylor-model sets (--sets taylor or --system); the zonotope sets have no lifted remainders");
    }
    if a.lifted_weight.is_some() {
        bail!("--lifted-weight applies to Taylor-model sets (--sets taylor or --system); the zonotope sets have no lifted parameters");
    }
    Ok(())
}

/// Run `samara reach`.
pub fn run(a: &ReachArgs) -> Result<ExitCode> {
    // Taylor-model runs shard by their --grid (crate::reach_system); zonotope runs by
    // their initial pieces.
    let taylor = a.system.is_some() || a.sets == "taylor" || a.target_ratio.is_some();
    if let Some(sh) = a.shard.filter(|_| !taylor) {
        return run_shard(a, sh);
    }
    if !a.grid.is_empty() && !taylor {
        bail!("--grid applies to Taylor-model sets (--sets taylor or --system); the zonotope sets are cut by --max-leaves (and sharded by their initial pieces)");
    }
    if let Some(sys) = &a.system {
        return crate::reach_system::run(a, sys);
    }
    if a.target_ratio.is_some() {
        return run_taylor(a);
    }
    match a.sets.as_str() {
        "zonotope" => {
            check_zonotope_flags(a)?;
            Ok(run_zonotope(a, false)?.0)
        }
        "taylor" => run_taylor(a),
        "auto" => {
            // The Taylor-model flags are checked now, not after the zonotope run.
            crate::reach_system::taylor_settings(a)?;
            // On to Taylor-model sets when the zonotopes leave the goal unknown, or lose
            // the enclosure with no goal (no result over the horizon either way).
            let (code, unknown) = run_zonotope(a, true)?;
            if !unknown {
                return Ok(code);
            }
            let mut t = a.clone();
            t.sets = "taylor".into();
            t.out = a.out.join("taylor");
            // The zonotope run started the thread pool already.
            t.threads = None;
            eprintln!(
                "--sets auto: the zonotope sets left the goal unknown or lost the enclosure (reach.json in {}); now Taylor-model sets, written to {}",
                a.out.display(),
                t.out.display()
            );
            run_taylor(&t)
        }
        other => bail!("--sets {other}: give zonotope, taylor or auto"),
    }
}

/// The built-in glider's `--lift-at` on Taylor-model sets (docs/reach.md).
const GLIDER_LIFT_AT: f64 = 1e-3;

/// The built-in glider setting on Taylor-model sets: the shipped system file of the
/// model with the flags' initial set, period, horizon, clip and goal.
fn run_taylor(a: &ReachArgs) -> Result<ExitCode> {
    // Without --order and --network-error, the glider's measured best (docs/reach.md):
    // order 2 with 7 symbolic-remainder parameters proves the full model's published
    // setting in 46 s, where the automatic ladder climbs to order 3 on the whole set and
    // times out.
    let mut tuned = a.clone();
    if a.target_ratio.is_some() {
        crate::reach_adaptive::glider_defaults(&mut tuned);
    } else if a.order.is_none() && a.network_error.is_none() {
        tuned.order = Some(2);
        tuned.network_error = Some("symbolic:7".into());
    }
    // Lift the flow's remainders early: on the glider's multi-state sets this keeps the
    // sets 2-4x tighter (docs/reach.md, "How small a set meets the criterion").
    tuned.lift_at = a.lift_at.or(Some(GLIDER_LIFT_AT));
    let a = &tuned;
    let plan = plan(a, a.shard.is_some())?;
    for w in units_warnings(a, &plan) {
        eprintln!("warning: {w}");
    }
    let sys = crate::reach_system::builtin_system(&plan.settings)?;
    // The published setting's measure, x + y (its width against the flights').
    let mut coef = vec![0.0; sys.dim()];
    for (i, n) in sys.states.iter().enumerate() {
        if n == "x" || n == "y" {
            coef[i] = 1.0;
        }
    }
    let xy = samara_reach::system::Measure {
        name: "x + y".into(),
        coef,
        offset: 0.0,
    };
    crate::reach_system::run_system(a, &sys, Path::new("built-in setting"), &plan.net, vec![xy])
}

/// The built-in glider setting on zonotope sets; also whether the run has no result
/// (the verdict is `unknown`, or there is no goal and a sub-box lost its enclosure). With
/// `quiet_unknown` such a run is reported on stderr only (files written), leaving stdout
/// to the run that follows (`--sets auto`).
fn run_zonotope(a: &ReachArgs, quiet_unknown: bool) -> Result<(ExitCode, bool)> {
    let plan = plan(a, false)?;
    let warnings = units_warnings(a, &plan);
    for w in &warnings {
        eprintln!("warning: {w}");
    }
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

    let o = Outcome::of(&res, &plan.settings, warnings);
    let settings = settings_json(
        &a.network.display().to_string(),
        a.threads.unwrap_or_else(rayon::current_num_threads),
        &plan.settings,
    );
    let report = report_json(
        settings,
        &plan.settings,
        &o,
        serde_json::to_value(&res.leaves)?,
    );
    write_atomic(
        &a.out.join("reach.json"),
        serde_json::to_string_pretty(&report)?.as_bytes(),
    )?;
    samara_report::reach::figure(
        &res,
        &figure_title(&a.network, &plan.settings),
        plan.settings.goal.as_ref().map(|g| g.ystar),
    )
    .render(&a.out.join("reach.png"), &a.out.join("reach.svg"))?;
    let unknown = matches!(o.verdict, Verdict::Unknown { .. }) || o.lost.is_some();
    if unknown && quiet_unknown {
        eprintln!("{}", human_line(&plan.settings, &o));
        out.keep();
        return Ok((ExitCode::from(1), true));
    }
    Ok((finish(&o, &plan.settings, &a.out, a.json, out)?, unknown))
}

/// Print the verdict (or the JSON summary), keep the output folder, and the exit code.
fn finish(
    o: &Outcome,
    s: &ReachSettings,
    dir: &Path,
    json_out: bool,
    out: samara_report::guard::OutDir,
) -> Result<ExitCode> {
    if json_out {
        println!("{}", serde_json::to_string_pretty(&summary(o, dir))?);
    } else {
        println!("{}", human_line(s, o));
        eprintln!("wrote {}", dir.display());
    }
    out.keep();
    Ok(match o.verdict {
        // No goal, but a sub-box lost its enclosure: no result over the horizon.
        Verdict::NoGoal if o.lost.is_some() => ExitCode::from(1),
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

fn settings_json(network: &str, threads: usize, s: &ReachSettings) -> serde_json::Value {
    let mut init = serde_json::Map::new();
    for (i, (lo, hi)) in s.init.iter().enumerate() {
        init.insert(STATE_NAMES[i].to_string(), serde_json::json!([lo, hi]));
    }
    serde_json::json!({
        "network": network,
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
        "threads": threads,
    })
}

/// What the report, the summary and the human line say of a run (one process, or merged
/// shards).
struct Outcome<'a> {
    verdict: &'a Verdict,
    final_x_plus_y: [f64; 2],
    sampled_x_plus_y: [f64; 2],
    subproblems: usize,
    seconds: f64,
    sampled_trajectories: usize,
    /// Where a sub-box lost its enclosure, if one did
    /// (`samara_reach::verdict::lost_enclosure`).
    lost: Option<String>,
    /// Warnings on the inputs ([`units_warnings`]), in the JSON as `warnings`.
    warnings: Vec<String>,
}

impl<'a> Outcome<'a> {
    fn of(res: &'a ReachResult, s: &ReachSettings, warnings: Vec<String>) -> Self {
        Outcome {
            warnings,
            lost: samara_reach::verdict::lost_enclosure(&res.leaves, s),
            verdict: &res.verdict,
            final_x_plus_y: res.final_x_plus_y,
            sampled_x_plus_y: res.sampled_x_plus_y,
            subproblems: res.subproblems(),
            seconds: res.seconds,
            sampled_trajectories: res.samples.len(),
        }
    }

    /// As `ReachResult::width_ratio`.
    fn width_ratio(&self) -> f64 {
        (self.final_x_plus_y[1] - self.final_x_plus_y[0])
            / (self.sampled_x_plus_y[1] - self.sampled_x_plus_y[0])
    }
}

/// `reach.json`: `settings` from [`settings_json`], `leaves` the serialised sub-boxes.
fn report_json(settings: Value, s: &ReachSettings, res: &Outcome, leaves: Value) -> Value {
    serde_json::json!({
        "settings": settings,
        "verdict": verdict_details(res.verdict),
        "final_x_plus_y": [num(res.final_x_plus_y[0]), num(res.final_x_plus_y[1])],
        "sampled_x_plus_y": res.sampled_x_plus_y,
        "width_ratio": num(res.width_ratio()),
        "subproblems": res.subproblems,
        "seconds": res.seconds,
        "sampled_trajectories": res.sampled_trajectories,
        "enclosure_lost": res.lost,
        "warnings": res.warnings,
        "state_names": &STATE_NAMES[..s.model.dim()],
        "leaves": leaves,
    })
}

fn summary(res: &Outcome, out: &Path) -> serde_json::Value {
    let mut v = verdict_details(res.verdict);
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
    m.insert("subproblems".into(), serde_json::json!(res.subproblems));
    m.insert("seconds".into(), serde_json::json!(res.seconds));
    m.insert("enclosure_lost".into(), serde_json::json!(res.lost));
    m.insert("warnings".into(), serde_json::json!(res.warnings));
    m.insert("out".into(), serde_json::json!(out.display().to_string()));
    v
}

fn human_line(s: &ReachSettings, res: &Outcome) -> String {
    let f = res.final_x_plus_y;
    let sm = res.sampled_x_plus_y;
    let goal = match &s.goal {
        Some(g) => match g.from {
            Some(t0) => format!(" (goal |x + y| <= {} on [{t0}, {}])", g.ystar, s.horizon),
            None => format!(" (goal |x + y| <= {} at t = {})", g.ystar, s.horizon),
        },
        None => String::new(),
    };
    let detail = match res.verdict {
        Verdict::Unknown { reason } => format!("; reason: {reason}"),
        Verdict::NoGoal => match &res.lost {
            Some(why) => format!("; no result: {why}"),
            None => String::new(),
        },
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
        res.subproblems,
        res.seconds
    )
}

/// The figure's title: the network's name and the model.
fn figure_title(network: &Path, s: &ReachSettings) -> String {
    let name = network
        .file_stem()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "network".into());
    format!("{name}, {} model", s.model.name())
}

/// `samara reach --shard I/N --out FILE`: part I of N of the run (the initial pieces
/// `Shard::range` of their number, each refined on its own) as a shard file.
fn run_shard(a: &ReachArgs, sh: Shard) -> Result<ExitCode> {
    match a.sets.as_str() {
        "zonotope" => check_zonotope_flags(a)?,
        "auto" => bail!("--shard with --sets auto: the two kinds of set are sharded differently; shard the zonotope run (--sets zonotope) or the Taylor-model run (--sets taylor with --grid)"),
        other => bail!("--sets {other}: give zonotope, taylor or auto"),
    }
    let plan = plan(a, true)?;
    let s = &plan.settings;
    let warnings = units_warnings(a, &plan);
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    start_threads(a)?;
    let t0 = Instant::now();
    let spinner = progress(s);
    let done = parts::prepare(&plan.net, s).map(|prep| {
        let range = sh.range(prep.pieces());
        let flown = prep.fly(range.clone());
        (prep, range, flown)
    });
    if let Some(p) = spinner {
        p.finish_and_clear();
    }
    let (prep, range, flown) = done.map_err(|e| anyhow!("{e}"))?;
    let secs = t0.elapsed().as_secs_f64();
    let mut inputs = vec![(
        "--network".to_string(),
        a.network.as_path(),
        "--network".to_string(),
    )];
    if let Some(p) = &a.spec {
        inputs.push(("--spec".to_string(), p.as_path(), "--spec".to_string()));
    }
    let run = run_json(s, shard::digest_inputs(inputs)?, prep.pieces());
    let mut result = json!({
        "pieces": [range.start, range.end],
        "shared": shared_json(&prep),
        "network": a.network.display().to_string(),
        // Where the merge reads the controller back to re-check a counterexample.
        "network_file": shard::resolved(&a.network),
        "spec_file": a.spec.as_deref().map(shard::resolved),
        "loop": a.loop_name,
        "warnings": warnings,
        "threads": a.threads.unwrap_or_else(rayon::current_num_threads),
        "seconds": secs,
        "subboxes": flown.iter().map(flown_json).collect::<Vec<_>>(),
    });
    // The figure's sampled trajectories (the same in every shard): kept once, in shard 0.
    if sh.i == 0 {
        let (curves, group_label) = samara_report::reach::sample_curves(&prep.samples);
        result["figure"] = json!({
            "group_label": group_label,
            "curves": curves.iter().map(|c| json!({
                "label": c.label,
                "points": c.points.iter().map(|&(x, y)| [shard::f(x), shard::f(y)]).collect::<Vec<_>>(),
            })).collect::<Vec<_>>(),
        });
    }
    shard::write(&a.out, "reach", sh, run, result)?;
    if a.json {
        println!(
            "{}",
            json!({"shard": [sh.i, sh.n], "pieces": [range.start, range.end],
                "subboxes": flown.len(), "out": a.out})
        );
    } else {
        println!(
            "shard {}/{}: pieces {}..{} of {} ({} sub-boxes flown), {secs:.3} s; partial result in {} (merge with `samara merge reach`)",
            sh.i,
            sh.n,
            range.start,
            range.end,
            prep.pieces(),
            flown.len(),
            a.out.display()
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// The exact text of an interval.
fn pair(v: [f64; 2]) -> Value {
    json!([shard::f(v[0]), shard::f(v[1])])
}

/// Read back a [`pair`]; `what` names it in messages.
fn read_pair(v: &Value, what: &str) -> Result<[f64; 2]> {
    let x = |i: usize| v[i].as_str().and_then(|t| t.parse::<f64>().ok());
    match (v.as_array().map(Vec::len), x(0), x(1)) {
        (Some(2), Some(a), Some(b)) => Ok([a, b]),
        _ => bail!("{what}: expected two number texts, found {v}"),
    }
}

/// Read back a [`shard::f`] value.
fn read_f(v: &Value, what: &str) -> Result<f64> {
    v.as_str()
        .and_then(|t| t.parse().ok())
        .ok_or_else(|| anyhow!("{what}: expected a number text, found {v}"))
}

/// The inputs (content digests of `--network` and `--spec`) and settings every shard of
/// one run shares (`run` of the shard file): numbers as exact text, so the merge rebuilds the settings bit for bit.
fn run_json(s: &ReachSettings, inputs: Value, pieces: usize) -> Value {
    json!({
        "inputs": inputs,
        "samara": env!("CARGO_PKG_VERSION"),
        "model": s.model.name(),
        "init": s.init.iter().map(|&(lo, hi)| pair([lo, hi])).collect::<Vec<_>>(),
        "horizon": shard::f(s.horizon),
        "period": shard::f(s.period),
        "clip": s.clip.map(|(lo, hi)| pair([lo, hi])),
        "reset_filter": s.reset_filter,
        "goal": s.goal.as_ref().map(|g| json!({"ystar": shard::f(g.ystar), "from": g.from.map(shard::f)})),
        "max_leaves": s.max_leaves,
        "initial_splits": s.initial_splits,
        "samples": s.samples,
        "seed": s.seed,
        "pieces": pieces,
    })
}

/// The settings of a run from its [`run_json`].
fn settings_from_run(run: &Value) -> Result<ReachSettings> {
    let bad = |what: &str| anyhow!("shard files: bad `run.{what}` ({})", run[what]);
    let model = run["model"]
        .as_str()
        .and_then(Model::from_name)
        .ok_or_else(|| bad("model"))?;
    let mut s = ReachSettings::published(model);
    let init = run["init"].as_array().ok_or_else(|| bad("init"))?;
    if init.len() != model.dim() {
        return Err(bad("init"));
    }
    s.init = init
        .iter()
        .map(|v| read_pair(v, "run.init").map(|[a, b]| (a, b)))
        .collect::<Result<_>>()?;
    s.horizon = read_f(&run["horizon"], "run.horizon")?;
    s.period = read_f(&run["period"], "run.period")?;
    s.clip = match &run["clip"] {
        Value::Null => None,
        v => Some(read_pair(v, "run.clip").map(|[a, b]| (a, b))?),
    };
    s.reset_filter = run["reset_filter"]
        .as_bool()
        .ok_or_else(|| bad("reset_filter"))?;
    s.goal = match &run["goal"] {
        Value::Null => None,
        g => Some(Goal {
            ystar: read_f(&g["ystar"], "run.goal.ystar")?,
            from: match &g["from"] {
                Value::Null => None,
                f => Some(read_f(f, "run.goal.from")?),
            },
        }),
    };
    let int = |what: &str| {
        run[what]
            .as_u64()
            .ok_or_else(|| bad(what))
            .and_then(|n| usize::try_from(n).map_err(|_| bad(what)))
    };
    s.max_leaves = int("max_leaves")?;
    s.initial_splits = int("initial_splits")?;
    s.samples = int("samples")?;
    s.seed = run["seed"].as_u64().ok_or_else(|| bad("seed"))?;
    Ok(s)
}

/// What every shard computes alike from the samples; the merge checks they agree.
fn shared_json(p: &parts::Prepared) -> Value {
    let violation = match &p.violation {
        Some(Verdict::Violated {
            initial,
            t,
            x_plus_y,
        }) => json!({
            "initial": initial.iter().map(|x| shard::f(*x)).collect::<Vec<_>>(),
            "t": shard::f(*t),
            "x_plus_y": shard::f(*x_plus_y),
        }),
        _ => Value::Null,
    };
    json!({
        "sampled_trajectories": p.samples.len(),
        "sampled_x_plus_y": pair(p.sampled_x_plus_y),
        "tol_noise": shard::f(p.tol_noise),
        "violation": violation,
    })
}

/// A flown sub-box in a shard file: numbers as exact text.
fn flown_json(f: &Flown) -> Value {
    let l = &f.leaf;
    let steps: Vec<Value> = l
        .steps
        .iter()
        .map(|st| {
            json!({
                "t": shard::f(st.t),
                "bbox": st.bbox.iter().map(|b| pair(*b)).collect::<Vec<_>>(),
                "x_plus_y": pair(st.x_plus_y),
                "x_plus_y_period": pair(st.x_plus_y_period),
                "ex": st.ex.map(pair),
            })
        })
        .collect();
    json!({
        "key": f.key,
        "want": f.want,
        "split": f.split,
        "goal": f.goal,
        "leaf": {
            "init": l.init.iter().map(|b| pair(*b)).collect::<Vec<_>>(),
            "params": l.params,
            "steps": steps,
            "failure": l.failure,
            "flow_steps": [l.flow_steps.0, l.flow_steps.1],
            "max_dev": shard::f(l.max_dev),
        },
    })
}

/// Read back a [`flown_json`].
fn read_flown(v: &Value, file: &Path) -> Result<Flown> {
    let key = v["key"].as_str().unwrap_or("?").to_string();
    let what = format!("{}: sub-box {key}", file.display());
    let bad = |field: &str| anyhow!("{what}: bad `{field}` ({})", v[field]);
    let l = &v["leaf"];
    let pairs = |x: &Value, field: &str| -> Result<Vec<[f64; 2]>> {
        x.as_array()
            .ok_or_else(|| anyhow!("{what}: bad `{field}`"))?
            .iter()
            .map(|b| read_pair(b, &format!("{what}: {field}")))
            .collect()
    };
    let idx = |x: &Value| x.as_u64().and_then(|n| usize::try_from(n).ok());
    let steps = l["steps"]
        .as_array()
        .ok_or_else(|| anyhow!("{what}: bad `steps`"))?
        .iter()
        .map(|st| {
            Ok(StepSet {
                t: read_f(&st["t"], &format!("{what}: t"))?,
                bbox: pairs(&st["bbox"], "bbox")?,
                x_plus_y: read_pair(&st["x_plus_y"], &format!("{what}: x_plus_y"))?,
                x_plus_y_period: read_pair(
                    &st["x_plus_y_period"],
                    &format!("{what}: x_plus_y_period"),
                )?,
                ex: match &st["ex"] {
                    Value::Null => None,
                    e => Some(read_pair(e, &format!("{what}: ex"))?),
                },
                set: None,
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let leaf = LeafRecord {
        init: pairs(&l["init"], "init")?,
        params: l["params"]
            .as_array()
            .and_then(|ps| ps.iter().map(idx).collect::<Option<Vec<_>>>())
            .ok_or_else(|| anyhow!("{what}: bad `params`"))?,
        steps,
        failure: match &l["failure"] {
            Value::Null => None,
            x => Some(
                x.as_str()
                    .ok_or_else(|| anyhow!("{what}: bad `failure`"))?
                    .to_string(),
            ),
        },
        flow_steps: match (idx(&l["flow_steps"][0]), idx(&l["flow_steps"][1])) {
            (Some(a), Some(b)) => (a, b),
            _ => bail!("{what}: bad `flow_steps`"),
        },
        max_dev: read_f(&l["max_dev"], &format!("{what}: max_dev"))?,
    };
    let split = match &v["split"] {
        Value::Null => None,
        j => Some(
            idx(j)
                .filter(|j| *j < leaf.params.len())
                .ok_or_else(|| bad("split"))?,
        ),
    };
    if leaf.failure.is_none() && leaf.steps.is_empty() {
        bail!("{what}: no enclosure recorded");
    }
    Ok(Flown {
        key,
        want: v["want"].as_bool().ok_or_else(|| bad("want"))?,
        split,
        goal: match &v["goal"] {
            Value::Null => None,
            g => Some(g.as_bool().ok_or_else(|| bad("goal"))?),
        },
        leaf,
    })
}

/// The error of a merge that needs sub-box `key`, which its shard did not fly.
fn missing(
    key: &str,
    shards: &[(PathBuf, Value)],
    n_pieces: usize,
    max_leaves: usize,
) -> anyhow::Error {
    let n = shards.len();
    let (piece, path) = key.split_once(':').unwrap_or((key, ""));
    let p: usize = piece.parse().unwrap_or(0);
    let i = (0..n)
        .find(|&i| Shard { i, n }.range(n_pieces).contains(&p))
        .unwrap_or(0);
    let file = shards[i].0.display();
    if path.is_empty() {
        return anyhow!("{file}: piece {key} of shard {i}/{n} is missing (a damaged shard file?); run that shard again");
    }
    let parent = &key[..key.len() - 1];
    anyhow!(
        "the run splits sub-box {parent} into {key}, which shard {i}/{n} ({file}) did not fly: the sub-box budget (--max-leaves {max_leaves}) ran out during the refinement, and that shard, which cannot see the other shards' sub-boxes, spent part of the budget's extra quarter (for sub-boxes that lost their enclosure) on sub-boxes the run does not split; this run cannot be merged exactly: run it without --shard, or with a larger --max-leaves"
    )
}

/// The merge's re-check of the shards' counterexample (a sampled trajectory that misses
/// the goal): the controller read back from where shard 0 found it (with its --spec),
/// which must be the files the shards digested, and the trajectory flown again
/// ([`samara_reach::verdict::recheck_violation`], the run's own falsification test).
fn recheck_counterexample(
    run: &Value,
    r0: &Value,
    file0: &Path,
    s: &ReachSettings,
    v: &Verdict,
) -> Result<()> {
    let at = format!("{}: the counterexample", file0.display());
    let path = |k: &str| -> Result<Option<PathBuf>> {
        match &r0[k] {
            Value::Null => Ok(None),
            Value::String(p) => Ok(Some(PathBuf::from(p))),
            x => bail!("{}: bad `{k}` ({x})", file0.display()),
        }
    };
    let network =
        path("network_file")?.ok_or_else(|| anyhow!("{}: no `network_file`", file0.display()))?;
    let spec = path("spec_file")?;
    for (flag, p) in [("--network", Some(&network)), ("--spec", spec.as_ref())] {
        let Some(p) = p else { continue };
        let now = shard::digest_file(p, &format!("{at}: re-checking it needs {flag}"))?;
        if run["inputs"][flag] != now.as_str() {
            bail!(
                "{at}: input `{flag}` ({}) changed since the shards ran (content digest {} then, {now} now); run every shard again",
                p.display(),
                run["inputs"][flag]
            );
        }
    }
    let decl = match &spec {
        Some(p) => Some(spec_settings(p, r0["loop"].as_str())?.1),
        None => None,
    };
    let net = controller(&network, decl.as_ref())?;
    samara_reach::verdict::recheck_violation(&net, s, v).map_err(|e| {
        anyhow!(
            "{at} does not hold: {e}; the shard is damaged or tampered with, run the shards again"
        )
    })
}

/// `samara merge reach`: the N shards' flown sub-boxes, the run's refinement replayed
/// over them (`samara_reach::parts::refine`: the same rounds and sub-box budget as one
/// process), then `DIR/reach.json` and the figures as one process writes them. The
/// verdict, the enclosures, the sub-boxes and the counterexample (a sampled trajectory,
/// the same in every shard) are the one-process run's; `seconds` is the sum of the
/// shards', `network` and `threads` are shard 0's. Refused (exit 2) when a sub-box the
/// run flies was not flown by its shard (rare; see `samara_reach::parts`).
pub fn merge_reach(
    run: &Value,
    shards: &[(PathBuf, Value)],
    out: &Path,
    json_out: bool,
) -> Result<ExitCode> {
    let s = settings_from_run(run)?;
    let n_pieces = run["pieces"]
        .as_u64()
        .and_then(|n| usize::try_from(n).ok())
        .ok_or_else(|| anyhow!("shard files: bad `run.pieces` ({})", run["pieces"]))?;
    let n = shards.len();
    let (file0, r0) = &shards[0];
    let mut nodes: HashMap<String, Flown> = HashMap::new();
    let mut seconds = 0.0;
    for (i, (file, r)) in shards.iter().enumerate() {
        let range = Shard { i, n }.range(n_pieces);
        if r["pieces"] != json!([range.start, range.end]) {
            bail!(
                "{}: pieces {}, expected {}..{} of {n_pieces} for shard {i}/{n}",
                file.display(),
                r["pieces"],
                range.start,
                range.end
            );
        }
        if r["shared"] != r0["shared"] {
            bail!(
                "{} and {}: the shards' simulated samples differ (different samara builds?): {} vs {}",
                file0.display(),
                file.display(),
                r0["shared"],
                r["shared"]
            );
        }
        seconds += r["seconds"].as_f64().unwrap_or(0.0);
        let list = r["subboxes"]
            .as_array()
            .ok_or_else(|| anyhow!("{}: no `subboxes` list", file.display()))?;
        for v in list {
            let f = read_flown(v, file)?;
            let piece = f
                .key
                .split_once(':')
                .and_then(|(p, _)| p.parse::<usize>().ok());
            if !piece.is_some_and(|p| range.contains(&p)) {
                bail!(
                    "{}: sub-box {} is not of this shard's pieces {}..{}",
                    file.display(),
                    f.key,
                    range.start,
                    range.end
                );
            }
            if nodes.contains_key(&f.key) {
                bail!("{}: sub-box {} given twice", file.display(), f.key);
            }
            nodes.insert(f.key.clone(), f);
        }
    }
    // The one-process rounds over the recorded flights.
    let start: Vec<String> = (0..n_pieces).map(parts::piece_key).collect();
    let mut done = parts::refine(
        start,
        0,
        s.max_leaves,
        |keys: Vec<String>| {
            keys.iter()
                .map(|k| {
                    nodes
                        .get(k)
                        .ok_or_else(|| missing(k, shards, n_pieces, s.max_leaves))
                })
                .collect::<Result<Vec<&Flown>>>()
        },
        |f| (parts::child_key(&f.key, 0), parts::child_key(&f.key, 1)),
    )?;
    let sh = &r0["shared"];
    let violation = match &sh["violation"] {
        Value::Null => None,
        v => Some(Verdict::Violated {
            initial: v["initial"]
                .as_array()
                .ok_or_else(|| anyhow!("{}: bad `violation`", file0.display()))?
                .iter()
                .map(|x| read_f(x, "violation.initial"))
                .collect::<Result<_>>()?,
            t: read_f(&v["t"], "violation.t")?,
            x_plus_y: read_f(&v["x_plus_y"], "violation.x_plus_y")?,
        }),
    };
    if let Some(v) = &violation {
        recheck_counterexample(run, r0, file0, &s, v)?;
    }
    let (verdict, fin) = parts::finish(&s, violation, &mut done);
    let o = Outcome {
        lost: samara_reach::verdict::lost_enclosure(done.iter().map(|f| &f.leaf), &s),
        warnings: serde_json::from_value(r0["warnings"].clone())
            .map_err(|e| anyhow!("{}: bad `warnings`: {e}", file0.display()))?,
        verdict: &verdict,
        final_x_plus_y: fin,
        sampled_x_plus_y: read_pair(&sh["sampled_x_plus_y"], "sampled_x_plus_y")?,
        subproblems: done.len(),
        seconds,
        sampled_trajectories: sh["sampled_trajectories"]
            .as_u64()
            .and_then(|n| usize::try_from(n).ok())
            .ok_or_else(|| anyhow!("{}: bad `sampled_trajectories`", file0.display()))?,
    };
    for w in &o.warnings {
        eprintln!("warning: {w}");
    }
    let network = r0["network"]
        .as_str()
        .ok_or_else(|| anyhow!("{}: bad `network`", file0.display()))?;
    let threads = r0["threads"]
        .as_u64()
        .and_then(|n| usize::try_from(n).ok())
        .ok_or_else(|| anyhow!("{}: bad `threads`", file0.display()))?;
    let leaves: Vec<&LeafRecord> = done.iter().map(|f| &f.leaf).collect();
    let fig = &r0["figure"];
    let curves = fig["curves"]
        .as_array()
        .ok_or_else(|| anyhow!("{}: no `figure` (shard 0 keeps it)", file0.display()))?
        .iter()
        .map(|c| {
            Ok(Curve {
                label: c["label"].as_str().unwrap_or("").to_string(),
                points: c["points"]
                    .as_array()
                    .ok_or_else(|| anyhow!("{}: bad figure curve", file0.display()))?
                    .iter()
                    .map(|p| read_pair(p, "figure point").map(|[x, y]| (x, y)))
                    .collect::<Result<_>>()?,
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let group_label = fig["group_label"].as_str().map(str::to_string);

    let dir = samara_report::guard::OutDir::prepare(out)?;
    let report = report_json(
        settings_json(network, threads, &s),
        &s,
        &o,
        serde_json::to_value(&leaves)?,
    );
    write_atomic(
        &out.join("reach.json"),
        serde_json::to_string_pretty(&report)?.as_bytes(),
    )?;
    samara_report::reach::draw(
        &figure_title(Path::new(network), &s),
        &verdict,
        &leaves,
        curves,
        group_label,
        s.goal.as_ref().map(|g| g.ystar),
    )
    .render(&out.join("reach.png"), &out.join("reach.svg"))?;
    finish(&o, &s, out, json_out, dir)
}

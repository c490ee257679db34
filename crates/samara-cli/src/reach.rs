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
use samara_app::reach::{
    merge_zonotope, Outcome, ReachReport, ReachSummary, SettingsEcho, ShardLine, ShardSource,
    ZonotopeRun, ZonotopeShard,
};
use samara_plant::{Model, STATE_NAMES};
use samara_reach::parts;
use samara_reach::{Goal, ReachSettings};
use samara_report::write_atomic;
use samara_spec::lower::NetDecl;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use crate::json_text;
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
    let net = crate::simulate::glider_network(network).with_context(|| {
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
    let settings = SettingsEcho::new(
        &a.network.display().to_string(),
        a.threads.unwrap_or_else(rayon::current_num_threads),
        &plan.settings,
    );
    let report = ReachReport::new(settings, &plan.settings, &o, res.leaves.clone());
    write_atomic(
        &a.out.join("reach.json"),
        json_text(&report, true)?.as_bytes(),
    )?;
    samara_report::reach::figure(
        &figure_title(&a.network, &plan.settings),
        res.verdict.name(),
        &samara_app::reach::figure_sets(&res.leaves),
        &samara_app::reach::figure_samples(&res.samples),
        plan.settings.goal.as_ref().map(|g| g.ystar),
    )
    .render(&a.out.join("reach.png"), &a.out.join("reach.svg"))?;
    let unknown = o.no_result();
    if unknown && quiet_unknown {
        eprintln!("{}", o.human_line(&plan.settings));
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
        println!("{}", json_text(&ReachSummary::new(o, dir), true)?);
    } else {
        println!("{}", o.human_line(s));
        eprintln!("wrote {}", dir.display());
    }
    out.keep();
    Ok(if o.success() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
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
    let run = ZonotopeRun::new(s, shard::digest_inputs(inputs)?, prep.pieces());
    let src = ShardSource {
        network: a.network.display().to_string(),
        network_file: shard::resolved(&a.network),
        spec_file: a.spec.as_deref().map(shard::resolved),
        loop_name: a.loop_name.clone(),
        warnings,
        threads: a.threads.unwrap_or_else(rayon::current_num_threads),
    };
    let result = ZonotopeShard::new(sh, &prep, range.clone(), &flown, secs, src);
    shard::write(&a.out, "reach", sh, &run, &result)?;
    if a.json {
        let line = ShardLine {
            shard: (sh.i, sh.n),
            pieces: (range.start, range.end),
            subboxes: flown.len(),
            out: a.out.clone(),
        };
        println!("{}", json_text(&line, false)?);
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

/// `samara merge reach` of zonotope shards (`samara_app::reach::merge_zonotope`), then
/// `DIR/reach.json` and the figures as one process writes them. The counterexample is
/// re-checked under the controller read back from where shard 0 found it (with its
/// --spec).
pub fn merge_reach(
    shards: &samara_app::shard::Shards,
    out: &Path,
    json_out: bool,
) -> Result<ExitCode> {
    let run: ZonotopeRun = shards.run_as()?;
    let results = shards.results_as::<ZonotopeShard>()?;
    let merged = merge_zonotope(&run, &results, |r| {
        r.run(&run, |network, spec, loop_name| {
            let decl = match spec {
                Some(p) => Some(spec_settings(p, loop_name).map_err(app_input)?.1),
                None => None,
            };
            controller(network, decl.as_ref()).map_err(app_input)
        })
    })?;
    for w in &merged.outcome.warnings {
        eprintln!("warning: {w}");
    }
    let s = &merged.settings;
    let dir = samara_report::guard::OutDir::prepare(out)?;
    write_atomic(
        &out.join("reach.json"),
        json_text(&merged.report(), true)?.as_bytes(),
    )?;
    samara_report::reach::draw(
        &figure_title(Path::new(&merged.network), s),
        merged.outcome.verdict.name(),
        &samara_app::reach::figure_sets(&merged.leaves),
        merged.curves.clone(),
        merged.group_label.clone(),
        s.goal.as_ref().map(|g| g.ystar),
    )
    .render(&out.join("reach.png"), &out.join("reach.svg"))?;
    finish(&merged.outcome, s, out, json_out, dir)
}

/// A CLI error as the library's input error (its message, causes included).
fn app_input(e: anyhow::Error) -> samara_app::AppError {
    samara_app::AppError::Input(crate::error_chain(&e))
}

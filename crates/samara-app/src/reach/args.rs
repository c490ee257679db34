//! The settings of `samara reach` as the command line gives them ([`ReachArgs`], the
//! flags themselves, deriving `clap::Args`) and every check of them: the built-in
//! glider's [`ReachSettings`] ([`ReachArgs::builtin_settings`]), the Taylor-model
//! settings ([`ReachArgs::taylor_settings`]), the sub-box and sample budgets, the flags
//! that do not apply to a path, `--grid` and `--target-ratio`, the loop of a `--spec`
//! and the built-in setting as a system file. The CLI parses, calls these, runs the
//! engine and prints; the limits live here.

use crate::bind::{check_horizon_period, check_period_count, num, MAX_STATE};
use crate::shard::{parse_shard, Shard};
use crate::{input, AppError, Front};
use samara_plant::{Model, STATE_NAMES};
use samara_reach::system::{NetworkError, SystemReachSettings};
use samara_reach::{Goal, ReachSettings};
use samara_spec::lower::NetDecl;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

type Result<T> = std::result::Result<T, AppError>;

/// Most control periods of a reachability run (the published run has 40; every period
/// costs a set-valued integration per sub-box).
pub const MAX_PERIODS: f64 = 10_000.0;
/// Longest control period of a reachability run.
pub const MAX_PERIOD: f64 = 10.0;
/// Most sub-boxes (`--max-leaves`).
pub const MAX_LEAVES: usize = 100_000;
/// Most simulated trajectories (`--samples`).
pub const MAX_SAMPLES: usize = 100_000;
/// Most sampled points kept in memory (samples x horizon / 0.05).
pub const MAX_SAMPLE_POINTS: f64 = 1e7;
/// Most a target ratio may be (beyond it the target says nothing).
pub const MAX_RATIO: f64 = 1e6;
/// Most worker threads.
pub const MAX_THREADS: usize = 1024;
/// The built-in glider's `--lift-at` on Taylor-model sets (docs/reach.md).
pub const GLIDER_LIFT_AT: f64 = 1e-3;
/// The built-in glider's `--time-order` in adaptive runs (`--target-ratio`): on the
/// six-state cell (bench/reach/cell_cost.md), order 8 with [`GLIDER_STEP_TOL`] takes
/// 790 flow steps where order 6 with the flow's default tolerance takes 1,792, at a
/// slightly narrower x + y.
pub const GLIDER_TIME_ORDER: usize = 8;
/// The built-in glider's `--step-tol` in adaptive runs (`--target-ratio`): each step's
/// Lagrange remainder may reach 1e-5 of the set's width (at order 6, the flow's default
/// 1e-7 takes 1,792 steps on that cell and 1e-5 1,078; the glider lifts the remainders
/// into parameters at [`GLIDER_LIFT_AT`] of the width anyway).
pub const GLIDER_STEP_TOL: f64 = 1e-5;

/// The built-in glider's largest starting cell in adaptive runs (`--target-ratio`
/// without `--grid`), per state: a third of the six-state set's v_xp, v_yp and omega
/// (+-0.01), a sixth of its theta, a quarter of the published y0 interval, x whole. On
/// the reduced model with the adaptive settings, cells of that size reach t = 20 inside
/// the band for both published networks (bench/reach/cell_cost.md, round 47: a quarter of
/// y0 costs what an eighth does, 12-16 CPU-s, so the set takes 648 starting cells where
/// the hand grid 3,3,3,6,1,8 took 1,296); a whole-set start instead flies
/// parents that are all lost (docs/notes/2026-11-reach-journal.md).
pub const GLIDER_CELL: [(&str, f64); 5] = [
    ("v_xp", 0.02 / 3.0),
    ("v_yp", 0.02 / 3.0),
    ("omega", 0.02 / 3.0),
    ("theta", 0.02 / 6.0),
    ("y", (0.3 / 0.07 - 0.1 / 0.07) / 4.0),
];

/// The published initial heights: y0 in [0.1/0.07, 0.3/0.07].
pub const Y0_DEFAULT: (f64, f64) = (0.1 / 0.07, 0.3 / 0.07);

/// Flags of `samara reach`. The defaults are the published CORA setting: reduced
/// model, start (1, 0, 0, 0, 0, y0) with y0 in [1.4286, 4.2857], period 0.5, horizon 20.
#[derive(clap::Args, Debug, Clone, Serialize)]
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
    /// Order in time of the Taylor-model flow's steps (--system, --sets taylor), 1 to 8:
    /// higher orders take longer steps where the flow is smooth, each step costing more
    /// (default 6; 8 in the built-in glider's adaptive runs, docs/reach.md).
    #[arg(long, allow_hyphen_values = true)]
    pub time_order: Option<i64>,
    /// Widest Lagrange remainder a step of the Taylor-model flow may add, as a share of
    /// the set's width (--system, --sets taylor), in (0, 0.01]; steps are halved until
    /// they meet it (an absolute floor of a hundredth of it keeps narrow states
    /// moving). Larger: longer, fewer steps; every remainder stays a sound enclosure
    /// (default 1e-7; 1e-5 in the built-in glider's adaptive runs, docs/reach.md).
    #[arg(long, allow_hyphen_values = true)]
    pub step_tol: Option<f64>,
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
    #[arg(long, value_name = "I/N", allow_hyphen_values = true, value_parser = parse_shard)]
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
    /// Discrete-time system files only (`next` updates, docs/system.md): which of an
    /// input table's listed values the analysis takes: `all` (default: every value, a
    /// branch each, the sound choice for any pilot), `middle`, `min` or `max`. With such
    /// a file --network may also be a folder (its .nnet/.onnx files in name order, one
    /// per mode value) or a comma-separated list, and `--init NAME=A[:B]` replaces a
    /// state's initial interval.
    #[arg(long, value_name = "all|middle|min|max", requires = "system")]
    pub choice: Option<String>,
}

/// Refuse 0 and more than [`MAX_THREADS`] worker threads, naming the flag.
pub fn check_threads(threads: Option<usize>) -> Result<()> {
    match threads {
        Some(0) => input("--threads 0: give at least 1 (or leave it out to use all cores)"),
        Some(n) if n > MAX_THREADS => input(format!(
            "--threads {n}: at most {MAX_THREADS} worker threads are allowed (more than the cores only costs memory); leave it out to use all cores"
        )),
        _ => Ok(()),
    }
}

/// Parse `A:B` or `A` into a finite, non-inverted interval inside
/// [-[`MAX_STATE`], [`MAX_STATE`]]; `what` names the flag and its value in messages
/// (e.g. `--y0 "3:2"`).
pub fn parse_interval(s: &str, what: &str) -> Result<(f64, f64)> {
    let bad = || {
        AppError::Input(format!(
            "{what}: expected A:B (e.g. 1.4286:4.2857) or a single value A, with finite numbers"
        ))
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
        return input(format!("{what}: the interval ends must be finite numbers"));
    }
    if a > b {
        return input(format!("{what}: the interval is empty (inverted, {a} > {b}); give A:B with A <= B, e.g. {b}:{a}"));
    }
    let m = MAX_STATE;
    if a < -m || b > m {
        return input(format!("{what}: the interval ends must lie in [-{m}, {m}], the range in which the nondimensional model means anything (published: y0 in [1.43, 4.29], the other states 0 or 1); give a smaller interval"));
    }
    Ok((a, b))
}

/// The settings of the loop of `--spec` (with `--loop`, or the first) and the
/// declaration of the network that flies it.
pub fn spec_settings(path: &Path, name: Option<&str>) -> Result<(ReachSettings, NetDecl)> {
    let spec = samara_spec::Spec::read(path).map_err(|e| AppError::Input(e.to_string()))?;
    let names: Vec<&str> = spec.loops.iter().map(|l| l.name.as_str()).collect();
    let lp = match name {
        Some(n) => spec.closed_loop(n).ok_or_else(|| {
            AppError::Input(format!(
                "--loop {n}: {} states no loop `{n}`; its loops: {}",
                path.display(),
                if names.is_empty() { "none".into() } else { names.join(", ") }
            ))
        })?,
        None => spec.loops.first().ok_or_else(|| {
            AppError::Input(format!(
                "--spec {}: states no closed loop; add `loop NAME of f: model reduced, period 0.5, horizon 20`, `start NAME: ...` and `goal NAME: |x + y| <= 2 at 20` (docs/spec.md, Closed loops)",
                path.display()
            ))
        })?,
    };
    if lp.period > MAX_PERIOD {
        return input(format!(
            "{}:{}:{}: reach takes periods up to {MAX_PERIOD}; e.g. period 0.5",
            path.display(),
            lp.pos.line,
            lp.pos.col
        ));
    }
    check_period_count(Front::Cli, lp.horizon, lp.period, MAX_PERIODS)?;
    let net = spec
        .networks
        .iter()
        .find(|n| n.name == lp.net)
        .cloned()
        .ok_or_else(|| {
            AppError::Input(format!("loop `{}`: unknown network `{}`", lp.name, lp.net))
        })?;
    Ok((ReachSettings::from_loop(lp), net))
}

/// The raw-unit controller of a loop: the file bound to the spec's network with the
/// spec's normalisation composed (`raw = C + S z`, `out_raw = offset + scale out`).
pub fn spec_controller(
    net: samara_nn::Network,
    d: &NetDecl,
    file: &Path,
) -> Result<samara_nn::Network> {
    if d.in_norm.is_none() && d.out_norm.is_none() {
        return Ok(net);
    }
    if net.input_norm.is_some() || net.output_denorm.is_some() {
        return input(format!(
            "--network {}: the file carries its own normalisation layers (it takes raw units), but the spec declares `normalise {}` (its network takes normalised units): pass the normalised file (e.g. base_model_norm.onnx), or fly the raw file without --spec",
            file.display(),
            d.name
        ));
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

impl ReachArgs {
    /// Whether the run uses Taylor-model sets (`--system`, `--sets taylor`,
    /// `--target-ratio`); they shard by their `--grid`, zonotope runs by their initial
    /// pieces.
    pub fn taylor(&self) -> bool {
        self.system.is_some() || self.sets == "taylor" || self.target_ratio.is_some()
    }

    /// The initial intervals `--y0` and `--init` give, by state name, parsed here (with
    /// messages naming the flag and its text); the rest is checked by
    /// `ReachRequest::settings`, the check Python's `samara.reach` makes. The run and its
    /// starting grid ([`Self::glider_start_grid`]) read the same intervals.
    fn builtin_init(&self, model: Model) -> Result<BTreeMap<String, (f64, f64)>> {
        let a = self;
        let mut init = BTreeMap::new();
        if let Some(y0) = &a.y0 {
            init.insert(
                "y".to_string(),
                parse_interval(y0, &format!("--y0 {y0:?}"))?,
            );
        }
        let names = &STATE_NAMES[..model.dim()];
        for spec in &a.init {
            let (name, iv) = spec.split_once('=').ok_or_else(|| {
                AppError::Input(format!(
                    "--init {spec:?}: expected NAME=A:B (e.g. --init theta=-0.01:0.01)"
                ))
            })?;
            let name = name.trim();
            let i = names.iter().position(|n| *n == name).ok_or_else(|| {
                let extra = if name == "E" {
                    format!(" (model {} has no filter state E)", model.name())
                } else {
                    String::new()
                };
                AppError::Input(format!(
                    "--init {spec:?}: unknown state {name:?}{extra}; choose one of {}",
                    names.join(", ")
                ))
            })?;
            if i == 5 && a.y0.is_some() {
                return input(format!(
                    "--init {spec:?}: y is also given by --y0; give it once"
                ));
            }
            if init.contains_key(name) {
                return input(format!(
                    "--init {spec:?}: state {name} is given twice; give it once"
                ));
            }
            init.insert(
                name.to_string(),
                parse_interval(iv, &format!("--init {spec:?}"))?,
            );
        }
        Ok(init)
    }

    /// The built-in glider setting the flags give (`--model`, `--y0`, `--init`,
    /// `--horizon`, `--period`, clip, goal, budgets), every limit checked.
    pub fn builtin_settings(&self) -> Result<ReachSettings> {
        let a = self;
        let model = Model::from_name(&a.model).ok_or_else(|| {
            AppError::Input(format!(
                "--model {:?}: unknown model; choose one of reduced, plate6, full",
                a.model
            ))
        })?;
        let init = a.builtin_init(model)?;
        let s = ReachRequest {
            model: a.model.clone(),
            init,
            horizon: a.horizon,
            period: a.period,
            goal_ystar: a.goal_ystar,
            goal_from: a.goal_from,
            clip: !a.no_clip,
            max_leaves: a.max_leaves,
            samples: a.samples,
            seed: None,
        }
        .settings(Front::Cli)?;
        check_threads(a.threads)?;
        // Sampled trajectories are recorded every 0.05 (or the finest step above that
        // which divides the period).
        let q = a.period / 0.05;
        let per_period = if (q - q.round()).abs() <= 1e-9 * q.max(1.0) && q.round() >= 1.0 {
            q.round()
        } else {
            q.ceil().max(1.0)
        };
        let points = s.samples as f64 * (a.horizon / a.period).round() * per_period;
        if points > MAX_SAMPLE_POINTS {
            return input(format!(
                "--samples {} with --horizon {}: {points:e} sampled points (one about every 0.05 time units per trajectory); at most {MAX_SAMPLE_POINTS:e} are kept in memory: pass fewer --samples or a shorter --horizon",
                s.samples,
                a.horizon
            ));
        }
        Ok(s)
    }

    /// `--max-leaves`, `--samples` and `--threads`, checked the same way for both paths
    /// (the built-in glider and system files; `check_budget`, as
    /// Python's calls); `default_leaves` is the path's sub-box budget, named in the
    /// messages.
    pub fn check_budget(&self, default_leaves: usize) -> Result<()> {
        check_budget(Front::Cli, self.max_leaves, self.samples, default_leaves)?;
        check_threads(self.threads)
    }

    /// `--order`, `--timeout`, `--network-error`, `--lift-at` and `--lifted-weight` do
    /// not apply to zonotope sets.
    pub fn check_zonotope_flags(&self) -> Result<()> {
        if self.order.is_some() {
            return input("--order applies to Taylor-model sets (--sets taylor or --system); the zonotope sets have no order");
        }
        if self.timeout.is_some() {
            return input("--timeout applies to Taylor-model sets (--sets taylor or --system); bound the zonotope run with --max-leaves");
        }
        if self.network_error.is_some() {
            return input("--network-error applies to Taylor-model sets (--sets taylor or --system); the zonotope sets keep the network's error as generators already");
        }
        if self.lift_at.is_some() {
            return input("--lift-at applies to Taylor-model sets (--sets taylor or --system); the zonotope sets have no lifted remainders");
        }
        if self.lifted_weight.is_some() {
            return input("--lifted-weight applies to Taylor-model sets (--sets taylor or --system); the zonotope sets have no lifted parameters");
        }
        if self.time_order.is_some() || self.step_tol.is_some() {
            return input("--time-order and --step-tol apply to Taylor-model sets (--sets taylor or --system); the zonotope flow has its own step control");
        }
        Ok(())
    }

    /// Flags of the built-in glider setting that do not apply to a system file (which
    /// states its own initial set, period, horizon, clip and goals), and `--sets`.
    pub fn check_system_flags(&self) -> Result<()> {
        let a = self;
        let given: Vec<&str> = [
            (a.y0.is_some(), "--y0"),
            (!a.init.is_empty(), "--init"),
            (a.goal_ystar.is_some(), "--goal-ystar"),
            (a.goal_from.is_some(), "--goal-from"),
            (a.no_clip, "--no-clip"),
            (a.model != "reduced", "--model"),
        ]
        .iter()
        .filter(|(on, _)| *on)
        .map(|(_, n)| *n)
        .collect();
        if !given.is_empty() {
            return input(format!(
                "{} do(es) not apply with --system: the system file states its model, initial set (`init`), goals (`goal`), clip and period; edit the file",
                given.join(", ")
            ));
        }
        if a.sets != "zonotope" {
            return input(
                "--sets does not apply with --system: system files always use Taylor-model sets",
            );
        }
        Ok(())
    }

    /// The built-in glider's tuning on Taylor-model sets, for the flags left out
    /// (docs/reach.md): adaptive runs take the six-state covering run's order 4,
    /// `symbolic:40` and lifted weight 2; other runs order 2 with `symbolic:7` (which
    /// proves the full model's published setting in 46 s where the automatic ladder
    /// times out); both lift the flow's remainders at [`GLIDER_LIFT_AT`] (2-4x tighter
    /// multi-state sets).
    pub fn glider_tuned(&self) -> ReachArgs {
        let mut t = self.clone();
        if self.order.is_none() && self.network_error.is_none() {
            if self.target_ratio.is_some() {
                t.order = Some(4);
                t.network_error = Some("symbolic:40".into());
                t.lifted_weight = self.lifted_weight.or(Some(2));
            } else {
                t.order = Some(2);
                t.network_error = Some("symbolic:7".into());
            }
        }
        t.lift_at = self.lift_at.or(Some(GLIDER_LIFT_AT));
        if self.target_ratio.is_some() {
            t.time_order = self.time_order.or(Some(GLIDER_TIME_ORDER as i64));
            t.step_tol = self.step_tol.or(Some(GLIDER_STEP_TOL));
            if self.order.is_none() && self.network_error.is_none() {
                t.grid = self.glider_start_grid();
            }
        }
        t
    }

    /// The starting grid of a built-in glider adaptive run without `--grid`: each state
    /// of the reduced model cut into the fewest equal pieces no wider than
    /// [`GLIDER_CELL`]. Empty (a whole-set start, as before) with `--grid` or `--shard`
    /// (whose cells the flags name), on another model, when no state but y needs a cut, when
    /// the grid would have more cells than `--max-leaves` (default 256) allows, or when
    /// an interval does not parse (the run's own check then says why).
    fn glider_start_grid(&self) -> Vec<String> {
        if !self.grid.is_empty() || self.shard.is_some() || self.model != "reduced" {
            return self.grid.clone();
        }
        let Some(model) = Model::from_name(&self.model) else {
            return Vec::new();
        };
        let Ok(init) = self.builtin_init(model) else {
            return Vec::new();
        };
        let width = |name: &str| match init.get(name) {
            Some((a, b)) => b - a,
            None if name == "y" => Y0_DEFAULT.1 - Y0_DEFAULT.0,
            None => 0.0,
        };
        let mut grid = Vec::new();
        let mut cells = 1usize;
        for (name, size) in GLIDER_CELL {
            let w = width(name);
            // The fewest pieces no wider than `size` (a hair of slack so that a width of
            // exactly K cells gives K).
            let k = (w / size - 1e-9).ceil().max(1.0);
            if k > 1.0 {
                let k = k.min(1e6) as usize;
                cells = cells.saturating_mul(k);
                grid.push(format!("{name}={k}"));
            }
        }
        let budget = self
            .max_leaves
            .unwrap_or(SystemReachSettings::default().max_boxes);
        // Only sets wide in the glider's velocity or rotation (the six-state set's kind,
        // where the cells were measured): a set wide in y alone (the published setting)
        // keeps its whole-set start.
        let rotational = grid.iter().any(|g| !g.starts_with("y="));
        if cells > budget || !rotational {
            return Vec::new();
        }
        grid
    }

    /// The Taylor-model settings the flags give (`--order`, `--timeout`,
    /// `--network-error`, `--lift-at`, `--lifted-weight`), checked; `--sets auto` checks
    /// them before its zonotope run.
    pub fn taylor_settings(&self) -> Result<SystemReachSettings> {
        let a = self;
        let mut s = SystemReachSettings::default();
        if let Some(k) = a.order {
            check_order(Front::Cli, k)?;
            s.order = k;
        }
        if let Some(t) = a.timeout {
            // Checked: finite and positive, so it is a limit.
            s.timeout = check_reach_timeout(Front::Cli, t)?;
        }
        if let Some(v) = a.lift_at {
            check_lift_at(Front::Cli, v)?;
            s.flow.lift_at = v;
        }
        if let Some(v) = &a.network_error {
            s.network_error = NetworkError::parse(v)
                .map_err(|e| AppError::Input(format!("--network-error {v:?}: {e}")))?;
            // Symbolic remainders go with order 3 unless --order says otherwise (as in
            // the automatic choice, samara_reach::system::NETWORK_ERROR_LADDER).
            if a.order.is_none() && matches!(s.network_error, Some(NetworkError::Symbolic { .. })) {
                s.order = 3;
            }
        }
        if let Some(v) = a.lifted_weight {
            check_lifted_weight(Front::Cli, v, s.order)?;
            s.flow.lifted_weight = v as u32;
        }
        if let Some(v) = a.time_order {
            s.flow.time_order = check_time_order(Front::Cli, v)?;
        }
        if let Some(v) = a.step_tol {
            check_step_tol(Front::Cli, v)?;
            set_step_tol(&mut s.flow, v);
        }
        Ok(s)
    }

    /// The Taylor-model settings of a run on a checked system: [`Self::taylor_settings`]
    /// with the system's `measures`, the budgets checked and applied.
    pub fn system_settings(
        &self,
        measures: Vec<samara_reach::system::Measure>,
    ) -> Result<SystemReachSettings> {
        let mut s = self.taylor_settings()?;
        s.measures = measures;
        self.check_budget(s.max_boxes)?;
        if let Some(n) = self.max_leaves {
            s.max_boxes = n;
        }
        if let Some(n) = self.samples {
            s.samples = n;
        }
        Ok(s)
    }

    /// `--grid NAME=K ...` as pieces per state (`None` without the flag), checked
    /// against the system's states and initial set.
    pub fn grid_pieces(&self, sys: &samara_system::System) -> Result<Option<Vec<usize>>> {
        if self.grid.is_empty() {
            return Ok(None);
        }
        let mut pieces = vec![1usize; sys.dim()];
        let mut seen = vec![false; sys.dim()];
        for g in &self.grid {
            let (name, k) = g.split_once('=').ok_or_else(|| {
                AppError::Input(format!("--grid {g:?}: expected NAME=K, a state and its number of pieces (e.g. --grid theta=3)"))
            })?;
            let i = sys
                .states
                .iter()
                .position(|n| n == name.trim())
                .ok_or_else(|| {
                    AppError::Input(format!(
                        "--grid {g:?}: no state `{}`; the states are {}",
                        name.trim(),
                        sys.states.join(", ")
                    ))
                })?;
            let k: usize = k.trim().parse().ok().filter(|k| *k >= 1).ok_or_else(|| {
                AppError::Input(format!(
                    "--grid {g:?}: K must be a whole number of pieces, at least 1"
                ))
            })?;
            if seen[i] {
                return input(format!(
                    "--grid {g:?}: state `{}` is cut twice; give each state once",
                    sys.states[i]
                ));
            }
            seen[i] = true;
            pieces[i] = k;
        }
        samara_reach::grid::cell_count(sys, &pieces)
            .map_err(|e| AppError::Input(format!("--grid: {e}")))?;
        Ok(Some(pieces))
    }

    /// `--target-ratio R` with what an adaptive run needs: R in [1, [`MAX_RATIO`]], no
    /// `--shard`, a measure at the horizon (`system` names the system file).
    pub fn check_adaptive(&self, ratio: f64, has_measure: bool, system: &Path) -> Result<()> {
        if !(ratio.is_finite() && (1.0..=MAX_RATIO).contains(&ratio)) {
            return input(format!("--target-ratio {ratio}: give a number from 1 to {MAX_RATIO:e}: the enclosure's width over the flights' spread, which is never below 1 (2 is issue 14's criterion)"));
        }
        if self.shard.is_some() && self.grid.is_empty() {
            return input("--shard with --target-ratio needs --grid NAME=K: the shards divide the grid's starting cells (cell c to shard c mod N), e.g. --grid theta=3 --grid y=8; the one-process run with the same --grid gives the same result");
        }
        if !has_measure {
            return input(format!("--target-ratio needs a measure at the horizon: {} has no `goal band |...| <= ... at end`; add one (its expression is what the target measures)", system.display()));
        }
        Ok(())
    }
}

/// Refuse a network that does not fit a system file: `label` names the network
/// (`--network FILE`, or Python's `network`), `system` the system file, in the message.
/// The one check of `samara reach --system`, `samara simulate --system` and Python's
/// `samara.reach_system`.
pub fn check_fits(
    label: &str,
    net: &samara_nn::Network,
    sys: &samara_system::System,
    system: &str,
) -> Result<()> {
    if !sys.fits_controller(net.n_inputs(), net.n_outputs()) {
        return input(format!(
            "{label} has {} inputs and {} outputs; {system} observes {} values and reads {} network outputs: use the controller made for this system",
            net.n_inputs(),
            net.n_outputs(),
            sys.n_observed(),
            sys.n_net_outputs
        ));
    }
    Ok(())
}

/// The built-in glider setting (`--model`, `--y0`, `--init`, `--period`, `--horizon`,
/// clip, goal) as a system: the shipped `examples/archcomp/alsomitra_<model>.sys`
/// (embedded; bit-identical to the built-in right-hand sides, see docs/system.md) with
/// its period, horizon, actuation, initial set and goal lines replaced by the flags'.
pub fn builtin_system(s: &ReachSettings) -> Result<samara_system::System> {
    let (file, text) = match s.model {
        Model::Reduced => (
            "alsomitra_reduced.sys",
            include_str!("../../../../examples/archcomp/alsomitra_reduced.sys"),
        ),
        Model::Plate6 => (
            "alsomitra_plate6.sys",
            include_str!("../../../../examples/archcomp/alsomitra_plate6.sys"),
        ),
        Model::Full => (
            "alsomitra_full.sys",
            include_str!("../../../../examples/archcomp/alsomitra_full.sys"),
        ),
    };
    let replaced = ["period", "horizon", "actuate", "init", "goal", "reset"];
    let mut src: String = text
        .lines()
        .filter(|l| {
            let w = l.split_whitespace().next().unwrap_or("");
            !replaced.contains(&w)
        })
        .map(|l| format!("{l}\n"))
        .collect();
    let names = ["v_xp", "v_yp", "omega", "theta", "x", "y", "E"];
    src.push_str(&format!("period {:?}\nhorizon {:?}\n", s.period, s.horizon));
    match s.clip {
        Some((lo, hi)) => src.push_str(&format!("actuate ex = net[0] clip [{lo:?}, {hi:?}]\n")),
        None => src.push_str("actuate ex = net[0]\n"),
    }
    if s.init.len() == 7 && s.reset_filter {
        src.push_str("reset E = 0\n");
    }
    for (n, (lo, hi)) in names.iter().zip(&s.init) {
        if lo == hi {
            src.push_str(&format!("init {n} = {lo:?}\n"));
        } else {
            src.push_str(&format!("init {n} in [{lo:?}, {hi:?}]\n"));
        }
    }
    if let Some(g) = &s.goal {
        match g.from {
            None => src.push_str(&format!("goal band |x + y| <= {:?} at end\n", g.ystar)),
            Some(f) => src.push_str(&format!(
                "goal band |x + y| <= {:?} always [{f:?}, {:?}]\n",
                g.ystar, s.horizon
            )),
        }
    }
    samara_system::System::parse(&src, &format!("{file} (built-in setting)"))
        .map_err(|e| AppError::Input(format!("the built-in setting as a system file: {e}")))
}

/// The published setting's measure on a system: x + y (its width against the
/// flights').
pub fn x_plus_y(sys: &samara_system::System) -> samara_reach::system::Measure {
    let mut coef = vec![0.0; sys.dim()];
    for (i, n) in sys.states.iter().enumerate() {
        if n == "x" || n == "y" {
            coef[i] = 1.0;
        }
    }
    samara_reach::system::Measure {
        name: "x + y".into(),
        coef,
        offset: 0.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        a: ReachArgs,
    }

    fn args(flags: &[&str]) -> ReachArgs {
        let mut v = vec!["reach", "--network", "n.onnx", "--out", "o"];
        v.extend_from_slice(flags);
        Cli::parse_from(v).a
    }

    #[test]
    fn the_published_setting_is_the_default() {
        let s = args(&[]).builtin_settings().unwrap();
        assert_eq!(s.init[5], (0.1 / 0.07, 0.3 / 0.07));
        assert_eq!((s.horizon, s.period), (20.0, 0.5));
    }

    #[test]
    fn each_limit_names_its_flag() {
        for (flags, start) in [
            (
                &["--period", "11"][..],
                "--period 11: reach takes periods up to 10",
            ),
            (
                &["--horizon", "20.3"],
                "--horizon 20.3 is not a positive multiple",
            ),
            (&["--goal-from", "1"], "--goal-from 1: needs a goal"),
            (&["--max-leaves", "0"], "--max-leaves 0: give at least 1"),
            (&["--threads", "0"], "--threads 0: give at least 1"),
            (&["--y0", "3:2"], "--y0 \"3:2\": the interval is empty"),
            (
                &["--init", "E=0"],
                "--init \"E=0\": unknown state \"E\" (model reduced",
            ),
        ] {
            let e = args(flags).builtin_settings().unwrap_err().to_string();
            assert!(e.starts_with(start), "{flags:?}: {e}");
        }
        let e = args(&["--order", "9"]).taylor_settings().unwrap_err();
        assert!(e.to_string().starts_with("--order 9: give 1 to 8"));
        let e = args(&["--order", "2"]).check_zonotope_flags().unwrap_err();
        assert!(e
            .to_string()
            .starts_with("--order applies to Taylor-model sets"));
        for (flags, start) in [
            (&["--time-order", "9"][..], "--time-order 9: give 1 to 8"),
            (&["--time-order", "0"], "--time-order 0: give 1 to 8"),
            (&["--step-tol", "0"], "--step-tol 0: give a share"),
            (&["--step-tol", "0.5"], "--step-tol 0.5: give a share"),
            (&["--step-tol", "NaN"], "--step-tol NaN: give a share"),
        ] {
            let e = args(flags).taylor_settings().unwrap_err().to_string();
            assert!(e.starts_with(start), "{flags:?}: {e}");
        }
        let s = args(&["--time-order", "8", "--step-tol", "1e-5"])
            .taylor_settings()
            .unwrap();
        assert_eq!(
            (s.flow.time_order, s.flow.rem_rel, s.flow.rem_tol),
            (8, 1e-5, 1e-5 * 1e-2)
        );
        let e = args(&["--step-tol", "1e-5"])
            .check_zonotope_flags()
            .unwrap_err();
        assert!(e
            .to_string()
            .starts_with("--time-order and --step-tol apply"));
    }

    #[test]
    fn the_glider_tuning_fills_only_what_is_left_out() {
        let t = args(&[]).glider_tuned();
        assert_eq!(
            (t.order, t.network_error.as_deref()),
            (Some(2), Some("symbolic:7"))
        );
        assert_eq!(t.lift_at, Some(GLIDER_LIFT_AT));
        assert_eq!((t.time_order, t.step_tol), (None, None));
        let t = args(&["--target-ratio", "2"]).glider_tuned();
        assert_eq!((t.order, t.lifted_weight), (Some(4), Some(2)));
        assert_eq!(
            (t.time_order, t.step_tol),
            (Some(GLIDER_TIME_ORDER as i64), Some(GLIDER_STEP_TOL))
        );
        assert!(t.grid.is_empty(), "{:?}", t.grid);
        let t = args(&["--target-ratio", "2", "--time-order", "6"]).glider_tuned();
        assert_eq!((t.time_order, t.step_tol), (Some(6), Some(GLIDER_STEP_TOL)));
        let six = [
            "--target-ratio",
            "2",
            "--init",
            "v_xp=0.99:1.01",
            "--init",
            "v_yp=-0.01:0.01",
            "--init",
            "omega=-0.01:0.01",
            "--init",
            "theta=-0.01:0.01",
            "--init",
            "x=-0.05:0.05",
        ];
        let t = args(&[&six[..], &["--max-leaves", "4096"]].concat()).glider_tuned();
        assert_eq!(
            t.grid,
            ["v_xp=3", "v_yp=3", "omega=3", "theta=6", "y=4"].map(String::from)
        );
        // Past the budget (default 256 cells), with a grid or shard of its own, with
        // settings of its own: no default grid.
        assert!(args(&six).glider_tuned().grid.is_empty());
        let t = args(&[&six[..], &["--max-leaves", "4096", "--grid", "theta=2"]].concat())
            .glider_tuned();
        assert_eq!(t.grid, ["theta=2"]);
        let t =
            args(&[&six[..], &["--max-leaves", "4096", "--order", "3"]].concat()).glider_tuned();
        assert!(t.grid.is_empty());
        // A narrower set: fewer pieces, none where a state fits one cell.
        let t = args(&[
            "--target-ratio",
            "2",
            "--init",
            "theta=-0.004:0.004",
            "--y0",
            "2.0:2.5",
        ])
        .glider_tuned();
        assert_eq!(t.grid, ["theta=3"]);
        let t = args(&["--order", "3", "--lift-at", "0.05"]).glider_tuned();
        assert_eq!(
            (t.order, t.network_error, t.lift_at),
            (Some(3), None, Some(0.05))
        );
    }
}

/// Longest control period `samara.reach` takes (the validated integrator takes at
/// most 400 steps of at most 0.0625 per period).
pub const REACH_MAX_PERIOD: f64 = MAX_PERIOD;
/// Most control periods of a `samara.reach` run.
pub const REACH_MAX_PERIODS: f64 = MAX_PERIODS;
/// Most sub-boxes, and most sampled flights, of a reach run.
pub const REACH_MAX_COUNT: usize = MAX_LEAVES;

/// The arguments of a zonotope reach run of the glider (`samara.reach`).
#[derive(Clone, Debug, Default)]
pub struct ReachRequest {
    /// `reduced`, `plate6` or `full`.
    pub model: String,
    /// Initial intervals by state name (the others: the published initial set).
    pub init: BTreeMap<String, (f64, f64)>,
    /// Horizon.
    pub horizon: f64,
    /// Control period.
    pub period: f64,
    /// The goal band's half-width, if there is a goal.
    pub goal_ystar: Option<f64>,
    /// Start of the goal's window (needs `goal_ystar`).
    pub goal_from: Option<f64>,
    /// Whether the controller's output is clipped to the actuator's range.
    pub clip: bool,
    /// Sub-box budget (default 64).
    pub max_leaves: Option<usize>,
    /// Sampled flights (default 200).
    pub samples: Option<usize>,
    /// Sampling seed.
    pub seed: Option<u64>,
}

impl ReachRequest {
    /// The run's settings, every argument checked; the messages name the arguments in
    /// `front`'s words.
    pub fn settings(&self, front: Front) -> Result<ReachSettings> {
        let Some(m) = Model::from_name(&self.model) else {
            return input(format!(
                "{} {:?}: unknown model; choose one of reduced, plate6, full",
                front.arg("model"),
                self.model
            ));
        };
        let mut s = ReachSettings::published(m);
        s.init[5] = Y0_DEFAULT;
        let names = &STATE_NAMES[..m.dim()];
        for (k, &(lo, hi)) in &self.init {
            let Some(i) = names.iter().position(|n| n == k) else {
                return input(format!(
                    "{}[{k:?}]: unknown state; choose one of {}",
                    front.arg("init"),
                    names.join(", ")
                ));
            };
            if !(lo.is_finite() && hi.is_finite() && lo <= hi && lo >= -1000.0 && hi <= 1000.0) {
                return input(format!(
                    "{}[{k:?}] = ({lo}, {hi}): give finite ends lo <= hi in [-1000, 1000]",
                    front.arg("init")
                ));
            }
            s.init[i] = (lo, hi);
        }
        let (h, p) = (self.horizon, self.period);
        let (hf, pf) = (front.arg("horizon"), front.arg("period"));
        check_horizon_period(front, h, p)?;
        if p > REACH_MAX_PERIOD {
            return input(format!("{pf} {p}: reach takes periods up to {REACH_MAX_PERIOD} (the validated integrator takes at most 400 steps of at most 0.0625 per period, so a longer hold cannot be enclosed); e.g. {}", front.eg("period", "0.5")));
        }
        check_period_count(front, h, p, REACH_MAX_PERIODS)?;
        let k = h / p;
        if (k - k.round()).abs() > 1e-9 * k.max(1.0) || k.round() < 1.0 {
            let n = k.floor().max(1.0);
            return input(format!(
                "{hf} {h} is not a positive multiple of {pf} {p}: choose e.g. {} (or another period)",
                front.eg("horizon", &(n * p).to_string())
            ));
        }
        s.horizon = h;
        s.period = p;
        if !self.clip {
            s.clip = None;
        }
        let (yf, ff) = (front.arg("goal_ystar"), front.arg("goal_from"));
        match (self.goal_ystar, self.goal_from) {
            (None, Some(f)) => {
                return input(format!(
                    "{ff} {}: needs a goal; add {} (e.g. {})",
                    num(f),
                    front.eg("goal_ystar", "Y"),
                    front.eg("goal_ystar", "2")
                ))
            }
            (Some(y), from) => {
                if !(y.is_finite() && y >= 0.0) {
                    return input(format!(
                        "{yf} {}: the band half-width must be a finite number >= 0 (e.g. {})",
                        num(y),
                        front.eg("goal_ystar", "2")
                    ));
                }
                if let Some(f) = from {
                    if !(f.is_finite() && f >= 0.0 && f <= h) {
                        return input(format!(
                            "{ff} {}: the window start must lie in [0, horizon = {h}]",
                            num(f)
                        ));
                    }
                }
                s.goal = Some(Goal { ystar: y, from });
            }
            (None, None) => {}
        }
        check_budget(front, self.max_leaves, self.samples, s.max_leaves)?;
        if let Some(n) = self.max_leaves {
            s.max_leaves = n;
        }
        if let Some(n) = self.samples {
            s.samples = n;
        }
        if let Some(v) = self.seed {
            s.seed = v;
        }
        Ok(s)
    }
}

/// The sub-box budget and the sampled flights of a reach run: at least 1 and at most
/// [`REACH_MAX_COUNT`] each (`default_leaves`, the run's default budget, is named in the
/// messages).
pub fn check_budget(
    front: Front,
    max_leaves: Option<usize>,
    samples: Option<usize>,
    default_leaves: usize,
) -> Result<()> {
    let (lf, sf) = (front.arg("max_leaves"), front.arg("samples"));
    if let Some(n) = max_leaves {
        if n == 0 {
            return input(format!(
                "{lf} 0: give at least 1 (default {default_leaves})"
            ));
        }
        if n > REACH_MAX_COUNT {
            return input(format!("{lf} {n}: at most {REACH_MAX_COUNT} sub-boxes are allowed (each is a full reachability run; the default is {default_leaves})"));
        }
    }
    if let Some(n) = samples {
        if n == 0 {
            return input(format!(
                "{sf} 0: give at least 1 (default 200); falsification needs trajectories"
            ));
        }
        if n > REACH_MAX_COUNT {
            return input(format!("{sf} {n}: at most {REACH_MAX_COUNT} trajectories are allowed (each is kept in memory; the default is 200)"));
        }
    }
    Ok(())
}

/// A Taylor-model order (`--order`, `order=`): 1 to 8.
pub fn check_order(front: Front, k: usize) -> Result<()> {
    if !(1..=8).contains(&k) {
        return input(format!(
            "{} {k}: give 1 to 8 (3-5 is usual; higher orders cost more per step)",
            front.arg("order")
        ));
    }
    Ok(())
}

/// The share of a state's width at which the flow's remainders become parameters
/// (`--lift-at`, `lift_at=`): in (0, 1].
pub fn check_lift_at(front: Front, v: f64) -> Result<()> {
    if !(v.is_finite() && v > 0.0 && v <= 1.0) {
        return input(format!(
            "{} {v}: give a share of the width in (0, 1], such as 0.05 or 0.001",
            front.arg("lift_at")
        ));
    }
    Ok(())
}

/// The weight of a lifted parameter toward the order (`--lifted-weight`,
/// `lifted_weight=`): 1 to the order.
pub fn check_lifted_weight(front: Front, v: i64, order: usize) -> Result<()> {
    if !(1..=order as i64).contains(&v) {
        return input(format!(
            "{} {v}: give 1 to the order ({order}): 1 weighs lifted parameters as initial ones, the order makes them linear",
            front.arg("lifted_weight")
        ));
    }
    Ok(())
}

/// The flow's order in time (`--time-order`): 1 to 8.
pub fn check_time_order(front: Front, v: i64) -> Result<usize> {
    if !(1..=8).contains(&v) {
        return input(format!(
            "{} {v}: give 1 to 8 (default 6): the order in time of each flow step",
            front.arg("time_order")
        ));
    }
    Ok(v as usize)
}

/// The flow's step tolerance (`--step-tol`): a share of the set's width in (0, 0.01].
pub fn check_step_tol(front: Front, v: f64) -> Result<()> {
    if !(v.is_finite() && v > 0.0 && v <= 1e-2) {
        return input(format!(
            "{} {v}: give a share of the set's width in (0, 0.01], such as 1e-7 (default) or 1e-5",
            front.arg("step_tol")
        ));
    }
    Ok(())
}

/// Sets the flow's step tolerance to `rel` of the set's width, with an absolute floor
/// a hundredth of it (the defaults' ratio, 1e-7 and 1e-9).
pub fn set_step_tol(flow: &mut samara_reach::tmflow::TmFlowSettings, rel: f64) {
    flow.rem_rel = rel;
    flow.rem_tol = rel * 1e-2;
}

/// A Taylor-model run's time limit (`--timeout`, `timeout=`): positive seconds, at most
/// 1e7.
pub fn check_reach_timeout(front: Front, t: f64) -> Result<samara_num::Timeout> {
    if !(t.is_finite() && t > 0.0 && t <= 1e7) {
        return input(format!(
            "{} {t}: give a number of seconds, positive and at most 1e7",
            front.arg("timeout")
        ));
    }
    samara_num::Timeout::from_secs_f64(t).map_err(|e| AppError::Input(e.to_string()))
}

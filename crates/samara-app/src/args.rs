//! The flags of samara's commands as typed settings ([`VerifyArgs`], [`TrainArgs`],
//! [`SimulateArgs`], ...), deriving `clap::Args` (the command line parses them; their
//! doc comments are its help text) and `Serialize`, with the checks of their values
//! ([`RobustnessArgs::validate`], [`TrainArgs::validate`], ...). The CLI wires them into
//! subcommands, calls the library and prints; the limits live here. The reach flags are
//! [`crate::reach::args::ReachArgs`].

use crate::shard::{parse_shard, Shard};
use crate::{input, AppError};
use samara_verify::robustness::Reference;
use serde::Serialize;
use std::path::PathBuf;

/// The `--threads` flag, flattened into a command's flags.
#[derive(clap::Args, Debug, Clone, Copy, Default, Serialize)]
pub struct ThreadsArg {
    /// Worker threads, 1 to 1024 (default: all cores); the verdicts do not depend on it
    #[arg(long)]
    pub threads: Option<usize>,
}

/// Flags shared by the spec commands.
#[derive(clap::Args, Debug, Clone, Serialize)]
pub struct SpecArgs {
    /// The specification file.
    pub spec: PathBuf,
    /// Bind a network name to an ONNX file (repeatable): --network f=net.onnx.
    #[arg(long = "network", value_name = "NAME=FILE")]
    pub networks: Vec<String>,
    /// Bind a parameter (repeatable): --param ystar=2.
    #[arg(long = "param", value_name = "NAME=VALUE")]
    pub params: Vec<String>,
    /// Bind a data set (repeatable): --dataset train=data.csv. Only the properties that
    /// quantify over a data set (`for p in data NAME`) need it; without this flag the
    /// spec's `dataset` path is used, relative to the spec file. The published training
    /// points are `../shared/reference/Training_Data_Normalised.csv`.
    #[arg(long = "dataset", value_name = "NAME=FILE")]
    pub datasets: Vec<String>,
}

/// Flags of `samara check`.
#[derive(clap::Args, Debug, Serialize)]
pub struct CheckArgs {
    #[command(flatten)]
    /// Spec and bindings.
    pub s: SpecArgs,
}

/// The search flags of `samara verify` and `samara critical`.
#[derive(clap::Args, Debug, Clone, Copy, Serialize)]
pub struct SearchFlags {
    /// Node limit per search (branch-and-bound nodes per disjunct); a search that reaches
    /// it is `unknown` (node_limit).
    #[arg(long, default_value_t = 200_000)]
    pub max_nodes: usize,
    /// JSON output.
    #[arg(long)]
    pub json: bool,
}

/// Flags of `samara verify`.
#[derive(clap::Args, Debug, Serialize)]
pub struct VerifyArgs {
    #[command(flatten)]
    /// Worker threads.
    pub threads: ThreadsArg,
    #[command(flatten)]
    /// Spec and bindings.
    pub s: SpecArgs,
    /// Only this property (default: all).
    #[arg(long)]
    pub property: Option<String>,
    /// Time limit of the whole command in seconds (>= 0; `inf` for none): every query
    /// gets what is left of it. A query cut short is `unknown` with its reason, never
    /// proved or violated.
    #[arg(long, default_value_t = 60.0)]
    pub timeout: f64,
    #[command(flatten)]
    /// Search settings and output.
    pub search: SearchFlags,
}

/// Flags of `samara critical`.
#[derive(clap::Args, Debug, Serialize)]
pub struct CriticalArgs {
    #[command(flatten)]
    /// Worker threads.
    pub threads: ThreadsArg,
    #[command(flatten)]
    /// Spec and bindings; `--param NAME` without a value names the parameter whose
    /// critical value is computed (it must be declared with a range).
    pub s: SpecArgs,
    /// The property.
    #[arg(long)]
    pub property: String,
    /// Time limit of the whole command in seconds (>= 0; `inf` for none), shared by its
    /// two searches (the supremum's, then the infimum's). A search cut short reports
    /// `unknown` with its reason (exit 1), never a critical value.
    #[arg(long, default_value_t = 60.0)]
    pub timeout: f64,
    #[command(flatten)]
    /// Search settings and output.
    pub search: SearchFlags,
}

/// Flags of `samara robustness`.
#[derive(clap::Args, Debug, Serialize)]
pub struct RobustnessArgs {
    #[command(flatten)]
    /// Worker threads.
    pub threads: ThreadsArg,
    /// The network (ONNX). Data and eps are in the units the network takes.
    #[arg(long)]
    pub network: PathBuf,
    /// Data set (CSV or IDX): inputs, then the label.
    #[arg(long)]
    pub data: PathBuf,
    /// Radii (comma-separated; each positive, finite and at most 1e6; repeated values
    /// count once).
    #[arg(long, default_value = "1e-5,1e-4,1e-3,1e-2")]
    pub eps: String,
    /// Bounds L (comma-separated; each finite and >= 0; repeated values count once).
    #[arg(long, default_value = "1e-5,1e-4,1e-3,1e-2")]
    pub lipschitz: String,
    /// Reference of the published form: label or network.
    #[arg(long, default_value = "label")]
    pub reference: String,
    /// published (|f(x') - ref| <= L / eps) or lipschitz (|f(x') - f(x)| <= L ||x' - x||).
    #[arg(long, default_value = "published")]
    pub form: String,
    /// Time limit of the whole command in seconds (>= 0; `inf` for none): every point's
    /// search stops at it; a point whose search is cut short counts as unknown unless
    /// its bounds already settle it.
    #[arg(long, default_value_t = 30.0)]
    pub timeout: f64,
    /// Node limit of each point's search; a point whose search reaches it counts as
    /// unknown unless its bounds already settle it.
    #[arg(long, default_value_t = 200_000)]
    pub max_nodes: usize,
    /// Per-point results CSV (refused if it is the --data or --network file). With
    /// --shard: this shard's partial result (JSON, for `samara merge robustness`).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// JSON output.
    #[arg(long)]
    pub json: bool,
    /// Compute only shard I of N (0-based): the data set's points split into N
    /// contiguous parts. Needs --out; `samara merge robustness` puts the N files together.
    #[arg(long, value_name = "I/N", allow_hyphen_values = true, value_parser = parse_shard)]
    pub shard: Option<Shard>,
}

/// Flags of `samara verify-vnnlib`.
#[derive(clap::Args, Debug, Serialize)]
pub struct VerifyVnnlibArgs {
    #[command(flatten)]
    /// Worker threads.
    pub threads: ThreadsArg,
    /// The network (ONNX).
    #[arg(long)]
    pub network: PathBuf,
    /// The property (VNN-LIB 1.0): a satisfying point is a counterexample.
    #[arg(long)]
    pub property: PathBuf,
    /// Time limit in seconds (>= 0; `inf` for none).
    #[arg(long, default_value_t = 60.0)]
    pub timeout: f64,
    /// Node limit per search (branch-and-bound nodes per disjunct); a search that reaches
    /// it is `unknown` (node_limit).
    #[arg(long, default_value_t = 200_000)]
    pub max_nodes: usize,
    /// Also write the verdict to FILE in the competition's result format (atomically):
    /// `unsat`, `timeout`, `unknown`, or `sat` followed by the counterexample
    /// `((X_0 v)` ... ` (Y_m v))`, one variable per line, outputs by the network's own f64
    /// evaluator.
    #[arg(long, value_name = "FILE")]
    pub result: Option<PathBuf>,
    /// JSON output.
    #[arg(long)]
    pub json: bool,
}

/// Flags of `samara export-vnnlib`.
#[derive(clap::Args, Debug, Serialize)]
pub struct ExportArgs {
    #[command(flatten)]
    /// Spec and bindings.
    pub s: SpecArgs,
    /// Output directory (one .vnnlib per property instance). It must be empty or not
    /// exist yet: a folder that holds files is refused (old and new files would mix);
    /// a folder this run created is removed again if the export fails.
    #[arg(long)]
    pub out: PathBuf,
    /// One file per disjunct of the counterexample region (for tools that cannot read `or`).
    #[arg(long)]
    pub split_disjuncts: bool,
    /// Only this property (default: all). The command exits 1 if any instance of the
    /// selected properties could not be written.
    #[arg(long)]
    pub property: Option<String>,
}

/// Flags of `samara train`. Defaults are the published setting (6-6-4-1, ReLU on every
/// layer, Adam lr 0.06, batch 50, 1000 epochs, 10% test split).
#[derive(clap::Args, Debug, Serialize)]
pub struct TrainArgs {
    /// Data set (CSV with or without header, or IDX): input columns then the output.
    #[arg(long)]
    pub data: PathBuf,
    /// Min-max constants file (row 1 minimum, row 2 range, like Normalisation_Constants.csv);
    /// computed from the data when absent.
    #[arg(long)]
    pub normalisation: Option<PathBuf>,
    /// plain | adversarial | lipschitz | dl2 | goedel | closed-loop (the goal
    /// |x + y| <= --goal-ystar at t = 20 of the reduced model's sample-and-hold loop,
    /// trained through the loop and checked by reach in counterexample-guided rounds;
    /// docs/training.md).
    #[arg(long, default_value = "plain")]
    pub method: String,
    /// Adversarial attack: fgsm (the published training) or pgd.
    #[arg(long, default_value = "fgsm")]
    pub attack: String,
    /// Layer widths, inputs first.
    #[arg(long, default_value = "6,6,4,1")]
    pub arch: String,
    /// Epochs.
    #[arg(long, default_value_t = 1000)]
    pub epochs: usize,
    /// Mini-batch size.
    #[arg(long, default_value_t = 50)]
    pub batch: usize,
    /// Adam learning rate.
    #[arg(long, default_value_t = 0.06)]
    pub lr: f64,
    /// Seed (same seed, same data: bit-identical network).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Attack radius in normalised input units.
    #[arg(long, default_value_t = 0.005)]
    pub eps: f64,
    /// Lipschitz constant L for `lipschitz` (normalised units).
    #[arg(long, default_value_t = 0.5)]
    pub lipschitz: f64,
    /// Weight of the Lipschitz or property term.
    #[arg(long)]
    pub weight: Option<f64>,
    /// dl2/goedel: add the Lipschitz penalty of `lipschitz` (constant --lipschitz) with
    /// this weight, as the case study's Goedel + Lipschitz and DL2 + Lipschitz networks
    #[arg(long)]
    pub lipschitz_weight: Option<f64>,
    /// No ReLU on the output layer (a linear output, as the case study's 6-64-32-1
    /// property-trained networks); the published 6-6-4-1 networks have one
    #[arg(long)]
    pub linear_output: bool,
    /// ystar of the case-study properties P1-P4 (models/alsomitra/alsomitra.spec) used
    /// by dl2/goedel without --spec.
    #[arg(long, default_value_t = 2.0)]
    pub ystar: f64,
    /// Take the dl2/goedel properties from this specification instead of the case
    /// study's (models/alsomitra/alsomitra.spec, compiled in).
    #[arg(long)]
    pub spec: Option<PathBuf>,
    /// Properties of --spec to train for (comma-separated; default: every property
    /// without data-set quantifiers).
    #[arg(long)]
    pub properties: Option<String>,
    /// Parameter bindings for --spec (repeatable): --param ystar=2.
    #[arg(long = "param", value_name = "NAME=VALUE")]
    pub params: Vec<String>,
    /// Output network (ONNX, raw units with its normalisation layers).
    #[arg(long)]
    pub out: PathBuf,
    /// Training log CSV (default: next to --out, `<stem>.log.csv`).
    #[arg(long)]
    pub log: Option<PathBuf>,
    /// Print the metrics as JSON.
    #[arg(long)]
    pub json: bool,
    /// Restarts from a fresh initialisation allowed when training gives a dead, constant
    /// or useless (training R^2 <= 0) network; restart k uses the k-th SplitMix64 output
    /// from --seed. Exit code 1 when every attempt was degenerate.
    #[arg(long, default_value_t = samara_train::DEFAULT_MAX_RESTARTS)]
    pub max_restarts: usize,
    /// Least R^2 on the training rows a finished network must reach, else training
    /// restarts (default 0.9 for plain and adversarial, whose published networks reach
    /// it; 0 for lipschitz, dl2 and goedel, which trade accuracy for their property).
    /// A network with R^2 <= 0 is always refused.
    #[arg(long)]
    pub min_r2: Option<f64>,
    /// Settings of --method closed-loop.
    #[command(flatten)]
    pub closed_loop: Box<ClosedLoopArgs>,
}

/// Flags of `samara train --method closed-loop`.
#[derive(clap::Args, Debug, Serialize)]
pub struct ClosedLoopArgs {
    /// closed-loop: the goal |x + y| <= Y at the horizon (t = 20) that reach must prove
    /// (default 2; with --spec, the goal of its loop).
    #[arg(long)]
    pub goal_ystar: Option<f64>,
    /// closed-loop with --spec: the loop to train for (default: the spec's first). Its
    /// start, period, horizon, clip and goal replace --y0, --goal-ystar and --goal-from.
    #[arg(long = "loop", value_name = "NAME", requires = "spec")]
    pub loop_name: Option<String>,
    /// closed-loop: also for every t in [T*, 20] (the goal over a window).
    #[arg(long)]
    pub goal_from: Option<f64>,
    /// closed-loop: the interval of initial y, A:B (default the published
    /// 0.1/0.07:0.3/0.07); the other states start at (1, 0, 0, 0, 0).
    #[arg(long)]
    pub y0: Option<String>,
    /// closed-loop: the flights are trained to |x + y| <= Y - margin, leaving the
    /// enclosures room.
    #[arg(long, default_value_t = 0.75)]
    pub margin: f64,
    /// closed-loop: most train-then-reach rounds.
    #[arg(long, default_value_t = 6)]
    pub rounds: usize,
    /// closed-loop: Adam steps per round (a round stops early once every flight meets
    /// the training bound).
    #[arg(long, default_value_t = 150)]
    pub steps_per_round: usize,
    /// closed-loop: Adam learning rate of the rounds (--lr is the data-only training's).
    #[arg(long, default_value_t = 0.005)]
    pub round_lr: f64,
    /// closed-loop: weight of the PID data MSE (normalised units) against the mean
    /// closed-loop penalty.
    #[arg(long, default_value_t = 100.0)]
    pub data_weight: f64,
    /// closed-loop: sub-boxes of reach in each round (the full --max-leaves is tried when
    /// this budget leaves the goal undecided, and in the last round).
    #[arg(long, default_value_t = 16)]
    pub round_leaves: usize,
    /// closed-loop: sub-boxes of the full reach.
    #[arg(long, default_value_t = 64)]
    pub max_leaves: usize,
}

/// Flags of `samara simulate`. The defaults reproduce the published protocol (plate6,
/// PID, nine starts y0 = n/0.07 for n = 0.1:0.025:0.3, ode45 clone, period 0.5,
/// horizon 20).
#[derive(clap::Args, Debug, Serialize)]
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

/// Run a VNN-COMP benchmark (its instances CSV): sat/unsat/timeout/unknown and seconds
/// per instance, a results CSV and a summary.
#[derive(clap::Args, Debug, Serialize)]
#[command(
    after_help = "Examples:\n  samara vnncomp benchmarks/acasxu/acasxu_instances.csv --out results.csv\n  samara vnncomp instances.csv --root benchmarks/acasxu --timeout-scale 0.5 --out r.csv --json\n\nExit codes: 0 the benchmark ran (its verdicts are data, in --out), 2 a usage or input error (the message names the CSV line, the file, the flag)."
)]
pub struct VnncompArgs {
    #[command(flatten)]
    /// Worker threads.
    pub threads: ThreadsArg,
    /// The benchmark's instances CSV: lines `onnx,vnnlib,timeout` (paths relative to the
    /// CSV's folder, or to --root).
    pub instances: PathBuf,
    /// Folder the CSV's paths are relative to (default: the CSV's folder).
    #[arg(long)]
    pub root: Option<PathBuf>,
    /// Results CSV (one line per instance: onnx,vnnlib,timeout,result,seconds,engine,
    /// detail); rewritten atomically after each instance.
    #[arg(long)]
    pub out: PathBuf,
    /// Multiply every instance's timeout by this (> 0). Each instance, its network's load
    /// included, ends within a second of its scaled timeout (`timeout` in its result)
    /// and the run goes on to the next.
    #[arg(long, default_value_t = 1.0)]
    pub timeout_scale: f64,
    /// Node limit per search of the exact optimiser (used for queries that are not
    /// box-shaped).
    #[arg(long, default_value_t = 200_000)]
    pub max_nodes: usize,
    /// JSON output (every instance and the summary) on stdout.
    #[arg(long)]
    pub json: bool,
    /// Run only shard I of N (0-based): the instance lines split into N contiguous
    /// parts. --out is then this shard's partial result (JSON); `samara merge vnncomp
    /// FILES --out results.csv` puts the N files together.
    #[arg(long, value_name = "I/N", allow_hyphen_values = true, value_parser = parse_shard)]
    pub shard: Option<Shard>,
}

/// Flags of `samara reproduce`: the whole case study in one command.
#[derive(clap::Args, Debug, Serialize)]
pub struct ReproduceArgs {
    /// Output directory for data, networks, tables, figures and the report.
    #[arg(long, default_value = "out/reproduce")]
    pub out: PathBuf,
    /// A smaller run that finishes in under a minute (fewer epochs and samples).
    #[arg(long)]
    pub quick: bool,
    /// A directory laid out like the published reference folder; its data and networks
    /// are analysed beside samara's own.
    #[arg(long)]
    pub published: Option<PathBuf>,
    /// The specification P1-P4 are read from: its properties drive DL2/Goedel training
    /// and the critical values of the verify stage, its network declaration gives the
    /// published networks' units and domain [default: the shipped
    /// models/alsomitra/alsomitra.spec, compiled in]. Edit a copy to move a threshold;
    /// the spec's text is part of every stage's cache key. A spec error is exit 2 with
    /// file:line:col.
    #[arg(long, value_name = "FILE")]
    pub spec: Option<PathBuf>,
    /// Recompute every stage (ignore the cache of finished stages).
    #[arg(long)]
    pub fresh: bool,
    /// Print results.json on stdout.
    #[arg(long)]
    pub json: bool,
}

/// The checked lists and choices of `samara robustness` ([`RobustnessArgs::validate`]).
#[derive(Clone, Debug, PartialEq)]
pub struct RobustnessChecked {
    /// The radii, repeats dropped.
    pub eps: Vec<f64>,
    /// The bounds L, repeats dropped.
    pub lipschitz: Vec<f64>,
    /// `--reference`.
    pub reference: Reference,
    /// Notes for the user (a repeated value counted once).
    pub notes: Vec<String>,
}

/// A comma-separated list of numbers, each checked by `ok` (whose text says what is
/// allowed), repeated values dropped (a note says so).
fn list(
    s: &str,
    flag: &str,
    ok: fn(f64) -> bool,
    allowed: &str,
    notes: &mut Vec<String>,
) -> Result<Vec<f64>, AppError> {
    let mut out: Vec<f64> = Vec::new();
    for x in s.split(',') {
        let v = x.trim().parse::<f64>().map_err(|_| {
            AppError::Input(format!("--{flag} {s:?}: {:?} is not a number; expected comma-separated numbers, e.g. --{flag} 1e-3,1e-2", x.trim()))
        })?;
        if !ok(v) {
            return input(format!(
                "--{flag} {s:?}: {} is out of range; each value must be {allowed}",
                x.trim()
            ));
        }
        if out.contains(&v) {
            notes.push(format!("note: --{flag} repeats {v:e}; it is counted once"));
            continue;
        }
        out.push(v);
    }
    Ok(out)
}

impl RobustnessArgs {
    /// `--eps` (each in (0, 1e6]), `--lipschitz` (each finite and >= 0), `--reference`
    /// and `--form`, checked.
    pub fn validate(&self) -> Result<RobustnessChecked, AppError> {
        let mut notes = Vec::new();
        use crate::robustness_form::{bound_ok, parse_form, parse_reference, radius_ok};
        let eps = list(
            &self.eps,
            "eps",
            radius_ok,
            crate::robustness_form::RADIUS_ALLOWED,
            &mut notes,
        )?;
        let lipschitz = list(
            &self.lipschitz,
            "lipschitz",
            bound_ok,
            crate::robustness_form::BOUND_ALLOWED,
            &mut notes,
        )?;
        let reference = parse_reference(crate::Front::Cli, &self.reference)?;
        parse_form(crate::Front::Cli, &self.form)?;
        Ok(RobustnessChecked {
            eps,
            lipschitz,
            reference,
            notes,
        })
    }

    /// The rows of the `--data` table, checked against a network of `n` inputs: enough
    /// columns (a label column with `--reference label`) and finite values where used.
    pub fn data_rows(
        &self,
        n: usize,
        t: &samara_nn::data::Table,
        reference: Reference,
    ) -> Result<Vec<Vec<f64>>, AppError> {
        let data = self.data.display();
        if t.cols < n {
            return input(format!(
                "--data {data}: {} columns but the network has {n} inputs",
                t.cols
            ));
        }
        if reference == Reference::Label && t.cols < n + 1 {
            return input(format!(
                "--data {data}: {} columns, the network's {n} inputs and no label column; add the label column (the reference of --reference label) or pass --reference network",
                t.cols
            ));
        }
        let rows: Vec<Vec<f64>> = (0..t.rows()).map(|i| t.row(i).to_vec()).collect();
        let used = if reference == Reference::Label {
            n + 1
        } else {
            n
        };
        for (i, r) in rows.iter().enumerate() {
            if let Some(j) = r.iter().take(used).position(|v| !v.is_finite()) {
                return input(format!(
                    "--data {data}: row {} column {} is {}, not a finite number; fix or drop the row",
                    i + 1,
                    j + 1,
                    r[j]
                ));
            }
        }
        Ok(rows)
    }
}

impl TrainArgs {
    /// Refuse flag values that no training can use, naming the flag and the fix (the
    /// training library checks the rest of the settings).
    pub fn validate(&self) -> Result<(), AppError> {
        if !(self.lipschitz > 0.0 && self.lipschitz.is_finite()) {
            return input(format!(
                "--lipschitz {}: the Lipschitz constant must be a positive number, e.g. 0.5",
                self.lipschitz
            ));
        }
        if let Some(w) = self.weight {
            if !(w >= 0.0 && w.is_finite()) {
                return input(format!(
                    "--weight {w}: the penalty weight must be a finite number >= 0, e.g. 10"
                ));
            }
        }
        if !(self.ystar >= 0.0 && self.ystar.is_finite()) {
            return input(format!(
                "--ystar {}: the threshold must be a finite number >= 0, e.g. 2",
                self.ystar
            ));
        }
        Ok(())
    }
}

impl VnncompArgs {
    /// `--timeout-scale`: finite and > 0.
    pub fn validate(&self) -> Result<(), AppError> {
        if !(self.timeout_scale > 0.0 && self.timeout_scale.is_finite()) {
            return input(format!(
                "--timeout-scale {}: must be a finite number > 0 (e.g. --timeout-scale 0.5)",
                self.timeout_scale
            ));
        }
        Ok(())
    }
}

impl SpecArgs {
    /// Load a spec and its bindings; every flag is checked here (exit 2 on a bad one).
    /// `free_params`: whether a bare `--param NAME` (no value) is allowed (`critical`).
    /// The checks are the library's ([`crate::Loaded`]); each units warning goes to
    /// `on_warning` as soon as its network is bound.
    pub fn load(
        &self,
        free_params: bool,
        mut on_warning: impl FnMut(String),
    ) -> Result<crate::Loaded<'static>, AppError> {
        let a = self;
        let spec = samara_spec::Spec::read(&a.spec).map_err(|e| AppError::Input(e.to_string()))?;
        let mut l = crate::Loaded::new(
            std::borrow::Cow::Owned(spec),
            a.spec.display().to_string(),
            crate::Front::Cli,
        );
        let mut seen = std::collections::HashSet::new();
        for s in &a.networks {
            let (k, v) = crate::bind::kv(s, "network")?;
            l.declared_network(&k, &format!("--network {k}=..."))?;
            if !seen.insert(k.clone()) {
                return input(format!(
                    "--network {k}=...: given twice; bind each network once"
                ));
            }
            let file = PathBuf::from(&v);
            let net = crate::bind::load_network(&file, &format!("--network {k}="))?;
            l.bind_network(&k, net, &format!("--network {k}={v}"), Some(&file))?;
            for w in l.warnings.drain(..) {
                on_warning(w);
            }
        }
        for s in &a.params {
            if !s.contains('=') {
                let k = s.trim();
                if !free_params {
                    return input(format!(
                    "--param {k}: no value; pass --param {k}=VALUE (only `samara critical` takes a bare --param NAME: the parameter to search)"
                ));
                }
                l.declared_param(k, &format!("--param {k}"))?;
                continue;
            }
            let (k, v) = crate::bind::kv(s, "param")?;
            let label = format!("--param {k}={v}");
            l.declared_param(&k, &label)?;
            if l.b.params.contains_key(&k) {
                return input(format!(
                    "--param {k}: given twice; bind each parameter once"
                ));
            }
            let x: f64 = v.parse().map_err(|_| {
                AppError::Input(format!(
                    "--param {k}={v}: not a number; pass e.g. --param {k}=2"
                ))
            })?;
            let searched = a.params.iter().any(|p| p.trim() == k).then_some(k.as_str());
            l.bind_param(&k, x, &label, searched)?;
        }
        // Values outside a declared `param NAME in [lo, hi]` are refused here (exit 2).
        let mut l = l.finish("--param")?;
        for s in &a.datasets {
            let (k, v) = crate::bind::kv(s, "dataset")?;
            if l.b.datasets.contains_key(&k) {
                return input(format!(
                    "--dataset {k}=...: given twice; bind each data set once"
                ));
            }
            l.bind_dataset(&k, std::path::Path::new(&v), &format!("--dataset {k}={v}"))?;
        }
        Ok(l)
    }
}

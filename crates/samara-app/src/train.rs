//! Training results as typed documents (`samara train --json`): a data-fitting run
//! ([`TrainSummary`]) and closed-loop training ([`ClosedLoopSummary`]).

use serde::{Deserialize, Serialize};

/// One restart of a training run from a degenerate network.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RestartEntry {
    /// Attempt number (0-based).
    pub attempt: usize,
    /// The seed of the network that was degenerate.
    pub seed: u64,
    /// The epoch at which it was found degenerate.
    pub epoch: usize,
    /// How it was degenerate.
    pub reason: String,
}

impl From<&samara_train::Restart> for RestartEntry {
    fn from(r: &samara_train::Restart) -> Self {
        RestartEntry {
            attempt: r.attempt,
            seed: r.seed,
            epoch: r.epoch,
            reason: r.reason.to_string(),
        }
    }
}

/// The `--json` summary of a data-fitting training run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrainSummary {
    /// The method.
    pub method: String,
    /// The network file.
    pub out: String,
    /// The loss log.
    pub log: String,
    /// Held-out rows.
    pub test_rows: usize,
    /// Held-out R^2.
    pub r2: f64,
    /// Held-out RMSE.
    pub rmse: f64,
    /// Held-out MAE.
    pub mae: f64,
    /// Attack radius.
    pub eps: f64,
    /// Worst output deviation under the attack.
    pub attack_worst_deviation: f64,
    /// Mean output deviation under the attack.
    pub attack_mean_deviation: f64,
    /// `--seed`.
    pub seed: u64,
    /// The seed the kept network was initialised from.
    pub init_seed: u64,
    /// Number of restarts.
    pub restarts: usize,
    /// The restarts.
    pub restart_log: Vec<RestartEntry>,
}

/// One round of closed-loop training: its record and its time in all.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RoundEntry {
    /// The round's record.
    #[serde(flatten)]
    pub round: samara_train::cegis::Round,
    /// Training and reach time together.
    pub seconds: f64,
}

impl From<&samara_train::cegis::Round> for RoundEntry {
    fn from(r: &samara_train::cegis::Round) -> Self {
        RoundEntry {
            round: r.clone(),
            seconds: r.train_seconds + r.reach_seconds,
        }
    }
}

/// The goal closed-loop training flies to.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LoopGoal {
    /// Band half-width.
    pub ystar: f64,
    /// Start of the window.
    pub from: Option<f64>,
    /// Horizon.
    pub horizon: f64,
    /// Initial heights.
    pub y0: [f64; 2],
    /// Model.
    pub model: String,
    /// Output clip.
    pub clip: Option<[f64; 2]>,
}

/// The pre-training on the data.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pretrain {
    /// Held-out R^2.
    pub test_r2: f64,
    /// Held-out RMSE.
    pub test_rmse: f64,
    /// Epochs.
    pub epochs: usize,
    /// Time.
    pub seconds: f64,
}

/// The `--json` summary of closed-loop training.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ClosedLoopSummary {
    /// Always `closed-loop`.
    pub method: String,
    /// The network file.
    pub out: String,
    /// The rounds log.
    pub log: String,
    /// The rounds figure.
    pub figure: String,
    /// The goal.
    pub goal: LoopGoal,
    /// Whether reach proved the goal.
    pub proved: bool,
    /// The last reach verdict.
    pub verdict: String,
    /// Enclosure of `x + y` at the horizon.
    pub enclosure: [f64; 2],
    /// Sampled range.
    pub sampled: [f64; 2],
    /// R^2 against the data.
    pub r2: f64,
    /// RMSE against the data.
    pub rmse: f64,
    /// Data rows.
    pub data_rows: usize,
    /// The pre-training.
    pub pretrain: Pretrain,
    /// The rounds.
    pub rounds: Vec<RoundEntry>,
    /// Training time.
    pub seconds: f64,
    /// `--seed`.
    pub seed: u64,
    /// The seed the kept network was initialised from.
    pub init_seed: u64,
    /// Number of restarts.
    pub restarts: usize,
    /// The restarts.
    pub restart_log: Vec<RestartEntry>,
}

// ---------------------------------------------------------------------------------
// `samara train`: the checks of its flags, the training method, the run and what it
// writes. The CLI prints the [`TrainDone`] it gets back; Python's `samara.train` takes
// its method from [`method`] too.

use crate::args::TrainArgs;
use crate::{input, AppError, Front};
use samara_report::guard::{check_output_file, resolve, OutDir};
use samara_train::{Attack, Logic, Method, MinMax, Restart, TrainError, TrainOptions};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// `--min-r2` when not given: 0.9 for the accuracy-only methods (plain, adversarial).
pub const DEFAULT_MIN_R2: f64 = 0.9;

/// The parent folder of an output file ("." for a bare file name).
fn parent(p: &Path) -> &Path {
    match p.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// Refuse outputs that would overwrite an input or each other, or that are folders;
/// returns the log path (`--log`, default `<--out stem>.log.csv`).
pub fn check_outputs(a: &TrainArgs) -> anyhow::Result<PathBuf> {
    let log_flag = if a.log.is_some() {
        "--log"
    } else {
        "--log (default <--out stem>.log.csv)"
    };
    let log_path = a
        .log
        .clone()
        .unwrap_or_else(|| a.out.with_extension("log.csv"));
    let mut inputs: Vec<(&str, &Path)> = vec![("--data", &a.data)];
    if let Some(n) = &a.normalisation {
        inputs.push(("--normalisation", n));
    }
    if let Some(s) = &a.spec {
        inputs.push(("--spec", s));
    }
    check_output_file("--out", &a.out, &inputs)?;
    check_output_file(log_flag, &log_path, &inputs)?;
    if resolve(&a.out) == resolve(&log_path) {
        anyhow::bail!(
            "--log {} is the same file as --out; choose another --log",
            log_path.display()
        );
    }
    for (flag, p) in [("--out", &a.out), (log_flag, &log_path)] {
        if p.is_dir() {
            let eg = if flag == "--out" {
                "net.onnx"
            } else {
                "net.log.csv"
            };
            anyhow::bail!(
                "{flag} {} is a folder; give a file name such as {}",
                p.display(),
                p.join(eg).display()
            );
        }
    }
    Ok(log_path)
}

/// The training method asked for, before it is checked ([`method`]).
#[derive(Clone, Debug, Default)]
pub struct MethodRequest<'a> {
    /// plain, adversarial, lipschitz, dl2 or goedel.
    pub method: &'a str,
    /// fgsm or pgd (adversarial).
    pub attack: &'a str,
    /// The Lipschitz bound (lipschitz).
    pub lipschitz: f64,
    /// The penalty weight (default 10 for lipschitz, 1 for dl2/goedel).
    pub weight: Option<f64>,
    /// `ystar` of the case study's P1-P4 (dl2/goedel without `spec`).
    pub ystar: f64,
    /// The spec whose properties dl2/goedel train for (default: the case study's).
    pub spec: Option<&'a Path>,
    /// The properties to train for, comma-separated (default: every one without binders).
    pub properties: Option<&'a str>,
    /// `NAME=VALUE` bindings of the spec's parameters.
    pub params: &'a [String],
    /// The architecture as the caller wrote it (named in messages).
    pub arch_text: &'a str,
}

/// The training method `r` with its options, for data `data` (normalised by `mm`) and a
/// network of widths `arch`. dl2 and goedel train for the properties of `r.spec`, or
/// P1-P4 of the case study (`models/alsomitra/alsomitra.spec`, compiled into
/// samara-train) over the box of `data` with `ystar` bound, lowered in the units of the
/// network being trained. Messages name the arguments in `front`'s words.
pub fn method(
    front: Front,
    r: &MethodRequest,
    data: &samara_train::Table,
    mm: &MinMax,
    arch: &[usize],
) -> Result<Method, AppError> {
    Ok(match r.method {
        "plain" => Method::Plain,
        "adversarial" => Method::Adversarial(match r.attack {
            "fgsm" => Attack::Fgsm,
            "pgd" => Attack::Pgd { steps: 10 },
            other => {
                return input(format!(
                    "{} {other:?}: choose fgsm or pgd",
                    front.arg("attack")
                ))
            }
        }),
        "lipschitz" => Method::Lipschitz {
            l: r.lipschitz,
            weight: r.weight.unwrap_or(10.0),
        },
        "dl2" | "goedel" => {
            let logic = if r.method == "dl2" {
                Logic::Dl2
            } else {
                Logic::Goedel
            };
            let props = spec_properties(front, r, mm, data)?;
            if arch.first() != Some(&(data.cols - 1)) {
                return input(format!(
                    "{} {}: the first width must be the data's {} inputs",
                    front.arg("arch"),
                    r.arch_text,
                    data.cols - 1
                ));
            }
            Method::Properties {
                logic,
                props,
                weight: r.weight.unwrap_or(1.0),
            }
        }
        other => {
            return input(match front {
                Front::Cli => format!(
                    "--method {other:?}: choose plain, adversarial, lipschitz, dl2, goedel or closed-loop"
                ),
                Front::Python => format!(
                    "method {other:?}: choose plain, adversarial, lipschitz, dl2 or goedel (closed-loop: use the CLI)"
                ),
            })
        }
    })
}

/// The dl2/goedel properties: those of `r.spec`, or P1-P4 of the case-study spec over
/// the data's box with `ystar = r.ystar`, lowered by samara-spec in the units of the
/// network being trained.
fn spec_properties(
    front: Front,
    r: &MethodRequest,
    mm: &MinMax,
    data: &samara_train::Table,
) -> Result<Vec<samara_train::Property>, AppError> {
    let spec = match r.spec {
        Some(path) => samara_spec::Spec::read(path).map_err(|e| AppError::Input(e.to_string()))?,
        None => samara_train::case_study_spec(),
    };
    let mut b = samara_spec::Bindings::default();
    let param = front.arg("param");
    for s in r.params {
        let Some((k, v)) = s.split_once('=') else {
            return input(format!("{param} {s:?}: expected NAME=VALUE"));
        };
        let Ok(v) = v.trim().parse::<f64>() else {
            return input(format!("{param} {s:?}: not a number"));
        };
        if !v.is_finite() {
            return input(format!("{param} {s:?}: the value must be a finite number"));
        }
        b.params.insert(k.trim().into(), v);
    }
    if r.spec.is_none() {
        b.params.entry("ystar".into()).or_insert(r.ystar);
    }
    let names: Vec<String> = match r.properties {
        Some(p) => p.split(',').map(|s| s.trim().to_string()).collect(),
        None => spec
            .properties
            .iter()
            .filter(|p| p.binders.is_empty())
            .map(|p| p.name.clone())
            .collect(),
    };
    let Some(decl) = spec.networks.first() else {
        return input("the spec declares no network");
    };
    let n = decl.inputs.len();
    if decl.outputs.len() != 1 || mm.min.len() != n + 1 || data.cols != n + 1 {
        return input(format!(
            "{} {}: the properties' network `{}` has {n} inputs and {} output(s); the data must have the inputs and one output",
            front.arg("method"),
            r.method,
            decl.name,
            decl.outputs.len()
        ));
    }
    // The case study's properties range over the box of the data trained on; a
    // spec's over its own domain.
    let domain = r.spec.is_none().then(|| {
        let d = MinMax::of(data);
        (0..n).map(|j| (d.min[j], d.min[j] + d.range[j])).collect()
    });
    let props = samara_train::spec_properties(&spec, &names, &b, mm, domain)
        .map_err(|e| AppError::Input(e.to_string()))?;
    if props.is_empty() {
        return input(format!("{}: no property to train for", front.arg("spec")));
    }
    Ok(props)
}

/// The `--json` document of `samara train`: a data-fitting run or closed-loop training.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum TrainDoc {
    /// plain, adversarial, lipschitz, dl2, goedel.
    Fit(TrainSummary),
    /// closed-loop.
    ClosedLoop(Box<ClosedLoopSummary>),
}

/// A finished `samara train`: its files written.
#[derive(Clone, Debug)]
pub struct TrainDone {
    /// The `--json` document.
    pub doc: TrainDoc,
    /// The human report (one line per restart, then the result), for stderr.
    pub human: Vec<String>,
    /// Closed-loop training that did not prove its goal: why, and what to try (exit 1;
    /// the network was written).
    pub not_proved: Option<String>,
}

/// What `samara train` gives back.
#[derive(Debug)]
pub enum TrainRun {
    /// The run finished and wrote its files.
    Done(Box<TrainDone>),
    /// No usable network (degenerate, or a metric not finite): nothing was written.
    Failed(TrainError),
}

/// One line per restart of a training run from a degenerate network.
pub fn restart_lines(restarts: &[Restart]) -> Vec<String> {
    restarts
        .iter()
        .map(|r| {
            format!(
                "restart {}: the network from seed {} was degenerate {} ({}); reinitialising",
                r.attempt + 1,
                r.seed,
                r.when(),
                r.reason
            )
        })
        .collect()
}

/// The loss log of a data-fitting run (`epoch,loss,test_rmse`).
pub fn log_csv(log: &[samara_train::train::LogRow]) -> String {
    let mut s = String::from("epoch,loss,test_rmse\n");
    for r in log {
        let _ = writeln!(s, "{},{:?},{:?}", r.epoch, r.loss, r.test_rmse);
    }
    s
}

/// `--arch`: comma-separated widths.
fn arch(a: &TrainArgs) -> anyhow::Result<Vec<usize>> {
    a.arch
        .split(',')
        .map(|s| s.trim().parse::<usize>())
        .collect::<Result<_, _>>()
        .map_err(|_| {
            anyhow::anyhow!(
                "--arch {:?}: expected comma-separated widths such as 6,6,4,1",
                a.arch
            )
        })
}

/// Run `samara train`: check the flags, train, write the network and the log (and for
/// closed-loop training the rounds figure). `terminal`: whether stderr is a terminal
/// (a data-fitting run draws its progress bar there unless `--json`).
pub fn run(a: &TrainArgs, terminal: bool) -> anyhow::Result<TrainRun> {
    let log_path = check_outputs(a)?;
    a.validate()?;
    let arch = arch(a)?;
    let data = samara_train::read_table(&a.data)?;
    let mm = match &a.normalisation {
        Some(p) => MinMax::read(p)?,
        None => MinMax::of(&data),
    };
    if a.method == "closed-loop" {
        if a.linear_output || a.lipschitz_weight.is_some() {
            anyhow::bail!("--linear-output and --lipschitz-weight do not apply to --method closed-loop (it trains the published 6-6-4-1 shape); leave them out");
        }
        return run_closed_loop(a, &data, &mm, arch, &log_path);
    }
    let request = MethodRequest {
        method: &a.method,
        attack: &a.attack,
        lipschitz: a.lipschitz,
        weight: a.weight,
        ystar: a.ystar,
        spec: a.spec.as_deref(),
        properties: a.properties.as_deref(),
        params: &a.params,
        arch_text: &a.arch,
    };
    let method = method(Front::Cli, &request, &data, &mm, &arch)?;
    let o = TrainOptions {
        arch,
        epochs: a.epochs,
        batch: a.batch,
        lr: a.lr,
        seed: a.seed,
        eps: a.eps,
        min_r2: a.min_r2.unwrap_or_else(|| default_min_r2(&method)),
        method,
        progress: terminal && !a.json,
        max_restarts: a.max_restarts,
        relu_output: !a.linear_output,
        lipschitz: a.lipschitz_weight.map(|w| (a.lipschitz, w)),
        ..Default::default()
    };
    if a.lipschitz_weight.is_some() && !matches!(o.method, Method::Properties { .. }) {
        anyhow::bail!(
            "--lipschitz-weight: adds a Lipschitz penalty to --method dl2 or goedel; with --method {} leave it out (--method lipschitz takes --weight)",
            a.method
        );
    }
    o.validate()?;
    // Create missing output folders now (a failed run removes them again).
    let out_dir = OutDir::prepare(parent(&a.out))?;
    let log_dir = OutDir::prepare(parent(&log_path))?;
    let outcome = match samara_train::train(&data, Some(&mm), &o) {
        Ok(r) => r,
        Err(e @ (TrainError::Degenerate { .. } | TrainError::NonFiniteMetric { .. })) => {
            return Ok(TrainRun::Failed(e))
        }
        Err(e) => return Err(e.into()),
    };
    // The numbers of `--json`, taken before the network is moved out of the outcome.
    let report = TrainReport::of(&a.method, &o, &outcome);
    let mut net = outcome.network;
    if net.n_inputs() == 6 && net.n_outputs() == 1 {
        net = net.with_names(&samara_nn::STATE_INPUTS, &["ex"])?;
    }
    samara_nn::onnx::save(&net, &a.out, &Default::default()).map_err(|e| {
        anyhow::Error::from(e).context(format!(
            "cannot write {}; choose a writable --out",
            a.out.display()
        ))
    })?;
    samara_report::write_atomic(&log_path, log_csv(&outcome.log).as_bytes())?;
    out_dir.keep();
    log_dir.keep();
    let m = &outcome.metrics;
    let mut human = restart_lines(&outcome.restarts);
    let restarted = match outcome.restarts.len() {
        0 => String::new(),
        n => format!(
            " after {n} restart{} (initialised from derived seed {})",
            if n == 1 { "" } else { "s" },
            outcome.init_seed
        ),
    };
    human.push(format!(
        "trained {} network{restarted}: test R^2 {:.4}, RMSE {:.3e}, MAE {:.3e}, worst attack deviation at eps {} = {:.3e}; wrote {} and {}",
        a.method,
        m.r2,
        m.rmse,
        m.mae,
        a.eps,
        m.attack_worst,
        a.out.display(),
        log_path.display()
    ));
    Ok(TrainRun::Done(Box::new(TrainDone {
        doc: TrainDoc::Fit(
            report.summary(a.out.display().to_string(), log_path.display().to_string()),
        ),
        human,
        not_proved: None,
    })))
}

/// The rounds log of closed-loop training.
pub fn rounds_csv(rounds: &[samara_train::cegis::Round]) -> String {
    let mut log = String::from(
        "round,steps,loss,mse,penalty,r2,starts,verdict,enclosure_lo,enclosure_hi,sampled_lo,sampled_hi,max_leaves,added,train_seconds,reach_seconds\n",
    );
    for r in rounds {
        let added: Vec<String> = r.added.iter().map(|v| format!("{v:?}")).collect();
        let _ = writeln!(
            log,
            "{},{},{:?},{:?},{:?},{:?},{},{},{:?},{:?},{:?},{:?},{},{},{:.3},{:.3}",
            r.round,
            r.steps,
            r.loss,
            r.mse,
            r.penalty,
            r.r2,
            r.starts,
            r.verdict,
            r.enclosure[0],
            r.enclosure[1],
            r.sampled[0],
            r.sampled[1],
            r.max_leaves,
            added.join(" "),
            r.train_seconds,
            r.reach_seconds
        );
    }
    log
}

/// The closed loop to train for: `--spec`'s (its `--loop`, or its first), or the
/// published one with the flags' goal and window.
fn closed_loop_base(t: &TrainArgs) -> anyhow::Result<samara_train::CegisOptions> {
    use samara_train::{CegisOptions, ClosedLoopLoss};
    let a = &*t.closed_loop;
    Ok(match &t.spec {
        Some(path) => {
            if a.y0.is_some() || a.goal_ystar.is_some() || a.goal_from.is_some() {
                anyhow::bail!("--y0/--goal-ystar/--goal-from: with --spec, closed-loop training flies the spec's loop (its start and goal); drop these flags or edit the loop in {}", path.display());
            }
            let spec = samara_spec::Spec::read(path).map_err(|e| anyhow::anyhow!("{e}"))?;
            let lp = match &a.loop_name {
                Some(n) => spec.closed_loop(n).ok_or_else(|| {
                    anyhow::anyhow!("--loop {n}: {} states no loop `{n}`", path.display())
                })?,
                None => spec.loops.first().ok_or_else(|| {
                    anyhow::anyhow!("--spec {}: states no closed loop to train for; add `loop`, `start` and `goal` statements (docs/spec.md, Closed loops), or train without --spec", path.display())
                })?,
            };
            CegisOptions::from_loop(lp)
                .map_err(|e| anyhow::anyhow!("--spec {}: {e}", path.display()))?
        }
        None => {
            let d = CegisOptions::default();
            CegisOptions {
                goal: a.goal_ystar.unwrap_or(d.goal),
                loss: ClosedLoopLoss {
                    from: a.goal_from,
                    ..d.loss.clone()
                },
                ..d
            }
        }
    })
}

/// `samara train --method closed-loop`.
fn run_closed_loop(
    t: &TrainArgs,
    data: &samara_train::Table,
    mm: &MinMax,
    arch: Vec<usize>,
    log_path: &Path,
) -> anyhow::Result<TrainRun> {
    use anyhow::bail;
    use samara_train::{train_closed_loop, CegisOptions, ClosedLoopLoss};
    let a = &*t.closed_loop;
    let base = closed_loop_base(t)?;
    let goal = base.goal;
    if !(goal > 0.0 && goal.is_finite()) {
        bail!("--goal-ystar {goal}: the goal bound must be a positive number, e.g. 2");
    }
    if !(a.margin >= 0.0 && a.margin <= goal) {
        bail!(
            "--margin {}: must be a number in [0, the goal = {goal}], e.g. 0.75",
            a.margin
        );
    }
    if let Some(f) = a.goal_from {
        if !(0.0..=20.0).contains(&f) {
            bail!("--goal-from {f}: the window must start in [0, 20] (the horizon)");
        }
    }
    if data.cols != 7 {
        bail!(
            "--method closed-loop: the data must have the 6 states (v_xp, v_yp, omega, theta, x, y) and ex as columns; {} has {}",
            t.data.display(),
            data.cols
        );
    }
    if a.round_leaves == 0 || a.max_leaves == 0 {
        bail!("--round-leaves and --max-leaves must be at least 1");
    }
    let y0 = match &a.y0 {
        Some(s) => crate::reach::args::parse_interval(s, &format!("--y0 {s:?}"))?,
        None => base.y0,
    };
    // The figure of the closed-loop rounds: `<--out stem>.rounds.png` and `.svg`.
    let (png, svg) = (
        t.out.with_extension("rounds.png"),
        t.out.with_extension("rounds.svg"),
    );
    let mut inputs: Vec<(&str, &Path)> = vec![("--data", &t.data)];
    if let Some(n) = &t.normalisation {
        inputs.push(("--normalisation", n));
    }
    check_output_file("the rounds figure (<--out stem>.rounds.png)", &png, &inputs)?;
    check_output_file("the rounds figure (<--out stem>.rounds.svg)", &svg, &inputs)?;
    let defaults = base;
    let o = CegisOptions {
        pretrain: TrainOptions {
            arch,
            epochs: t.epochs,
            batch: t.batch,
            lr: t.lr,
            seed: t.seed,
            eps: t.eps,
            method: Method::Plain,
            progress: false,
            max_restarts: t.max_restarts,
            min_r2: t.min_r2.unwrap_or(DEFAULT_MIN_R2),
            ..Default::default()
        },
        loss: ClosedLoopLoss {
            bound: goal - a.margin,
            ..defaults.loss.clone()
        },
        goal,
        y0,
        steps_per_round: a.steps_per_round,
        lr: a.round_lr,
        data_weight: a.data_weight,
        max_rounds: a.rounds,
        round_reach: (a.round_leaves, defaults.round_reach.1),
        final_reach: (a.max_leaves, defaults.final_reach.1),
        progress: !t.json,
        ..defaults
    };
    o.pretrain.validate()?;
    o.validate()?;
    let out_dir = OutDir::prepare(parent(&t.out))?;
    let log_dir = OutDir::prepare(parent(log_path))?;
    let outcome = match train_closed_loop(data, Some(mm), &o) {
        Ok(r) => r,
        Err(e @ (TrainError::Degenerate { .. } | TrainError::NonFiniteMetric { .. })) => {
            return Ok(TrainRun::Failed(e))
        }
        Err(e) => return Err(e.into()),
    };
    samara_nn::onnx::save(&outcome.network, &t.out, &Default::default()).map_err(|e| {
        anyhow::Error::from(e).context(format!(
            "cannot write {}; choose a writable --out",
            t.out.display()
        ))
    })?;
    samara_report::write_atomic(log_path, rounds_csv(&outcome.rounds).as_bytes())?;
    let proved = if outcome.proved {
        "proved"
    } else {
        "not proved"
    };
    samara_train::cegis::rounds_figure(
        &outcome.rounds,
        goal,
        &format!(
            "closed-loop training: |x + y| <= {} at t = {}, {proved}",
            goal, o.loss.horizon
        ),
        &png,
        &svg,
    )
    .map_err(|e| anyhow::anyhow!("cannot write the rounds figure: {e}"))?;
    out_dir.keep();
    log_dir.keep();
    let verdict = outcome.reach.verdict.name();
    let enc = outcome.reach.final_x_plus_y;
    let m = &outcome.pretrain_metrics;
    let summary = ClosedLoopSummary {
        method: "closed-loop".into(),
        out: t.out.display().to_string(),
        log: log_path.display().to_string(),
        figure: png.display().to_string(),
        goal: LoopGoal {
            ystar: goal,
            from: o.loss.from,
            horizon: o.loss.horizon,
            y0: [y0.0, y0.1],
            model: "reduced".into(),
            clip: o.loss.clip.map(|c| [c.0, c.1]),
        },
        proved: outcome.proved,
        verdict: verdict.to_string(),
        enclosure: enc,
        sampled: outcome.reach.sampled_x_plus_y,
        r2: outcome.r2,
        rmse: outcome.rmse,
        data_rows: data.rows(),
        pretrain: Pretrain {
            test_r2: m.r2,
            test_rmse: m.rmse,
            epochs: t.epochs,
            seconds: outcome.pretrain_seconds,
        },
        rounds: outcome.rounds.iter().map(RoundEntry::from).collect(),
        seconds: outcome.seconds,
        seed: t.seed,
        init_seed: outcome.init_seed,
        restarts: outcome.restarts.len(),
        restart_log: outcome.restarts.iter().map(RestartEntry::from).collect(),
    };
    let mut human = restart_lines(&outcome.restarts);
    let n = outcome.rounds.len();
    human.push(format!(
        "closed-loop training: {} after {} round{} in {:.1} s; x + y at t = {} {} (goal |x + y| <= {}); R^2 {:.4} against the {} data rows; wrote {}, {} and {}",
        verdict,
        n,
        if n == 1 { "" } else { "s" },
        outcome.seconds,
        o.loss.horizon,
        samara_train::cegis::enclosure_text(enc),
        goal,
        outcome.r2,
        data.rows(),
        t.out.display(),
        log_path.display(),
        png.display()
    ));
    let not_proved = (!outcome.proved).then(|| {
        format!(
            "the goal was not proved within {} rounds (last verdict: {verdict}); the network was written; try more --rounds or --steps-per-round, a larger --margin or --max-leaves",
            a.rounds
        )
    });
    Ok(TrainRun::Done(Box::new(TrainDone {
        doc: TrainDoc::ClosedLoop(Box::new(summary)),
        human,
        not_proved,
    })))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn table(cols: usize) -> samara_train::Table {
        samara_train::Table {
            names: (0..cols).map(|j| format!("c{j}")).collect(),
            cols,
            values: (0..cols * 4).map(|i| i as f64).collect(),
        }
    }

    fn err(front: Front, method: &str, attack: &str, cols: usize, arch: &[usize]) -> String {
        let data = table(cols);
        let r = MethodRequest {
            method,
            attack,
            lipschitz: 1.0,
            ystar: 2.0,
            arch_text: "5,4,1",
            ..Default::default()
        };
        method_err(front, &r, &data, arch)
    }

    fn method_err(
        front: Front,
        r: &MethodRequest,
        data: &samara_train::Table,
        arch: &[usize],
    ) -> String {
        match method(front, r, data, &MinMax::of(data), arch) {
            Ok(_) => String::new(),
            Err(e) => e.to_string(),
        }
    }

    /// `samara train` and `samara.train` choose their method through one function; the
    /// messages name the flag or the keyword argument.
    #[test]
    fn one_method_check_names_each_fronts_argument() {
        assert_eq!(
            err(Front::Cli, "nope", "fgsm", 7, &[6, 1]),
            "--method \"nope\": choose plain, adversarial, lipschitz, dl2, goedel or closed-loop"
        );
        assert_eq!(
            err(Front::Python, "nope", "fgsm", 7, &[6, 1]),
            "method \"nope\": choose plain, adversarial, lipschitz, dl2 or goedel (closed-loop: use the CLI)"
        );
        assert_eq!(
            err(Front::Python, "adversarial", "x", 7, &[6, 1]),
            "attack \"x\": choose fgsm or pgd"
        );
        assert_eq!(
            err(Front::Cli, "dl2", "fgsm", 7, &[5, 4, 1]),
            "--arch 5,4,1: the first width must be the data's 6 inputs"
        );
        assert_eq!(
            err(Front::Python, "goedel", "fgsm", 5, &[4, 1]),
            "method goedel: the properties' network `f` has 6 inputs and 1 output(s); the data must have the inputs and one output"
        );
        // P1-P4 of the case study, lowered for a 6-input network.
        assert_eq!(err(Front::Python, "dl2", "fgsm", 7, &[6, 4, 1]), "");
    }
}

/// The least held-out R^2 a training run of method `m` must reach unless told
/// otherwise (`samara train --min-r2`'s default): 0.9 for data fitting (plain,
/// adversarial), 0 for the methods that trade accuracy for a property.
pub fn default_min_r2(m: &Method) -> f64 {
    match m {
        Method::Plain | Method::Adversarial(_) => DEFAULT_MIN_R2,
        _ => 0.0,
    }
}

/// The report of a data-fitting training run: the fields of `samara train --json`
/// (without the file paths), the R^2 on the training rows, and the log as (epoch,
/// loss, test RMSE) rows.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TrainReport {
    /// The method.
    pub method: String,
    /// Held-out rows.
    pub test_rows: usize,
    /// Held-out R^2.
    pub r2: f64,
    /// R^2 on the training rows.
    pub r2_train: f64,
    /// Held-out RMSE.
    pub rmse: f64,
    /// Held-out MAE.
    pub mae: f64,
    /// Attack radius.
    pub eps: f64,
    /// Worst output deviation under the attack.
    pub attack_worst_deviation: f64,
    /// Mean output deviation under the attack.
    pub attack_mean_deviation: f64,
    /// The seed asked for.
    pub seed: u64,
    /// The seed the kept network was initialised from.
    pub init_seed: u64,
    /// Number of restarts.
    pub restarts: usize,
    /// The restarts.
    pub restart_log: Vec<RestartEntry>,
    /// (epoch, loss, test RMSE) per logged epoch.
    pub log: Vec<(usize, f64, f64)>,
}

impl TrainReport {
    /// The report of `outcome`, trained by `method` with options `o`.
    pub fn of(
        method: &str,
        o: &samara_train::TrainOptions,
        outcome: &samara_train::TrainOutcome,
    ) -> Self {
        let m = &outcome.metrics;
        TrainReport {
            method: method.to_string(),
            test_rows: m.n_test,
            r2: m.r2,
            r2_train: m.r2_train,
            rmse: m.rmse,
            mae: m.mae,
            eps: o.eps,
            attack_worst_deviation: m.attack_worst,
            attack_mean_deviation: m.attack_mean,
            seed: o.seed,
            init_seed: outcome.init_seed,
            restarts: outcome.restarts.len(),
            restart_log: outcome.restarts.iter().map(RestartEntry::from).collect(),
            log: outcome
                .log
                .iter()
                .map(|r| (r.epoch, r.loss, r.test_rmse))
                .collect(),
        }
    }
}

impl TrainReport {
    /// The `samara train --json` summary of this run, whose network and log were
    /// written to `out` and `log`: the same numbers, so the CLI can print it from the
    /// report instead of filling the fields again.
    pub fn summary(&self, out: String, log: String) -> TrainSummary {
        TrainSummary {
            method: self.method.clone(),
            out,
            log,
            test_rows: self.test_rows,
            r2: self.r2,
            rmse: self.rmse,
            mae: self.mae,
            eps: self.eps,
            attack_worst_deviation: self.attack_worst_deviation,
            attack_mean_deviation: self.attack_mean_deviation,
            seed: self.seed,
            init_seed: self.init_seed,
            restarts: self.restarts,
            restart_log: self.restart_log.clone(),
        }
    }
}

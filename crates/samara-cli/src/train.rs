//! `samara train`.

use anyhow::{anyhow, bail, Context, Result};
pub use samara_app::args::TrainArgs;
use samara_app::train::{ClosedLoopSummary, LoopGoal, Pretrain, RestartEntry, RoundEntry};
use samara_report::guard::{check_output_file, resolve, OutDir};
use samara_train::{
    read_table, train, Attack, Logic, Method, MinMax, Restart, TrainError, TrainOptions,
};
use std::fmt::Write as _;
use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// `--min-r2` when not given: 0.9 for the accuracy-only methods.
pub const DEFAULT_MIN_R2: f64 = 0.9;

/// The parent folder of an output file ("." for a bare file name).
fn parent(p: &Path) -> &Path {
    match p.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    }
}

/// Refuse outputs that would overwrite an input or each other, or that are folders;
/// returns the log path.
fn check_outputs(a: &TrainArgs) -> Result<PathBuf> {
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
        bail!(
            "--log {} is the same file as --out; choose another --log",
            log_path.display()
        );
    }
    for (flag, p) in [("--out", &a.out), (log_flag, &log_path)] {
        if p.is_dir() {
            bail!(
                "{flag} {} is a folder; give a file name such as {}",
                p.display(),
                p.join(if flag == "--out" {
                    "net.onnx"
                } else {
                    "net.log.csv"
                })
                .display()
            );
        }
    }
    Ok(log_path)
}

/// The dl2/goedel properties: those of --spec, or P1-P4 of the case-study spec
/// (models/alsomitra/alsomitra.spec, compiled in) over the data's box with `ystar =
/// --ystar`, lowered by samara-spec in the units of the network being trained.
fn spec_properties(
    a: &TrainArgs,
    mm: &MinMax,
    data: &samara_train::Table,
) -> Result<Vec<samara_train::Property>> {
    let spec = match &a.spec {
        Some(path) => samara_spec::Spec::read(path).map_err(|e| anyhow!("{e}"))?,
        None => samara_train::case_study_spec(),
    };
    let mut b = samara_spec::Bindings::default();
    for s in &a.params {
        let (k, v) = s
            .split_once('=')
            .ok_or_else(|| anyhow!("--param {s:?}: expected NAME=VALUE"))?;
        let v: f64 = v
            .trim()
            .parse()
            .map_err(|_| anyhow!("--param {s:?}: not a number"))?;
        if !v.is_finite() {
            bail!("--param {s:?}: the value must be a finite number");
        }
        b.params.insert(k.trim().into(), v);
    }
    if a.spec.is_none() {
        b.params.entry("ystar".into()).or_insert(a.ystar);
    }
    let names: Vec<String> = match &a.properties {
        Some(p) => p.split(',').map(|s| s.trim().to_string()).collect(),
        None => spec
            .properties
            .iter()
            .filter(|p| p.binders.is_empty())
            .map(|p| p.name.clone())
            .collect(),
    };
    let decl = spec
        .networks
        .first()
        .ok_or_else(|| anyhow!("the spec declares no network"))?;
    let n = decl.inputs.len();
    if decl.outputs.len() != 1 || mm.min.len() != n + 1 || data.cols != n + 1 {
        bail!(
            "--method {}: the properties' network `{}` has {n} inputs and {} output(s); the data must have the inputs and one output",
            a.method,
            decl.name,
            decl.outputs.len()
        );
    }
    // The case study's properties range over the box of the data trained on; a
    // --spec's over its own domain.
    let domain = a.spec.is_none().then(|| {
        let d = MinMax::of(data);
        (0..n).map(|j| (d.min[j], d.min[j] + d.range[j])).collect()
    });
    let props =
        samara_train::spec_properties(&spec, &names, &b, mm, domain).map_err(|e| anyhow!("{e}"))?;
    if props.is_empty() {
        bail!("--spec: no property to train for");
    }
    Ok(props)
}

/// Run `samara train`.
pub fn run(a: &TrainArgs) -> Result<ExitCode> {
    let log_path = check_outputs(a)?;
    a.validate()?;
    let arch: Vec<usize> = a
        .arch
        .split(',')
        .map(|s| s.trim().parse::<usize>())
        .collect::<Result<_, _>>()
        .map_err(|_| {
            anyhow!(
                "--arch {:?}: expected comma-separated widths such as 6,6,4,1",
                a.arch
            )
        })?;
    let data = read_table(&a.data)?;
    let mm = match &a.normalisation {
        Some(p) => MinMax::read(p)?,
        None => MinMax::of(&data),
    };
    if a.method == "closed-loop" {
        if a.linear_output || a.lipschitz_weight.is_some() {
            bail!("--linear-output and --lipschitz-weight do not apply to --method closed-loop (it trains the published 6-6-4-1 shape); leave them out");
        }
        return run_closed_loop(a, &data, &mm, arch, &log_path);
    }
    let method = match a.method.as_str() {
        "plain" => Method::Plain,
        "adversarial" => Method::Adversarial(match a.attack.as_str() {
            "fgsm" => Attack::Fgsm,
            "pgd" => Attack::Pgd { steps: 10 },
            other => bail!("--attack {other:?}: choose fgsm or pgd"),
        }),
        "lipschitz" => Method::Lipschitz {
            l: a.lipschitz,
            weight: a.weight.unwrap_or(10.0),
        },
        "dl2" | "goedel" => {
            let logic = if a.method == "dl2" {
                Logic::Dl2
            } else {
                Logic::Goedel
            };
            let props = spec_properties(a, &mm, &data)?;
            if arch.first() != Some(&(data.cols - 1)) {
                bail!(
                    "--arch {}: the first width must be the data's {} inputs",
                    a.arch,
                    data.cols - 1
                );
            }
            Method::Properties {
                logic,
                props,
                weight: a.weight.unwrap_or(1.0),
            }
        }
        other => bail!(
            "--method {other:?}: choose plain, adversarial, lipschitz, dl2, goedel or closed-loop"
        ),
    };
    let min_r2 = a.min_r2.unwrap_or(match method {
        Method::Plain | Method::Adversarial(_) => DEFAULT_MIN_R2,
        _ => 0.0,
    });
    let o = TrainOptions {
        arch,
        epochs: a.epochs,
        batch: a.batch,
        lr: a.lr,
        seed: a.seed,
        eps: a.eps,
        method,
        progress: std::io::stderr().is_terminal() && !a.json,
        max_restarts: a.max_restarts,
        min_r2,
        relu_output: !a.linear_output,
        lipschitz: a.lipschitz_weight.map(|w| (a.lipschitz, w)),
        ..Default::default()
    };
    if a.lipschitz_weight.is_some() && !matches!(o.method, Method::Properties { .. }) {
        bail!(
            "--lipschitz-weight: adds a Lipschitz penalty to --method dl2 or goedel; with --method {} leave it out (--method lipschitz takes --weight)",
            a.method
        );
    }
    o.validate()?;
    // Create missing output folders now (a failed run removes them again).
    let out_dir = OutDir::prepare(parent(&a.out))?;
    let log_dir = OutDir::prepare(parent(&log_path))?;
    let outcome = match train(&data, Some(&mm), &o) {
        Ok(r) => r,
        Err(e @ (TrainError::Degenerate { .. } | TrainError::NonFiniteMetric { .. })) => {
            eprintln!("error: {e}; nothing was written");
            return Ok(ExitCode::from(1));
        }
        Err(e) => return Err(e.into()),
    };
    // The numbers of `--json`, taken before the network is moved out of the outcome.
    let report = samara_app::python_front::TrainReport::of(&a.method, &o, &outcome);
    let mut net = outcome.network;
    if net.n_inputs() == 6 && net.n_outputs() == 1 {
        net = net.with_names(&samara_nn::STATE_INPUTS, &["ex"])?;
    }
    samara_nn::onnx::save(&net, &a.out, &Default::default())
        .with_context(|| format!("cannot write {}; choose a writable --out", a.out.display()))?;
    let mut log = String::from("epoch,loss,test_rmse\n");
    for r in &outcome.log {
        let _ = writeln!(log, "{},{:?},{:?}", r.epoch, r.loss, r.test_rmse);
    }
    samara_report::write_atomic(&log_path, log.as_bytes())?;
    out_dir.keep();
    log_dir.keep();
    let m = &outcome.metrics;
    if a.json {
        let s = report.summary(a.out.display().to_string(), log_path.display().to_string());
        println!("{}", crate::json_text(&s, true)?);
    } else {
        print_restarts(&outcome.restarts);
        let restarted = match outcome.restarts.len() {
            0 => String::new(),
            n => format!(
                " after {n} restart{} (initialised from derived seed {})",
                if n == 1 { "" } else { "s" },
                outcome.init_seed
            ),
        };
        eprintln!(
            "trained {} network{restarted}: test R^2 {:.4}, RMSE {:.3e}, MAE {:.3e}, worst attack deviation at eps {} = {:.3e}; wrote {} and {}",
            a.method,
            m.r2,
            m.rmse,
            m.mae,
            a.eps,
            m.attack_worst,
            a.out.display(),
            log_path.display()
        );
    }
    Ok(ExitCode::SUCCESS)
}

/// The figure of the closed-loop rounds: `<--out stem>.rounds.png` and `.svg`.
/// One line on stderr per restart of a training run.
fn print_restarts(restarts: &[Restart]) {
    for r in restarts {
        eprintln!(
            "restart {}: the network from seed {} was degenerate {} ({}); reinitialising",
            r.attempt + 1,
            r.seed,
            r.when(),
            r.reason
        );
    }
}

fn rounds_figure_paths(out: &Path) -> (PathBuf, PathBuf) {
    (
        out.with_extension("rounds.png"),
        out.with_extension("rounds.svg"),
    )
}

/// `samara train --method closed-loop`.
fn run_closed_loop(
    t: &TrainArgs,
    data: &samara_train::Table,
    mm: &MinMax,
    arch: Vec<usize>,
    log_path: &Path,
) -> Result<ExitCode> {
    use samara_train::{train_closed_loop, CegisOptions, ClosedLoopLoss};
    let a = &*t.closed_loop;
    // The closed loop: the spec's (--spec), or the published one with the flags' goal
    // and start.
    let base = match &t.spec {
        Some(path) => {
            if a.y0.is_some() || a.goal_ystar.is_some() || a.goal_from.is_some() {
                bail!("--y0/--goal-ystar/--goal-from: with --spec, closed-loop training flies the spec's loop (its start and goal); drop these flags or edit the loop in {}", path.display());
            }
            let spec = samara_spec::Spec::read(path).map_err(|e| anyhow!("{e}"))?;
            let lp = match &a.loop_name {
                Some(n) => spec.closed_loop(n).ok_or_else(|| {
                    anyhow!("--loop {n}: {} states no loop `{n}`", path.display())
                })?,
                None => spec.loops.first().ok_or_else(|| {
                    anyhow!("--spec {}: states no closed loop to train for; add `loop`, `start` and `goal` statements (docs/spec.md, Closed loops), or train without --spec", path.display())
                })?,
            };
            CegisOptions::from_loop(lp).map_err(|e| anyhow!("--spec {}: {e}", path.display()))?
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
    };
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
        Some(s) => samara_app::reach::args::parse_interval(s, &format!("--y0 {s:?}"))?,
        None => base.y0,
    };
    let (png, svg) = rounds_figure_paths(&t.out);
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
            eprintln!("error: {e}; nothing was written");
            return Ok(ExitCode::from(1));
        }
        Err(e) => return Err(e.into()),
    };
    samara_nn::onnx::save(&outcome.network, &t.out, &Default::default())
        .with_context(|| format!("cannot write {}; choose a writable --out", t.out.display()))?;
    let mut log = String::from(
        "round,steps,loss,mse,penalty,r2,starts,verdict,enclosure_lo,enclosure_hi,sampled_lo,sampled_hi,max_leaves,added,train_seconds,reach_seconds\n",
    );
    for r in &outcome.rounds {
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
    samara_report::write_atomic(log_path, log.as_bytes())?;
    samara_train::cegis::rounds_figure(
        &outcome.rounds,
        goal,
        &format!(
            "closed-loop training: |x + y| <= {} at t = {}, {}",
            goal,
            o.loss.horizon,
            if outcome.proved {
                "proved"
            } else {
                "not proved"
            }
        ),
        &png,
        &svg,
    )
    .map_err(|e| anyhow!("cannot write the rounds figure: {e}"))?;
    out_dir.keep();
    log_dir.keep();
    let verdict = outcome.reach.verdict.name();
    let enc = outcome.reach.final_x_plus_y;
    let training_seconds = outcome.seconds;
    if t.json {
        let m = &outcome.pretrain_metrics;
        let s = ClosedLoopSummary {
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
            seconds: training_seconds,
            seed: t.seed,
            init_seed: outcome.init_seed,
            restarts: outcome.restarts.len(),
            restart_log: outcome.restarts.iter().map(RestartEntry::from).collect(),
        };
        println!("{}", crate::json_text(&s, true)?);
    } else {
        print_restarts(&outcome.restarts);
        eprintln!(
            "closed-loop training: {} after {} round{} in {:.1} s; x + y at t = {} {} (goal |x + y| <= {}); R^2 {:.4} against the {} data rows; wrote {}, {} and {}",
            verdict,
            outcome.rounds.len(),
            if outcome.rounds.len() == 1 { "" } else { "s" },
            training_seconds,
            o.loss.horizon,
            samara_train::cegis::enclosure_text(enc),
            goal,
            outcome.r2,
            data.rows(),
            t.out.display(),
            log_path.display(),
            png.display()
        );
    }
    if outcome.proved {
        Ok(ExitCode::SUCCESS)
    } else {
        eprintln!(
            "the goal was not proved within {} rounds (last verdict: {verdict}); the network was written; try more --rounds or --steps-per-round, a larger --margin or --max-leaves",
            a.rounds
        );
        Ok(ExitCode::from(1))
    }
}

//! `samara reach --system FILE --network NETS` for a discrete-time system file (`next`
//! updates, a mode set by `argmax`, networks switched by the mode; docs/system.md,
//! "Discrete-time systems"): boxes with the sound argmax (`samara_reach::discrete`).
//! `--network` is one network, a directory (its `.nnet`/`.onnx` files in name order,
//! one per mode value) or a comma-separated list; `--init NAME=A[:B]` replaces a
//! state's initial interval; `--choice` picks the input tables' values. Writes
//! `DIR/reach.json` and prints one line (or a JSON summary with `--json`). Exit 0
//! verified, 1 falsified or unknown, 2 bad input.

use crate::json_text;
use anyhow::{anyhow, bail, Context, Result};
use samara_app::reach::args::ReachArgs;
use samara_reach::discrete::{
    mode_name, reach_discrete, Choice, Controllers, DiscreteResult, DiscreteSettings,
    DiscreteVerdict,
};
use samara_report::write_atomic;
use samara_system::System;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

/// The report written to `reach.json`.
#[derive(Serialize)]
struct Report<'a> {
    system: String,
    networks: Vec<String>,
    choice: Choice,
    init: &'a [(f64, f64)],
    result: &'a DiscreteResult,
}

/// The `--json` summary.
#[derive(Serialize)]
struct Summary<'a> {
    verdict: &'a str,
    reason: Option<&'a str>,
    seconds: f64,
    steps: usize,
    sets_at_end: usize,
    splits: usize,
    mode_branches: usize,
    choice: Choice,
}

/// If `path` is a discrete-time system, run it and return the exit code; `None` for a
/// continuous system (the caller goes on with Taylor-model sets).
pub fn route(a: &ReachArgs, path: &Path) -> Result<Option<ExitCode>> {
    let sys = System::from_file(path).map_err(|e| anyhow!("{e}"))?;
    if !sys.is_discrete() {
        if a.choice.is_some() {
            bail!("--choice applies to discrete-time system files (`next` updates); {} is continuous-time", path.display());
        }
        return Ok(None);
    }
    run(a, sys, path).map(Some)
}

/// The network files `--network` names: a directory's `.nnet`/`.onnx` files in name
/// order, a comma-separated list, or one file.
fn network_paths(p: &Path) -> Result<Vec<PathBuf>> {
    if p.is_dir() {
        let mut v: Vec<PathBuf> = std::fs::read_dir(p)
            .with_context(|| format!("--network {}", p.display()))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|f| {
                f.extension().and_then(|e| e.to_str()).is_some_and(|e| {
                    e.eq_ignore_ascii_case("nnet") || e.eq_ignore_ascii_case("onnx")
                })
            })
            .collect();
        v.sort();
        if v.is_empty() {
            bail!(
                "--network {}: the directory holds no .nnet or .onnx file",
                p.display()
            );
        }
        return Ok(v);
    }
    Ok(p.to_string_lossy()
        .split(',')
        .map(|s| PathBuf::from(s.trim()))
        .collect())
}

/// `--init NAME=A:B` or `NAME=A` over the file's initial box.
fn apply_init(sys: &mut System, init: &[String]) -> Result<()> {
    for s in init {
        let Some((n, r)) = s.split_once('=') else {
            bail!("--init {s}: write NAME=A:B or NAME=A");
        };
        let Some(i) = sys.state_index(n.trim()) else {
            bail!(
                "--init {s}: `{n}` is not a state of the system (states: {})",
                sys.states.join(", ")
            );
        };
        let (lo, hi) = match r.split_once(':') {
            Some((l, h)) => (l.trim().parse::<f64>(), h.trim().parse::<f64>()),
            None => (r.trim().parse::<f64>(), r.trim().parse::<f64>()),
        };
        let (Ok(lo), Ok(hi)) = (lo, hi) else {
            bail!("--init {s}: the bounds are not numbers");
        };
        if !(lo.is_finite() && hi.is_finite() && lo <= hi) {
            bail!("--init {s}: give finite bounds with A <= B");
        }
        sys.init[i] = (lo, hi);
    }
    Ok(())
}

fn run(a: &ReachArgs, mut sys: System, path: &Path) -> Result<ExitCode> {
    let given: Vec<&str> = [
        (a.y0.is_some(), "--y0"),
        (a.goal_ystar.is_some(), "--goal-ystar"),
        (a.goal_from.is_some(), "--goal-from"),
        (a.no_clip, "--no-clip"),
        (a.order.is_some(), "--order"),
        (a.network_error.is_some(), "--network-error"),
        (a.shard.is_some(), "--shard"),
        (!a.grid.is_empty(), "--grid"),
        (a.target_ratio.is_some(), "--target-ratio"),
    ]
    .iter()
    .filter(|(on, _)| *on)
    .map(|(_, n)| *n)
    .collect();
    if !given.is_empty() {
        bail!(
            "{} do(es) not apply to a discrete-time system file (boxes with the sound argmax); it takes --network, --init, --choice, --max-leaves, --samples, --timeout, --out, --json",
            given.join(", ")
        );
    }
    apply_init(&mut sys, &a.init)?;
    let choice = match &a.choice {
        None => Choice::All,
        Some(c) => {
            Choice::parse(c).ok_or_else(|| anyhow!("--choice {c}: give all, middle, min or max"))?
        }
    };
    let paths = network_paths(&a.network)?;
    let mut nets = Vec::new();
    for p in &paths {
        nets.push(samara_nn::load(p).with_context(|| format!("--network {}", p.display()))?);
    }
    let ctrl = Controllers::new(&sys, nets)
        .map_err(|e| anyhow!("--network {}: {e}", a.network.display()))?;
    let mut s = DiscreteSettings {
        choice,
        ..Default::default()
    };
    if let Some(n) = a.max_leaves {
        s.max_sets = n;
    }
    if let Some(n) = a.samples {
        s.samples = n;
    }
    if let Some(t) = a.timeout {
        s.timeout = samara_num::Timeout::from_secs_f64(t).map_err(|e| anyhow!("--timeout {e}"))?;
    }
    let mut inputs = vec![("--system", path)];
    inputs.extend(paths.iter().map(|p| ("--network", p.as_path())));
    samara_report::guard::check_output_dir("--out", &a.out, &["reach.json"], &inputs)?;
    let out = samara_report::guard::OutDir::prepare(&a.out)?;
    let res = reach_discrete(&sys, &ctrl, &s).map_err(|e| anyhow!("{}: {e}", path.display()))?;
    let report = Report {
        system: path.display().to_string(),
        networks: paths.iter().map(|p| p.display().to_string()).collect(),
        choice,
        init: &sys.init,
        result: &res,
    };
    write_atomic(
        &a.out.join("reach.json"),
        json_text(&report, true)?.as_bytes(),
    )?;
    out.keep();
    let (name, reason) = match &res.verdict {
        DiscreteVerdict::Verified => ("verified", None),
        DiscreteVerdict::Falsified { .. } => ("falsified", None),
        DiscreteVerdict::Unknown { reason } => ("unknown", Some(reason.as_str())),
    };
    if a.json {
        let sm = Summary {
            verdict: name,
            reason,
            seconds: res.elapsed_s,
            steps: sys.steps(),
            sets_at_end: res.sets.last().map_or(0, |v| v.len()),
            splits: res.splits,
            mode_branches: res.mode_branches,
            choice,
        };
        println!("{}", json_text(&sm, true)?);
    } else {
        let detail = match &res.verdict {
            DiscreteVerdict::Verified => format!(
                "every goal holds on all {} sets at each of the {} steps ({} halvings, {} sets branched into several modes)",
                res.sets.iter().map(|v| v.len()).sum::<usize>(),
                sys.steps(),
                res.splits,
                res.mode_branches
            ),
            DiscreteVerdict::Falsified {
                trajectory,
                goal,
                step,
            } => format!(
                "`{goal}` fails at step {step} of a simulated trajectory from {:?} (states {:?}, mode {})",
                trajectory.states[0],
                trajectory.states[*step],
                mode_name(&sys, trajectory.modes[*step])
            ),
            DiscreteVerdict::Unknown { reason } => reason.clone(),
        };
        println!(
            "{}: {name} ({:.3} s, choice {:?}): {detail}",
            path.display(),
            res.elapsed_s,
            choice
        );
        eprintln!("wrote {}", a.out.display());
    }
    Ok(if name == "verified" {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

//! `samara reach --system FILE --network NETS` for a discrete-time system file (`next`
//! updates, a mode set by `argmax`, networks switched by the mode; docs/system.md,
//! "Discrete-time systems"): boxes with the sound argmax (`samara_reach::discrete`).
//!
//! `--network` is one network, a directory (its `.nnet`/`.onnx` files in name order, one
//! per mode value) or a comma-separated list; `--init NAME=A[:B]` replaces a state's
//! initial interval; `--choice` picks the input tables' values. [`run`] checks the flags,
//! flies the sets, writes `DIR/reach.json` atomically and returns what the fronts print.

use crate::reach::args::ReachArgs;
use anyhow::{anyhow, bail, Context, Result};
use samara_reach::discrete::{
    mode_name, reach_discrete, Choice, Controllers, DiscreteResult, DiscreteSettings,
    DiscreteVerdict,
};
use samara_report::write_atomic;
use samara_system::System;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// The report written to `reach.json`.
#[derive(Serialize)]
pub struct DiscreteReport<'a> {
    /// The system file.
    pub system: String,
    /// The networks, in mode order.
    pub networks: Vec<String>,
    /// Which table values the run used.
    pub choice: Choice,
    /// The initial box flown (after `--init`).
    pub init: &'a [(f64, f64)],
    /// The sets and the verdict.
    pub result: &'a DiscreteResult,
}

/// The `--json` summary.
#[derive(Serialize)]
pub struct DiscreteSummary {
    /// `proved`, `violated` or `unknown`.
    pub verdict: &'static str,
    /// Why, when unknown.
    pub reason: Option<String>,
    /// Wall time in seconds.
    pub seconds: f64,
    /// Steps of the file's horizon.
    pub steps: usize,
    /// Sets at the last instant reached.
    pub sets_at_end: usize,
    /// Halvings of ambiguous sets.
    pub splits: usize,
    /// Sets that branched into several modes.
    pub mode_branches: usize,
    /// Which table values the run used.
    pub choice: Choice,
}

/// What a discrete run gives its front: the summary, the human line, and whether every
/// goal was proved (exit 0; 1 otherwise).
pub struct DiscreteDone {
    /// The `--json` summary.
    pub summary: DiscreteSummary,
    /// The one-line text.
    pub human: String,
    /// Every goal proved.
    pub proved: bool,
}

/// `--choice` beside a continuous-time system file (`path`): refused, naming the file.
pub fn refuse_choice(a: &ReachArgs, path: &Path) -> Result<()> {
    if a.choice.is_some() {
        bail!(
            "--choice applies to discrete-time system files (`next` updates); {} is continuous-time",
            path.display()
        );
    }
    Ok(())
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

/// The flags that do not apply to a discrete file, refused by name.
fn refuse_continuous_flags(a: &ReachArgs) -> Result<()> {
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
    Ok(())
}

/// Run the discrete system `sys` (read from `path`) as `a` says: check the flags, load
/// the networks, fly the sets, write `reach.json` into `--out` (atomically; nothing is
/// written on bad input).
pub fn run(a: &ReachArgs, mut sys: System, path: &Path) -> Result<DiscreteDone> {
    refuse_continuous_flags(a)?;
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
    let report = DiscreteReport {
        system: path.display().to_string(),
        networks: paths.iter().map(|p| p.display().to_string()).collect(),
        choice,
        init: &sys.init,
        result: &res,
    };
    write_atomic(
        &a.out.join("reach.json"),
        crate::json_pretty(&report)?.as_bytes(),
    )?;
    out.keep();
    let summary = DiscreteSummary {
        verdict: res.verdict.name(),
        reason: match &res.verdict {
            DiscreteVerdict::Unknown { reason } => Some(reason.clone()),
            _ => None,
        },
        seconds: res.elapsed_s,
        steps: sys.steps(),
        sets_at_end: res.sets.last().map_or(0, |v| v.len()),
        splits: res.splits,
        mode_branches: res.mode_branches,
        choice,
    };
    let detail = match &res.verdict {
        DiscreteVerdict::Proved | DiscreteVerdict::NoGoal => format!(
            "every goal holds on all {} sets at each of the {} steps ({} halvings, {} sets branched into several modes)",
            res.sets.iter().map(|v| v.len()).sum::<usize>(),
            sys.steps(),
            res.splits,
            res.mode_branches
        ),
        DiscreteVerdict::Violated(v) => format!(
            "`{}` fails at step {} of a simulated trajectory from {:?} (states {:?}, mode {})",
            v.goal,
            v.step,
            v.trajectory.states[0],
            v.trajectory.states[v.step],
            mode_name(&sys, v.trajectory.modes[v.step])
        ),
        DiscreteVerdict::Unknown { reason } => reason.clone(),
    };
    let human = format!(
        "{}: {} ({:.3} s, choice {:?}): {detail}",
        path.display(),
        summary.verdict,
        res.elapsed_s,
        choice
    );
    Ok(DiscreteDone {
        proved: matches!(res.verdict, DiscreteVerdict::Proved),
        summary,
        human,
    })
}

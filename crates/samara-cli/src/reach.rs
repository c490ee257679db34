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

use anyhow::{anyhow, bail, Result};
pub use samara_app::reach::args::ReachArgs;
use samara_app::reach::args::{builtin_system, x_plus_y};
pub(crate) use samara_app::reach::glider::{self, WRITES};
use samara_app::reach::{Outcome, ReachSummary};
use samara_reach::parts;
use samara_reach::ReachSettings;
use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

use crate::json_text;
use crate::shard::Shard;

/// Start the global worker pool with `--threads` workers (all cores without it).
pub(crate) fn start_threads(a: &ReachArgs) -> Result<()> {
    crate::threads::start(a.threads)
}

/// Run `samara reach`.
pub fn run(a: &ReachArgs) -> Result<ExitCode> {
    // Taylor-model runs shard by their --grid (crate::reach_system); zonotope runs by
    // their initial pieces.
    let taylor = a.taylor();
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
            a.check_zonotope_flags()?;
            Ok(run_zonotope(a, false)?.0)
        }
        "taylor" => run_taylor(a),
        "auto" => {
            // The Taylor-model flags are checked now, not after the zonotope run.
            a.taylor_settings()?;
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

/// The built-in glider setting on Taylor-model sets: the shipped system file of the
/// model with the flags' initial set, period, horizon, clip and goal, and the glider's
/// tuning for the flags left out ([`ReachArgs::glider_tuned`]).
fn run_taylor(a: &ReachArgs) -> Result<ExitCode> {
    let a = &a.glider_tuned();
    let plan = a.plan(a.shard.is_some())?;
    for w in a.units_warnings(&plan) {
        eprintln!("warning: {w}");
    }
    let sys = builtin_system(&plan.settings)?;
    let xy = x_plus_y(&sys);
    crate::reach_system::run_system(a, &sys, Path::new("built-in setting"), &plan.net, vec![xy])
}

/// The built-in glider setting on zonotope sets; also whether the run has no result
/// (the verdict is `unknown`, or there is no goal and a sub-box lost its enclosure). With
/// `quiet_unknown` such a run is reported on stderr only (files written), leaving stdout
/// to the run that follows (`--sets auto`).
fn run_zonotope(a: &ReachArgs, quiet_unknown: bool) -> Result<(ExitCode, bool)> {
    let plan = a.plan(false)?;
    let warnings = a.units_warnings(&plan);
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
    let threads = a.threads.unwrap_or_else(rayon::current_num_threads);
    let o = glider::write_run(a, &plan, &res, warnings, threads)?;
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

/// `samara reach --shard I/N --out FILE`: part I of N of the run (the initial pieces
/// `Shard::range` of their number, each refined on its own) as a shard file.
fn run_shard(a: &ReachArgs, sh: Shard) -> Result<ExitCode> {
    match a.sets.as_str() {
        "zonotope" => a.check_zonotope_flags()?,
        "auto" => bail!("--shard with --sets auto: the two kinds of set are sharded differently; shard the zonotope run (--sets zonotope) or the Taylor-model run (--sets taylor with --grid)"),
        other => bail!("--sets {other}: give zonotope, taylor or auto"),
    }
    let plan = a.plan(true)?;
    let s = &plan.settings;
    let warnings = a.units_warnings(&plan);
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
    let threads = a.threads.unwrap_or_else(rayon::current_num_threads);
    let (line, human) =
        glider::write_shard(a, sh, s, &prep, range, &flown, secs, warnings, threads)?;
    if a.json {
        println!("{}", json_text(&line, false)?);
    } else {
        println!("{human}");
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
    let merged = glider::merge(shards)?;
    for w in &merged.outcome.warnings {
        eprintln!("warning: {w}");
    }
    let dir = samara_report::guard::OutDir::prepare(out)?;
    glider::write_merged(&merged, out)?;
    finish(&merged.outcome, &merged.settings, out, json_out, dir)
}

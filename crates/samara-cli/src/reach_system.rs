//! `samara reach --system FILE --network NET`: sound reachable sets of any closed loop
//! written as a system file (docs/system.md), with Taylor-model sets
//! (`samara_reach::system`). Writes `DIR/reach.json` (settings, verdict, the hull of the
//! state at each control instant and over each period, the sub-boxes) and prints one
//! line, or the JSON summary with `--json`.

use crate::json_text;
use crate::shard::{self, Shard};
use anyhow::{anyhow, bail, Context, Result};
use samara_app::reach::args::{check_fits, ReachArgs};
use samara_app::reach::system::{
    human_line, merge_taylor, success, SystemReport, SystemSettingsEcho, SystemSummary, TaylorRun,
    TaylorShard,
};
use samara_app::shard::Shards;
use samara_reach::grid;
use samara_reach::system::{reach_system, Measure, SystemReachSettings};
use samara_report::write_atomic;
use std::path::Path;
use std::process::ExitCode;

/// Files `reach --system` writes.
const WRITES: [&str; 1] = ["reach.json"];

/// Run `samara reach --system`.
pub fn run(a: &ReachArgs, path: &Path) -> Result<ExitCode> {
    // Parsed once: the file says whether it is a discrete-time system.
    let sys = samara_system::System::from_file(path).map_err(|e| anyhow!("{e}"))?;
    if sys.is_discrete() {
        return crate::reach_discrete::run(a, sys, path);
    }
    samara_app::reach::discrete::refuse_choice(a, path)?;
    a.check_system_flags()?;
    let net = samara_nn::load(&a.network)
        .with_context(|| format!("--network {}", a.network.display()))?;
    let measures = samara_reach::system::end_band_measures(&sys);
    run_system(a, &sys, path, &net, measures)
}

/// Reachability of a checked system under a loaded controller; `path` names the
/// system in messages and the report. With --grid the cells are flown as separate runs
/// (`samara_reach::grid`); with --shard only this shard's range of them, written as a
/// shard file for `samara merge reach`.
pub fn run_system(
    a: &ReachArgs,
    sys: &samara_system::System,
    path: &Path,
    net: &samara_nn::Network,
    measures: Vec<Measure>,
) -> Result<ExitCode> {
    check_fits(
        &format!("--network {}", a.network.display()),
        net,
        sys,
        &path.display().to_string(),
    )?;
    let s = a.system_settings(measures)?;
    let pieces = a.grid_pieces(sys)?;
    if let Some(r) = a.target_ratio {
        return crate::reach_adaptive::run(a, r, sys, path, net, s, pieces);
    }
    let inputs = if path.is_file() {
        vec![("--system", path), ("--network", a.network.as_path())]
    } else {
        vec![("--network", a.network.as_path())]
    };
    if let Some(sh) = a.shard {
        let Some(pieces) = pieces else {
            bail!("--shard with Taylor-model sets needs --grid NAME=K (the grid's cells are what the shards divide), e.g. --grid theta=3 --grid y=8");
        };
        return run_shard(a, sh, sys, path, net, &s, &pieces, &inputs);
    }
    crate::threads::start(a.threads)?;
    samara_report::guard::check_output_dir("--out", &a.out, &WRITES, &inputs)?;
    let out = samara_report::guard::OutDir::prepare(&a.out)?;
    let res = match &pieces {
        None => reach_system(sys, net, &s),
        Some(p) => {
            let total = grid::cell_count(sys, p).map_err(|e| anyhow!("--grid: {e}"))?;
            grid::reach_cells(sys, net, &s, p, 0..total)
        }
    }
    .map_err(|e| anyhow!("{}: {e}", path.display()))?;
    let report = SystemReport {
        system: path.display().to_string(),
        network: a.network.display().to_string(),
        settings: SystemSettingsEcho::new(&s, pieces.as_deref()),
        result: res,
    };
    let code = write_report(&a.out, a.json, &report)?;
    out.keep();
    Ok(code)
}

/// Write `out/reach.json` and print the human line (or the JSON summary); the exit code
/// of the verdict. Shared by runs and `samara merge reach` of Taylor-model shards.
fn write_report(out: &Path, json: bool, report: &SystemReport) -> Result<ExitCode> {
    write_atomic(&out.join("reach.json"), json_text(report, true)?.as_bytes())?;
    let res = &report.result;
    if json {
        println!("{}", json_text(&SystemSummary::new(res), true)?);
    } else {
        println!("{}", human_line(&report.system, res));
        eprintln!("wrote {}", out.display());
    }
    Ok(if success(res) {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// `--shard I/N` of a Taylor-model grid run: cells `Shard::range` of the grid's, written
/// as a shard file.
#[allow(clippy::too_many_arguments)]
fn run_shard(
    a: &ReachArgs,
    sh: Shard,
    sys: &samara_system::System,
    path: &Path,
    net: &samara_nn::Network,
    s: &SystemReachSettings,
    pieces: &[usize],
    inputs: &[(&str, &Path)],
) -> Result<ExitCode> {
    samara_report::guard::check_output_file("--out", &a.out, inputs)?;
    let total = grid::cell_count(sys, pieces).map_err(|e| anyhow!("--grid: {e}"))?;
    let range = sh.range(total);
    if range.is_empty() {
        bail!(
            "--shard {}/{}: the grid has {total} cells, fewer than the {} shards; use at most {total} shards or a finer --grid",
            sh.i,
            sh.n,
            sh.n
        );
    }
    let network = shard::digest_inputs([(
        "--network".to_string(),
        a.network.as_path(),
        "--network".to_string(),
    )])?;
    let run = TaylorRun::new(sys, network["--network"].clone(), s, pieces, total);
    crate::threads::start(a.threads)?;
    let res = grid::reach_cells(sys, net, s, pieces, range.clone())
        .map_err(|e| anyhow!("{}: {e}", path.display()))?;
    let result = TaylorShard {
        cells: (range.start, range.end),
        system_name: path.display().to_string(),
        network_name: a.network.display().to_string(),
        reach: res,
    };
    let (line, human) = result.write(&a.out, sh, &run)?;
    if a.json {
        println!("{}", json_text(&line, false)?);
    } else {
        println!("{human}");
    }
    Ok(ExitCode::SUCCESS)
}

/// `samara merge reach` of Taylor-model grid shards
/// (`samara_app::reach::system::merge_taylor`), written as the one-process run writes
/// them.
pub fn merge_shards(shards: &Shards, out: &Path, json: bool) -> Result<ExitCode> {
    if !shards.run["target_ratio"].is_null() {
        return crate::reach_adaptive::merge_shards(shards, out, json);
    }
    let run: TaylorRun = shards.run_as()?;
    let report = merge_taylor(&run, &shards.results_as::<TaylorShard>()?)?;
    let dir = samara_report::guard::OutDir::prepare(out)?;
    let code = write_report(out, json, &report)?;
    dir.keep();
    Ok(code)
}

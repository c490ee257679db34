//! `samara reach ... --target-ratio R`: Taylor-model sets with adaptive splitting toward
//! a width target (`samara_reach::adaptive`): the cells are cut where an enclosure is
//! lost or the measure at the horizon (the glider's x + y, a system file's first
//! `goal band ... at end`) leaves the band that keeps the hull within R times the
//! flights' spread. Writes `DIR/reach.json` (the system run's report plus an `adaptive`
//! object) and prints one line, or the JSON summary with `--json`.

use crate::json_text;
use crate::shard::Shard;
use anyhow::{anyhow, bail, Result};
use samara_app::reach::adaptive::{
    adaptive_success, adaptive_text, checkpoint_path, run_shard as run_shard_cells, AdaptiveEcho,
    AdaptiveReport, AdaptiveSummary, ShardRun,
};
use samara_app::reach::args::ReachArgs;
use samara_app::reach::system::{human_line, SystemSummary};
use samara_reach::adaptive::{reach_adaptive, AdaptiveReach, AdaptiveSettings};
use samara_reach::system::SystemReachSettings;
use samara_report::write_atomic;
use std::path::Path;
use std::process::ExitCode;
use std::sync::Arc;

/// Run the adaptive mode on a checked system (`s`: the run's settings with their
/// measures, `pieces`: --grid as the starting cells).
pub(crate) fn run(
    a: &ReachArgs,
    ratio: f64,
    sys: &samara_system::System,
    path: &Path,
    net: &samara_nn::Network,
    s: SystemReachSettings,
    pieces: Option<Vec<usize>>,
) -> Result<ExitCode> {
    a.check_adaptive(ratio, !s.measures.is_empty(), path)?;
    crate::threads::start(a.threads)?;
    let inputs = if path.is_file() {
        vec![("--system", path), ("--network", a.network.as_path())]
    } else {
        vec![("--network", a.network.as_path())]
    };
    if let Some(sh) = a.shard {
        let Some(pieces) = pieces else {
            bail!("--shard with --target-ratio needs --grid NAME=K");
        };
        return run_shard(a, ratio, sys, path, net, &s, &pieces, sh, &inputs);
    }
    samara_report::guard::check_output_dir("--out", &a.out, &["reach.json"], &inputs)?;
    let out = samara_report::guard::OutDir::prepare(&a.out)?;
    let settings = AdaptiveSettings {
        target_ratio: ratio,
        measure: 0,
        pieces: pieces.clone(),
        on_round: Some(Arc::new(|line: &str| eprintln!("{line}"))),
        ..AdaptiveSettings::default()
    };
    let res =
        reach_adaptive(sys, net, &s, &settings).map_err(|e| anyhow!("{}: {e}", path.display()))?;
    let system = path.display().to_string();
    let report = AdaptiveReport::new(
        &system,
        &a.network.display().to_string(),
        &s,
        pieces.as_deref(),
        &res,
    );
    let code = write_adaptive(&a.out, a.json, &report, &res)?;
    out.keep();
    Ok(code)
}

/// Write `out/reach.json` of an adaptive run and print its line (or the JSON summary);
/// the exit code. Shared by one-process runs and `samara merge reach` of their shards.
pub(crate) fn write_adaptive(
    out: &Path,
    json: bool,
    report: &AdaptiveReport,
    res: &AdaptiveReach,
) -> Result<ExitCode> {
    write_atomic(&out.join("reach.json"), json_text(report, true)?.as_bytes())?;
    if json {
        let summary = AdaptiveSummary {
            run: SystemSummary::new(&res.reach),
            adaptive: AdaptiveEcho::new(res, false),
        };
        println!("{}", json_text(&summary, true)?);
    } else {
        println!(
            "{}; {}",
            human_line(&report.system, &res.reach),
            adaptive_text(res)
        );
        eprintln!("wrote {}", out.display());
    }
    Ok(if adaptive_success(res) {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

/// `--shard I/N` of an adaptive run: the grid's starting cells `I` mod `N`, checkpointed
/// to `OUT.cells` as they finish (a rerun resumes), written as the shard file `OUT`.
/// Exit 0 when the shard finished, 1 when it stopped early (not mergeable yet).
#[allow(clippy::too_many_arguments)]
fn run_shard(
    a: &ReachArgs,
    ratio: f64,
    sys: &samara_system::System,
    path: &Path,
    net: &samara_nn::Network,
    s: &SystemReachSettings,
    pieces: &[usize],
    sh: Shard,
    inputs: &[(&str, &Path)],
) -> Result<ExitCode> {
    samara_report::guard::check_output_file("--out", &a.out, inputs)?;
    let network = crate::shard::digest_inputs([(
        "--network".to_string(),
        a.network.as_path(),
        "--network".to_string(),
    )])?;
    let cp = checkpoint_path(&a.out);
    let done = run_shard_cells(ShardRun {
        sys,
        net,
        settings: s,
        pieces,
        target_ratio: ratio,
        shard: sh,
        checkpoint: Some(&cp),
        system_name: path.display().to_string(),
        network_name: a.network.display().to_string(),
        network_digest: network["--network"].clone(),
        on_round: Some(Arc::new(|line: &str| eprintln!("{line}"))),
    })?;
    if let Some(e) = &done.checkpoint_error {
        eprintln!("warning: {e} (the shard's result is complete; a rerun would start afresh)");
    }
    crate::shard::write(&a.out, "reach", sh, &done.run, &done.result)?;
    let (line, human) = done.lines(sh, &a.out);
    if a.json {
        println!("{}", json_text(&line, false)?);
    } else {
        println!("{human}");
    }
    // A shard stopped early (its --timeout or --max-leaves) cannot be merged: exit 1, so
    // that a job array sees it and runs it again (it resumes from its checkpoint).
    Ok(if done.result.adaptive.stopped.is_some() {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}
/// `samara merge reach` of adaptive shards (`samara_app::reach::adaptive::merge_shards`),
/// written as the one-process run writes them.
pub(crate) fn merge_shards(
    shards: &samara_app::shard::Shards,
    out: &Path,
    json: bool,
) -> Result<ExitCode> {
    let run: samara_app::reach::system::TaylorRun = shards.run_as()?;
    let parts = shards.results_as::<samara_app::reach::adaptive::AdaptiveShard>()?;
    let (report, res) = samara_app::reach::adaptive::merge_shards(&run, &parts)?;
    let dir = samara_report::guard::OutDir::prepare(out)?;
    let code = write_adaptive(out, json, &report, &res)?;
    dir.keep();
    Ok(code)
}

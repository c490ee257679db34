//! `samara reach ... --target-ratio R`: Taylor-model sets with adaptive splitting toward
//! a width target (`samara_reach::adaptive`): the cells are cut where an enclosure is
//! lost or the measure at the horizon (the glider's x + y, a system file's first
//! `goal band ... at end`) leaves the band that keeps the hull within R times the
//! flights' spread. Writes `DIR/reach.json` (the system run's report plus an `adaptive`
//! object) and prints one line, or the JSON summary with `--json`.

use crate::json_text;
use anyhow::{anyhow, Result};
use samara_app::reach::adaptive::{
    adaptive_success, adaptive_text, AdaptiveEcho, AdaptiveReport, AdaptiveSettingsEcho,
    AdaptiveSummary,
};
use samara_app::reach::args::ReachArgs;
use samara_app::reach::system::{human_line, SystemSettingsEcho, SystemSummary};
use samara_reach::adaptive::{reach_adaptive, AdaptiveSettings};
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
    samara_report::guard::check_output_dir("--out", &a.out, &["reach.json"], &inputs)?;
    let out = samara_report::guard::OutDir::prepare(&a.out)?;
    let settings = AdaptiveSettings {
        target_ratio: ratio,
        measure: 0,
        pieces: pieces.clone(),
        on_round: Some(Arc::new(|line: &str| eprintln!("{line}"))),
        shard: None,
    };
    let res =
        reach_adaptive(sys, net, &s, &settings).map_err(|e| anyhow!("{}: {e}", path.display()))?;
    let system = path.display().to_string();
    let report = AdaptiveReport {
        system: system.clone(),
        network: a.network.display().to_string(),
        settings: AdaptiveSettingsEcho {
            run: SystemSettingsEcho::new(&s, pieces.as_deref()),
            target_ratio: ratio,
        },
        result: res.reach.clone(),
        adaptive: AdaptiveEcho::new(&res, true),
    };
    write_atomic(
        &a.out.join("reach.json"),
        json_text(&report, true)?.as_bytes(),
    )?;
    if a.json {
        let summary = AdaptiveSummary {
            run: SystemSummary::new(&res.reach),
            adaptive: AdaptiveEcho::new(&res, false),
        };
        println!("{}", json_text(&summary, true)?);
    } else {
        println!(
            "{}; {}",
            human_line(&system, &res.reach),
            adaptive_text(&res)
        );
        eprintln!("wrote {}", a.out.display());
    }
    out.keep();
    Ok(if adaptive_success(&res) {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

//! `samara reproduce`.

use anyhow::Result;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;

/// Flags of `samara reproduce`: the whole case study in one command.
#[derive(clap::Args, Debug)]
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
    /// Recompute every stage (ignore the cache of finished stages).
    #[arg(long)]
    pub fresh: bool,
    /// Print results.json on stdout.
    #[arg(long)]
    pub json: bool,
}

/// Run `samara reproduce`.
pub fn run(a: &ReproduceArgs) -> Result<ExitCode> {
    let opts = samara_repro::ReproduceOptions {
        out: a.out.clone(),
        quick: a.quick,
        published: a.published.clone(),
        fresh: a.fresh,
        progress: std::io::stderr().is_terminal() && !a.json,
        command_line: std::env::args().collect::<Vec<_>>().join(" "),
    };
    let outcome = samara_repro::run(&opts)?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&outcome.results)?);
    } else {
        if !outcome.reused.is_empty() {
            eprintln!(
                "reused finished stages: {} (pass --fresh to recompute)",
                outcome.reused.join(", ")
            );
        }
        eprintln!(
            "done in {:.1} s: {}/report.html, {}/report.md, {}/results.json",
            outcome.seconds,
            a.out.display(),
            a.out.display(),
            a.out.display()
        );
    }
    Ok(ExitCode::SUCCESS)
}

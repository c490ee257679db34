//! `samara reproduce`.

use anyhow::{bail, Result};
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

/// What a run writes at the top of `--out`.
const WRITES: [&str; 8] = [
    "data",
    "figures",
    "networks",
    "tables",
    ".cache",
    "report.html",
    "report.md",
    "results.json",
];

/// Run `samara reproduce`.
pub fn run(a: &ReproduceArgs) -> Result<ExitCode> {
    // The spec first: a bad one stops the run before any folder is created.
    let spec = match &a.spec {
        Some(p) => samara_repro::ReproSpec::read(p)?,
        None => samara_repro::ReproSpec::shipped(),
    };
    let mut inputs: Vec<(&str, &std::path::Path)> = Vec::new();
    if let Some(p) = &a.spec {
        inputs.push(("--spec", p));
    }
    if let Some(p) = &a.published {
        // Check the input before any folder is created, and never write into it.
        if !p.is_dir() {
            bail!(
                "--published {}: no such directory; give a folder laid out like the published reference/ (Training_Data.csv, *_norm.onnx, *_denorm.onnx)",
                p.display()
            );
        }
        inputs.push(("--published", p));
    }
    if !inputs.is_empty() {
        samara_report::guard::check_output_dir("--out", &a.out, &WRITES, &inputs)?;
    }
    let out = samara_report::guard::OutDir::prepare(&a.out)?;
    let opts = samara_repro::ReproduceOptions {
        out: a.out.clone(),
        quick: a.quick,
        published: a.published.clone(),
        fresh: a.fresh,
        progress: std::io::stderr().is_terminal() && !a.json,
        command_line: std::env::args().collect::<Vec<_>>().join(" "),
        spec,
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
    out.keep();
    Ok(ExitCode::SUCCESS)
}

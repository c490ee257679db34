//! `samara reproduce`.

use anyhow::{bail, Result};
pub use samara_app::args::ReproduceArgs;
use std::io::IsTerminal;
use std::process::ExitCode;

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

//! `samara reach --system FILE` for a discrete-time system file: parse, call
//! `samara_app::reach::discrete`, print. Exit 0 proved, 1 violated or unknown, 2 bad input.

use crate::json_text;
use anyhow::Result;
use samara_app::reach::args::ReachArgs;
use samara_app::reach::discrete;
use std::path::Path;
use std::process::ExitCode;

/// If `path` is a discrete-time system, run it and return the exit code; `None` for a
/// continuous system (the caller goes on with Taylor-model sets).
pub fn route(a: &ReachArgs, path: &Path) -> Result<Option<ExitCode>> {
    let Some(sys) = discrete::discrete_system(a, path)? else {
        return Ok(None);
    };
    let done = discrete::run(a, sys, path)?;
    if a.json {
        println!("{}", json_text(&done.summary, true)?);
    } else {
        println!("{}", done.human);
        eprintln!("wrote {}", a.out.display());
    }
    Ok(Some(if done.proved {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    }))
}

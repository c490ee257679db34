//! `samara reach --system FILE` for a discrete-time system file: parse, call
//! `samara_app::reach::discrete`, print. Exit 0 proved, 1 violated or unknown, 2 bad input.

use crate::json_text;
use anyhow::Result;
use samara_app::reach::args::ReachArgs;
use samara_app::reach::discrete;
use std::path::Path;
use std::process::ExitCode;

/// Run the discrete-time system `sys`, read from `path`, and return the exit code.
pub fn run(a: &ReachArgs, sys: samara_system::System, path: &Path) -> Result<ExitCode> {
    let done = discrete::run(a, sys, path)?;
    if a.json {
        println!("{}", json_text(&done.summary, true)?);
    } else {
        println!("{}", done.human);
        eprintln!("wrote {}", a.out.display());
    }
    Ok(if done.proved {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}

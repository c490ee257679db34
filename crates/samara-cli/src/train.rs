//! `samara train`: the run is `samara_app::train::run` (flags checked, network trained,
//! files written); this prints what it gives back.

use anyhow::Result;
pub use samara_app::args::TrainArgs;
use samara_app::train::TrainRun;
use std::io::IsTerminal;
use std::process::ExitCode;

/// Run `samara train`.
pub fn run(a: &TrainArgs) -> Result<ExitCode> {
    let done = match samara_app::train::run(a, std::io::stderr().is_terminal())? {
        TrainRun::Done(d) => d,
        TrainRun::Failed(e) => {
            eprintln!("error: {e}; nothing was written");
            return Ok(ExitCode::from(1));
        }
    };
    if a.json {
        println!("{}", crate::json_text(&done.doc, true)?);
    } else {
        for l in &done.human {
            eprintln!("{l}");
        }
    }
    match &done.not_proved {
        Some(m) => {
            eprintln!("{m}");
            Ok(ExitCode::from(1))
        }
        None => Ok(ExitCode::SUCCESS),
    }
}

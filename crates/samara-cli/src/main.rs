//! `samara`: the command-line shell over the samara libraries. Every subcommand parses
//! its flags into the library's settings and calls the library; nothing else lives here.
//!
//! Exit codes (as ripgrep): 0 success, 1 a property was violated or a check failed,
//! 2 a usage or input error.

mod nnload;
mod reach;
mod reproduce;
mod simulate;
mod train;
mod verify;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// samara: from data to proof for neural-network controllers of the Alsomitra glider.
#[derive(Parser)]
#[command(name = "samara", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Simulate the closed loop (plant + PID, constant or network controller); write
    /// trajectories, the training data set, its normalisation constants and figures.
    Simulate(simulate::SimulateArgs),
    /// Train a controller network (plain, adversarial, lipschitz, dl2, goedel) and
    /// export it to ONNX.
    Train(train::TrainArgs),
    /// Parse and type-check a specification; summarise its properties.
    Check(verify::CheckArgs),
    /// Prove or refute the properties of a specification exactly.
    Verify(verify::VerifyArgs),
    /// The exact critical value of a parameter for which a property holds.
    Critical(verify::CriticalArgs),
    /// Local-robustness tables (P5) over a data set.
    Robustness(verify::RobustnessArgs),
    /// Check one VNN-LIB 1.0 property on one network (VNN-COMP style: sat/unsat/unknown).
    VerifyVnnlib(verify::VerifyVnnlibArgs),
    /// Write each property instance as a VNN-LIB 1.0 file.
    ExportVnnlib(verify::ExportArgs),
    /// Sound reachable sets of the closed loop (plant + network) from an initial box,
    /// with a goal |x + y| <= Y decided: proved, violated or unknown.
    Reach(reach::ReachArgs),
    /// Reproduce the whole case study (data, controllers, proofs, reachable sets,
    /// figures, report) in one command.
    Reproduce(reproduce::ReproduceArgs),
}

fn main() -> ExitCode {
    let cli = match Cli::try_parse() {
        Ok(c) => c,
        Err(e) => {
            let _ = e.print();
            return match e.kind() {
                clap::error::ErrorKind::DisplayHelp | clap::error::ErrorKind::DisplayVersion => {
                    ExitCode::SUCCESS
                }
                _ => ExitCode::from(2),
            };
        }
    };
    let result = match &cli.command {
        Command::Simulate(a) => simulate::run(a),
        Command::Reach(a) => reach::run(a),
        Command::Reproduce(a) => reproduce::run(a),
        Command::Train(a) => train::run(a),
        Command::Check(a) => verify::run_check(a),
        Command::Verify(a) => verify::run_verify(a),
        Command::Critical(a) => verify::run_critical(a),
        Command::Robustness(a) => verify::run_robustness(a),
        Command::ExportVnnlib(a) => verify::run_export(a),
        Command::VerifyVnnlib(a) => verify::run_verify_vnnlib(a),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::from(2)
        }
    }
}

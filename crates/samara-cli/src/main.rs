//! `samara`: the command-line shell over the samara libraries. Every subcommand parses
//! its flags into the library's settings and calls the library; nothing else lives here.
//!
//! Exit codes (as ripgrep): 0 success, 1 a property was violated or a check failed,
//! 2 a usage or input error.

mod merge;
mod reach;
mod reach_adaptive;
mod reach_discrete;
mod reach_system;
mod reproduce;
mod shard;
mod simulate;
mod threads;
mod train;
mod verify;
mod vnncomp;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// samara: from data to proof for neural-network controllers of the Alsomitra glider.
#[derive(Parser)]
#[command(name = "samara", version, about, long_about = None, after_help = EXIT_CODES)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// The exit codes, shown at the end of every subcommand's help.
const EXIT_CODES: &str = "Exit codes: 0 success, 1 a property was violated or a check failed \
(unknown counts as not proved), 2 a usage or input error (the message names the flag or \
file, the place and the fix).";

macro_rules! help {
    ($($line:expr),+ $(,)?) => {
        concat!("Examples:\n", $("  ", $line, "\n",)+ "\n",
            "Exit codes: 0 success, 1 a property was violated or a check failed \
(unknown counts as not proved), 2 a usage or input error (the message names the flag or \
file, the place and the fix).")
    };
}

#[derive(Subcommand)]
enum Command {
    /// Simulate the closed loop (plant + PID, constant or network controller); write
    /// trajectories, the training data set, its normalisation constants and figures.
    #[command(after_help = help!(
        "samara simulate --out out/sim                      # the published protocol (PID, nine starts)",
        "samara simulate --controller net.onnx --y0 -1:2:5 --out out/net --json",
        "samara simulate --controller constant:0.187 --y0 2,3 --horizon 10 --no-plot --out out/c",
    ))]
    Simulate(simulate::SimulateArgs),
    /// Train a controller network (plain, adversarial, lipschitz, dl2, goedel) and
    /// export it to ONNX.
    #[command(after_help = help!(
        "samara train --data out/sim/training_data.csv --out net.onnx",
        "samara train --data Training_Data.csv --method adversarial --eps 0.005 --seed 1 --out adv.onnx",
    ))]
    Train(train::TrainArgs),
    /// Parse and type-check a specification; summarise its properties.
    #[command(after_help = help!("samara check models/alsomitra/alsomitra.spec"))]
    Check(verify::CheckArgs),
    /// Prove or refute the properties of a specification exactly.
    #[command(after_help = help!(
        "samara verify models/alsomitra/alsomitra.spec --network f=base_model_norm.onnx",
        "samara verify SPEC --network f=net.onnx --param ystar=2 --property P1 --json",
    ))]
    Verify(verify::VerifyArgs),
    /// The exact critical value of a parameter for which a property holds.
    #[command(after_help = help!(
        "samara critical models/alsomitra/alsomitra.spec --property P1 --network f=base_model_norm.onnx",
    ))]
    Critical(verify::CriticalArgs),
    /// Local-robustness tables (P5) over a data set.
    #[command(after_help = help!(
        "samara robustness --network base_model_norm.onnx --data Training_Data_Normalised.csv",
        "samara robustness --network net.onnx --data data.csv --eps 1e-3,1e-2 --out p5.csv --json",
    ))]
    Robustness(verify::RobustnessArgs),
    /// Check one VNN-LIB 1.0 property on one network (VNN-COMP style: sat/unsat/unknown).
    #[command(after_help = help!(
        "samara verify-vnnlib --network net.onnx --property p.vnnlib   # exit 0 unsat, 1 sat or unknown",
    ))]
    VerifyVnnlib(verify::VerifyVnnlibArgs),
    /// Write each property instance as a VNN-LIB 1.0 file.
    #[command(after_help = help!(
        "samara export-vnnlib models/alsomitra/alsomitra.spec --out out/vnnlib --network f=base_model_norm.onnx",
    ))]
    ExportVnnlib(verify::ExportArgs),
    Vnncomp(vnncomp::VnncompArgs),
    /// Merge the shard files of a `--shard I/N` run (robustness, vnncomp, reach) into
    /// what one process writes.
    Merge(merge::MergeArgs),
    /// Sound reachable sets of the closed loop (plant + network) from an initial box,
    /// with a goal |x + y| <= Y decided: proved, violated or unknown.
    #[command(after_help = help!(
        "samara reach --network base_model_denorm.onnx --goal-ystar 2 --out out/reach",
        "samara reach --network net.onnx --y0 2:2.5 --init theta=-0.01:0.01 --horizon 5 --out out/r --json",
        "samara reach --network net.onnx --goal-ystar 2 --shard $SLURM_ARRAY_TASK_ID/8 --out r-$SLURM_ARRAY_TASK_ID.json",
        "samara merge reach r-*.json --out out/reach   # the 8 parts: the one-process reach.json and figures",
        "(exit 0: proved or no goal; 1: violated or unknown; 2: bad input)",
    ))]
    Reach(reach::ReachArgs),
    /// Reproduce the whole case study (data, controllers, proofs, reachable sets,
    /// figures, report) in one command.
    #[command(after_help = help!(
        "samara reproduce --quick --out out/quick",
        "samara reproduce --quick --spec my.spec --out out/edited   # P1-P4 from an edited copy of the spec",
        "samara reproduce --published ../shared/reference --out out/reproduce",
    ))]
    Reproduce(reproduce::ReproduceArgs),
    /// Print a shell completion script (bash, zsh, fish, powershell, elvish) on stdout.
    #[command(after_help = help!(
        "samara completions bash > ~/.local/share/bash-completion/completions/samara",
        "samara completions zsh > ~/.zfunc/_samara",
        "samara completions fish > ~/.config/fish/completions/samara.fish",
    ))]
    Completions {
        /// The shell.
        #[arg(value_enum)]
        shell: clap_complete::Shell,
    },
}

fn main() -> ExitCode {
    quiet_on_broken_pipe();
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
        Command::Verify(a) => threads::start(a.threads.threads).and_then(|_| verify::run_verify(a)),
        Command::Critical(a) => {
            threads::start(a.threads.threads).and_then(|_| verify::run_critical(a))
        }
        Command::Robustness(a) => {
            threads::start(a.threads.threads).and_then(|_| verify::run_robustness(a))
        }
        Command::ExportVnnlib(a) => verify::run_export(a),
        Command::VerifyVnnlib(a) => {
            threads::start(a.threads.threads).and_then(|_| verify::run_verify_vnnlib(a))
        }
        Command::Vnncomp(a) => {
            threads::start(a.threads.threads).and_then(|_| vnncomp::run_vnncomp(a))
        }
        Command::Merge(a) => merge::run_merge(a),
        Command::Completions { shell } => {
            use clap::CommandFactory;
            let mut cmd = Cli::command();
            clap_complete::generate(*shell, &mut cmd, "samara", &mut std::io::stdout());
            Ok(ExitCode::SUCCESS)
        }
    };
    match result {
        Ok(code) => code,
        Err(e) if is_broken_pipe(&e) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {}", error_chain(&e));
            ExitCode::from(2)
        }
    }
}

/// The JSON text of a typed result as the CLI prints it: through `serde_json::Value`, so
/// keys are sorted (the layout every `--json` document and output file has had).
pub(crate) fn json_text<T: serde::Serialize>(v: &T, pretty: bool) -> anyhow::Result<String> {
    Ok(if pretty {
        samara_app::json_pretty(v)?
    } else {
        serde_json::to_value(v)?.to_string()
    })
}

/// Whether `text` is the message of a write into a closed pipe (`EPIPE`), as printed by
/// `std::io::Error` ("Broken pipe (os error 32)") or by `println!`'s panic.
fn mentions_broken_pipe(text: &str) -> bool {
    text.contains("Broken pipe") || text.contains("os error 32")
}

/// Whether an error (or one of its causes) is a write into a closed pipe.
fn is_broken_pipe(e: &anyhow::Error) -> bool {
    e.chain().any(|c| {
        c.downcast_ref::<std::io::Error>()
            .is_some_and(|io| io.kind() == std::io::ErrorKind::BrokenPipe)
            || mentions_broken_pipe(&c.to_string())
    })
}

/// Make a write to a closed stdout end the program quietly with exit code 0, as ripgrep
/// and other good CLIs do (`samara verify-vnnlib ... --json | head -c 10`), instead of
/// `println!`'s panic message "failed printing to stdout: Broken pipe". Rust ignores
/// `SIGPIPE`, so the write returns `EPIPE` and `println!` panics; this panic hook
/// recognises that panic (in any thread) and exits at once. Every other panic keeps the
/// default report.
fn quiet_on_broken_pipe() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let payload = info.payload();
        let text = payload
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| payload.downcast_ref::<&str>().copied())
            .unwrap_or("");
        if mentions_broken_pipe(text) {
            std::process::exit(0);
        }
        default(info)
    }));
}

/// The message of `e` and its causes (`samara_app::error_text`: each cause once).
fn error_chain(e: &anyhow::Error) -> String {
    samara_app::error_text(e)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Debug, thiserror::Error)]
    #[error("f.onnx: cannot read: {source}")]
    struct Read {
        source: std::io::Error,
    }

    #[test]
    fn an_os_error_is_printed_once() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "No such file");
        let e = anyhow::Error::new(Read { source: io }).context("--network f.onnx");
        assert_eq!(
            error_chain(&e),
            "--network f.onnx: f.onnx: cannot read: No such file"
        );
        let e = anyhow::anyhow!("outer").context("ctx");
        assert_eq!(error_chain(&e), "ctx: outer");
    }

    #[test]
    fn the_cli_definition_is_consistent() {
        use clap::CommandFactory;
        Cli::command().debug_assert();
    }
}

//! The application layer of samara: what the command-line tool (`samara-cli`) and the
//! Python package (`python/`) share, so that neither copies the other.
//!
//! - [`bind`]: a specification with its networks, parameters and data sets bound and
//!   checked ([`Loaded`]), with messages that name the argument the way the caller's
//!   users wrote it ([`Front`]: `--network f=FILE` on the command line,
//!   `networks["f"]` in Python);
//! - [`verify`]: proving every instance of the selected properties ([`run_verify`]) and
//!   the two-sided critical value of a parameter ([`critical_value`]);
//! - [`robustness`]: the robustness table of a sweep;
//! - [`reach`]: reachability results (`reach.json`, summaries, the human lines) and the
//!   reach shard files with their merge;
//! - [`shard`]: the shard files of `--shard I/N` runs and their checks;
//! - [`simulate`], [`train`]: simulation and training runs (their checks, the runs,
//!   their files and summaries);
//! - [`check`], [`export`]: `samara check` (every property lowered) and
//!   `samara export-vnnlib`; the human lines of verify and critical are methods of
//!   their results;
//! - [`python_front`]: the checks and results of the Python package's calls;
//! - [`vnncomp`]: deciding one VNN-COMP instance with the counterexample re-check and
//!   downgrade policy, and the competition's result words and files.
//!
//! Every result is a typed value deriving `Serialize`/`Deserialize`; its JSON (serde's
//! map with sorted keys) is the `--json` document of the CLI.

pub mod args;
pub mod benchmark;
pub mod bind;
pub mod check;
pub mod export;
mod human;
pub mod python_front;
pub mod reach;
pub mod robustness;
pub mod robustness_form;
pub mod shard;
pub mod simulate;
pub mod train;
pub mod verify;
pub mod vnncomp;

pub use bind::{check_horizon_period, suggest, Front, Loaded};
pub use verify::{critical_value, run_verify, CriticalValue, Holds, VerdictRow};

use serde::{Deserialize, Serialize};

/// An error of the application layer: bad input (the CLI's exit code 2, Python's
/// `ValueError`) or a failed computation (Python's `SamaraError`).
#[derive(Debug, thiserror::Error)]
pub enum AppError {
    /// A bad argument or input file; the message names it and the fix.
    #[error("{0}")]
    Input(String),
    /// The verifier refused or failed on a query.
    #[error(transparent)]
    Verify(#[from] samara_verify::VerifyError),
}

/// `Err(AppError::Input(message))`.
pub fn input<T>(m: impl Into<String>) -> Result<T, AppError> {
    Err(AppError::Input(m.into()))
}

/// Why a search gave no verdict: the machine-readable `kind` (`timeout`, `node_limit`,
/// ...) and the human message.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Reason {
    /// `UnknownReason::kind`.
    pub kind: String,
    /// `UnknownReason`'s text.
    pub message: String,
}

impl From<&samara_verify::UnknownReason> for Reason {
    fn from(r: &samara_verify::UnknownReason) -> Self {
        Reason {
            kind: r.kind().to_string(),
            message: r.to_string(),
        }
    }
}

/// Serde adapter for a float that serde_json writes as `null` when it is not finite:
/// `null` reads back as NaN (the value is not a number either way).
pub mod nan_as_null {
    use serde::{Deserialize, Deserializer, Serializer};

    /// Write the number (serde_json: `null` if not finite).
    pub fn serialize<S: Serializer>(x: &f64, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_f64(*x)
    }

    /// Read a number, `null` as NaN.
    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
    }
}

/// The JSON text of a typed result as the CLI prints it and writes its files: through
/// `serde_json::Value`, so keys are sorted (the layout every `--json` document and
/// output file has had), pretty-printed.
pub fn json_pretty<T: Serialize>(v: &T) -> serde_json::Result<String> {
    serde_json::to_string_pretty(&serde_json::to_value(v)?)
}

/// The message of `e` and its causes joined by `: `, skipping a cause whose text the
/// message already carries (library errors often print their source themselves, as in
/// `cannot read: No such file or directory (os error 2)`; anyhow's `{:#}` would then
/// print the OS error twice). The CLI prints its errors so.
pub fn error_text(e: &anyhow::Error) -> String {
    let mut msg = String::new();
    for cause in e.chain() {
        let c = cause.to_string();
        if c.is_empty() || msg.contains(&c) {
            continue;
        }
        if !msg.is_empty() {
            msg.push_str(": ");
        }
        msg.push_str(&c);
    }
    msg
}

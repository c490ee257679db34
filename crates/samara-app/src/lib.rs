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
//! - [`simulate`], [`train`]: the summaries of simulation and training runs;
//! - [`python_front`]: the checks and results of the Python package's calls;
//! - [`vnncomp`]: deciding one VNN-COMP instance with the counterexample re-check and
//!   downgrade policy, and the competition's result words and files.
//!
//! Every result is a typed value deriving `Serialize`/`Deserialize`; its JSON (serde's
//! map with sorted keys) is the `--json` document of the CLI.

pub mod args;
pub mod bind;
pub mod python_front;
pub mod reach;
pub mod robustness;
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

//! Helpers shared by the CLI test files: the binary under test and the published
//! reference files.
#![allow(dead_code)] // each test file uses its own subset

use std::process::Command;

mod reference;
pub mod sealing;

/// The `samara` binary built for these tests.
pub fn samara() -> Command {
    Command::new(env!("CARGO_BIN_EXE_samara"))
}

/// The JSON a run printed on stdout, after asserting it exited 0 (its stderr in the
/// failure message).
pub fn json_of_success(o: &std::process::Output) -> serde_json::Value {
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_slice(&o.stdout).unwrap()
}

#[allow(unused_imports)] // each test file uses its own subset
pub use reference::reference;

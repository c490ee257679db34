//! Helpers shared by the CLI test files: the binary under test and the published
//! reference files.
#![allow(dead_code)] // each test file uses its own subset

use std::process::Command;

mod reference;

/// The `samara` binary built for these tests.
pub fn samara() -> Command {
    Command::new(env!("CARGO_BIN_EXE_samara"))
}

#[allow(unused_imports)] // each test file uses its own subset
pub use reference::reference;

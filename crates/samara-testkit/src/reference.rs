// The published reference files: one policy for every crate's tests. This file is the
// body of `samara_testkit` (a dev-dependency) and is also included by path, through
// `crates/samara-cli/tests/support/reference.rs`, by test files that predate the crate.

use std::path::{Path, PathBuf};

/// The folder of the published case-study files, `../shared/reference` beside the
/// repository (`CARGO_MANIFEST_DIR` of any crate is two levels below the repository).
pub fn reference_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/reference")
}

/// A published reference file. A missing file fails the test (never a silent pass) with
/// a message saying where the file is expected.
pub fn reference(name: &str) -> PathBuf {
    let p = reference_dir().join(name);
    assert!(
        p.exists(),
        "reference file {} not found: the tests read the published case-study files \
         from ../shared/reference beside the repository (README.md); put them there",
        p.display()
    );
    p
}

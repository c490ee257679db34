//! The published reference files, for the tests of every crate (included by path, so
//! there is one helper and one message).
#![allow(dead_code)] // each test file uses its own subset

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

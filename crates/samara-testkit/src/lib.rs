//! Test helpers shared by samara's crates (use it as a dev-dependency).
//!
//! The published case-study files (networks, training data, normalisation constants)
//! live in `../shared/reference` beside the repository, not in it. Tests reach them
//! through [`reference`](fn@reference), with one policy: a missing file fails the test with a message
//! naming the file and where it is expected; a test never skips or passes silently
//! because a reference file is absent.

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

/// The folder of the published files, for a command that takes the folder itself
/// (`samara reproduce --published DIR`): fails, naming the file, when the training data
/// it starts from is missing.
pub fn published_dir() -> PathBuf {
    reference("Training_Data.csv");
    reference_dir()
}

/// [`reference`](fn@reference) as a path string (for command lines).
pub fn reference_str(name: &str) -> String {
    reference(name).display().to_string()
}

/// Fails unless every `tests/*.rs` file of the crate at `manifest_dir` is built: a
/// module of the crate's one integration test binary, `tests/all.rs` (a `mod NAME;`
/// line), or one of `own`, the files that are test binaries of their own (named as
/// `[[test]]` targets in its `Cargo.toml`). With `autotests = false`, which the one
/// binary needs, a file in neither place would never be compiled or run.
pub fn assert_every_test_file_is_built(manifest_dir: &str, own: &[&str]) {
    let dir = Path::new(manifest_dir).join("tests");
    let all = std::fs::read_to_string(dir.join("all.rs"))
        .unwrap_or_else(|e| panic!("{}: {e}", dir.join("all.rs").display()));
    for e in std::fs::read_dir(&dir).unwrap_or_else(|e| panic!("{}: {e}", dir.display())) {
        let name = e
            .expect("a folder entry")
            .file_name()
            .to_string_lossy()
            .into_owned();
        let Some(stem) = name.strip_suffix(".rs") else {
            continue;
        };
        if stem == "all" || own.contains(&name.as_str()) {
            continue;
        }
        assert!(
            all.contains(&format!("\nmod {stem};\n")),
            "{}/{name} is not built: add `mod {stem};` to tests/all.rs",
            dir.display()
        );
    }
}

#[cfg(test)]
mod tests {
    #[test]
    #[should_panic(expected = "no-such-file.onnx not found")]
    fn a_missing_reference_file_fails_naming_it() {
        super::reference("no-such-file.onnx");
    }

    #[test]
    fn the_published_network_is_found() {
        assert!(super::reference("base_model_norm.onnx").is_file());
    }
}

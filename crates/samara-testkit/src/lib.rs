//! Test helpers shared by samara's crates (use it as a dev-dependency).
//!
//! The published case-study files (networks, training data, normalisation constants)
//! live in `../shared/reference` beside the repository, not in it. Tests reach them
//! through [`reference`], with one policy: a missing file fails the test with a message
//! naming the file and where it is expected; a test never skips or passes silently
//! because a reference file is absent.

include!("reference.rs");

/// [`reference`] as a path string (for command lines).
pub fn reference_str(name: &str) -> String {
    reference(name).display().to_string()
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

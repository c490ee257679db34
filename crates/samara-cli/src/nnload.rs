//! Loading networks for the CLI (ONNX through samara-nn).

use anyhow::{bail, Result};
use std::path::Path;

/// Load a network file.
pub fn load_network(path: &Path) -> Result<samara_nn::Network> {
    bail!(
        "{}: ONNX import is not available in this build yet",
        path.display()
    )
}

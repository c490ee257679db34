//! Loading networks for the CLI (ONNX through samara-nn).

use anyhow::Result;
use std::path::Path;

/// Load a network file; a 6-input network gets the case study's state names
/// (v_xp, v_yp, omega, theta, x, y) and a 1-output network the name `ex`.
pub fn load_network(path: &Path) -> Result<samara_nn::Network> {
    let net = samara_nn::onnx::load(path)?;
    if net.n_inputs() == 6 && net.n_outputs() == 1 {
        return Ok(net.with_names(&samara_nn::STATE_INPUTS, &["ex"])?);
    }
    Ok(net)
}

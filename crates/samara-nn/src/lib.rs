//! Neural networks for samara: an intermediate representation (a sequence of layers with
//! named inputs and outputs), evaluation generic over [`samara_num::Scalar`], and ONNX
//! import and export ([`onnx`]), and the NNet text format of ACAS Xu ([`nnet`]).
//! Networks that are not such a chain (convolutions, pooling, residual blocks, the
//! VNN-COMP operator set) are read as a DAG of operators ([`graph`], [`ops`]), evaluated
//! in f64, and lowered to the chain where they are piecewise linear. [`attack`] searches
//! an input box for a counterexample by projected signed-gradient steps.
#![warn(missing_docs)]

pub mod attack;
pub mod data;
pub mod graph;
pub mod ir;
pub mod limits;
pub mod nnet;
pub mod onnx;
pub mod ops;

pub use ir::{Activation, Affine, Layer, Network};

/// Why a network file could not be read: the error of its format.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// An ONNX file ([`onnx::load`]).
    #[error(transparent)]
    Onnx(#[from] onnx::OnnxError),
    /// An NNet file ([`nnet::load`]).
    #[error(transparent)]
    Nnet(#[from] nnet::NnetError),
}

/// A network file read by its extension: `.nnet` (any case) in the NNet text format of
/// ACAS Xu, anything else as ONNX. Every command reads its network files here, so each
/// takes both formats.
pub fn load(path: impl AsRef<std::path::Path>) -> Result<Network, LoadError> {
    load_until(path, None)
}

/// [`load`] within a time limit: an ONNX import past `deadline` stops with
/// [`onnx::OnnxError::Timeout`] ([`LoadError::timed_out`]), so a command whose
/// `--timeout` counts the load keeps it. (NNet files are read in milliseconds.)
pub fn load_until(
    path: impl AsRef<std::path::Path>,
    deadline: Option<std::time::Instant>,
) -> Result<Network, LoadError> {
    let path = path.as_ref();
    let nnet = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("nnet"));
    Ok(if nnet {
        nnet::load(path)?
    } else {
        onnx::load_until(path, deadline)?
    })
}

impl LoadError {
    /// Whether the load stopped at its deadline ([`load_until`]) rather than on the file.
    pub fn timed_out(&self) -> bool {
        matches!(self, LoadError::Onnx(onnx::OnnxError::Timeout { .. }))
    }
}

/// The case study's input names, in order.
pub const STATE_INPUTS: [&str; 6] = ["v_xp", "v_yp", "omega", "theta", "x", "y"];

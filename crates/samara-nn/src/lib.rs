//! Neural networks for samara: an intermediate representation (a sequence of layers with
//! named inputs and outputs), evaluation generic over [`samara_num::Scalar`], and (in
//! other modules) ONNX import and export.

pub mod ir;

pub use ir::{Activation, Affine, Layer, Network};

//! ONNX import and export of feed-forward networks.
//!
//! Import walks the graph's nodes in order (ONNX requires a topological order), keeps
//! constant tensors (initializers, `Constant` nodes) aside and follows the single live
//! activation vector from the graph input to the graph output, turning each node into
//! an affine map or an activation of the [`crate::Network`] IR. A leading block of
//! elementwise affine nodes (`Sub`/`Div`/`Mul`/`Add` with constants, before any `Gemm`
//! or `MatMul`) becomes the network's input normalisation; a trailing one after the last
//! activation becomes its output denormalisation. Anything else is an error naming the
//! operator, the node and the file, with the supported list.

mod export;
mod import;
pub mod proto;

pub use export::{export, save, ExportOptions};
pub use import::{from_bytes, load, OnnxError, SUPPORTED_OPS};

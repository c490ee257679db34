//! ONNX import and export of feed-forward networks.
//!
//! Import walks the graph's nodes in order (ONNX requires a topological order), keeps
//! constant tensors (initializers, `Constant` nodes) aside and follows the single live
//! activation vector from the graph input to the graph output, turning each node into
//! an affine map or an activation of the [`crate::Network`] IR. The live tensor's shape
//! is tracked (one sample is evaluated: the input's first dimension, when it has two
//! or more, is the batch dimension and counts as 1, as does any symbolic dimension), so broadcasting, Flatten/Reshape/Squeeze/Unsqueeze/Transpose and `Conv`
//! are lowered exactly. A `Conv` is imported only when it is a dense layer (its kernel
//! covers the whole input image, no padding, stride 1, dilation 1, one group), as the
//! MATLAB converter writes them. Opsets before 7 are read with their own semantics:
//! `broadcast`/`axis` of `Add`/`Sub`/`Mul`/`Div` (B matched to a contiguous block of A's
//! dimensions, no size-1 expansion) and of `Gemm`'s C, and Reshape's `shape` attribute
//! (opsets 1 to 4). A leading block of
//! elementwise affine nodes (`Sub`/`Div`/`Mul`/`Add` with constants, before any `Gemm`
//! or `MatMul`) becomes the network's input normalisation; a trailing one after the last
//! activation becomes its output denormalisation. Anything else is an error naming the
//! operator, the node and the file, with the supported list.

mod export;
pub(crate) mod import;
mod load;
pub mod proto;

pub use export::{export, save, ExportOptions};
pub use import::{OnnxError, SUPPORTED_OPS};
pub use load::{
    from_bytes, from_bytes_until, from_bytes_within, graph_from_bytes, load, load_graph,
    load_logits, load_logits_until, load_until,
};

//! The entry points of ONNX import: read the file, try the chain importer
//! ([`super::import`]) and fall back to the graph importer ([`crate::graph::import`])
//! with its lowering to the chain form. A module of its own, above both importers, so
//! that the graph importer can use the chain importer's protobuf helpers without the two
//! importing each other.

use super::import::{chain_from_bytes, OnnxError};
use super::proto::ModelProto;
use crate::ir::Network;
use prost::Message;
use std::path::Path;

/// Load a network from an ONNX file.
pub fn load(path: impl AsRef<Path>) -> Result<Network, OnnxError> {
    let (bytes, file) = read(path.as_ref())?;
    from_bytes(&bytes, &file)
}

/// The file's bytes and its name for messages.
fn read(path: &Path) -> Result<(Vec<u8>, String), OnnxError> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|cause| OnnxError::Io {
        file: file.clone(),
        cause,
    })?;
    Ok((bytes, file))
}

/// Decode and convert an ONNX model held in memory; `file` names it in errors.
///
/// A chain of dense layers is read by the chain importer (which also folds input
/// normalisation and output denormalisation into the network's distinguished layers).
/// A model it does not read (an operator or a pattern it refuses: sliding-window
/// convolutions, pooling, residual branches, a weight on the left of `MatMul`...) is read
/// as a [`crate::graph::Graph`] and lowered to the chain form
/// ([`crate::graph::lower`]); an error then names the node, the operator and, where
/// one is at fault, the attribute.
pub fn from_bytes(bytes: &[u8], file: &str) -> Result<Network, OnnxError> {
    match chain_from_bytes(bytes, file) {
        Err(chain_err @ OnnxError::Unsupported { .. }) => {
            let graph = match graph_from_bytes(bytes, file) {
                Ok(g) => g,
                Err(graph_err @ OnnxError::Unsupported { .. }) => {
                    return Err(more_relevant(bytes, chain_err, graph_err))
                }
                Err(_) => return Err(chain_err),
            };
            crate::graph::lower::lower(&graph).map_err(|e| OnnxError::Unsupported {
                file: file.into(),
                node: e.node,
                op: e.op,
                detail: format!(": {}", e.message),
            })
        }
        other => other,
    }
}

/// Of the chain importer's and the graph importer's refusals, the one to show: the
/// graph's, unless it refuses a node the chain importer read (an earlier node: e.g.
/// legacy broadcasting, which only the chain importer reads) or the same node with the
/// chain importer's more specific message (all but Conv, MatMul and Gemm, which the
/// chain importer refuses whenever they are not a dense layer).
fn more_relevant(bytes: &[u8], chain_err: OnnxError, graph_err: OnnxError) -> OnnxError {
    let (OnnxError::Unsupported { node: cn, .. }, OnnxError::Unsupported { node: gn, op, .. }) =
        (&chain_err, &graph_err)
    else {
        return graph_err;
    };
    let Ok(model) = ModelProto::decode(bytes) else {
        return graph_err;
    };
    let nodes = model.graph.map(|g| g.node).unwrap_or_default();
    let index = |name: &str| {
        nodes.iter().enumerate().position(|(k, n)| {
            n.name == name || (n.name.is_empty() && format!("#{k} ({})", n.op_type) == name)
        })
    };
    match (index(cn), index(gn)) {
        (Some(c), Some(g)) if g < c => chain_err,
        (Some(c), Some(g)) if g == c && !matches!(op.as_str(), "Conv" | "MatMul" | "Gemm") => {
            chain_err
        }
        _ => graph_err,
    }
}

/// Read an ONNX model held in memory as a [`crate::graph::Graph`] (any DAG of the
/// supported operators, piecewise linear or not); `file` names it in errors.
pub fn graph_from_bytes(bytes: &[u8], file: &str) -> Result<crate::graph::Graph, OnnxError> {
    let model = ModelProto::decode(bytes).map_err(|e| OnnxError::Decode {
        file: file.into(),
        message: e.to_string(),
    })?;
    crate::graph::import::from_model(&model, file)
}

/// Read an ONNX file as a [`crate::graph::Graph`].
pub fn load_graph(path: impl AsRef<Path>) -> Result<crate::graph::Graph, OnnxError> {
    let (bytes, file) = read(path.as_ref())?;
    graph_from_bytes(&bytes, &file)
}

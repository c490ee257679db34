//! The entry points of ONNX import: read the file, try the chain importer
//! ([`super::import`]) and fall back to the graph importer ([`crate::graph::import`])
//! with its lowering to the chain form. A module of its own, above both importers, so
//! that the graph importer can use the chain importer's protobuf helpers without the two
//! importing each other.

use super::import::{chain_from_bytes, OnnxError};
use super::proto::ModelProto;
use crate::ir::Network;
use crate::limits::{import_memory, show_bytes, Budget, IMPORT_MEMORY_ENV, TIMED_OUT};
use prost::Message;
use std::path::Path;
use std::time::Instant;

/// Load a network from an ONNX file, within the import memory budget
/// ([`crate::limits`]).
pub fn load(path: impl AsRef<Path>) -> Result<Network, OnnxError> {
    load_until(path, None)
}

/// [`load`] that stops with [`OnnxError::Timeout`] once `deadline` has passed (checked
/// per node and inside the lowering's long loops): a time limit that counts the import
/// (lowering an image-sized convolutional network takes minutes) is kept.
pub fn load_until(path: impl AsRef<Path>, deadline: Option<Instant>) -> Result<Network, OnnxError> {
    let (bytes, file) = read(path.as_ref())?;
    if deadline.is_some_and(|d| Instant::now() >= d) {
        return Err(OnnxError::Timeout { file });
    }
    from_bytes_until(&bytes, &file, env_budget(&file)?, deadline)
}

/// The budget of [`import_memory`], or the error naming the variable.
fn env_budget(file: &str) -> Result<u64, OnnxError> {
    import_memory().map_err(|message| OnnxError::Structure {
        file: file.into(),
        place: "import memory".into(),
        message,
    })
}

/// The file's bytes and its name for messages. A file larger than the import budget
/// is refused before it is read (its weights alone would not fit).
fn read(path: &Path) -> Result<(Vec<u8>, String), OnnxError> {
    let file = path.display().to_string();
    let allowed = env_budget(&file)?;
    if let Ok(meta) = std::fs::metadata(path) {
        if meta.len() > allowed {
            return Err(OnnxError::Structure {
                file,
                place: "file".into(),
                message: format!(
                    "the file has {}, more than the {} samara allows for a network's import; if the machine has the memory, raise the limit with the environment variable {IMPORT_MEMORY_ENV} (e.g. {IMPORT_MEMORY_ENV}=32G)",
                    show_bytes(meta.len()),
                    show_bytes(allowed)
                ),
            });
        }
    }
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
    from_bytes_within(bytes, file, env_budget(file)?)
}

/// [`from_bytes`] with an import budget of `allowed` bytes: every allocation that
/// grows with a shape the file declares (its constants as f64, the dense maps built,
/// the lowering's layers) is charged first, and past `allowed` the import stops with
/// an error naming the tensor or node and the bytes needed.
pub fn from_bytes_within(bytes: &[u8], file: &str, allowed: u64) -> Result<Network, OnnxError> {
    from_bytes_until(bytes, file, allowed, None)
}

/// [`from_bytes_within`] with a deadline: past it, [`OnnxError::Timeout`].
pub fn from_bytes_until(
    bytes: &[u8],
    file: &str,
    allowed: u64,
    deadline: Option<Instant>,
) -> Result<Network, OnnxError> {
    from_bytes_inner(bytes, file, allowed, deadline).map_err(|e| {
        if stopped_by_deadline(&e) {
            OnnxError::Timeout { file: file.into() }
        } else {
            e
        }
    })
}

/// Whether an importer's error is [`Budget::check_time`]'s (it travels as the message
/// of a structural or lowering error).
fn stopped_by_deadline(e: &OnnxError) -> bool {
    match e {
        OnnxError::Timeout { .. } => true,
        OnnxError::Structure { message, .. } => message == TIMED_OUT,
        OnnxError::Unsupported { detail, .. } => detail == &format!(": {TIMED_OUT}"),
        _ => false,
    }
}

fn from_bytes_inner(
    bytes: &[u8],
    file: &str,
    allowed: u64,
    deadline: Option<Instant>,
) -> Result<Network, OnnxError> {
    let new_budget = || Budget::new(allowed).with_deadline(deadline);
    match chain_from_bytes(bytes, file, &new_budget()) {
        Err(chain_err @ OnnxError::Unsupported { .. }) => {
            // The chain importer's allocations are dropped: the graph starts afresh.
            let budget = new_budget();
            let graph = match graph_within(bytes, file, &budget) {
                Ok(g) => g,
                Err(graph_err @ OnnxError::Unsupported { .. }) => {
                    return Err(more_relevant(bytes, chain_err, graph_err))
                }
                // Over the memory budget or out of time: that is the reason to show.
                Err(e @ OnnxError::Structure { .. })
                    if e.to_string().contains(IMPORT_MEMORY_ENV) || stopped_by_deadline(&e) =>
                {
                    return Err(e)
                }
                // A node the graph importer reads but cannot take (a value, a shape): its
                // message, when the chain importer refused that node or an earlier one.
                Err(e @ OnnxError::Structure { .. }) if structure_first(bytes, &chain_err, &e) => {
                    return Err(e)
                }
                Err(_) => return Err(chain_err),
            };
            crate::graph::lower::lower_within(&graph, &budget).map_err(|e| lower_error(file, e))
        }
        other => other,
    }
}

/// A lowering refusal as an import error. Over the memory budget the operator is
/// supported: the network is too large for the limit, which the message names with
/// the way to raise it.
fn lower_error(file: &str, e: crate::graph::lower::LowerError) -> OnnxError {
    if e.message.contains(IMPORT_MEMORY_ENV) || e.message == TIMED_OUT {
        OnnxError::Structure {
            file: file.into(),
            place: format!("node `{}` ({})", e.node, e.op),
            message: e.message,
        }
    } else {
        OnnxError::Unsupported {
            file: file.into(),
            node: e.node,
            op: e.op,
            detail: format!(": {}", e.message),
        }
    }
}

/// [`load`] for a property that only compares outputs with each other: a final
/// `Softmax` over all the outputs is left out ([`crate::graph::Graph::strip_final_softmax`])
/// and the network computes the logits; `true` when it was. Any other network loads as
/// [`load`] reads it.
pub fn load_logits(path: impl AsRef<Path>) -> Result<(Network, bool), OnnxError> {
    load_logits_until(path, None)
}

/// [`load_logits`] that stops with [`OnnxError::Timeout`] once `deadline` has passed,
/// as [`load_until`] does.
pub fn load_logits_until(
    path: impl AsRef<Path>,
    deadline: Option<Instant>,
) -> Result<(Network, bool), OnnxError> {
    let (bytes, file) = read(path.as_ref())?;
    if deadline.is_some_and(|d| Instant::now() >= d) {
        return Err(OnnxError::Timeout { file });
    }
    let allowed = env_budget(&file)?;
    let ends_in_softmax = ModelProto::decode(bytes.as_slice())
        .ok()
        .and_then(|m| m.graph)
        .and_then(|g| g.node.last().map(|n| n.op_type == "Softmax"))
        .unwrap_or(false);
    if ends_in_softmax {
        let budget = Budget::new(allowed).with_deadline(deadline);
        if let Ok(mut graph) = graph_within(&bytes, &file, &budget) {
            if graph.strip_final_softmax() {
                return crate::graph::lower::lower_within(&graph, &budget)
                    .map(|net| (net, true))
                    .map_err(|e| match lower_error(&file, e) {
                        e if stopped_by_deadline(&e) => OnnxError::Timeout { file: file.clone() },
                        e => e,
                    });
            }
        }
    }
    from_bytes_until(&bytes, &file, allowed, deadline).map(|net| (net, false))
}

/// Of the chain importer's and the graph importer's refusals, the one to show: the
/// graph's, unless it refuses a node the chain importer read (an earlier node: e.g.
/// legacy broadcasting, which only the chain importer reads) or the same node with the
/// chain importer's more specific message (all but Conv, MatMul and Gemm, which the
/// chain importer refuses whenever they are not a dense layer).
fn more_relevant(bytes: &[u8], chain_err: OnnxError, graph_err: OnnxError) -> OnnxError {
    let (
        OnnxError::Unsupported {
            node: cn,
            detail: cd,
            ..
        },
        OnnxError::Unsupported { node: gn, op, .. },
    ) = (&chain_err, &graph_err)
    else {
        return graph_err;
    };
    let Ok(model) = ModelProto::decode(bytes) else {
        return graph_err;
    };
    let nodes = model.graph.map(|g| g.node).unwrap_or_default();
    let index = |name: &str| node_index(&nodes, name);
    match (index(cn), index(gn)) {
        (Some(c), Some(g)) if g < c => chain_err,
        // (An operator only the graph importer reads has no detail from the chain's.)
        (Some(c), Some(g))
            if g == c && !cd.is_empty() && !matches!(op.as_str(), "Conv" | "MatMul" | "Gemm") =>
        {
            chain_err
        }
        _ => graph_err,
    }
}

/// The position of the node named `name` in errors (its name, or `#k (Op)`).
fn node_index(nodes: &[super::proto::NodeProto], name: &str) -> Option<usize> {
    nodes.iter().enumerate().position(|(k, n)| {
        n.name == name || (n.name.is_empty() && format!("#{k} ({})", n.op_type) == name)
    })
}

/// Whether the graph importer's structural error `graph_err` is at the node the chain
/// importer refused in `chain_err` or after it (then it is the reason to show; before
/// it, the chain importer read that node, e.g. with legacy broadcasting).
fn structure_first(bytes: &[u8], chain_err: &OnnxError, graph_err: &OnnxError) -> bool {
    let (OnnxError::Unsupported { node: cn, .. }, OnnxError::Structure { place, .. }) =
        (chain_err, graph_err)
    else {
        return false;
    };
    let Ok(model) = ModelProto::decode(bytes) else {
        return false;
    };
    let nodes = model.graph.map(|g| g.node).unwrap_or_default();
    let index = |name: &str| node_index(&nodes, name);
    let gname = place
        .strip_prefix("node `")
        .and_then(|r| r.split('`').next())
        .unwrap_or("");
    matches!((index(cn), index(gname)), (Some(c), Some(g)) if g >= c)
}

/// Read an ONNX model held in memory as a [`crate::graph::Graph`] (any DAG of the
/// supported operators, piecewise linear or not); `file` names it in errors.
pub fn graph_from_bytes(bytes: &[u8], file: &str) -> Result<crate::graph::Graph, OnnxError> {
    graph_within(bytes, file, &Budget::new(env_budget(file)?))
}

/// [`graph_from_bytes`] charging the graph's constants to `budget`.
fn graph_within(
    bytes: &[u8],
    file: &str,
    budget: &Budget,
) -> Result<crate::graph::Graph, OnnxError> {
    let model = ModelProto::decode(bytes).map_err(|e| OnnxError::Decode {
        file: file.into(),
        message: e.to_string(),
    })?;
    crate::graph::import::from_model_within(&model, file, budget)
}

/// Read an ONNX file as a [`crate::graph::Graph`].
pub fn load_graph(path: impl AsRef<Path>) -> Result<crate::graph::Graph, OnnxError> {
    let (bytes, file) = read(path.as_ref())?;
    graph_from_bytes(&bytes, &file)
}

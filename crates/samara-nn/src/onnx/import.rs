use super::proto::{self, AttributeProto, ModelProto, NodeProto, TensorProto};
use crate::ir::{Activation, Affine, Layer, Network};
use crate::limits::Budget;
use prost::Message;
use std::collections::HashMap;

/// Operators the importer understands (the chain importer's and the graph importer's;
/// Softmax, Sin, Cos, Exp, Sqrt, Abs and Pow are evaluated but not lowered to the chain
/// form the verifier reads, except a final Softmax that `load_logits` leaves out; Sign
/// is lowered by the graph importer as an activation of its own).
pub const SUPPORTED_OPS: &[&str] = &[
    "Gemm",
    "MatMul",
    "Conv",
    "Add",
    "Sub",
    "Mul",
    "Div",
    "Relu",
    "Sigmoid",
    "Tanh",
    "Clip",
    "Flatten",
    "Reshape",
    "Transpose",
    "Identity",
    "Squeeze",
    "Unsqueeze",
    "Dropout",
    "Constant",
    "ConvTranspose",
    "BatchNormalization",
    "MaxPool",
    "AveragePool",
    "GlobalAveragePool",
    "Pad",
    "Upsample",
    "Pow",
    "Neg",
    "LeakyRelu",
    "PRelu",
    "Sign",
    "Sin",
    "Cos",
    "Exp",
    "Sqrt",
    "Abs",
    "Softmax",
    "Concat",
    "Slice",
    "Split",
    "Gather",
    "Shape",
    "Cast",
    "ConstantOfShape",
];

/// Most dimensions of a tensor (constant or activation).
pub const MAX_RANK: usize = 32;

/// Why a file could not be imported.
#[derive(Debug, thiserror::Error)]
pub enum OnnxError {
    /// The file could not be read.
    // The OS error is part of the message and deliberately not a `source()`: shown both
    // ways it would be printed twice by `{:#}` (issue 17).
    #[error("{file}: cannot read: {cause}")]
    Io {
        /// File.
        file: String,
        /// Cause.
        cause: std::io::Error,
    },
    /// Not a protobuf ModelProto.
    #[error("{file}: not a valid ONNX model ({message}); is the file truncated or not ONNX?")]
    Decode {
        /// File.
        file: String,
        /// Decoder message.
        message: String,
    },
    /// An operator samara does not import.
    #[error("{file}: node `{node}`: unsupported operator `{op}`{detail}; supported: {}", SUPPORTED_OPS.join(", "))]
    Unsupported {
        /// File.
        file: String,
        /// Node name (or index).
        node: String,
        /// Operator.
        op: String,
        /// Extra explanation.
        detail: String,
    },
    /// The caller's deadline passed while the network was read or lowered
    /// ([`crate::limits::Budget::check_time`]): not an input error, a time limit.
    #[error("{file}: {}", crate::limits::TIMED_OUT)]
    Timeout {
        /// File.
        file: String,
    },
    /// Structural problem (shapes, missing tensors, several inputs...).
    #[error("{file}: {place}: {message}")]
    Structure {
        /// File.
        file: String,
        /// Node, tensor or graph part.
        place: String,
        /// What is wrong and how to fix it.
        message: String,
    },
}

/// A constant tensor in f64.
#[derive(Clone, Debug)]
pub(crate) struct Const {
    pub(crate) dims: Vec<usize>,
    pub(crate) data: Vec<f64>,
}

/// A constant tensor in f64, its values charged to `budget` before they are converted.
pub(crate) fn tensor_to_const(
    t: &TensorProto,
    file: &str,
    budget: &Budget,
) -> Result<Const, OnnxError> {
    let err = |m: String| OnnxError::Structure {
        file: file.into(),
        place: format!("tensor `{}`", t.name),
        message: m,
    };
    if t.data_location == 1 {
        return Err(err(
            "external data is not supported; re-save the model with the weights inside the file"
                .into(),
        ));
    }
    if t.dims.len() > MAX_RANK {
        return Err(err(format!(
            "has {} dimensions; samara imports tensors of at most {MAX_RANK}",
            t.dims.len()
        )));
    }
    let dims: Vec<usize> = t
        .dims
        .iter()
        .map(|&d| usize::try_from(d).map_err(|_| err(format!("negative dimension {d}"))))
        .collect::<Result<_, _>>()?;
    let n = dims
        .iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d))
        .ok_or_else(|| {
            err(format!(
                "shape {dims:?} declares more than 2^64 values; the file is corrupt"
            ))
        })?;
    // The bytes or values the file holds must match the shape before anything is
    // converted (so a corrupt shape never drives an allocation).
    let held = match t.data_type {
        proto::FLOAT | proto::INT32 if !t.raw_data.is_empty() => t.raw_data.len() / 4,
        proto::DOUBLE | proto::INT64 if !t.raw_data.is_empty() => t.raw_data.len() / 8,
        proto::FLOAT => t.float_data.len(),
        proto::DOUBLE => t.double_data.len(),
        proto::INT64 => t.int64_data.len(),
        proto::INT32 => t.int32_data.len(),
        _ => n,
    };
    if held != n {
        return Err(err(format!(
            "holds {held} values but its shape {dims:?} needs {n}; the file is corrupt or truncated"
        )));
    }
    budget
        .charge(n, &|| format!("its shape {dims:?} ({n} values as f64)"))
        .map_err(err)?;
    let data: Vec<f64> = match t.data_type {
        proto::FLOAT => {
            if !t.raw_data.is_empty() {
                if t.raw_data.len() != 4 * n {
                    return Err(err(format!("raw_data has {} bytes, expected {} for {n} float32 values", t.raw_data.len(), 4 * n)));
                }
                t.raw_data.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]) as f64).collect()
            } else {
                t.float_data.iter().map(|&v| v as f64).collect()
            }
        }
        proto::DOUBLE => {
            if !t.raw_data.is_empty() {
                if t.raw_data.len() != 8 * n {
                    return Err(err(format!("raw_data has {} bytes, expected {} for {n} float64 values", t.raw_data.len(), 8 * n)));
                }
                t.raw_data.chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes"))).collect()
            } else {
                t.double_data.clone()
            }
        }
        proto::INT64 => {
            if !t.raw_data.is_empty() {
                t.raw_data.chunks_exact(8).map(|c| i64::from_le_bytes(c.try_into().expect("8 bytes")) as f64).collect()
            } else {
                t.int64_data.iter().map(|&v| v as f64).collect()
            }
        }
        proto::INT32 => {
            if !t.raw_data.is_empty() {
                t.raw_data.chunks_exact(4).map(|c| i32::from_le_bytes(c.try_into().expect("4 bytes")) as f64).collect()
            } else {
                t.int32_data.iter().map(|&v| v as f64).collect()
            }
        }
        other => {
            return Err(err(format!(
                "data type {other} is not supported (float32, float64, int32, int64 are); convert the model's weights to float32"
            )))
        }
    };
    if data.len() != n {
        return Err(err(format!(
            "holds {} values but its shape {dims:?} needs {n}",
            data.len()
        )));
    }
    if let Some(i) = data.iter().position(|v| !v.is_finite()) {
        return Err(err(format!(
            "value {i} is {} (NaN or infinite weights); retrain or repair the network",
            data[i]
        )));
    }
    Ok(Const { dims, data })
}

pub(crate) fn attr<'a>(n: &'a NodeProto, name: &str) -> Option<&'a AttributeProto> {
    n.attribute.iter().find(|a| a.name == name)
}

/// One segment of the network being built.
enum Seg {
    Affine { a: Affine, elementwise: bool },
    Act(Activation),
}

struct Builder<'f> {
    file: &'f str,
    segs: Vec<Seg>,
    dim: usize,
    /// Every map built is charged here before it is allocated.
    budget: &'f Budget,
}

impl Builder<'_> {
    /// Charge `values` f64 entries of a map `node` builds.
    fn charge(
        &self,
        values: usize,
        node: &str,
        what: &dyn Fn() -> String,
    ) -> Result<(), OnnxError> {
        self.budget
            .charge(values, what)
            .map_err(|message| OnnxError::Structure {
                file: self.file.into(),
                place: node.into(),
                message,
            })
    }

    /// Compose `y = W x + b` (new map) after the pending segment. Elementwise maps merge
    /// into a pending affine; dense maps start a new segment after an elementwise one.
    /// Two dense maps are composed only when their product is no larger than the two
    /// (a 2 -> 64 -> 4096 stack becomes one 2 -> 4096 map; an 8192 -> 2048 -> 4096 one
    /// stays two maps, as the product would be larger and cost 69 G multiplications).
    /// The product is charged to the budget; `node` names the node in errors.
    fn push_affine(&mut self, a: Affine, elementwise: bool, node: &str) -> Result<(), OnnxError> {
        if let Some(Seg::Affine {
            a: prev,
            elementwise: pe,
        }) = self.segs.last()
        {
            let (n, k, m) = (prev.inp, prev.out, a.out);
            let smaller =
                (m as u128) * (n as u128) <= (m as u128) * (k as u128) + (k as u128) * (n as u128);
            if elementwise || (!*pe && smaller) {
                self.charge(m.saturating_mul(n), node, &|| {
                    format!("composing its {k} -> {m} map with the preceding {n} -> {k} one")
                })?;
                if let Some(Seg::Affine {
                    a: prev,
                    elementwise: pe,
                }) = self.segs.last_mut()
                {
                    *prev = compose(prev, &a);
                    *pe = *pe && elementwise;
                }
                self.dim = m;
                return Ok(());
            }
        }
        self.dim = a.out;
        self.segs.push(Seg::Affine { a, elementwise });
        Ok(())
    }

    /// The elementwise map `y_i = scale_i x_i + bias_i`: folded into a pending affine map
    /// row by row (no allocation), else a new diagonal map (`n x n` dense, charged).
    fn push_diag(&mut self, scale: &[f64], bias: &[f64], node: &str) -> Result<(), OnnxError> {
        if let Some(Seg::Affine { a: prev, .. }) = self.segs.last_mut() {
            for (i, (&s, &c)) in scale.iter().zip(bias).enumerate() {
                // As `compose` with a diagonal map: a zero scale clears the row.
                let row = prev.row_values_mut(i);
                if s == 0.0 {
                    row.fill(0.0);
                } else {
                    row.iter_mut().for_each(|w| *w *= s);
                }
                prev.b[i] = s * prev.b[i] + c;
            }
            return Ok(());
        }
        let n = scale.len();
        self.charge(n.saturating_mul(n), node, &|| {
            format!("its elementwise map on {n} entries (an {n} x {n} dense map)")
        })?;
        self.push_affine(diag(scale, bias), true, node)
    }
}

/// `second ∘ first`.
fn compose(first: &Affine, second: &Affine) -> Affine {
    let (n, m) = (first.inp, second.out);
    let mut w = vec![0.0; m * n];
    let mut b = second.b.clone();
    for i in 0..m {
        second.row(i).for_each_nonzero(|j, s| {
            let wi = &mut w[i * n..(i + 1) * n];
            first.row(j).for_each_nonzero(|l, f| wi[l] += s * f);
            b[i] += s * first.b[j];
        });
    }
    Affine::new(n, m, w, b)
}

fn diag(d: &[f64], bias: &[f64]) -> Affine {
    let n = d.len();
    let mut w = vec![0.0; n * n];
    for i in 0..n {
        w[i * n + i] = d[i];
    }
    Affine::new(n, n, w, bias.to_vec())
}

/// Number of entries of a tensor of this shape (`None` on overflow).
fn numel(shape: &[usize]) -> Option<usize> {
    shape.iter().try_fold(1usize, |a, &d| a.checked_mul(d))
}

/// Multidirectional (numpy) broadcast of two shapes, `None` if they do not broadcast.
fn broadcast_shapes(a: &[usize], b: &[usize]) -> Option<Vec<usize>> {
    crate::ops::elementwise::broadcast_shapes(a, b).ok()
}

use crate::ops::elementwise::broadcast_index as broadcast_gather;

/// The model's graph, or the error naming `file` when it has none.
pub(crate) fn model_graph<'m>(
    model: &'m ModelProto,
    file: &str,
) -> Result<&'m proto::GraphProto, OnnxError> {
    model.graph.as_ref().ok_or_else(|| OnnxError::Decode {
        file: file.into(),
        message: "the model has no graph".into(),
    })
}

/// The default-domain opset of a model (`i64::MAX`, the current semantics, if none).
pub(crate) fn default_opset(model: &ModelProto) -> i64 {
    model
        .opset_import
        .iter()
        .find(|o| o.domain.is_empty() || o.domain == "ai.onnx")
        .map(|o| o.version)
        .unwrap_or(i64::MAX)
}

/// The shape of one sample of an input declared with `dims`: the first dimension of an
/// input of rank 2 or more is the batch dimension (whatever size it declares) and
/// counts as 1, as does a symbolic or unset dimension.
pub(crate) fn sample_shape(dims: &[proto::Dimension]) -> Vec<usize> {
    dims.iter()
        .enumerate()
        .map(|(k, d)| match d.dim_value {
            Some(v) if v > 0 && !(k == 0 && dims.len() >= 2) => {
                usize::try_from(v).unwrap_or(usize::MAX)
            }
            _ => 1,
        })
        .collect()
}

/// The integer values of a constant (shapes, axes).
fn const_ints(c: &Const) -> Option<Vec<i64>> {
    c.data
        .iter()
        .map(|&v| (v.fract() == 0.0 && v.abs() < 9.0e15).then_some(v as i64))
        .collect()
}

/// An axis in `[-r, r)` (or `[-r, r]` with `inclusive`) as an index.
fn norm_axis(a: i64, r: usize, inclusive: bool) -> Option<usize> {
    let r = r as i64;
    let a = if a < 0 { a + r } else { a };
    let hi = if inclusive { r } else { r - 1 };
    (0..=hi).contains(&a).then_some(a as usize)
}

/// The chain importer: one live tensor through dense layers and activations.
/// Every allocation that grows with a declared shape is charged to `budget` first.
pub(crate) fn chain_from_bytes(
    bytes: &[u8],
    file: &str,
    budget: &Budget,
) -> Result<Network, OnnxError> {
    let model = ModelProto::decode(bytes).map_err(|e| OnnxError::Decode {
        file: file.into(),
        message: e.to_string(),
    })?;
    let structure = |place: &str, message: String| OnnxError::Structure {
        file: file.into(),
        place: place.into(),
        message,
    };
    let graph = model_graph(&model, file)?;
    // The default-domain opset decides the semantics of the legacy attributes (opsets
    // 1 to 6: `broadcast`/`axis` of the binary operators and Gemm, Reshape's `shape`
    // attribute). A model without one is read with the current semantics.
    let opset = default_opset(&model);
    if opset < 1 {
        return Err(structure(
            "opset_import",
            format!("opset {opset} does not exist (ONNX opsets start at 1); the file is corrupt"),
        ));
    }
    let mut consts: HashMap<String, Const> = HashMap::new();
    for t in &graph.initializer {
        consts.insert(t.name.clone(), tensor_to_const(t, file, budget)?);
    }
    let inputs: Vec<_> = graph
        .input
        .iter()
        .filter(|i| !consts.contains_key(&i.name))
        .collect();
    if inputs.len() != 1 {
        return Err(structure(
            "graph inputs",
            format!("expected exactly one non-constant input, found {}; samara imports single-input feed-forward networks", inputs.len()),
        ));
    }
    let input = inputs[0];
    let in_place = format!("input `{}`", input.name);
    let dims = input
        .r#type
        .as_ref()
        .and_then(|t| t.tensor_type.as_ref())
        .and_then(|t| t.shape.as_ref())
        .map(|s| s.dim.as_slice())
        .unwrap_or(&[]);
    if dims.len() > MAX_RANK {
        return Err(structure(
            &in_place,
            format!(
                "has {} dimensions; samara imports at most {MAX_RANK}",
                dims.len()
            ),
        ));
    }
    dims.last()
        .and_then(|d| d.dim_value)
        .filter(|&d| d > 0)
        .ok_or_else(|| {
            structure(
                &in_place,
                "its last dimension must be a fixed positive number".into(),
            )
        })?;
    // One sample is evaluated: the first dimension of an input of rank 2 or more is the
    // batch dimension (whatever size it declares), and a symbolic or unset dimension is 1.
    // Samara's network is then the per-sample function; a constant that depends on the
    // batch size no longer broadcasts and is refused.
    let in_shape = sample_shape(dims);
    let in_dim = numel(&in_shape)
        .filter(|&d| budget.fits(d))
        .ok_or_else(|| {
            structure(
                &in_place,
                format!("declares shape {in_shape:?}, more entries than the import's memory budget holds ({}); is the file corrupt?", crate::limits::show_bytes(budget.allowed())),
            )
        })?;
    let mut live = input.name.clone();
    let mut b = Builder {
        file,
        segs: Vec::new(),
        dim: in_dim,
        budget,
    };
    // Shape of the live tensor (symbolic dimensions as 1); its row-major entries are the
    // activation vector, so the product of `shape` is always `b.dim`.
    let mut shape = in_shape;

    for (idx, node) in graph.node.iter().enumerate() {
        let nname = if node.name.is_empty() {
            format!("#{idx} ({})", node.op_type)
        } else {
            node.name.clone()
        };
        let unsupported = |detail: String| OnnxError::Unsupported {
            file: file.into(),
            node: nname.clone(),
            op: node.op_type.clone(),
            detail,
        };
        let shape_err = |m: String| structure(&format!("node `{nname}` ({})", node.op_type), m);
        budget.check_time().map_err(&shape_err)?;
        if !node.domain.is_empty() && node.domain != "ai.onnx" {
            return Err(unsupported(format!(" from domain `{}`", node.domain)));
        }
        if node.op_type == "Constant" {
            let t = attr(node, "value")
                .and_then(|a| a.t.as_ref())
                .ok_or_else(|| unsupported(" without a tensor `value` attribute".into()))?;
            let out = node.output.first().cloned().unwrap_or_default();
            consts.insert(out, tensor_to_const(t, file, budget)?);
            continue;
        }
        let uses_live = node.input.contains(&live);
        if !uses_live {
            // A computation on constants only (e.g. shape arithmetic) is not supported.
            return Err(unsupported(" on constant inputs only (constant folding is not supported; simplify the model with onnx-simplifier)".into()));
        }
        let other_const = |k: usize| -> Result<Option<&Const>, OnnxError> {
            match node.input.get(k) {
                None => Ok(None),
                Some(n) if n.is_empty() => Ok(None),
                Some(n) if *n == live => Err(unsupported(
                    " with the activation used twice (residual or doubled paths are not supported)"
                        .into(),
                )),
                Some(n) => consts.get(n).map(Some).ok_or_else(|| {
                    shape_err(format!(
                        "input `{n}` is neither the live tensor nor a constant"
                    ))
                }),
            }
        };
        let d = b.dim;
        let int_attr = |name: &str, default: i64| attr(node, name).map(|a| a.i).unwrap_or(default);
        // A single row: every dimension but the last is 1 (the activation is one sample).
        let one_row = |what: &str| -> Result<(), OnnxError> {
            if shape.len() > 1 && numel(&shape[..shape.len() - 1]) != Some(1) {
                return Err(unsupported(format!(
                    " with {what} of shape {shape:?} (several rows; samara imports networks evaluated on one sample)"
                )));
            }
            Ok(())
        };
        let new_shape: Vec<usize> = match node.op_type.as_str() {
            "Gemm" => {
                if node.input[0] != live {
                    return Err(unsupported(" with the activation as second operand".into()));
                }
                let ta = int_attr("transA", 0);
                let tb = int_attr("transB", 0);
                let alpha = attr(node, "alpha").map(|a| a.f as f64).unwrap_or(1.0);
                let beta = attr(node, "beta").map(|a| a.f as f64).unwrap_or(1.0);
                if ta != 0 {
                    return Err(unsupported(" with transA = 1".into()));
                }
                // A is the activation as one row [1, K] (a vector, a [1, K] matrix, or a
                // tensor whose leading dimensions are all 1, as MATLAB's converter writes).
                one_row("A")?;
                let bm = other_const(1)?.ok_or_else(|| shape_err("missing B".into()))?;
                if bm.dims.len() != 2 {
                    return Err(shape_err(format!(
                        "B must be a matrix, has shape {:?}",
                        bm.dims
                    )));
                }
                let (r, c) = (bm.dims[0], bm.dims[1]);
                let (k, m) = if tb == 0 { (r, c) } else { (c, r) };
                if k != d {
                    return Err(shape_err(format!(
                        "B has {k} rows (after transB) but the activation has {d} entries"
                    )));
                }
                b.charge(m * d, &nname, &|| format!("its {d} -> {m} map"))?;
                let mut w = vec![0.0; m * d];
                for i in 0..m {
                    for j in 0..d {
                        let v = if tb == 0 {
                            bm.data[j * c + i]
                        } else {
                            bm.data[i * c + j]
                        };
                        w[i * d + j] = alpha * v;
                    }
                }
                let bias = match other_const(2)? {
                    None => vec![0.0; m],
                    Some(cv) => {
                        // C is added to the [1, m] product. Opsets 7 and later broadcast
                        // it unidirectionally; opsets 1 to 6 only with `broadcast = 1`
                        // (which then allows the same shapes for one row), else C must be
                        // [1, m].
                        let legacy_exact = opset < 7 && int_attr("broadcast", 0) == 0;
                        let fits = if legacy_exact {
                            cv.dims == [1, m]
                        } else {
                            cv.dims.len() <= 2
                                && broadcast_shapes(&cv.dims, &[1, m]).as_deref() == Some(&[1, m])
                        };
                        if !fits {
                            return Err(shape_err(if legacy_exact {
                                format!(
                                    "C has shape {:?}; without broadcast = 1 (opset {opset}) it must be [1, {m}]",
                                    cv.dims
                                )
                            } else {
                                format!(
                                    "C has shape {:?}, which does not broadcast to the output [1, {m}]",
                                    cv.dims
                                )
                            }));
                        }
                        if cv.data.len() == 1 {
                            vec![beta * cv.data[0]; m]
                        } else {
                            cv.data.iter().map(|v| beta * v).collect()
                        }
                    }
                };
                b.push_affine(Affine::new(d, m, w, bias), false, &nname)?;
                vec![1, m]
            }
            "MatMul" => {
                if node.input[0] != live {
                    return Err(unsupported(" with the activation as second operand".into()));
                }
                one_row("A")?;
                let bm = other_const(1)?.ok_or_else(|| shape_err("missing B".into()))?;
                if bm.dims.len() != 2 || bm.dims[0] != d {
                    return Err(shape_err(format!(
                        "B has shape {:?}, expected [{d}, m]",
                        bm.dims
                    )));
                }
                let m = bm.dims[1];
                b.charge(m * d, &nname, &|| format!("its {d} -> {m} map"))?;
                let mut w = vec![0.0; m * d];
                for i in 0..m {
                    for j in 0..d {
                        w[i * d + j] = bm.data[j * m + i];
                    }
                }
                b.push_affine(Affine::new(d, m, w, vec![0.0; m]), false, &nname)?;
                let mut s = shape.clone();
                if let Some(l) = s.last_mut() {
                    *l = m;
                }
                s
            }
            "Conv" => conv(
                node,
                &shape,
                d,
                &live,
                &other_const,
                &unsupported,
                &shape_err,
            )
            .and_then(|(a, s)| {
                // The map is a copy of the kernel (itself charged as a constant).
                b.charge(a.stored(), &nname, &|| {
                    format!("its {} -> {} map", a.inp, a.out)
                })?;
                b.push_affine(a, false, &nname)?;
                Ok(s)
            })?,
            "Add" | "Sub" | "Mul" | "Div" => {
                let live_first = node.input[0] == live;
                let c = other_const(if live_first { 1 } else { 0 })?
                    .ok_or_else(|| shape_err("missing constant operand".into()))?;
                let (vals, out) = if opset < 7 {
                    legacy_broadcast(node, &shape, c, live_first, d, &unsupported, &shape_err)?
                } else {
                    let out = broadcast_shapes(&shape, &c.dims).ok_or_else(|| {
                        shape_err(format!(
                            "the constant of shape {:?} does not broadcast with the activation of shape {shape:?}",
                            c.dims
                        ))
                    })?;
                    if numel(&out) != Some(d) {
                        return Err(unsupported(format!(
                            " broadcasting the activation of shape {shape:?} to the larger {out:?} (the constant has shape {:?})",
                            c.dims
                        )));
                    }
                    let vals: Vec<f64> = broadcast_gather(&out, &c.dims)
                        .into_iter()
                        .map(|i| c.data[i])
                        .collect();
                    (vals, out)
                };
                let (scale, bias): (Vec<f64>, Vec<f64>) = match (node.op_type.as_str(), live_first)
                {
                    ("Add", _) => (vec![1.0; d], vals),
                    ("Sub", true) => (vec![1.0; d], vals.iter().map(|v| -v).collect()),
                    ("Sub", false) => (vec![-1.0; d], vals),
                    ("Mul", _) => (vals, vec![0.0; d]),
                    ("Div", true) => {
                        if vals.contains(&0.0) {
                            return Err(shape_err("division by a zero constant".into()));
                        }
                        (vals.iter().map(|v| 1.0 / v).collect(), vec![0.0; d])
                    }
                    _ => {
                        return Err(unsupported(
                            " with a constant divided by the activation (not affine)".into(),
                        ))
                    }
                };
                b.push_diag(&scale, &bias, &nname)?;
                out
            }
            "Relu" => {
                b.segs.push(Seg::Act(Activation::Relu));
                shape.clone()
            }
            "Sigmoid" => {
                b.segs.push(Seg::Act(Activation::Sigmoid));
                shape.clone()
            }
            "Tanh" => {
                b.segs.push(Seg::Act(Activation::Tanh));
                shape.clone()
            }
            "Clip" => {
                let bound = |k: usize, name: &str, default: f64| -> Result<f64, OnnxError> {
                    if let Some(c) = other_const(k)? {
                        return c
                            .data
                            .first()
                            .copied()
                            .ok_or_else(|| shape_err(format!("empty {name}")));
                    }
                    Ok(attr(node, name).map(|a| a.f as f64).unwrap_or(default))
                };
                let lo = bound(1, "min", f64::NEG_INFINITY)?;
                let hi = bound(2, "max", f64::INFINITY)?;
                if lo.is_nan() || hi.is_nan() || lo > hi {
                    return Err(shape_err(format!(
                        "bounds [{lo}, {hi}] are not an interval; min must be <= max"
                    )));
                }
                b.segs.push(Seg::Act(Activation::Clamp { lo, hi }));
                shape.clone()
            }
            "Identity" | "Dropout" => shape.clone(),
            "Flatten" => {
                let a = int_attr("axis", 1);
                let k = norm_axis(a, shape.len(), true).ok_or_else(|| {
                    shape_err(format!("axis {a} is out of range for shape {shape:?}"))
                })?;
                let lead = numel(&shape[..k]).unwrap_or(usize::MAX);
                vec![lead, d / lead.max(1)]
            }
            "Squeeze" | "Unsqueeze" => {
                let axes: Option<Vec<i64>> = match other_const(1)? {
                    Some(c) => Some(
                        const_ints(c).ok_or_else(|| shape_err("axes must be integers".into()))?,
                    ),
                    None => attr(node, "axes").map(|a| a.ints.clone()),
                };
                let squeeze = node.op_type == "Squeeze";
                let r = if squeeze {
                    shape.len()
                } else {
                    shape.len() + axes.as_ref().map_or(0, |a| a.len())
                };
                let mut ks = Vec::new();
                for &a in axes.iter().flatten() {
                    let k = norm_axis(a, r, false).ok_or_else(|| {
                        shape_err(format!("axis {a} is out of range for rank {r}"))
                    })?;
                    if ks.contains(&k) {
                        return Err(shape_err(format!("axis {a} is repeated")));
                    }
                    ks.push(k);
                }
                if squeeze {
                    if axes.is_none() {
                        shape.iter().copied().filter(|&s| s != 1).collect()
                    } else {
                        if let Some(&k) = ks.iter().find(|&&k| shape[k] != 1) {
                            return Err(shape_err(format!(
                                "axis {k} of shape {shape:?} is not 1 and cannot be squeezed"
                            )));
                        }
                        (0..shape.len())
                            .filter(|k| !ks.contains(k))
                            .map(|k| shape[k])
                            .collect()
                    }
                } else {
                    if axes.is_none() {
                        return Err(shape_err("missing axes".into()));
                    }
                    let mut rest = shape.iter().copied();
                    (0..r)
                        .map(|k| {
                            if ks.contains(&k) {
                                1
                            } else {
                                rest.next().unwrap_or(1)
                            }
                        })
                        .collect()
                }
            }
            "Reshape" => {
                // Opsets 1 to 4 give the target shape as an attribute, later ones as a
                // constant second input.
                let target: Vec<i64> = match other_const(1)? {
                    Some(c) => const_ints(c)
                        .ok_or_else(|| shape_err("the shape must be integers".into()))?,
                    None if opset < 5 => attr(node, "shape")
                        .map(|a| a.ints.clone())
                        .ok_or_else(|| shape_err("missing shape".into()))?,
                    None => return Err(shape_err("missing shape".into())),
                };
                reshape(&shape, &target, d, int_attr("allowzero", 0) != 0).ok_or_else(|| {
                    unsupported(format!(
                        " to shape {target:?}: not a valid reshape of the activation of shape {shape:?}"
                    ))
                })?
            }
            "Transpose" => {
                let r = shape.len();
                let perm: Vec<usize> = match attr(node, "perm") {
                    None => (0..r).rev().collect(),
                    Some(a) => a
                        .ints
                        .iter()
                        .map(|&p| usize::try_from(p).ok().filter(|&p| p < r))
                        .collect::<Option<_>>()
                        .filter(|p: &Vec<usize>| p.len() == r && (0..r).all(|k| p.contains(&k)))
                        .ok_or_else(|| {
                            shape_err(format!(
                                "perm {:?} is not a permutation of the {r} axes of shape {shape:?}",
                                a.ints
                            ))
                        })?,
                };
                let out: Vec<usize> = perm.iter().map(|&p| shape[p]).collect();
                // Entry `flat` of the output reads the input entry at the permuted index.
                let mut strides = vec![1usize; r];
                for k in (0..r.saturating_sub(1)).rev() {
                    strides[k] = strides[k + 1] * shape[k + 1];
                }
                let src: Vec<usize> = (0..d)
                    .map(|flat| {
                        let (mut rem, mut idx) = (flat, 0);
                        for k in (0..r).rev() {
                            idx += (rem % out[k]) * strides[perm[k]];
                            rem /= out[k];
                        }
                        idx
                    })
                    .collect();
                if src.iter().enumerate().any(|(i, &j)| i != j) {
                    b.charge(d.saturating_mul(d), &nname, &|| {
                        format!("its permutation of {d} entries (a {d} x {d} dense map)")
                    })?;
                    let mut w = vec![0.0; d * d];
                    for (i, &j) in src.iter().enumerate() {
                        w[i * d + j] = 1.0;
                    }
                    b.push_affine(Affine::new(d, d, w, vec![0.0; d]), false, &nname)?;
                }
                out
            }
            _ => return Err(unsupported(String::new())),
        };
        if new_shape.len() > MAX_RANK || numel(&new_shape) != Some(b.dim) {
            return Err(shape_err(format!(
                "gives shape {new_shape:?}, which does not hold the {} entries computed",
                b.dim
            )));
        }
        shape = new_shape;
        live = node
            .output
            .first()
            .cloned()
            .ok_or_else(|| shape_err("node has no output".into()))?;
    }
    let outputs: Vec<_> = graph.output.iter().collect();
    if outputs.len() != 1 || outputs[0].name != live {
        return Err(structure(
            "graph outputs",
            format!(
                "expected one output computed from the input (`{live}`), found {:?}",
                outputs.iter().map(|o| o.name.as_str()).collect::<Vec<_>>()
            ),
        ));
    }
    let out_dim = b.dim;
    let _ = b.file;
    let mut segs = b.segs;
    let mut input_norm = None;
    let mut output_denorm = None;
    let has_dense = segs.iter().any(|s| {
        matches!(
            s,
            Seg::Affine {
                elementwise: false,
                ..
            }
        ) || matches!(s, Seg::Act(_))
    });
    if has_dense && segs.len() > 1 {
        if let Some(Seg::Affine {
            elementwise: true, ..
        }) = segs.first()
        {
            if let Seg::Affine { a, .. } = segs.remove(0) {
                input_norm = Some(a);
            }
        }
        let n = segs.len();
        if n >= 2 && matches!(segs[n - 2], Seg::Act(_)) {
            if let Some(Seg::Affine {
                elementwise: true, ..
            }) = segs.last()
            {
                if let Some(Seg::Affine { a, .. }) = segs.pop() {
                    output_denorm = Some(a);
                }
            }
        }
    }
    // Each map in the storage its density calls for ([`Affine::compact`]): the chain's
    // maps are built dense, but a network of min and max units (the two-level lattice
    // networks of VNN-COMP's tllverifybench, 2048 x 512 maps with two non-zeros a row)
    // is almost all zeros, and the bounds' passes over sparse rows visit only the
    // non-zeros (CROWN's intermediate bounds over the whole box of the N=32 network: 385 ms with
    // dense maps, 10 ms sparse).
    let layers = segs
        .into_iter()
        .map(|s| match s {
            Seg::Affine { a, .. } => Layer::Affine(a.compact()),
            Seg::Act(a) => Layer::Act(a),
        })
        .collect();
    let net = Network {
        input_names: (0..in_dim)
            .map(|i| format!("{}[{i}]", input.name))
            .collect(),
        output_names: (0..out_dim).map(|i| format!("{live}[{i}]")).collect(),
        input_norm,
        layers,
        output_denorm,
    };
    net.validate()
        .map_err(|e| structure("network", e.to_string()))?;
    Ok(net)
}

/// The values a legacy (opsets 1 to 6) `Add`/`Sub`/`Mul`/`Div` combines with each entry
/// of the activation, and the result's shape. Without `broadcast = 1` both operands have
/// the same shape. With it, the second operand B is broadcast to the first, A: B holds
/// one value, or B's shape equals A's dimensions from `axis` on (default: A's trailing
/// dimensions), with no expansion of size-1 dimensions. The activation may be B only
/// when that does not enlarge it.
#[allow(clippy::type_complexity)]
fn legacy_broadcast(
    node: &NodeProto,
    shape: &[usize],
    c: &Const,
    live_first: bool,
    d: usize,
    unsupported: &dyn Fn(String) -> OnnxError,
    shape_err: &dyn Fn(String) -> OnnxError,
) -> Result<(Vec<f64>, Vec<usize>), OnnxError> {
    let (a, bs): (&[usize], &[usize]) = if live_first {
        (shape, &c.dims)
    } else {
        (&c.dims, shape)
    };
    let broadcast = attr(node, "broadcast").map(|x| x.i).unwrap_or(0);
    let padded: Vec<usize> = if broadcast == 0 {
        if a != bs {
            return Err(shape_err(format!(
                "operands of shapes {a:?} and {bs:?}: without broadcast = 1 (opsets before 7) they must have the same shape"
            )));
        }
        bs.to_vec()
    } else if numel(bs) == Some(1) && bs.len() <= a.len() {
        vec![1; a.len()]
    } else {
        let (ra, rb) = (a.len(), bs.len());
        let axis = match attr(node, "axis") {
            Some(x) => usize::try_from(x.i).ok(),
            None => ra.checked_sub(rb),
        }
        .filter(|&s| s + rb <= ra)
        .ok_or_else(|| {
            shape_err(format!(
                "B of shape {bs:?} does not fit in A of shape {a:?}{} (legacy broadcasting)",
                attr(node, "axis").map_or(String::new(), |x| format!(" from axis {}", x.i))
            ))
        })?;
        if a[axis..axis + rb] != *bs {
            return Err(shape_err(format!(
                "B of shape {bs:?} is not A's dimensions {:?} from axis {axis} (A has shape {a:?}); \
                 legacy broadcasting (opsets before 7) does not expand size-1 dimensions",
                &a[axis..axis + rb]
            )));
        }
        let mut p = vec![1; ra];
        p[axis..axis + rb].copy_from_slice(bs);
        p
    };
    if live_first {
        let vals = broadcast_gather(a, &padded)
            .into_iter()
            .map(|i| c.data[i])
            .collect();
        Ok((vals, a.to_vec()))
    } else {
        // The result has A's (the constant's) shape; the activation B is not enlarged
        // only when A holds as many entries, and then B's entries map one to one.
        if numel(a) != Some(d) {
            return Err(unsupported(format!(
                " broadcasting the activation of shape {bs:?} to the larger constant shape {a:?}"
            )));
        }
        Ok((c.data.clone(), a.to_vec()))
    }
}

/// A `Conv` that is exactly a dense layer: its kernel covers the whole spatial extent of
/// the input (no padding, stride 1, dilation 1, one group), so the output is
/// `[1, M, 1, ..., 1]` with `y[m] = sum_{c,h,w} W[m,c,h,w] x[c,h,w] + B[m]`, which in the
/// row-major order of the activation is the matrix `W` reshaped to `[M, C*H*W]`.
#[allow(clippy::type_complexity)]
fn conv<'c>(
    node: &NodeProto,
    shape: &[usize],
    d: usize,
    live: &str,
    other_const: &dyn Fn(usize) -> Result<Option<&'c Const>, OnnxError>,
    unsupported: &dyn Fn(String) -> OnnxError,
    shape_err: &dyn Fn(String) -> OnnxError,
) -> Result<(Affine, Vec<usize>), OnnxError> {
    const DENSE: &str = "only a Conv whose kernel covers the whole input image, with no padding, stride 1, dilation 1 and group 1, is a dense layer";
    if node.input.first().map(String::as_str) != Some(live) {
        return Err(unsupported(" with the activation as the kernel".into()));
    }
    if shape.len() < 3 {
        return Err(shape_err(format!(
            "the input has shape {shape:?}; Conv needs [N, C, spatial...]"
        )));
    }
    if shape[0] != 1 {
        return Err(unsupported(format!(
            " on a batch of {} images (samara imports networks evaluated on one sample)",
            shape[0]
        )));
    }
    let spatial = &shape[2..];
    let ch = shape[1];
    let w = other_const(1)?.ok_or_else(|| shape_err("missing the kernel W".into()))?;
    if w.dims.len() != shape.len() || w.dims[1] != ch {
        return Err(shape_err(format!(
            "the kernel W has shape {:?}; for the input of shape {shape:?} it must be [M, {ch}, ...] with {} spatial dimensions",
            w.dims,
            spatial.len()
        )));
    }
    let m = w.dims[0];
    let kernel = &w.dims[2..];
    let group = attr(node, "group").map(|a| a.i).unwrap_or(1);
    if group != 1 {
        return Err(unsupported(format!(" with group = {group} ({DENSE})")));
    }
    if let Some(a) = attr(node, "kernel_shape") {
        if a.ints.len() != kernel.len() || a.ints.iter().zip(kernel).any(|(&k, &w)| k != w as i64) {
            return Err(shape_err(format!(
                "kernel_shape {:?} disagrees with the kernel W of shape {:?}",
                a.ints, w.dims
            )));
        }
    }
    if kernel != spatial {
        return Err(unsupported(format!(
            " with a {kernel:?} kernel over a {spatial:?} input image (a sliding window; {DENSE})"
        )));
    }
    let ones = |name: &str, want: i64| -> Result<(), OnnxError> {
        if let Some(a) = attr(node, name) {
            if a.ints.iter().any(|&v| v != want) {
                return Err(unsupported(format!(" with {name} {:?} ({DENSE})", a.ints)));
            }
        }
        Ok(())
    };
    ones("pads", 0)?;
    ones("strides", 1)?;
    ones("dilations", 1)?;
    if let Some(a) = attr(node, "auto_pad") {
        let s = String::from_utf8_lossy(&a.s);
        let pads_nothing = kernel.iter().all(|&k| k == 1);
        if !(s.is_empty() || s == "NOTSET" || s == "VALID" || pads_nothing) {
            return Err(unsupported(format!(" with auto_pad {s} ({DENSE})")));
        }
    }
    // The kernel's entries per output channel are C*H*W = d (as the input's).
    let bias = match other_const(2)? {
        None => vec![0.0; m],
        Some(c) if c.data.len() == m && c.dims.len() == 1 => c.data.clone(),
        Some(c) => {
            return Err(shape_err(format!(
                "the bias B has shape {:?}, expected [{m}]",
                c.dims
            )))
        }
    };
    if w.data.len() != m * d {
        return Err(shape_err(format!(
            "the kernel W of shape {:?} does not match the input of {d} entries",
            w.dims
        )));
    }
    let mut out = vec![1usize; shape.len()];
    out[1] = m;
    Ok((Affine::new(d, m, w.data.clone(), bias), out))
}

/// The shape a `Reshape` to `target` gives a tensor of `shape` (`d` entries): `0` copies
/// the input's dimension (unless `allowzero`), `-1` is inferred. `None` if invalid.
fn reshape(shape: &[usize], target: &[i64], d: usize, allowzero: bool) -> Option<Vec<usize>> {
    if target.len() > MAX_RANK || numel(shape) != Some(d) {
        return None;
    }
    crate::ops::shape::reshape_shape(shape, target, allowzero).ok()
}

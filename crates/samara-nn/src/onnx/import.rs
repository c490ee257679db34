use super::proto::{self, AttributeProto, ModelProto, NodeProto, TensorProto};
use crate::ir::{Activation, Affine, Layer, Network};
use prost::Message;
use std::collections::HashMap;
use std::path::Path;

/// Operators the importer understands.
pub const SUPPORTED_OPS: &[&str] = &[
    "Gemm",
    "MatMul",
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
    "Identity",
    "Squeeze",
    "Unsqueeze",
    "Dropout",
    "Constant",
];

/// Widest activation vector (inputs, outputs, hidden layers) the importer builds: the
/// affine maps are stored dense, so a declared width is a `width x width` allocation.
/// A file that declares more is refused before anything is allocated.
pub const MAX_WIDTH: usize = 4096;

/// Most values of one constant tensor (16M, 128 MB as f64).
pub const MAX_TENSOR_VALUES: usize = 1 << 24;

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
struct Const {
    dims: Vec<usize>,
    data: Vec<f64>,
}

/// Load a network from an ONNX file.
pub fn load(path: impl AsRef<Path>) -> Result<Network, OnnxError> {
    let path = path.as_ref();
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|cause| OnnxError::Io {
        file: file.clone(),
        cause,
    })?;
    from_bytes(&bytes, &file)
}

fn tensor_to_const(t: &TensorProto, file: &str) -> Result<Const, OnnxError> {
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
    let dims: Vec<usize> = t
        .dims
        .iter()
        .map(|&d| usize::try_from(d).map_err(|_| err(format!("negative dimension {d}"))))
        .collect::<Result<_, _>>()?;
    let n = dims
        .iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d))
        .filter(|&n| n <= MAX_TENSOR_VALUES)
        .ok_or_else(|| {
            err(format!(
                "shape {dims:?} declares more than {MAX_TENSOR_VALUES} values; samara imports controller-sized networks"
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

fn attr<'a>(n: &'a NodeProto, name: &str) -> Option<&'a AttributeProto> {
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
}

impl Builder<'_> {
    /// Compose `y = W x + b` (new map) after the pending segment. Elementwise maps merge
    /// into a pending affine; dense maps start a new segment after an elementwise one.
    fn push_affine(&mut self, a: Affine, elementwise: bool) {
        self.dim = a.out;
        if let Some(Seg::Affine {
            a: prev,
            elementwise: pe,
        }) = self.segs.last_mut()
        {
            if elementwise || !*pe {
                *prev = compose(prev, &a);
                *pe = *pe && elementwise;
                return;
            }
        }
        self.segs.push(Seg::Affine { a, elementwise });
    }
}

/// `second ∘ first`.
fn compose(first: &Affine, second: &Affine) -> Affine {
    let (n, k, m) = (first.inp, first.out, second.out);
    let mut w = vec![0.0; m * n];
    let mut b = second.b.clone();
    for i in 0..m {
        for j in 0..k {
            let s = second.w[i * k + j];
            if s != 0.0 {
                for l in 0..n {
                    w[i * n + l] += s * first.w[j * n + l];
                }
                b[i] += s * first.b[j];
            }
        }
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

/// Decode and convert an ONNX model held in memory; `file` names it in errors.
pub fn from_bytes(bytes: &[u8], file: &str) -> Result<Network, OnnxError> {
    let model = ModelProto::decode(bytes).map_err(|e| OnnxError::Decode {
        file: file.into(),
        message: e.to_string(),
    })?;
    let structure = |place: &str, message: String| OnnxError::Structure {
        file: file.into(),
        place: place.into(),
        message,
    };
    let graph = model.graph.as_ref().ok_or_else(|| OnnxError::Decode {
        file: file.into(),
        message: "the model has no graph".into(),
    })?;
    if let Some(op) = model
        .opset_import
        .iter()
        .find(|o| o.domain.is_empty() || o.domain == "ai.onnx")
    {
        if op.version < 7 {
            return Err(structure(
                "opset_import",
                format!(
                    "opset {} is older than 7; re-export with a newer opset",
                    op.version
                ),
            ));
        }
    }
    let mut consts: HashMap<String, Const> = HashMap::new();
    for t in &graph.initializer {
        consts.insert(t.name.clone(), tensor_to_const(t, file)?);
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
    let in_dim = input
        .r#type
        .as_ref()
        .and_then(|t| t.tensor_type.as_ref())
        .and_then(|t| t.shape.as_ref())
        .and_then(|s| s.dim.last())
        .and_then(|d| d.dim_value)
        .filter(|&d| d > 0)
        .ok_or_else(|| {
            structure(
                &format!("input `{}`", input.name),
                "its last dimension must be a fixed positive number".into(),
            )
        })?;
    let in_dim = usize::try_from(in_dim)
        .ok()
        .filter(|&d| d <= MAX_WIDTH)
        .ok_or_else(|| {
            structure(
                &format!("input `{}`", input.name),
                format!("declares {in_dim} entries; samara imports at most {MAX_WIDTH} (is the file corrupt?)"),
            )
        })?;
    let mut live = input.name.clone();
    let mut b = Builder {
        file,
        segs: Vec::new(),
        dim: in_dim,
    };

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
        if !node.domain.is_empty() && node.domain != "ai.onnx" {
            return Err(unsupported(format!(" from domain `{}`", node.domain)));
        }
        if node.op_type == "Constant" {
            let t = attr(node, "value")
                .and_then(|a| a.t.as_ref())
                .ok_or_else(|| unsupported(" without a tensor `value` attribute".into()))?;
            let out = node.output.first().cloned().unwrap_or_default();
            consts.insert(out, tensor_to_const(t, file)?);
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
        let too_wide = |m: usize| {
            shape_err(format!(
                "gives {m} entries; samara imports networks at most {MAX_WIDTH} wide"
            ))
        };
        match node.op_type.as_str() {
            "Gemm" => {
                if node.input[0] != live {
                    return Err(unsupported(" with the activation as second operand".into()));
                }
                let ta = attr(node, "transA").map(|a| a.i).unwrap_or(0);
                let tb = attr(node, "transB").map(|a| a.i).unwrap_or(0);
                let alpha = attr(node, "alpha").map(|a| a.f as f64).unwrap_or(1.0);
                let beta = attr(node, "beta").map(|a| a.f as f64).unwrap_or(1.0);
                if ta != 0 {
                    return Err(unsupported(" with transA = 1".into()));
                }
                let bm = other_const(1)?.ok_or_else(|| shape_err("missing B".into()))?;
                if bm.dims.len() != 2 {
                    return Err(shape_err(format!(
                        "B must be a matrix, has shape {:?}",
                        bm.dims
                    )));
                }
                let (r, c) = (bm.dims[0], bm.dims[1]);
                let (k, m) = if tb == 0 { (r, c) } else { (c, r) };
                if m > MAX_WIDTH {
                    return Err(too_wide(m));
                }
                if k != d {
                    return Err(shape_err(format!(
                        "B has {k} rows (after transB) but the activation has {d} entries"
                    )));
                }
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
                    Some(cv) if cv.data.len() == 1 => vec![beta * cv.data[0]; m],
                    Some(cv) if cv.data.len() == m => cv.data.iter().map(|v| beta * v).collect(),
                    Some(cv) => {
                        return Err(shape_err(format!(
                            "C has {} values, expected 1 or {m}",
                            cv.data.len()
                        )))
                    }
                };
                b.push_affine(Affine::new(d, m, w, bias), false);
            }
            "MatMul" => {
                if node.input[0] != live {
                    return Err(unsupported(" with the activation as second operand".into()));
                }
                let bm = other_const(1)?.ok_or_else(|| shape_err("missing B".into()))?;
                if bm.dims.len() != 2 || bm.dims[0] != d {
                    return Err(shape_err(format!(
                        "B has shape {:?}, expected [{d}, m]",
                        bm.dims
                    )));
                }
                let m = bm.dims[1];
                if m > MAX_WIDTH {
                    return Err(too_wide(m));
                }
                let mut w = vec![0.0; m * d];
                for i in 0..m {
                    for j in 0..d {
                        w[i * d + j] = bm.data[j * m + i];
                    }
                }
                b.push_affine(Affine::new(d, m, w, vec![0.0; m]), false);
            }
            "Add" | "Sub" | "Mul" | "Div" => {
                let live_first = node.input[0] == live;
                let c = other_const(if live_first { 1 } else { 0 })?
                    .ok_or_else(|| shape_err("missing constant operand".into()))?;
                let vals: Vec<f64> = match c.data.len() {
                    1 => vec![c.data[0]; d],
                    n if n == d => c.data.clone(),
                    n => return Err(shape_err(format!("constant has {n} values; it must broadcast to the activation's {d} (1 or {d})"))),
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
                b.push_affine(diag(&scale, &bias), true);
            }
            "Relu" => b.segs.push(Seg::Act(Activation::Relu)),
            "Sigmoid" => b.segs.push(Seg::Act(Activation::Sigmoid)),
            "Tanh" => b.segs.push(Seg::Act(Activation::Tanh)),
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
            }
            "Identity" | "Dropout" | "Flatten" | "Squeeze" | "Unsqueeze" => {}
            "Reshape" => {
                let sh = other_const(1)?.ok_or_else(|| shape_err("missing shape".into()))?;
                let last = sh.data.last().copied().unwrap_or(-1.0);
                let others_trivial = sh.data[..sh.data.len().saturating_sub(1)]
                    .iter()
                    .all(|v| [1.0, -1.0, 0.0].contains(v));
                if !(others_trivial && (last == d as f64 || last == -1.0)) {
                    return Err(unsupported(format!(
                        " to shape {:?} (only reshapes that keep a vector of {d} are supported)",
                        sh.data
                    )));
                }
            }
            _ => return Err(unsupported(String::new())),
        }
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
    let layers = segs
        .into_iter()
        .map(|s| match s {
            Seg::Affine { a, .. } => Layer::Affine(a),
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

//! ONNX model -> [`Graph`]. Every node becomes an [`Op`] with its attributes checked (an
//! attribute samara does not know, or a value it does not support, is an error naming
//! the node, the operator and the attribute); nodes on constants only are folded; the
//! others are evaluated once on zeros so that every tensor's shape is known.

use super::{Graph, Node, Value};
use crate::limits::Budget;
use crate::onnx::import::{attr, default_opset, model_graph, sample_shape, tensor_to_const};
use crate::onnx::proto::{ModelProto, NodeProto};
use crate::onnx::OnnxError;
use crate::ops::conv::AutoPad;
use crate::ops::elementwise::{BinOp, UnOp};
use crate::ops::{ConvAttrs, ConvTransposeAttrs, Op, PoolAttrs, Tensor};
use std::collections::HashMap;

/// Operators the graph importer reads.
pub const GRAPH_OPS: &[&str] = &[
    "Conv",
    "ConvTranspose",
    "BatchNormalization",
    "MaxPool",
    "AveragePool",
    "GlobalAveragePool",
    "Pad",
    "Upsample",
    "Add",
    "Sub",
    "Mul",
    "Div",
    "Pow",
    "Neg",
    "Relu",
    "LeakyRelu",
    "PRelu",
    "Sigmoid",
    "Tanh",
    "Clip",
    "Sign",
    "Sin",
    "Cos",
    "Exp",
    "Sqrt",
    "Abs",
    "Softmax",
    "MatMul",
    "Gemm",
    "Concat",
    "Slice",
    "Split",
    "Gather",
    "Reshape",
    "Flatten",
    "Transpose",
    "Squeeze",
    "Unsqueeze",
    "Identity",
    "Dropout",
    "Constant",
    "Shape",
    "Cast",
    "ConstantOfShape",
];

/// The attributes each operator may carry (anything else is refused by name).
fn known_attrs(op: &str) -> &'static [&'static str] {
    match op {
        "Conv" => &[
            "auto_pad",
            "dilations",
            "group",
            "kernel_shape",
            "pads",
            "strides",
        ],
        "ConvTranspose" => &[
            "auto_pad",
            "dilations",
            "group",
            "kernel_shape",
            "pads",
            "strides",
            "output_padding",
        ],
        "BatchNormalization" => &["epsilon", "momentum", "training_mode", "spatial", "is_test"],
        "MaxPool" => &[
            "auto_pad",
            "ceil_mode",
            "dilations",
            "kernel_shape",
            "pads",
            "storage_order",
            "strides",
        ],
        "AveragePool" => &[
            "auto_pad",
            "ceil_mode",
            "count_include_pad",
            "dilations",
            "kernel_shape",
            "pads",
            "strides",
        ],
        "Pad" => &["mode", "pads", "value"],
        "Upsample" => &["mode", "scales"],
        "LeakyRelu" => &["alpha"],
        "Clip" => &["min", "max"],
        "Softmax" => &["axis"],
        "Gemm" => &["alpha", "beta", "transA", "transB", "broadcast"],
        "Concat" | "Gather" | "Flatten" => &["axis"],
        "Slice" => &["starts", "ends", "axes"],
        "Split" => &["axis", "split", "num_outputs"],
        "Reshape" => &["shape", "allowzero"],
        "Transpose" => &["perm"],
        "Squeeze" | "Unsqueeze" => &["axes"],
        "Dropout" => &["ratio", "seed", "is_test"],
        "Shape" => &["start", "end"],
        "Cast" => &["to", "saturate"],
        "ConstantOfShape" => &["value"],
        _ => &[],
    }
}

/// An import error about one node.
struct NodeErr<'a> {
    file: &'a str,
    node: String,
    op: String,
}

impl NodeErr<'_> {
    fn unsupported(&self, detail: String) -> OnnxError {
        OnnxError::Unsupported {
            file: self.file.into(),
            node: self.node.clone(),
            op: self.op.clone(),
            detail,
        }
    }
    fn structure(&self, message: String) -> OnnxError {
        OnnxError::Structure {
            file: self.file.into(),
            place: format!("node `{}` ({})", self.node, self.op),
            message,
        }
    }
}

fn ints(n: &NodeProto, name: &str) -> Option<Vec<i64>> {
    attr(n, name).map(|a| a.ints.clone())
}

fn int(n: &NodeProto, name: &str, def: i64) -> i64 {
    attr(n, name).map_or(def, |a| a.i)
}

fn float(n: &NodeProto, name: &str, def: f64) -> f64 {
    attr(n, name).map_or(def, |a| a.f as f64)
}

fn string(n: &NodeProto, name: &str) -> Option<String> {
    attr(n, name).map(|a| String::from_utf8_lossy(&a.s).into_owned())
}

fn usizes(v: Option<Vec<i64>>, what: &str, e: &NodeErr) -> Result<Vec<usize>, OnnxError> {
    v.unwrap_or_default()
        .iter()
        .map(|&x| {
            usize::try_from(x)
                .map_err(|_| e.unsupported(format!(" with attribute `{what}` holding {x}")))
        })
        .collect()
}

fn auto_pad(n: &NodeProto, e: &NodeErr) -> Result<AutoPad, OnnxError> {
    match string(n, "auto_pad").as_deref() {
        None | Some("") | Some("NOTSET") => Ok(AutoPad::NotSet),
        Some("VALID") => Ok(AutoPad::Valid),
        Some("SAME_UPPER") => Ok(AutoPad::SameUpper),
        Some("SAME_LOWER") => Ok(AutoPad::SameLower),
        Some(s) => Err(e.unsupported(format!(" with attribute `auto_pad` = {s}"))),
    }
}

fn conv_attrs(n: &NodeProto, e: &NodeErr) -> Result<ConvAttrs, OnnxError> {
    let group = int(n, "group", 1);
    let kernel_shape = ints(n, "kernel_shape");
    Ok(ConvAttrs {
        strides: usizes(ints(n, "strides"), "strides", e)?,
        pads: usizes(ints(n, "pads"), "pads", e)?,
        dilations: usizes(ints(n, "dilations"), "dilations", e)?,
        group: usize::try_from(group)
            .ok()
            .filter(|&g| g > 0)
            .ok_or_else(|| e.unsupported(format!(" with attribute `group` = {group}")))?,
        auto_pad: auto_pad(n, e)?,
        kernel_shape: kernel_shape
            .map(|k| usizes(Some(k), "kernel_shape", e))
            .transpose()?,
    })
}

fn pool_attrs(n: &NodeProto, e: &NodeErr) -> Result<PoolAttrs, OnnxError> {
    let kernel = usizes(ints(n, "kernel_shape"), "kernel_shape", e)?;
    if kernel.is_empty() {
        return Err(e.structure("missing attribute `kernel_shape`".into()));
    }
    if int(n, "storage_order", 0) != 0 {
        return Err(
            e.unsupported(" with attribute `storage_order` = 1 (column-major indices)".into())
        );
    }
    Ok(PoolAttrs {
        kernel,
        strides: usizes(ints(n, "strides"), "strides", e)?,
        pads: usizes(ints(n, "pads"), "pads", e)?,
        dilations: usizes(ints(n, "dilations"), "dilations", e)?,
        ceil_mode: int(n, "ceil_mode", 0) != 0,
        count_include_pad: int(n, "count_include_pad", 0) != 0,
        auto_pad: auto_pad(n, e)?,
    })
}

/// The operator of a node, its attributes checked.
fn parse_op(n: &NodeProto, opset: i64, e: &NodeErr) -> Result<Op, OnnxError> {
    let op = n.op_type.as_str();
    if !GRAPH_OPS.contains(&op) {
        return Err(e.unsupported(String::new()));
    }
    if let Some(a) = n
        .attribute
        .iter()
        .find(|a| !known_attrs(op).contains(&a.name.as_str()))
    {
        return Err(e.unsupported(format!(
            " with attribute `{}`, which samara does not read",
            a.name
        )));
    }
    Ok(match op {
        "Conv" => Op::Conv(conv_attrs(n, e)?),
        "ConvTranspose" => {
            if attr(n, "output_shape").is_some() {
                return Err(e.unsupported(" with attribute `output_shape`".into()));
            }
            Op::ConvTranspose(ConvTransposeAttrs {
                conv: conv_attrs(n, e)?,
                output_padding: usizes(ints(n, "output_padding"), "output_padding", e)?,
            })
        }
        "BatchNormalization" => {
            if int(n, "training_mode", 0) != 0 {
                return Err(e.unsupported(
                    " with attribute `training_mode` = 1 (samara evaluates inference mode)".into(),
                ));
            }
            if int(n, "spatial", 1) != 1 {
                return Err(e.unsupported(" with attribute `spatial` = 0".into()));
            }
            if n.output.iter().skip(1).any(|o| !o.is_empty()) {
                return Err(e.unsupported(" with training outputs (running mean/var)".into()));
            }
            Op::BatchNorm {
                epsilon: float(n, "epsilon", 1e-5),
            }
        }
        "MaxPool" => {
            if n.output.iter().skip(1).any(|o| !o.is_empty()) {
                return Err(e.unsupported(" with its Indices output".into()));
            }
            Op::MaxPool(pool_attrs(n, e)?)
        }
        "AveragePool" => Op::AveragePool(pool_attrs(n, e)?),
        "GlobalAveragePool" => Op::GlobalAveragePool,
        "Upsample" => {
            let mode = string(n, "mode").unwrap_or_else(|| "nearest".into());
            if mode != "nearest" {
                return Err(
                    e.unsupported(format!(" with attribute `mode` = {mode} (nearest only)"))
                );
            }
            Op::Upsample {
                scales: n
                    .attribute
                    .iter()
                    .find(|a| a.name == "scales")
                    .map(|a| a.floats.iter().map(|&v| v as f64).collect()),
            }
        }
        "Pad" => {
            let mode = string(n, "mode").unwrap_or_else(|| "constant".into());
            if mode != "constant" {
                return Err(e.unsupported(format!(
                    " with attribute `mode` = {mode} (constant padding only)"
                )));
            }
            Op::Pad {
                pads: if opset < 11 { ints(n, "pads") } else { None },
                value: float(n, "value", 0.0),
            }
        }
        "Add" | "Sub" | "Mul" | "Div" | "Pow" => {
            if opset < 7 && int(n, "broadcast", 0) != 0 {
                return Err(e.unsupported(" with attribute `broadcast` (opsets before 7)".into()));
            }
            Op::Binary(match op {
                "Add" => BinOp::Add,
                "Sub" => BinOp::Sub,
                "Mul" => BinOp::Mul,
                "Div" => BinOp::Div,
                _ => BinOp::Pow,
            })
        }
        "Neg" => Op::Unary(UnOp::Neg),
        "Relu" => Op::Unary(UnOp::Relu),
        "Sigmoid" => Op::Unary(UnOp::Sigmoid),
        "Tanh" => Op::Unary(UnOp::Tanh),
        "Sign" => Op::Unary(UnOp::Sign),
        "Sin" => Op::Unary(UnOp::Sin),
        "Cos" => Op::Unary(UnOp::Cos),
        "Exp" => Op::Unary(UnOp::Exp),
        "Sqrt" => Op::Unary(UnOp::Sqrt),
        "Abs" => Op::Unary(UnOp::Abs),
        "LeakyRelu" => Op::LeakyRelu {
            alpha: float(n, "alpha", 0.01),
        },
        "PRelu" => Op::PRelu,
        "Clip" => Op::Clip {
            lo: float(n, "min", f64::NEG_INFINITY),
            hi: float(n, "max", f64::INFINITY),
        },
        "Softmax" => Op::Softmax {
            axis: int(n, "axis", if opset < 13 { 1 } else { -1 }),
        },
        "MatMul" => Op::MatMul,
        "Gemm" => {
            if opset < 7 && int(n, "broadcast", 0) != 0 {
                return Err(e.unsupported(" with attribute `broadcast` (opsets before 7)".into()));
            }
            Op::Gemm {
                alpha: float(n, "alpha", 1.0),
                beta: float(n, "beta", 1.0),
                trans_a: int(n, "transA", 0) != 0,
                trans_b: int(n, "transB", 0) != 0,
            }
        }
        "Concat" => Op::Concat {
            axis: int(n, "axis", 0),
        },
        "Slice" => Op::Slice {
            attrs: if opset < 10 {
                Some((
                    ints(n, "starts")
                        .ok_or_else(|| e.structure("missing attribute `starts`".into()))?,
                    ints(n, "ends")
                        .ok_or_else(|| e.structure("missing attribute `ends`".into()))?,
                    ints(n, "axes"),
                ))
            } else {
                None
            },
        },
        "Split" => Op::Split {
            axis: int(n, "axis", 0),
            sizes: ints(n, "split"),
            outputs: n.output.len(),
        },
        "Gather" => Op::Gather {
            axis: int(n, "axis", 0),
        },
        "Reshape" => Op::Reshape {
            shape: if opset < 5 { ints(n, "shape") } else { None },
            allowzero: int(n, "allowzero", 0) != 0,
        },
        "Flatten" => Op::Flatten {
            axis: int(n, "axis", 1),
        },
        "Transpose" => Op::Transpose {
            perm: ints(n, "perm"),
        },
        "Squeeze" => Op::Squeeze {
            axes: ints(n, "axes"),
        },
        "Unsqueeze" => Op::Unsqueeze {
            axes: ints(n, "axes"),
        },
        "Identity" | "Dropout" => Op::Identity,
        "Shape" => Op::Shape {
            start: int(n, "start", 0),
            end: attr(n, "end").map(|a| a.i),
        },
        "Cast" => {
            // Integer element types of TensorProto.DataType.
            let to = int(n, "to", 1);
            Op::Cast {
                to_int: matches!(to, 2..=7 | 12 | 13),
            }
        }
        "ConstantOfShape" => Op::ConstantOfShape {
            value: attr(n, "value")
                .and_then(|a| a.t.as_ref())
                .map(|t| {
                    tensor_to_const(t, e.file, &Budget::new(1 << 20))
                        .map(|c| c.data.first().copied().unwrap_or(0.0))
                })
                .transpose()?
                .unwrap_or(0.0),
        },
        _ => return Err(e.unsupported(String::new())),
    })
}

/// Inputs that may be computed from the network's input (the others must be
/// constants: kernels, shapes, indices, pads, axes).
fn may_be_dynamic(op: &str, k: usize) -> bool {
    match op {
        "Add" | "Sub" | "Mul" | "Div" | "MatMul" | "Concat" => true,
        "Gemm" => k < 2,
        "Pow" => k == 0,
        _ => k == 0,
    }
}

/// Read an ONNX model into a [`Graph`]; `file` names it in errors. Its constants are
/// charged to the import budget of [`crate::limits::import_memory`].
pub fn from_model(model: &ModelProto, file: &str) -> Result<Graph, OnnxError> {
    let budget = Budget::from_env().map_err(|message| OnnxError::Structure {
        file: file.into(),
        place: "import memory".into(),
        message,
    })?;
    from_model_within(model, file, &budget)
}

/// [`from_model`] charging every constant the graph keeps (initializers, `Constant`
/// nodes, folded nodes) to `budget` before it is stored.
pub fn from_model_within(
    model: &ModelProto,
    file: &str,
    budget: &Budget,
) -> Result<Graph, OnnxError> {
    let structure = |place: &str, message: String| OnnxError::Structure {
        file: file.into(),
        place: place.into(),
        message,
    };
    let graph = model_graph(model, file)?;
    let opset = default_opset(model);
    let mut values: Vec<Value> = Vec::new();
    let mut ids: HashMap<String, usize> = HashMap::new();
    fn add(
        values: &mut Vec<Value>,
        ids: &mut HashMap<String, usize>,
        name: &str,
        shape: Vec<usize>,
        konst: Option<Tensor>,
    ) -> usize {
        values.push(Value {
            name: name.into(),
            shape,
            konst,
        });
        ids.insert(name.into(), values.len() - 1);
        values.len() - 1
    }
    for t in &graph.initializer {
        let c = tensor_to_const(t, file, budget)?;
        add(
            &mut values,
            &mut ids,
            &t.name,
            c.dims.clone(),
            Some(Tensor::new(c.dims, c.data)),
        );
    }
    let inputs: Vec<_> = graph
        .input
        .iter()
        .filter(|i| !graph.initializer.iter().any(|t| t.name == i.name))
        .collect();
    if inputs.len() != 1 {
        return Err(structure(
            "graph inputs",
            format!("expected exactly one non-constant input, found {}; samara imports single-input networks", inputs.len()),
        ));
    }
    let input = inputs[0];
    let dims = input
        .r#type
        .as_ref()
        .and_then(|t| t.tensor_type.as_ref())
        .and_then(|t| t.shape.as_ref())
        .map(|s| s.dim.as_slice())
        .unwrap_or(&[]);
    let in_shape = sample_shape(dims);
    if crate::ops::numel(&in_shape).is_none_or(|n| !budget.fits(n)) {
        return Err(structure(
            &format!("input `{}`", input.name),
            format!(
                "declares shape {in_shape:?}, more entries than the import's memory budget holds ({}); is the file corrupt?",
                crate::limits::show_bytes(budget.allowed())
            ),
        ));
    }
    let in_id = add(&mut values, &mut ids, &input.name, in_shape, None);
    let mut nodes = Vec::new();
    for (idx, n) in graph.node.iter().enumerate() {
        let e = NodeErr {
            file,
            node: if n.name.is_empty() {
                format!("#{idx} ({})", n.op_type)
            } else {
                n.name.clone()
            },
            op: n.op_type.clone(),
        };
        budget.check_time().map_err(|m| e.structure(m))?;
        if !n.domain.is_empty() && n.domain != "ai.onnx" {
            return Err(e.unsupported(format!(" from domain `{}`", n.domain)));
        }
        if n.op_type == "Constant" {
            let t = if let Some(t) = attr(n, "value").and_then(|a| a.t.as_ref()) {
                let c = tensor_to_const(t, file, budget)?;
                Tensor::new(c.dims, c.data)
            } else if let Some(a) = attr(n, "value_float") {
                Tensor::new(vec![], vec![a.f as f64])
            } else if let Some(a) = attr(n, "value_int") {
                Tensor::new(vec![], vec![a.i as f64])
            } else if let Some(a) = attr(n, "value_floats") {
                Tensor::new(
                    vec![a.floats.len()],
                    a.floats.iter().map(|&v| v as f64).collect(),
                )
            } else if let Some(a) = attr(n, "value_ints") {
                Tensor::new(
                    vec![a.ints.len()],
                    a.ints.iter().map(|&v| v as f64).collect(),
                )
            } else {
                return Err(e.unsupported(" without a `value` attribute samara reads".into()));
            };
            let out = n.output.first().cloned().unwrap_or_default();
            add(&mut values, &mut ids, &out, t.shape.clone(), Some(t));
            continue;
        }
        let op = parse_op(n, opset, &e)?;
        let inputs: Vec<Option<usize>> = n
            .input
            .iter()
            .map(|name| {
                if name.is_empty() {
                    Ok(None)
                } else {
                    ids.get(name).copied().map(Some).ok_or_else(|| {
                        e.structure(format!("input `{name}` is computed by no earlier node"))
                    })
                }
            })
            .collect::<Result<_, _>>()?;
        for (k, i) in inputs.iter().enumerate() {
            if let Some(i) = i {
                if values[*i].konst.is_none() && !may_be_dynamic(&n.op_type, k) {
                    return Err(e.unsupported(format!(
                        " with input {k} (`{}`) computed from the network's input (samara needs it constant)",
                        values[*i].name
                    )));
                }
            }
        }
        let all_const = inputs.iter().flatten().all(|&i| values[i].konst.is_some());
        let zeros: Vec<Option<Tensor>> = inputs
            .iter()
            .map(|i| {
                i.map(|i| {
                    values[i]
                        .konst
                        .clone()
                        .unwrap_or_else(|| Tensor::zeros(&values[i].shape))
                })
            })
            .collect();
        let refs: Vec<Option<&Tensor>> = zeros.iter().map(|t| t.as_ref()).collect();
        let outs = op.eval(&refs).map_err(|m| e.structure(m))?;
        if outs.len() < n.output.len() {
            return Err(e.structure(format!(
                "declares {} outputs, computes {}",
                n.output.len(),
                outs.len()
            )));
        }
        // A constant that enlarges the activation by broadcasting (e.g. one value per
        // row of a batch) changes what one sample computes: refused, as by the chain
        // importer.
        if !all_const
            && matches!(op, Op::Binary(_) | Op::PRelu)
            && outs.first().is_some_and(|o| {
                let dyn_max = inputs
                    .iter()
                    .flatten()
                    .filter(|&&i| values[i].konst.is_none())
                    .map(|&i| values[i].shape.iter().product::<usize>())
                    .max()
                    .unwrap_or(0);
                o.numel() > dyn_max
            })
        {
            return Err(e.unsupported(format!(
                " broadcasting the activation to the larger shape {:?} (a constant that depends on the batch row, or enlarges one sample)",
                outs[0].shape
            )));
        }
        if all_const {
            // Folded constants stay in the graph.
            let kept: usize = outs.iter().map(Tensor::numel).sum();
            budget
                .charge(kept, &|| format!("its constant result ({kept} values)"))
                .map_err(|m| e.structure(m))?;
        }
        let mut out_ids = Vec::new();
        for (name, t) in n.output.iter().zip(outs) {
            let shape = t.shape.clone();
            out_ids.push(add(
                &mut values,
                &mut ids,
                name,
                shape,
                all_const.then_some(t),
            ));
        }
        if !all_const {
            nodes.push(Node {
                name: e.node.clone(),
                op_type: n.op_type.clone(),
                op,
                inputs,
                outputs: out_ids,
            });
        }
    }
    if graph.output.len() != 1 {
        return Err(structure(
            "graph outputs",
            format!(
                "expected one output, found {}; samara imports single-output networks",
                graph.output.len()
            ),
        ));
    }
    let out_name = &graph.output[0].name;
    let output = *ids.get(out_name).ok_or_else(|| {
        structure(
            "graph outputs",
            format!("output `{out_name}` is computed by no node"),
        )
    })?;
    if values[output].konst.is_some() {
        return Err(structure(
            "graph outputs",
            format!("output `{out_name}` does not depend on the input"),
        ));
    }
    Ok(Graph {
        values,
        nodes,
        input: in_id,
        output,
    })
}

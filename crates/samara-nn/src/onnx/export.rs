use super::proto::{self, AttributeProto, GraphProto, ModelProto, NodeProto, OperatorSetIdProto};
use super::proto::{TensorProto, ValueInfoProto};
use crate::ir::{Activation, Affine, Layer, Network};
use prost::Message;
use std::path::Path;

/// Options of [`export`].
#[derive(Clone, Debug)]
pub struct ExportOptions {
    /// Include the input normalisation and output denormalisation (true: the file takes
    /// raw inputs; false: the body only, normalised units).
    pub with_normalisation: bool,
    /// Store weights as float64 (exact) instead of float32 (the default; what most
    /// runtimes expect). float32 rounds each weight to 24 bits (relative 6e-8).
    pub float64: bool,
    /// Producer name recorded in the file.
    pub producer: String,
}

impl Default for ExportOptions {
    fn default() -> Self {
        ExportOptions {
            with_normalisation: true,
            float64: false,
            producer: "samara".into(),
        }
    }
}

fn elem_type(o: &ExportOptions) -> i32 {
    if o.float64 {
        proto::DOUBLE
    } else {
        proto::FLOAT
    }
}

fn tensor(name: &str, dims: &[usize], data: &[f64], o: &ExportOptions) -> TensorProto {
    let raw = if o.float64 {
        data.iter().flat_map(|v| v.to_le_bytes()).collect()
    } else {
        data.iter()
            .flat_map(|v| (*v as f32).to_le_bytes())
            .collect()
    };
    TensorProto {
        dims: dims.iter().map(|&d| d as i64).collect(),
        data_type: elem_type(o),
        name: name.into(),
        raw_data: raw,
        ..Default::default()
    }
}

fn value_info(name: &str, dim: usize, o: &ExportOptions) -> ValueInfoProto {
    ValueInfoProto::tensor(name, elem_type(o), &[1, dim as i64])
}

fn node(
    op: &str,
    name: String,
    inputs: Vec<String>,
    output: String,
    attrs: Vec<AttributeProto>,
) -> NodeProto {
    NodeProto {
        input: inputs,
        output: vec![output],
        name,
        op_type: op.into(),
        attribute: attrs,
        domain: String::new(),
    }
}

fn is_diagonal(a: &Affine) -> bool {
    a.inp == a.out && (0..a.out).all(|i| a.row(i).nonzeros().all(|(j, _)| i == j))
}

/// Build the ONNX model of a network: `Gemm` per dense layer (`transB = 1`), `Relu`,
/// `Sigmoid`, `Tanh`, `Clip` (bounds as inputs, opset 13), and diagonal normalisation
/// layers as `Mul` + `Add`, so samara's importer recognises them again.
pub fn export(net: &Network, o: &ExportOptions) -> ModelProto {
    let mut nodes = Vec::new();
    let mut inits = Vec::new();
    let mut live = "input".to_string();
    let mut k = 0usize;
    let mut layers: Vec<(Layer, bool)> = Vec::new();
    if o.with_normalisation {
        if let Some(a) = &net.input_norm {
            layers.push((Layer::Affine(a.clone()), true));
        }
    }
    layers.extend(net.layers.iter().cloned().map(|l| (l, false)));
    if o.with_normalisation {
        if let Some(a) = &net.output_denorm {
            layers.push((Layer::Affine(a.clone()), true));
        }
    }
    let mut dim = if o.with_normalisation {
        net.n_inputs()
    } else {
        net.input_norm
            .as_ref()
            .map(|a| a.out)
            .unwrap_or(net.n_inputs())
    };
    let in_dim = dim;
    for (layer, norm) in layers {
        k += 1;
        let out = format!("t{k}");
        match layer {
            Layer::Affine(a) if norm && is_diagonal(&a) => {
                let d: Vec<f64> = (0..a.out).map(|i| a.weight(i, i)).collect();
                let (sn, bn, mid) = (format!("scale{k}"), format!("shift{k}"), format!("t{k}m"));
                inits.push(tensor(&sn, &[a.out], &d, o));
                inits.push(tensor(&bn, &[a.out], &a.b, o));
                nodes.push(node(
                    "Mul",
                    format!("mul{k}"),
                    vec![live.clone(), sn],
                    mid.clone(),
                    vec![],
                ));
                nodes.push(node(
                    "Add",
                    format!("add{k}"),
                    vec![mid, bn],
                    out.clone(),
                    vec![],
                ));
                dim = a.out;
            }
            Layer::Affine(a) => {
                let (wn, bn) = (format!("W{k}"), format!("b{k}"));
                // ONNX `Gemm` takes a dense matrix: a sparse (lowered convolution's)
                // map is written dense.
                inits.push(tensor(&wn, &[a.out, a.inp], &a.to_dense(), o));
                inits.push(tensor(&bn, &[a.out], &a.b, o));
                let tb = AttributeProto {
                    name: "transB".into(),
                    i: 1,
                    r#type: 2,
                    ..Default::default()
                };
                nodes.push(node(
                    "Gemm",
                    format!("gemm{k}"),
                    vec![live.clone(), wn, bn],
                    out.clone(),
                    vec![tb],
                ));
                dim = a.out;
            }
            Layer::Act(Activation::Relu) => nodes.push(node(
                "Relu",
                format!("relu{k}"),
                vec![live.clone()],
                out.clone(),
                vec![],
            )),
            Layer::Act(Activation::Sigmoid) => nodes.push(node(
                "Sigmoid",
                format!("sigmoid{k}"),
                vec![live.clone()],
                out.clone(),
                vec![],
            )),
            Layer::Act(Activation::Tanh) => nodes.push(node(
                "Tanh",
                format!("tanh{k}"),
                vec![live.clone()],
                out.clone(),
                vec![],
            )),
            Layer::Act(Activation::Sign) => nodes.push(node(
                "Sign",
                format!("sign{k}"),
                vec![live.clone()],
                out.clone(),
                vec![],
            )),
            Layer::Act(Activation::Clamp { lo, hi }) => {
                let (ln, hn) = (format!("lo{k}"), format!("hi{k}"));
                // Clip bounds are scalars of the input's type.
                inits.push(tensor(&ln, &[], &[lo.max(-f32::MAX as f64)], o));
                inits.push(tensor(&hn, &[], &[hi.min(f32::MAX as f64)], o));
                nodes.push(node(
                    "Clip",
                    format!("clip{k}"),
                    vec![live.clone(), ln, hn],
                    out.clone(),
                    vec![],
                ));
            }
        }
        live = out;
    }
    // Name the final tensor `output`.
    if let Some(last) = nodes.last_mut() {
        last.output = vec!["output".into()];
        live = "output".into();
    } else {
        nodes.push(node(
            "Identity",
            "identity".into(),
            vec![live.clone()],
            "output".into(),
            vec![],
        ));
        live = "output".into();
    }
    let graph = GraphProto {
        node: nodes,
        name: "samara_network".into(),
        initializer: inits,
        doc_string: format!(
            "inputs: {}; outputs: {}",
            net.input_names.join(", "),
            net.output_names.join(", ")
        ),
        input: vec![value_info("input", in_dim, o)],
        output: vec![value_info(&live, dim, o)],
    };
    ModelProto {
        ir_version: 7,
        producer_name: o.producer.clone(),
        producer_version: env!("CARGO_PKG_VERSION").into(),
        graph: Some(graph),
        opset_import: vec![OperatorSetIdProto {
            domain: String::new(),
            version: 13,
        }],
        ..Default::default()
    }
}

/// Export and write atomically (temporary sibling file, then rename).
pub fn save(net: &Network, path: impl AsRef<Path>, o: &ExportOptions) -> std::io::Result<()> {
    let path = path.as_ref();
    let bytes = export(net, o).encode_to_vec();
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let tmp = path.with_file_name(format!(".{name}.{}.tmp", std::process::id()));
    std::fs::write(&tmp, bytes)
        .and_then(|_| std::fs::rename(&tmp, path))
        .inspect_err(|_| {
            let _ = std::fs::remove_file(&tmp);
        })
}

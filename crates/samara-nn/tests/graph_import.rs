//! The graph import (issue 37): the conv / BN / residual / pooling fixtures written by
//! bench/nn/make_conv_fixture.py evaluate equal to onnxruntime (expected outputs in the
//! CSV, computed by onnxruntime, an independent runtime), both by the graph evaluation
//! and by the lowered chain the verifier reads; unsupported operators and attributes
//! are errors naming the node, the operator and the attribute.

use prost::Message;
use samara_nn::ir::{Activation, Layer};
use samara_nn::onnx::{self, proto, OnnxError};
use samara_nn::ops::Tensor;

fn data(name: &str) -> String {
    format!("{}/tests/data/{name}", env!("CARGO_MANIFEST_DIR"))
}

/// Rows of (inputs, expected outputs).
fn rows(stem: &str, ni: usize) -> Vec<(Vec<f64>, Vec<f64>)> {
    let text = std::fs::read_to_string(data(&format!("{stem}.csv"))).unwrap();
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.is_empty())
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            (v[..ni].to_vec(), v[ni..].to_vec())
        })
        .collect()
}

/// Largest |got - want| / max(1, |want|): onnxruntime computes in float32 (relative
/// rounding about 1e-7 per operation), samara in f64 from the same float32 weights.
fn worst(got: &[f64], want: &[f64]) -> f64 {
    assert_eq!(got.len(), want.len());
    got.iter()
        .zip(want)
        .map(|(g, w)| (g - w).abs() / w.abs().max(1.0))
        .fold(0.0, f64::max)
}

fn check_fixture(stem: &str, n_in: usize, n_out: usize) {
    let path = data(&format!("{stem}.onnx"));
    let graph = onnx::load_graph(&path).unwrap();
    let chain = onnx::load(&path).unwrap();
    assert_eq!((graph.n_inputs(), graph.n_outputs()), (n_in, n_out));
    assert_eq!((chain.n_inputs(), chain.n_outputs()), (n_in, n_out));
    // The chain the verifier reads: affine maps each followed by ReLU.
    assert!(chain
        .layers
        .iter()
        .all(|l| matches!(l, Layer::Affine(_) | Layer::Act(Activation::Relu))));
    let rs = rows(stem, n_in);
    assert_eq!(rs.len(), 30);
    let (mut eg, mut ec) = (0.0f64, 0.0f64);
    for (x, y) in &rs {
        eg = eg.max(worst(&graph.eval_f64(x).unwrap(), y));
        ec = ec.max(worst(&chain.eval_f64(x), y));
    }
    assert!(eg < 1e-5, "{stem}: graph evaluation off by {eg:e}");
    assert!(ec < 1e-5, "{stem}: lowered chain off by {ec:e}");
}

#[test]
fn conv_bn_residual_pool_fixture_agrees_with_onnxruntime() {
    check_fixture("conv_residual", 72, 3);
}

/// bench/nn/make_upsample_fixture.py: nearest Upsample (opset 9, scales as an input)
/// by integer and by non-integer scales, as VNN-COMP 2023's cgan uses it.
#[test]
fn upsample_fixture_agrees_with_onnxruntime() {
    check_fixture("upsample", 18, 4);
}

/// bench/nn/make_upsample_fixture.py: the input used twice, once through a Slice to
/// INT64_MAX (PyTorch's `x[:, 2:]`), as VNN-COMP 2024's linearizenn networks are.
#[test]
fn skip_slice_fixture_agrees_with_onnxruntime() {
    check_fixture("skip_slice", 4, 2);
}

/// bench/nn/make_sign_fixture.py: VNN-COMP 2023 traffic_signs' binarised layout (NHWC
/// transposes around a +-1 convolution, Larq's `sign(sign(x) + 0.1)`, a +-1 dense layer,
/// a final Softmax), on integer inputs that put exact zeros into `Sign` and on uniform
/// ones. The graph evaluation equals onnxruntime, and so does the chain without the
/// final softmax (`load_logits`) followed by a softmax; `load` still refuses the
/// Softmax by name.
#[test]
fn sign_fixture_agrees_with_onnxruntime() {
    let path = data("sign_bnn.onnx");
    let graph = onnx::load_graph(&path).unwrap();
    let (chain, dropped) = onnx::load_logits(&path).unwrap();
    assert!(dropped);
    assert_eq!((chain.n_inputs(), chain.n_outputs()), (32, 5));
    assert!(chain
        .layers
        .iter()
        .any(|l| matches!(l, Layer::Act(Activation::Sign))));
    let msg = onnx::load(&path).unwrap_err().to_string();
    assert!(
        msg.contains("`softmax`") && msg.contains("Softmax"),
        "{msg}"
    );
    let softmax = |z: &[f64]| {
        let m = z.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let e: Vec<f64> = z.iter().map(|v| (v - m).exp()).collect();
        let s: f64 = e.iter().sum();
        e.iter().map(|v| v / s).collect::<Vec<f64>>()
    };
    let rs = rows("sign_bnn", 32);
    assert_eq!(rs.len(), 30);
    for (x, y) in &rs {
        let eg = worst(&graph.eval_f64(x).unwrap(), y);
        let ec = worst(&softmax(&chain.eval_f64(x)), y);
        assert!(eg < 1e-5 && ec < 1e-5, "graph off by {eg:e}, chain {ec:e}");
    }
}

#[test]
fn ops_mix_fixture_agrees_with_onnxruntime() {
    check_fixture("ops_mix", 32, 4);
}

/// Beyond the CSV's points, the lowered chain equals the graph evaluation on inputs far
/// outside the fixture's range (every ReLU of the MaxPool trees and of the skip
/// carries active or not).
#[test]
fn lowered_chain_equals_graph_evaluation_on_wide_inputs() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(37);
    for stem in ["conv_residual", "ops_mix"] {
        let path = data(&format!("{stem}.onnx"));
        let graph = onnx::load_graph(&path).unwrap();
        let chain = onnx::load(&path).unwrap();
        for _ in 0..300 {
            let x: Vec<f64> = (0..graph.n_inputs())
                .map(|_| rng.gen_range(-20.0..20.0))
                .collect();
            let g = graph.eval_f64(&x).unwrap();
            let c = chain.eval_f64(&x);
            let e = g
                .iter()
                .zip(&c)
                .map(|(a, b)| (a - b).abs() / a.abs().max(1.0))
                .fold(0.0, f64::max);
            assert!(e < 1e-9, "{stem}: {g:?} vs {c:?}");
        }
    }
}

fn fixture_model() -> proto::ModelProto {
    let bytes = std::fs::read(data("conv_residual.onnx")).unwrap();
    proto::ModelProto::decode(bytes.as_slice()).unwrap()
}

fn node_mut<'a>(m: &'a mut proto::ModelProto, name: &str) -> &'a mut proto::NodeProto {
    m.graph
        .as_mut()
        .unwrap()
        .node
        .iter_mut()
        .find(|n| n.name == name)
        .unwrap()
}

fn load_err(m: &proto::ModelProto) -> (OnnxError, String) {
    let e = onnx::from_bytes(&m.encode_to_vec(), "fixture.onnx").unwrap_err();
    let msg = e.to_string();
    (e, msg)
}

fn assert_names(msg: &str, needles: &[&str]) {
    for n in needles {
        assert!(msg.contains(n), "`{n}` not in: {msg}");
    }
}

#[test]
fn unsupported_attribute_values_name_node_operator_and_attribute() {
    let mut m = fixture_model();
    let pad = node_mut(&mut m, "pad");
    pad.attribute
        .iter_mut()
        .find(|a| a.name == "mode")
        .unwrap()
        .s = b"reflect".to_vec();
    let (e, msg) = load_err(&m);
    assert!(matches!(e, OnnxError::Unsupported { .. }), "{msg}");
    assert_names(
        &msg,
        &["fixture.onnx", "`pad`", "`Pad`", "`mode`", "reflect"],
    );

    let mut m = fixture_model();
    node_mut(&mut m, "conv1")
        .attribute
        .push(proto::AttributeProto {
            name: "frobnicate".into(),
            i: 1,
            r#type: 2,
            ..Default::default()
        });
    let (_, msg) = load_err(&m);
    assert_names(&msg, &["`conv1`", "`Conv`", "`frobnicate`"]);

    let mut m = fixture_model();
    node_mut(&mut m, "bn1")
        .attribute
        .push(proto::AttributeProto {
            name: "training_mode".into(),
            i: 1,
            r#type: 2,
            ..Default::default()
        });
    let (_, msg) = load_err(&m);
    assert_names(&msg, &["`bn1`", "`BatchNormalization`", "`training_mode`"]);
}

/// Upsample's other modes, and downsampling scales, are refused naming the node.
#[test]
fn upsample_modes_and_scales_samara_does_not_take_are_refused_by_name() {
    let bytes = std::fs::read(data("upsample.onnx")).unwrap();
    let mut m = proto::ModelProto::decode(bytes.as_slice()).unwrap();
    node_mut(&mut m, "up_int")
        .attribute
        .iter_mut()
        .find(|a| a.name == "mode")
        .unwrap()
        .s = b"linear".to_vec();
    let (e, msg) = load_err(&m);
    assert!(matches!(e, OnnxError::Unsupported { .. }), "{msg}");
    assert_names(&msg, &["`up_int`", "`Upsample`", "`mode`", "linear"]);
    let mut m = proto::ModelProto::decode(bytes.as_slice()).unwrap();
    let s2 = m
        .graph
        .as_mut()
        .unwrap()
        .initializer
        .iter_mut()
        .find(|t| t.name == "s2")
        .unwrap();
    s2.raw_data = [1.0f32, 1.0, 0.5, 2.0]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    s2.float_data.clear();
    let msg = onnx::graph_from_bytes(&m.encode_to_vec(), "fixture.onnx")
        .unwrap_err()
        .to_string();
    assert_names(&msg, &["`up_frac`", "scale 0.5"]);
}

#[test]
fn unknown_and_unlowerable_operators_are_refused_by_name() {
    // An operator samara does not know.
    let mut m = fixture_model();
    node_mut(&mut m, "relu2").op_type = "Elu".into();
    let (e, msg) = load_err(&m);
    assert!(matches!(e, OnnxError::Unsupported { .. }), "{msg}");
    assert_names(&msg, &["`relu2`", "`Elu`", "supported: Gemm"]);

    // An operator the graph evaluates but the chain form cannot hold: the graph still
    // loads and evaluates, the lowering is refused naming the node.
    let mut m = fixture_model();
    node_mut(&mut m, "relu_branch").op_type = "Sin".into();
    let bytes = m.encode_to_vec();
    let g = onnx::graph_from_bytes(&bytes, "fixture.onnx").unwrap();
    assert_eq!(g.eval_f64(&[0.1; 72]).unwrap().len(), 3);
    let (_, msg) = load_err(&m);
    assert_names(&msg, &["`relu_branch`", "`Sin`", "cannot be lowered"]);
}

/// Operator evaluations on values small enough to check by hand.
#[test]
fn operators_match_hand_computed_values() {
    use samara_nn::ops::{conv, pool, shape, ConvAttrs, PoolAttrs};
    // 1x1x3x3 input 1..9, 2x2 kernel of ones, stride 1, no pad: window sums.
    let x = Tensor::new(vec![1, 1, 3, 3], (1..=9).map(f64::from).collect());
    let w = Tensor::new(vec![1, 1, 2, 2], vec![1.0; 4]);
    let a = ConvAttrs {
        strides: vec![],
        pads: vec![],
        dilations: vec![],
        group: 1,
        auto_pad: conv::AutoPad::NotSet,
        kernel_shape: None,
    };
    assert_eq!(
        conv::conv(&x, &w, None, &a).unwrap().data,
        vec![12.0, 16.0, 24.0, 28.0]
    );
    // Pad 1, stride 2: corners of the padded image.
    let a2 = ConvAttrs {
        strides: vec![2, 2],
        pads: vec![1, 1, 1, 1],
        ..a.clone()
    };
    assert_eq!(
        conv::conv(&x, &w, None, &a2).unwrap().data,
        vec![1.0, 5.0, 11.0, 28.0]
    );
    // MaxPool 2x2 stride 1 and AveragePool with count_include_pad.
    let p = PoolAttrs {
        kernel: vec![2, 2],
        strides: vec![],
        pads: vec![],
        dilations: vec![],
        ceil_mode: false,
        count_include_pad: false,
        auto_pad: conv::AutoPad::NotSet,
    };
    assert_eq!(
        pool::max_pool(&x, &p).unwrap().data,
        vec![5.0, 6.0, 8.0, 9.0]
    );
    let pp = PoolAttrs {
        pads: vec![1, 1, 0, 0],
        strides: vec![2, 2],
        count_include_pad: true,
        ..p.clone()
    };
    // Windows at (-1,-1): {1} / 4; (-1,1): {2,3} / 4; (1,-1): {4,7} / 4; (1,1): {5,6,8,9} / 4.
    assert_eq!(
        pool::average_pool(&x, &pp).unwrap().data,
        vec![0.25, 1.25, 2.75, 7.0]
    );
    // Slice with a negative step, Gather with a negative index.
    let v = Tensor::new(vec![5], (0..5).map(f64::from).collect());
    assert_eq!(
        shape::slice(&v, &[-1], &[-6], None, Some(&[-2]))
            .unwrap()
            .data,
        vec![4.0, 2.0, 0.0]
    );
    assert_eq!(
        shape::gather(&v, &[-1, 0], &[2], 0).unwrap().data,
        vec![4.0, 0.0]
    );
}

fn op(op_type: &str, inputs: &[&str], out: &str, axis: Option<i64>) -> proto::NodeProto {
    proto::NodeProto {
        input: inputs.iter().map(|s| s.to_string()).collect(),
        output: vec![out.into()],
        name: format!("{op_type}_{out}"),
        op_type: op_type.into(),
        attribute: axis
            .map(|a| {
                vec![proto::AttributeProto {
                    name: "axis".into(),
                    i: a,
                    r#type: 2,
                    ..Default::default()
                }]
            })
            .unwrap_or_default(),
        ..Default::default()
    }
}

/// A ReLU output concatenated with a negative constant is not non-negative: carried
/// through a later ReLU layer it must keep its negative entry (a wrong "non-negative"
/// mark would carry it by identity, and the ReLU would zero it).
#[test]
fn concat_with_a_negative_constant_is_carried_with_its_sign() {
    let m = proto::ModelProto {
        ir_version: 8,
        opset_import: vec![proto::OperatorSetIdProto {
            domain: String::new(),
            version: 13,
        }],
        graph: Some(proto::GraphProto {
            node: vec![
                op("Relu", &["x"], "r", None),
                op("Concat", &["r", "k"], "c", Some(0)),
                op("Neg", &["x"], "n", None),
                op("Relu", &["n"], "s", None),
                op("Concat", &["c", "s"], "y", Some(0)),
            ],
            initializer: vec![proto::TensorProto {
                dims: vec![1],
                data_type: proto::FLOAT,
                float_data: vec![-1.5],
                name: "k".into(),
                ..Default::default()
            }],
            input: vec![proto::ValueInfoProto::tensor("x", proto::FLOAT, &[2])],
            output: vec![proto::ValueInfoProto::tensor("y", proto::FLOAT, &[5])],
            ..Default::default()
        }),
        ..Default::default()
    };
    let bytes = m.encode_to_vec();
    let g = onnx::graph_from_bytes(&bytes, "neg.onnx").unwrap();
    let chain = onnx::from_bytes(&bytes, "neg.onnx").unwrap();
    for x in [[0.5f64, -2.0], [-1.0, 3.0], [0.0, 0.0]] {
        // Hand-computed: [relu(x0), relu(x1), -1.5, relu(-x0), relu(-x1)].
        let want = [
            x[0].max(0.0),
            x[1].max(0.0),
            -1.5,
            (-x[0]).max(0.0),
            (-x[1]).max(0.0),
        ];
        assert_eq!(g.eval_f64(&x).unwrap(), want);
        assert_eq!(chain.eval_f64(&x), want);
    }
}

/// An ordinary Clip lowers to `lo + relu(x - lo) - relu(x - hi)`; min above max is
/// refused by the chain importer as before (the graph evaluation reads it as the
/// constant max, onnxruntime's reading, and so does its lowering inside larger graphs).
#[test]
fn clip_lowering_matches_its_evaluation() {
    let scalar = |name: &str, v: f32| proto::TensorProto {
        dims: vec![],
        data_type: proto::FLOAT,
        float_data: vec![v],
        name: name.into(),
        ..Default::default()
    };
    for (lo, hi) in [(-0.5f32, 0.7f32), (1.0, -1.0)] {
        let m = proto::ModelProto {
            ir_version: 8,
            opset_import: vec![proto::OperatorSetIdProto {
                domain: String::new(),
                version: 13,
            }],
            graph: Some(proto::GraphProto {
                node: vec![op("Clip", &["x", "lo", "hi"], "y", None)],
                initializer: vec![scalar("lo", lo), scalar("hi", hi)],
                input: vec![proto::ValueInfoProto::tensor("x", proto::FLOAT, &[3])],
                output: vec![proto::ValueInfoProto::tensor("y", proto::FLOAT, &[3])],
                ..Default::default()
            }),
            ..Default::default()
        };
        let bytes = m.encode_to_vec();
        let x = [-2.0, 0.25, 3.0];
        let g = onnx::graph_from_bytes(&bytes, "clip.onnx").unwrap();
        if lo > hi {
            assert_eq!(g.eval_f64(&x).unwrap(), vec![hi as f64; 3]);
            let e = onnx::from_bytes(&bytes, "clip.onnx")
                .unwrap_err()
                .to_string();
            assert!(e.contains("min must be <= max"), "{e}");
        } else {
            let chain = onnx::from_bytes(&bytes, "clip.onnx").unwrap();
            let want = vec![lo as f64, 0.25, hi as f64];
            assert_eq!(chain.eval_f64(&x), want);
            assert_eq!(g.eval_f64(&x).unwrap(), want);
        }
    }
}

//! Importer coverage for the ARCH-COMP AINNCS controller formats: opset-6 binary
//! operators and Gemm with the legacy `broadcast`/`axis` attributes (MATLAB converter
//! 18.2), and dense layers written as a `Conv` whose kernel covers the whole input image
//! (MATLAB Deep Learning Toolbox converter 20.x). The models are built here from the
//! crate's protobuf messages; expected outputs are straight-line arithmetic on the
//! weights written here, never the loader.

use prost::Message;
use samara_nn::onnx::{self, proto, OnnxError};

// ------------------------------------------------------------------ model building

/// A tensor type with these dimensions (`None`: a symbolic dimension "N").
fn vi(name: &str, dims: &[Option<i64>]) -> proto::ValueInfoProto {
    proto::ValueInfoProto {
        name: name.into(),
        r#type: Some(proto::TypeProto {
            tensor_type: Some(proto::TypeProtoTensor {
                elem_type: proto::FLOAT,
                shape: Some(proto::TensorShapeProto {
                    dim: dims
                        .iter()
                        .map(|d| proto::Dimension {
                            dim_value: *d,
                            dim_param: d.is_none().then(|| "N".to_string()),
                        })
                        .collect(),
                }),
            }),
        }),
    }
}

fn fixed(dims: &[i64]) -> Vec<Option<i64>> {
    dims.iter().map(|&d| Some(d)).collect()
}

fn t(name: &str, dims: &[i64], v: &[f64]) -> proto::TensorProto {
    assert_eq!(dims.iter().product::<i64>() as usize, v.len(), "{name}");
    proto::TensorProto {
        dims: dims.to_vec(),
        data_type: proto::FLOAT,
        name: name.into(),
        float_data: v.iter().map(|&x| x as f32).collect(),
        ..Default::default()
    }
}

fn ti(name: &str, v: &[i64]) -> proto::TensorProto {
    proto::TensorProto {
        dims: vec![v.len() as i64],
        data_type: proto::INT64,
        name: name.into(),
        int64_data: v.to_vec(),
        ..Default::default()
    }
}

enum A {
    I(i64),
    F(f32),
    Ints(Vec<i64>),
}

fn node(op: &str, name: &str, inputs: &[&str], out: &str, attrs: &[(&str, A)]) -> proto::NodeProto {
    proto::NodeProto {
        input: inputs.iter().map(|s| s.to_string()).collect(),
        output: vec![out.into()],
        name: name.into(),
        op_type: op.into(),
        attribute: attrs
            .iter()
            .map(|(k, a)| {
                let mut p = proto::AttributeProto {
                    name: k.to_string(),
                    ..Default::default()
                };
                match a {
                    A::I(i) => {
                        p.i = *i;
                        p.r#type = 2;
                    }
                    A::F(f) => {
                        p.f = *f;
                        p.r#type = 1;
                    }
                    A::Ints(v) => {
                        p.ints = v.clone();
                        p.r#type = 7;
                    }
                }
                p
            })
            .collect(),
        ..Default::default()
    }
}

fn model(
    opset: i64,
    input: proto::ValueInfoProto,
    nodes: Vec<proto::NodeProto>,
    inits: Vec<proto::TensorProto>,
    out: &str,
) -> proto::ModelProto {
    proto::ModelProto {
        ir_version: 3,
        producer_name: "samara test".into(),
        graph: Some(proto::GraphProto {
            node: nodes,
            initializer: inits,
            input: vec![input],
            output: vec![vi(out, &[])],
            ..Default::default()
        }),
        opset_import: vec![proto::OperatorSetIdProto {
            domain: String::new(),
            version: opset,
        }],
        ..Default::default()
    }
}

fn load(m: &proto::ModelProto, file: &str) -> Result<samara_nn::Network, OnnxError> {
    onnx::from_bytes(&m.encode_to_vec(), file)
}

/// Deterministic values that are exact in float32 (multiples of 1/16 in [-2, 2)).
fn vals(seed: u64, n: usize) -> Vec<f64> {
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    (0..n)
        .map(|_| {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            ((s >> 11) % 64) as f64 / 16.0 - 2.0
        })
        .collect()
}

fn inputs(seed: u64, n: usize) -> Vec<Vec<f64>> {
    (0..20).map(|k| vals(seed * 100 + k, n)).collect()
}

fn close(a: &[f64], b: &[f64]) {
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(b) {
        assert!((x - y).abs() <= 1e-12 * y.abs().max(1.0), "{a:?} vs {b:?}");
    }
}

// ------------------------------------------------------------------ opset 6 broadcast

/// x: [1, 2, 3]. Legacy broadcasting: `Sub` of s[j] along axis 1, `Mul` by m[k] (suffix
/// match), `Add` of one value, `Div` by dv[j][k] (suffix [2, 3]), then `cc - v` with the
/// activation as second operand (same shape), Flatten, Gemm (transB, alpha, beta, C
/// broadcast), Relu, Gemm (C exactly [1, 2] without broadcast).
struct Legacy {
    s: Vec<f64>,
    m: Vec<f64>,
    a0: f64,
    dv: Vec<f64>,
    cc: Vec<f64>,
    w1: Vec<f64>,
    c1: Vec<f64>,
    w2: Vec<f64>,
    c2: Vec<f64>,
}

impl Legacy {
    fn new() -> Self {
        let mut dv = vals(4, 6);
        for v in &mut dv {
            if *v == 0.0 {
                *v = 0.5;
            }
        }
        Legacy {
            s: vals(1, 2),
            m: vals(2, 3),
            a0: 0.75,
            dv,
            cc: vals(5, 6),
            w1: vals(6, 24),
            c1: vals(7, 4),
            w2: vals(8, 8),
            c2: vals(9, 2),
        }
    }

    fn model(&self, opset: i64) -> proto::ModelProto {
        let bc = || ("broadcast", A::I(1));
        model(
            opset,
            vi("x", &fixed(&[1, 2, 3])),
            vec![
                node(
                    "Sub",
                    "sub_s",
                    &["x", "s"],
                    "v1",
                    &[bc(), ("axis", A::I(1))],
                ),
                node("Mul", "mul_m", &["v1", "m"], "v2", &[bc()]),
                node("Add", "add_a0", &["v2", "a0"], "v3", &[bc()]),
                node("Div", "div_dv", &["v3", "dv"], "v4", &[bc()]),
                node("Sub", "cc_minus", &["cc", "v4"], "v5", &[bc()]),
                node("Flatten", "flat", &["v5"], "f", &[("axis", A::I(1))]),
                node(
                    "Gemm",
                    "gemm1",
                    &["f", "w1", "c1"],
                    "g1",
                    &[
                        ("transB", A::I(1)),
                        ("alpha", A::F(0.5)),
                        ("beta", A::F(2.0)),
                        bc(),
                    ],
                ),
                node("Relu", "relu", &["g1"], "r", &[]),
                node(
                    "Gemm",
                    "gemm2",
                    &["r", "w2", "c2"],
                    "y",
                    &[("broadcast", A::I(0))],
                ),
            ],
            vec![
                t("s", &[2], &self.s),
                t("m", &[3], &self.m),
                t("a0", &[1], &[self.a0]),
                t("dv", &[2, 3], &self.dv),
                t("cc", &[1, 2, 3], &self.cc),
                t("w1", &[4, 6], &self.w1),
                t("c1", &[4], &self.c1),
                t("w2", &[4, 2], &self.w2),
                t("c2", &[1, 2], &self.c2),
            ],
            "y",
        )
    }

    fn expected(&self, x: &[f64]) -> Vec<f64> {
        let mut f = [0.0; 6];
        for j in 0..2 {
            for k in 0..3 {
                let v = ((x[3 * j + k] - self.s[j]) * self.m[k] + self.a0) / self.dv[3 * j + k];
                f[3 * j + k] = self.cc[3 * j + k] - v;
            }
        }
        let mut r = [0.0; 4];
        for (i, ri) in r.iter_mut().enumerate() {
            let mut acc = 0.0;
            for (l, fl) in f.iter().enumerate() {
                acc += self.w1[6 * i + l] * fl; // transB: B is [4, 6]
            }
            *ri = (0.5 * acc + 2.0 * self.c1[i]).max(0.0);
        }
        (0..2)
            .map(|o| (0..4).map(|i| r[i] * self.w2[2 * i + o]).sum::<f64>() + self.c2[o])
            .collect()
    }
}

#[test]
fn opset6_binary_ops_and_gemm_honour_broadcast_and_axis() {
    let l = Legacy::new();
    let net = load(&l.model(6), "legacy.onnx").unwrap();
    assert_eq!((net.n_inputs(), net.n_outputs()), (6, 2));
    // The elementwise block is the input normalisation; then 6->4, Relu, 4->2.
    assert!(net.input_norm.is_some());
    assert_eq!(net.layers.len(), 3);
    for x in inputs(1, 6) {
        close(&net.eval_f64(&x), &l.expected(&x));
    }
}

#[test]
fn legacy_broadcast_refusals_are_clear() {
    let l = Legacy::new();
    let with = |f: &dyn Fn(&mut proto::GraphProto)| {
        let mut m = l.model(6);
        f(m.graph.as_mut().unwrap());
        load(&m, "legacy.onnx").unwrap_err().to_string()
    };
    // s of shape [2] matched from axis 2 (A's dimension there is 3).
    let e = with(&|g| g.node[0].attribute[1].i = 2);
    assert!(
        e.contains("legacy.onnx") && e.contains("sub_s") && e.contains("axis"),
        "{e}"
    );
    // Without broadcast = 1 the shapes must agree.
    let e = with(&|g| g.node[1].attribute.clear());
    assert!(e.contains("mul_m") && e.contains("broadcast = 1"), "{e}");
    // [1, 3] against A's trailing [2, 3]: numpy would expand the 1, legacy does not.
    let e = with(&|g| g.initializer[1].dims = vec![1, 3]);
    assert!(e.contains("mul_m") && e.contains("size-1"), "{e}");
    // The activation as B broadcast into a larger constant A.
    let e = with(&|g| {
        g.initializer[4].dims = vec![2, 1, 2, 3];
        g.initializer[4].float_data = [vals(5, 6), vals(5, 6)]
            .concat()
            .iter()
            .map(|&v| v as f32)
            .collect();
    });
    assert!(e.contains("cc_minus") && e.contains("larger"), "{e}");
    // Gemm C not [1, 2] without broadcast.
    let e = with(&|g| g.initializer[8].dims = vec![2]);
    assert!(e.contains("gemm2") && e.contains("[1, 2]"), "{e}");
}

#[test]
fn opset7_numpy_broadcasting_expands_size_one_dimensions() {
    // The same [1, 3] constant that legacy broadcasting refuses broadcasts at opset 13.
    let m = model(
        13,
        vi("x", &fixed(&[1, 2, 3])),
        vec![node("Mul", "mul", &["x", "m"], "y", &[])],
        vec![t("m", &[1, 3], &[1.0, 2.0, 3.0])],
        "y",
    );
    let net = load(&m, "np.onnx").unwrap();
    let x = [1.0, 1.0, 1.0, 2.0, 2.0, 2.0];
    close(&net.eval_f64(&x), &[1.0, 2.0, 3.0, 2.0, 4.0, 6.0]);
    // A constant that would enlarge the activation is refused.
    let m = model(
        13,
        vi("x", &fixed(&[1, 3])),
        vec![node("Add", "add", &["x", "c"], "y", &[])],
        vec![t("c", &[2, 1], &[1.0, 2.0])],
        "y",
    );
    let e = load(&m, "np.onnx").unwrap_err().to_string();
    assert!(e.contains("add") && e.contains("larger"), "{e}");
}

#[test]
fn opset1_reshape_takes_its_shape_attribute() {
    let m = model(
        1,
        vi("x", &fixed(&[1, 1, 1, 2])),
        vec![
            node(
                "Reshape",
                "rs",
                &["x"],
                "r",
                &[("shape", A::Ints(vec![1, -1]))],
            ),
            node(
                "Gemm",
                "g",
                &["r", "w", "c"],
                "y",
                &[("broadcast", A::I(1))],
            ),
        ],
        vec![t("w", &[2, 1], &[2.0, -3.0]), t("c", &[1], &[0.5])],
        "y",
    );
    let net = load(&m, "old.onnx").unwrap();
    close(&net.eval_f64(&[1.0, 1.0]), &[2.0 - 3.0 + 0.5]);
}

// ------------------------------------------------------------------ dense as Conv

/// The MATLAB 20.x pattern: input [N, 1, 1, 4] minus its mean image, Conv [5, 1, 1, 4]
/// over the 1x4 image, Relu, Conv [3, 5, 1, 1], Tanh, Conv [2, 3, 1, 1] without bias,
/// Flatten.
struct Matlab {
    mean: Vec<f64>,
    w1: Vec<f64>,
    b1: Vec<f64>,
    w2: Vec<f64>,
    b2: Vec<f64>,
    w3: Vec<f64>,
}

fn conv_attrs(k: &[i64]) -> Vec<(&'static str, A)> {
    vec![
        ("group", A::I(1)),
        ("dilations", A::Ints(vec![1, 1])),
        ("kernel_shape", A::Ints(k.to_vec())),
        ("pads", A::Ints(vec![0, 0, 0, 0])),
        ("strides", A::Ints(vec![1, 1])),
    ]
}

impl Matlab {
    fn new() -> Self {
        Matlab {
            mean: vals(11, 4),
            w1: vals(12, 20),
            b1: vals(13, 5),
            w2: vals(14, 15),
            b2: vals(15, 3),
            w3: vals(16, 6),
        }
    }

    fn model(&self) -> proto::ModelProto {
        model(
            8,
            vi("input", &[None, Some(1), Some(1), Some(4)]),
            vec![
                node("Sub", "input_Sub", &["input", "mean"], "s", &[]),
                node(
                    "Conv",
                    "Operation_1",
                    &["s", "w1", "b1"],
                    "c1",
                    &conv_attrs(&[1, 4]),
                ),
                node("Relu", "relu_1", &["c1"], "r1", &[]),
                node(
                    "Conv",
                    "Operation_2",
                    &["r1", "w2", "b2"],
                    "c2",
                    &conv_attrs(&[1, 1]),
                ),
                node("Tanh", "tanh_2", &["c2"], "r2", &[]),
                node(
                    "Conv",
                    "linear_3",
                    &["r2", "w3"],
                    "c3",
                    &conv_attrs(&[1, 1]),
                ),
                node(
                    "Flatten",
                    "linear_3_Flatten",
                    &["c3"],
                    "y",
                    &[("axis", A::I(1))],
                ),
            ],
            vec![
                t("mean", &[1, 1, 1, 4], &self.mean),
                t("w1", &[5, 1, 1, 4], &self.w1),
                t("b1", &[5], &self.b1),
                t("w2", &[3, 5, 1, 1], &self.w2),
                t("b2", &[3], &self.b2),
                t("w3", &[2, 3, 1, 1], &self.w3),
            ],
            "y",
        )
    }

    fn expected(&self, x: &[f64]) -> Vec<f64> {
        let s: Vec<f64> = (0..4).map(|k| x[k] - self.mean[k]).collect();
        let r1: Vec<f64> = (0..5)
            .map(|m| ((0..4).map(|k| self.w1[4 * m + k] * s[k]).sum::<f64>() + self.b1[m]).max(0.0))
            .collect();
        let r2: Vec<f64> = (0..3)
            .map(|m| ((0..5).map(|c| self.w2[5 * m + c] * r1[c]).sum::<f64>() + self.b2[m]).tanh())
            .collect();
        (0..2)
            .map(|m| (0..3).map(|c| self.w3[3 * m + c] * r2[c]).sum::<f64>())
            .collect()
    }
}

#[test]
fn matlab_dense_as_conv_chain_is_affine() {
    let mm = Matlab::new();
    let net = load(&mm.model(), "matlab.onnx").unwrap();
    assert_eq!((net.n_inputs(), net.n_outputs()), (4, 2));
    assert!(
        net.input_norm.is_some(),
        "the mean image is the input normalisation"
    );
    let shapes: Vec<String> = net
        .layers
        .iter()
        .map(|l| match l {
            samara_nn::Layer::Affine(a) => format!("{}x{}", a.out, a.inp),
            samara_nn::Layer::Act(a) => format!("{a:?}"),
        })
        .collect();
    assert_eq!(shapes, ["5x4", "Relu", "3x5", "Tanh", "2x3"]);
    for x in inputs(2, 4) {
        close(&net.eval_f64(&x), &mm.expected(&x));
    }
}

/// A multi-channel image [1, 2, 2, 2], transposed (H and W swapped), a Conv with a full
/// [3, 2, 2, 2] kernel, then Reshape / Squeeze / Unsqueeze plumbing and a MatMul.
#[test]
fn full_kernel_conv_over_channels_and_transposed_image() {
    let w = vals(21, 24);
    let b = vals(22, 3);
    let p = vals(23, 6);
    let m = model(
        8,
        vi("x", &fixed(&[1, 2, 2, 2])),
        vec![
            node(
                "Transpose",
                "tr",
                &["x"],
                "xt",
                &[("perm", A::Ints(vec![0, 1, 3, 2]))],
            ),
            node("Conv", "conv", &["xt", "w", "b"], "c", &[]),
            node("Reshape", "rs", &["c", "shape"], "r", &[]),
            node("Squeeze", "sq", &["r"], "q", &[("axes", A::Ints(vec![0]))]),
            node(
                "Unsqueeze",
                "usq",
                &["q"],
                "u",
                &[("axes", A::Ints(vec![0]))],
            ),
            node("MatMul", "mm", &["u", "p"], "y", &[]),
        ],
        vec![
            t("w", &[3, 2, 2, 2], &w),
            t("b", &[3], &b),
            ti("shape", &[1, -1]),
            t("p", &[3, 2], &p),
        ],
        "y",
    );
    let net = load(&m, "chan.onnx").unwrap();
    for x in inputs(3, 8) {
        // x[c][h][w] at 4c + 2h + w; the transposed image xt[c][h][w] = x[c][w][h].
        let conv: Vec<f64> = (0..3)
            .map(|o| {
                let mut acc = b[o];
                for c in 0..2 {
                    for h in 0..2 {
                        for ww in 0..2 {
                            acc += w[8 * o + 4 * c + 2 * h + ww] * x[4 * c + 2 * ww + h];
                        }
                    }
                }
                acc
            })
            .collect();
        let want: Vec<f64> = (0..2)
            .map(|j| (0..3).map(|o| conv[o] * p[2 * o + j]).sum())
            .collect();
        close(&net.eval_f64(&x), &want);
    }
}

/// A Conv that is not a dense layer (padding, strides, dilations, a sliding kernel) is
/// no longer refused (issue 37): it loads through the graph import and its lowering to
/// the chain form, and evaluates like the graph evaluation. A Conv that is not a
/// convolution of its input (group 2 over one channel, kernel_shape disagreeing with W)
/// is still refused by name.
#[test]
fn conv_that_is_not_a_dense_layer_loads_through_the_graph_path() {
    let mm = Matlab::new();
    let with = |f: &dyn Fn(&mut proto::NodeProto)| {
        let mut m = mm.model();
        f(&mut m.graph.as_mut().unwrap().node[1]);
        m
    };
    let same = |m: &proto::ModelProto| {
        let bytes = m.encode_to_vec();
        let net = onnx::from_bytes(&bytes, "conv.onnx").unwrap();
        let g = onnx::graph_from_bytes(&bytes, "conv.onnx").unwrap();
        for k in 0..5 {
            let x: Vec<f64> = vals(40 + k, net.n_inputs());
            let (a, b) = (net.eval_f64(&x), g.eval_f64(&x).unwrap());
            for (p, q) in a.iter().zip(&b) {
                assert!((p - q).abs() <= 1e-12 * q.abs().max(1.0), "{a:?} vs {b:?}");
            }
        }
    };
    same(&with(&|n| n.attribute[3].ints = vec![0, 1, 0, 1]));
    same(&with(&|n| n.attribute[4].ints = vec![1, 2]));
    let check = |e: OnnxError, needles: &[&str]| {
        let msg = e.to_string();
        assert!(
            matches!(
                e,
                OnnxError::Unsupported { .. } | OnnxError::Structure { .. }
            ),
            "{msg}"
        );
        for n in ["conv.onnx", "Operation_1", "Conv"].iter().chain(needles) {
            assert!(msg.contains(n), "`{n}` not in: {msg}");
        }
    };
    let err = |m: proto::ModelProto| load(&m, "conv.onnx").unwrap_err();
    // The graph importer reads grouped convolutions; its message says why this one
    // does not fit (the kernel's channels against the group).
    check(
        err(with(&|n| n.attribute[0].i = 2)),
        &["group 2", "input channels"],
    );
    check(
        err(with(&|n| n.attribute[2].ints = vec![1, 2])),
        &["kernel_shape"],
    );

    // A smaller kernel (1x2 over the 1x4 image) is a sliding window.
    let mut m = mm.model();
    let g = m.graph.as_mut().unwrap();
    g.node[1].attribute[2].ints = vec![1, 2];
    g.initializer[1] = t("w1", &[5, 1, 1, 2], &vals(12, 10));
    same(&m);
}

/// Every single-field mutation of the test models loads or fails with an error naming
/// the file; none panics.
#[test]
fn mutated_legacy_and_conv_models_never_panic() {
    let models = [Legacy::new().model(6), Matlab::new().model()];
    let mut cases = 0;
    let mut try_load = |m: &proto::ModelProto| {
        cases += 1;
        match onnx::from_bytes(&m.encode_to_vec(), "mut.onnx") {
            Ok(net) => {
                let y = net.eval_f64(&vec![0.25; net.n_inputs()]);
                assert_eq!(y.len(), net.n_outputs());
            }
            Err(e) => assert!(e.to_string().starts_with("mut.onnx"), "{e}"),
        }
    };
    let odd = [0i64, 1, 2, 3, 4, 5, -1, -2, 7, 1 << 40];
    for base in &models {
        let g = base.graph.as_ref().unwrap();
        for ni in 0..g.node.len() {
            for ai in 0..g.node[ni].attribute.len() {
                for &v in &odd {
                    let mut m = base.clone();
                    let a = &mut m.graph.as_mut().unwrap().node[ni].attribute[ai];
                    a.i = v;
                    try_load(&m);
                    let ints = |f: &dyn Fn(&mut Vec<i64>)| {
                        let mut m = base.clone();
                        f(&mut m.graph.as_mut().unwrap().node[ni].attribute[ai].ints);
                        m
                    };
                    if !g.node[ni].attribute[ai].ints.is_empty() {
                        try_load(&ints(&|a| a[0] = v));
                        try_load(&ints(&|a| {
                            a.pop();
                        }));
                        try_load(&ints(&|a| a.push(v)));
                    }
                }
                let mut m = base.clone();
                m.graph.as_mut().unwrap().node[ni].attribute.remove(ai);
                try_load(&m);
            }
            for ii in 0..g.node[ni].input.len() {
                let mut m = base.clone();
                m.graph.as_mut().unwrap().node[ni].input.remove(ii);
                try_load(&m);
            }
            let mut m = base.clone();
            m.graph.as_mut().unwrap().node.remove(ni);
            try_load(&m);
        }
        for ti in 0..g.initializer.len() {
            for k in 0..=g.initializer[ti].dims.len() {
                for &v in &odd {
                    let mut m = base.clone();
                    let d = &mut m.graph.as_mut().unwrap().initializer[ti].dims;
                    if k < d.len() {
                        d[k] = v;
                    } else {
                        d.push(v);
                    }
                    try_load(&m);
                }
            }
        }
        for &v in &odd {
            let mut m = base.clone();
            m.opset_import[0].version = v;
            try_load(&m);
            let mut m = base.clone();
            let dims = &mut m.graph.as_mut().unwrap().input[0]
                .r#type
                .as_mut()
                .unwrap()
                .tensor_type
                .as_mut()
                .unwrap()
                .shape
                .as_mut()
                .unwrap()
                .dim;
            dims[0].dim_value = Some(v);
            try_load(&m);
        }
    }
    assert!(cases > 500, "{cases}");
}

/// The first dimension of a rank-2 (or more) input is the batch dimension: a fixed batch
/// of 2 rows imports as the per-row function; a constant that depends on the batch
/// (one value per row) does not broadcast to one sample and is refused.
#[test]
fn fixed_batch_dimension_is_evaluated_per_sample() {
    let gemm = node("Gemm", "g", &["x", "w", "c"], "y", &[]);
    let w = t("w", &[3, 1], &[1.0, 2.0, 4.0]);
    let m = model(
        13,
        vi("x", &fixed(&[2, 3])),
        vec![gemm.clone()],
        vec![w.clone(), t("c", &[1], &[0.5])],
        "y",
    );
    let net = load(&m, "batch.onnx").unwrap();
    assert_eq!((net.n_inputs(), net.n_outputs()), (3, 1));
    close(&net.eval_f64(&[1.0, 1.0, 1.0]), &[7.5]);
    let m = model(
        13,
        vi("x", &fixed(&[2, 3])),
        vec![
            node("Add", "per_row", &["x", "r"], "a", &[]),
            node("Gemm", "g", &["a", "w", "c"], "y", &[]),
        ],
        vec![t("r", &[2, 1], &[1.0, 2.0]), w, t("c", &[1], &[0.5])],
        "y",
    );
    let e = load(&m, "batch.onnx").unwrap_err().to_string();
    assert!(e.contains("per_row") && e.contains("larger"), "{e}");
}

//! Export then import gives the same network (float64 export: bit-identical; float32:
//! within float32 rounding), and bad files are errors, never panics.

use proptest::prelude::*;
use prost::Message;
use rand::{Rng, SeedableRng};
use samara_nn::onnx::{self, proto, ExportOptions, OnnxError};
use samara_nn::{Activation, Affine, Layer, Network};

fn random_net(seed: u64, with_norm: bool) -> Network {
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    let dims = [6, 8, 5, 1];
    let mut layers = Vec::new();
    for w in dims.windows(2) {
        let (i, o) = (w[0], w[1]);
        layers.push(Layer::Affine(Affine::new(
            i,
            o,
            (0..i * o).map(|_| r.gen_range(-1.0..1.0)).collect(),
            (0..o).map(|_| r.gen_range(-0.5..0.5)).collect(),
        )));
        layers.push(Layer::Act(match seed % 3 {
            0 => Activation::Relu,
            1 => Activation::Tanh,
            _ => Activation::Sigmoid,
        }));
    }
    layers.push(Layer::Act(Activation::Clamp { lo: 0.0, hi: 0.9 }));
    Network {
        input_names: (0..6).map(|i| format!("x{i}")).collect(),
        output_names: vec!["y".into()],
        input_norm: with_norm.then(|| {
            Affine::normalise(
                &[1.0, -0.5, -0.3, -1.0, 0.0, -40.0],
                &[2.5, 0.6, 0.4, 0.9, 41.0, 46.0],
            )
        }),
        layers,
        output_denorm: with_norm.then(|| Affine::denormalise(&[0.181], &[0.012])),
    }
}

#[test]
fn float64_round_trip_is_exact() {
    for seed in 0..6 {
        let net = random_net(seed, seed % 2 == 0);
        let o = ExportOptions {
            float64: true,
            ..Default::default()
        };
        let bytes = onnx::export(&net, &o).encode_to_vec();
        let back = onnx::from_bytes(&bytes, "mem").unwrap();
        assert_eq!(back.layers, net.layers);
        assert_eq!(back.input_norm, net.input_norm);
        assert_eq!(back.output_denorm, net.output_denorm);
    }
}

#[test]
fn float32_round_trip_agrees_to_float32_precision() {
    let net = random_net(7, true);
    let bytes = onnx::export(&net, &ExportOptions::default()).encode_to_vec();
    let back = onnx::from_bytes(&bytes, "mem").unwrap();
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    for _ in 0..200 {
        let x: Vec<f64> = (0..6).map(|_| r.gen_range(-40.0..40.0)).collect();
        let (a, b) = (net.eval_f64(&x)[0], back.eval_f64(&x)[0]);
        assert!((a - b).abs() < 1e-6, "{a} vs {b}");
    }
}

#[test]
fn export_without_normalisation_is_the_body() {
    let net = random_net(3, true);
    let o = ExportOptions {
        with_normalisation: false,
        float64: true,
        ..Default::default()
    };
    let back = onnx::from_bytes(&onnx::export(&net, &o).encode_to_vec(), "mem").unwrap();
    assert!(back.input_norm.is_none() && back.output_denorm.is_none());
    let x = [0.2, 0.4, 0.6, 0.1, 0.9, 0.5];
    assert_eq!(back.eval_f64(&x), net.eval_normalised(&x));
}

fn model_with(nodes: Vec<proto::NodeProto>, inits: Vec<proto::TensorProto>, out: &str) -> Vec<u8> {
    let vi = |n: &str, d: i64| proto::ValueInfoProto {
        name: n.into(),
        r#type: Some(proto::TypeProto {
            tensor_type: Some(proto::TypeProtoTensor {
                elem_type: 1,
                shape: Some(proto::TensorShapeProto {
                    dim: vec![proto::Dimension {
                        dim_value: Some(d),
                        dim_param: None,
                    }],
                }),
            }),
        }),
    };
    proto::ModelProto {
        ir_version: 7,
        graph: Some(proto::GraphProto {
            node: nodes,
            initializer: inits,
            input: vec![vi("x", 3)],
            output: vec![vi(out, 3)],
            ..Default::default()
        }),
        opset_import: vec![proto::OperatorSetIdProto {
            domain: String::new(),
            version: 13,
        }],
        ..Default::default()
    }
    .encode_to_vec()
}

fn n(op: &str, name: &str, inputs: &[&str], out: &str) -> proto::NodeProto {
    proto::NodeProto {
        input: inputs.iter().map(|s| s.to_string()).collect(),
        output: vec![out.into()],
        name: name.into(),
        op_type: op.into(),
        ..Default::default()
    }
}

#[test]
fn unsupported_operator_names_op_node_file_and_list() {
    let bytes = model_with(vec![n("Softmax", "sm0", &["x"], "y")], vec![], "y");
    let e = onnx::from_bytes(&bytes, "model.onnx").unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, OnnxError::Unsupported { .. }));
    for needle in ["model.onnx", "sm0", "Softmax", "supported: Gemm"] {
        assert!(msg.contains(needle), "{msg}");
    }
}

#[test]
fn nan_weights_and_shape_mismatch_are_errors() {
    let t = |name: &str, dims: Vec<i64>, v: Vec<f32>| proto::TensorProto {
        dims,
        data_type: 1,
        name: name.into(),
        float_data: v,
        ..Default::default()
    };
    let bytes = model_with(
        vec![n("Add", "add0", &["x", "c"], "y")],
        vec![t("c", vec![3], vec![1.0, f32::NAN, 0.0])],
        "y",
    );
    let msg = onnx::from_bytes(&bytes, "nan.onnx")
        .unwrap_err()
        .to_string();
    assert!(msg.contains("NaN") && msg.contains("`c`"), "{msg}");
    let bytes = model_with(
        vec![n("MatMul", "mm", &["x", "w"], "y")],
        vec![t("w", vec![4, 3], vec![0.0; 12])],
        "y",
    );
    let msg = onnx::from_bytes(&bytes, "shape.onnx")
        .unwrap_err()
        .to_string();
    assert!(msg.contains("mm") && msg.contains("[4, 3]"), "{msg}");
}

#[test]
fn truncated_and_foreign_files_are_decode_errors() {
    let good = onnx::export(&random_net(1, true), &ExportOptions::default()).encode_to_vec();
    for cut in [1, good.len() / 3, good.len() - 1] {
        assert!(onnx::from_bytes(&good[..cut], "t.onnx").is_err());
    }
    assert!(matches!(
        onnx::from_bytes(b"not an onnx file at all", "x.onnx"),
        Err(OnnxError::Decode { .. })
    ));
    let missing = onnx::load("/nonexistent/net.onnx").unwrap_err().to_string();
    assert!(missing.contains("/nonexistent/net.onnx"));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(400))]
    #[test]
    fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        let _ = onnx::from_bytes(&bytes, "fuzz.onnx");
    }

    #[test]
    fn mutated_models_never_panic(pos in 0usize..10_000, val in any::<u8>()) {
        let mut good = onnx::export(&random_net(2, true), &ExportOptions::default()).encode_to_vec();
        let p = pos % good.len();
        good[p] = val;
        let _ = onnx::from_bytes(&good, "mutated.onnx");
    }
}

/// Needs bench/.venv (bench/setup_venv.sh): `cargo test -p samara-nn -- --ignored`.
#[test]
#[ignore = "needs onnxruntime in bench/.venv (bench/setup_venv.sh); run with --ignored"]
fn exported_network_agrees_with_onnxruntime() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let py = root.join("bench/.venv/bin/python");
    assert!(py.exists(), "run bench/setup_venv.sh first");
    let dir = std::env::temp_dir().join(format!("samara-export-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for (seed, f64w) in [(0u64, false), (1, false), (2, true)] {
        let net = random_net(seed, true);
        let model = dir.join(format!("net{seed}.onnx"));
        onnx::save(
            &net,
            &model,
            &ExportOptions {
                float64: f64w,
                ..Default::default()
            },
        )
        .unwrap();
        let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(seed + 10);
        let mut csv = String::new();
        for _ in 0..300 {
            // float32-representable inputs so both sides read the same numbers.
            let x: Vec<f64> = (0..6).map(|_| r.gen_range(-40.0f32..40.0) as f64).collect();
            let y = net.eval_f64(&x);
            let row: Vec<String> = x.iter().chain(&y).map(|v| format!("{v:?}")).collect();
            csv.push_str(&row.join(","));
            csv.push('\n');
        }
        let data = dir.join(format!("net{seed}.csv"));
        std::fs::write(&data, csv).unwrap();
        let out = std::process::Command::new(&py)
            .arg(root.join("bench/nn/check_export.py"))
            .arg(&model)
            .arg(&data)
            .output()
            .unwrap();
        eprintln!("{}", String::from_utf8_lossy(&out.stdout));
        assert!(
            out.status.success(),
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

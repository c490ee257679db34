//! Sparse storage of lowered convolutions (issue 37): the lowering stores a map with
//! few non-zeros (a convolution's, a pooling's, a transposed convolution's) by
//! compressed rows. On random Conv / MaxPool / AveragePool / ConvTranspose graphs the
//! lowered chain evaluates as the graph evaluation (the operators computed directly,
//! an independent code path) and the same network with its maps stored dense and
//! stored sparse gives the same values; the memory budget charges the non-zeros; a
//! sparse network exports dense and imports back to the same values.

use prost::Message;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use samara_nn::onnx::{self, proto, ExportOptions};
use samara_nn::{Affine, Layer, Network};

fn tensor(name: &str, dims: &[i64], rng: &mut ChaCha8Rng) -> proto::TensorProto {
    let n = dims.iter().product::<i64>() as usize;
    proto::TensorProto::float(
        name,
        dims,
        (0..n).map(|_| rng.gen_range(-0.6f32..0.6)).collect(),
    )
}

/// A random graph on a `c x 16 x 16` image: Conv (3x3, stride 1 or 2, padded) + Relu, a
/// 2x2 MaxPool or AveragePool, a ConvTranspose (2x2, stride 2) + Relu, then a Gemm to
/// 5 outputs. Returns the ONNX bytes.
fn random_graph(rng: &mut ChaCha8Rng) -> Vec<u8> {
    let c = rng.gen_range(1..=2i64);
    let (c1, c2) = (rng.gen_range(2..=4i64), rng.gen_range(1..=3i64));
    let s1 = rng.gen_range(1..=2i64);
    let h1 = (16 + 2 - 3) / s1 + 1;
    let h2 = h1 / 2;
    let h3 = h2 * 2;
    let pool = if rng.gen_bool(0.5) {
        "MaxPool"
    } else {
        "AveragePool"
    };
    let flat = c2 * h3 * h3;
    let nodes = vec![
        proto::NodeProto::op(
            "Conv",
            &["x", "w1", "b1"],
            "y1",
            vec![
                proto::AttributeProto::ints("kernel_shape", &[3, 3]),
                proto::AttributeProto::ints("strides", &[s1, s1]),
                proto::AttributeProto::ints("pads", &[1, 1, 1, 1]),
            ],
        ),
        proto::NodeProto::op("Relu", &["y1"], "a1", vec![]),
        proto::NodeProto::op(
            pool,
            &["a1"],
            "p1",
            vec![
                proto::AttributeProto::ints("kernel_shape", &[2, 2]),
                proto::AttributeProto::ints("strides", &[2, 2]),
            ],
        ),
        proto::NodeProto::op(
            "ConvTranspose",
            &["p1", "w2", "b2"],
            "y2",
            vec![
                proto::AttributeProto::ints("kernel_shape", &[2, 2]),
                proto::AttributeProto::ints("strides", &[2, 2]),
            ],
        ),
        proto::NodeProto::op("Relu", &["y2"], "a2", vec![]),
        proto::NodeProto::op("Flatten", &["a2"], "f", vec![]),
        proto::NodeProto::op(
            "Gemm",
            &["f", "w3", "b3"],
            "y",
            vec![proto::AttributeProto {
                name: "transB".into(),
                i: 1,
                r#type: 2,
                ..Default::default()
            }],
        ),
    ];
    let init = vec![
        tensor("w1", &[c1, c, 3, 3], rng),
        tensor("b1", &[c1], rng),
        tensor("w2", &[c1, c2, 2, 2], rng),
        tensor("b2", &[c2], rng),
        tensor("w3", &[5, flat], rng),
        tensor("b3", &[5], rng),
    ];
    proto::ModelProto {
        ir_version: 8,
        opset_import: vec![proto::OperatorSetIdProto {
            domain: String::new(),
            version: 13,
        }],
        graph: Some(proto::GraphProto {
            node: nodes,
            initializer: init,
            input: vec![proto::ValueInfoProto::tensor(
                "x",
                proto::FLOAT,
                &[1, c, 16, 16],
            )],
            output: vec![proto::ValueInfoProto::tensor("y", proto::FLOAT, &[1, 5])],
            ..Default::default()
        }),
        ..Default::default()
    }
    .encode_to_vec()
}

/// The network with every affine layer in the storage `f` gives.
fn restored(net: &Network, f: impl Fn(&Affine) -> Affine) -> Network {
    let mut n = net.clone();
    for l in n.layers.iter_mut() {
        if let Layer::Affine(a) = l {
            *a = f(a);
        }
    }
    n
}

fn sparse_layers(net: &Network) -> usize {
    net.layers
        .iter()
        .filter(|l| matches!(l, Layer::Affine(a) if a.is_sparse()))
        .count()
}

#[test]
fn lowered_random_conv_graphs_evaluate_the_same_dense_and_sparse() {
    let mut rng = ChaCha8Rng::seed_from_u64(46);
    for trial in 0..12 {
        let bytes = random_graph(&mut rng);
        let graph = onnx::graph_from_bytes(&bytes, "g.onnx").unwrap();
        let chain = onnx::from_bytes(&bytes, "g.onnx").unwrap();
        assert!(sparse_layers(&chain) > 0, "trial {trial}: no sparse layer");
        let dense = restored(&chain, Affine::densified);
        let sparse = restored(&chain, Affine::sparsified);
        assert_eq!(sparse_layers(&dense), 0);
        assert_eq!(dense, chain, "equality compares the maps, not the storage");
        for _ in 0..40 {
            let x: Vec<f64> = (0..chain.n_inputs())
                .map(|_| rng.gen_range(-3.0..3.0))
                .collect();
            let (yc, yd, ys) = (chain.eval_f64(&x), dense.eval_f64(&x), sparse.eval_f64(&x));
            assert_eq!(yc, yd, "trial {trial}");
            assert_eq!(yc, ys, "trial {trial}");
            // The generic evaluator (the interval and Taylor-model readers' path).
            assert_eq!(
                sparse.eval::<f64>(&x),
                dense.eval::<f64>(&x),
                "trial {trial}"
            );
            // The graph evaluation: the operators themselves.
            let g = graph.eval_f64(&x).unwrap();
            for (a, b) in g.iter().zip(&yc) {
                assert!(
                    (a - b).abs() <= 1e-9 * a.abs().max(1.0),
                    "trial {trial}: {g:?} {yc:?}"
                );
            }
        }
        // Export writes the sparse maps dense; the file imports back to the same values.
        let o = ExportOptions {
            float64: true,
            ..Default::default()
        };
        let back = onnx::from_bytes(&onnx::export(&sparse, &o).encode_to_vec(), "b.onnx").unwrap();
        let x: Vec<f64> = (0..chain.n_inputs())
            .map(|_| rng.gen_range(-3.0..3.0))
            .collect();
        let (yb, ys) = (back.eval_f64(&x), sparse.eval_f64(&x));
        for (a, b) in yb.iter().zip(&ys) {
            assert!(
                (a - b).abs() <= 1e-12 * a.abs().max(1.0),
                "trial {trial}: {yb:?} {ys:?}"
            );
        }
    }
}

/// The budget charges a sparse layer's non-zeros: a graph whose lowering would take
/// more than the budget dense loads within it, and a budget below its sparse size
/// is still refused with the variable named.
#[test]
fn the_budget_charges_the_non_zeros_of_sparse_layers() {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let bytes = random_graph(&mut rng);
    let chain = onnx::from_bytes(&bytes, "g.onnx").unwrap();
    let dense_bytes: usize = chain
        .layers
        .iter()
        .map(|l| match l {
            Layer::Affine(a) => a.out * a.inp * 8,
            Layer::Act(_) => 0,
        })
        .sum();
    let stored_bytes: usize = chain
        .layers
        .iter()
        .map(|l| match l {
            Layer::Affine(a) => a.stored() * 12,
            Layer::Act(_) => 0,
        })
        .sum();
    assert!(
        stored_bytes * 4 < dense_bytes,
        "{stored_bytes} {dense_bytes}"
    );
    // Constants (float32 -> f64), the lowering's live maps and the layers: well under
    // the dense size.
    assert!(onnx::from_bytes_within(&bytes, "g.onnx", (dense_bytes / 2) as u64).is_ok());
    let e = onnx::from_bytes_within(&bytes, "g.onnx", (stored_bytes / 4) as u64)
        .unwrap_err()
        .to_string();
    assert!(e.contains(samara_nn::limits::IMPORT_MEMORY_ENV), "{e}");
}

/// A sparse map built from rows: duplicates add up, zero sums are dropped, a column
/// past the inputs is a shape error for `validate`, and `weight`, `row` and
/// `to_dense` read the same matrix.
#[test]
fn sparse_rows_read_as_their_dense_matrix() {
    let a = Affine::from_rows(
        4,
        vec![
            vec![(2, 1.5), (0, -1.0), (2, 0.5)],
            vec![],
            vec![(3, 2.0), (3, -2.0), (1, 0.25)],
        ],
        vec![0.1, 0.2, 0.3],
    );
    assert!(a.is_sparse());
    assert_eq!(a.stored(), 3);
    let want = [-1.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.25, 0.0, 0.0];
    assert_eq!(&a.to_dense()[..], &want);
    for i in 0..3 {
        for j in 0..4 {
            assert_eq!(a.weight(i, j), want[i * 4 + j]);
        }
    }
    assert_eq!(a.row(2).nonzeros().collect::<Vec<_>>(), vec![(1, 0.25)]);
    assert_eq!(a, Affine::new(4, 3, want.to_vec(), vec![0.1, 0.2, 0.3]));
    let mut y = vec![0.0; 3];
    a.apply_f64(&[1.0, 2.0, 3.0, 4.0], &mut y);
    assert_eq!(y, vec![0.1 + -1.0 + 2.0 * 3.0, 0.2, 0.3 + 0.25 * 2.0]);
    let bad = Affine::from_rows(2, vec![vec![(5, 1.0)]], vec![0.0]);
    let net = Network {
        input_names: vec!["a".into(), "b".into()],
        output_names: vec!["y".into()],
        input_norm: None,
        layers: vec![Layer::Affine(bad)],
        output_denorm: None,
    };
    assert!(matches!(
        net.validate(),
        Err(samara_nn::ir::IrError::Shape { layer: 0 })
    ));
    // A budget too small for the dense form refuses it with the variable named.
    let small = samara_nn::limits::Budget::new(64);
    let e = a.to_dense_within(&small).unwrap_err();
    assert!(e.contains(samara_nn::limits::IMPORT_MEMORY_ENV), "{e}");
}

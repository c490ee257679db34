//! Import limits by memory (issue 36): a network is refused only when its import would
//! need more than the memory budget (`samara_nn::limits`), not by fixed caps on widths
//! or tensor sizes. Wide networks with few inputs (VNN-COMP's tllverifybench) load and
//! evaluate as a direct matrix-vector product of their weights says; past the budget,
//! import stops with an error naming the place, the bytes and the variable that raises
//! it; two dense maps in a row are composed only when their product is not larger.

use prost::Message;
use rand::{Rng, SeedableRng};
use samara_nn::limits::IMPORT_MEMORY_ENV;
use samara_nn::onnx::{self, ExportOptions};
use samara_nn::{Activation, Affine, Layer, Network};

fn data(name: &str) -> String {
    format!("{}/tests/data/{name}", env!("CARGO_MANIFEST_DIR"))
}

fn random_affine(r: &mut impl Rng, i: usize, o: usize) -> Affine {
    Affine::new(
        i,
        o,
        (0..i * o).map(|_| r.gen_range(-1.0..1.0)).collect(),
        (0..o).map(|_| r.gen_range(-0.5..0.5)).collect(),
    )
}

fn net(layers: Vec<Layer>, n_in: usize, n_out: usize) -> Network {
    Network {
        input_names: (0..n_in).map(|i| format!("x{i}")).collect(),
        output_names: (0..n_out).map(|i| format!("y{i}")).collect(),
        input_norm: None,
        layers,
        output_denorm: None,
    }
}

fn f64_bytes(n: &Network) -> Vec<u8> {
    let o = ExportOptions {
        float64: true,
        ..Default::default()
    };
    onnx::export(n, &o).encode_to_vec()
}

/// `W x + b` by the definition, row by row.
fn apply(a: &Affine, x: &[f64]) -> Vec<f64> {
    (0..a.out)
        .map(|i| a.b[i] + (0..a.inp).map(|j| a.weight(i, j) * x[j]).sum::<f64>())
        .collect()
}

/// 2 -> 4100 -> 4100 -> 1 with ReLUs: wider than the old 4,096 cap, and its middle
/// weight (16,810,000 values) over the old 16,777,216 values per tensor.
fn wide() -> Network {
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(36);
    let (a, b, c) = (
        random_affine(&mut r, 2, 4100),
        random_affine(&mut r, 4100, 4100),
        random_affine(&mut r, 4100, 1),
    );
    net(
        vec![
            Layer::Affine(a),
            Layer::Act(Activation::Relu),
            Layer::Affine(b),
            Layer::Act(Activation::Relu),
            Layer::Affine(c),
        ],
        2,
        1,
    )
}

#[test]
fn a_network_past_the_old_fixed_caps_loads_within_the_budget_and_evaluates_by_its_weights() {
    let n = wide();
    let bytes = f64_bytes(&n);
    let back = onnx::from_bytes(&bytes, "wide.onnx").unwrap();
    assert_eq!(back.layers, n.layers);
    let Layer::Affine(a) = &n.layers[0] else {
        panic!()
    };
    let Layer::Affine(b) = &n.layers[2] else {
        panic!()
    };
    let Layer::Affine(c) = &n.layers[4] else {
        panic!()
    };
    let relu = |v: Vec<f64>| v.into_iter().map(|z| z.max(0.0)).collect::<Vec<_>>();
    for x in [[0.3, -0.7], [-1.0, 1.0], [0.0, 0.0]] {
        let want = apply(c, &relu(apply(b, &relu(apply(a, &x)))));
        let got = back.eval_f64(&x);
        assert!(
            (got[0] - want[0]).abs() <= 1e-9 * want[0].abs().max(1.0),
            "{got:?} {want:?}"
        );
    }
    // About 2 x 134 MB in f64 (the constant and its transposed map), far under 8 GiB.
    let needed = 2 * 8 * 4100 * 4100;
    assert!(onnx::from_bytes_within(&bytes, "wide.onnx", needed + (1 << 20)).is_ok());
}

#[test]
fn past_the_budget_import_stops_naming_the_place_the_bytes_and_the_variable() {
    let bytes = f64_bytes(&wide());
    // Enough for the first layer's constants, not for the 4100 x 4100 weight.
    let e = onnx::from_bytes_within(&bytes, "wide.onnx", 64 << 20)
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("wide.onnx: tensor `"), "{e}");
    assert!(e.contains("[4100, 4100]"), "{e}");
    assert!(e.contains("134,480,000 bytes"), "{e}");
    assert!(
        e.contains("67,108,864 bytes (0.06 GiB) samara allows"),
        "{e}"
    );
    assert!(e.contains(&format!("{IMPORT_MEMORY_ENV}=16G")), "{e}");
    // A map built by the importer is charged too: the constants fit, the transposed
    // copy of the big weight does not.
    let e = onnx::from_bytes_within(&bytes, "wide.onnx", 8 * (4100 * 4100 + 8 * 4100 + 100))
        .unwrap_err()
        .to_string();
    assert!(e.contains("its 4100 -> 4100 map"), "{e}");
    assert!(e.contains(IMPORT_MEMORY_ENV), "{e}");
}

#[test]
fn the_graph_importer_and_its_lowering_are_charged_to_the_same_budget() {
    let bytes = std::fs::read(data("conv_residual.onnx")).unwrap();
    assert!(onnx::from_bytes_within(&bytes, "conv_residual.onnx", 1 << 30).is_ok());
    // Small budgets stop the import at a constant or at a dense layer of the lowering,
    // with the variable named; the budget error is shown, not the chain importer's
    // refusal of the sliding convolution.
    let mut seen_lowering = false;
    for kib in [1u64, 4, 16, 64, 256] {
        if let Err(e) = onnx::from_bytes_within(&bytes, "conv_residual.onnx", kib << 10) {
            let e = e.to_string();
            assert!(e.contains(IMPORT_MEMORY_ENV), "{kib} KiB: {e}");
            seen_lowering |= e.contains("lowering to dense layers");
            // A network over the budget is not an unsupported operator.
            assert!(!e.contains("unsupported operator"), "{kib} KiB: {e}");
        }
    }
    assert!(seen_lowering);
}

#[test]
fn two_dense_maps_in_a_row_are_composed_only_when_the_product_is_not_larger() {
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    // 2 -> 4 -> 8: the product (8 x 2) is smaller than the two maps: one layer.
    let (a, b) = (random_affine(&mut r, 2, 4), random_affine(&mut r, 4, 8));
    let n = net(
        vec![Layer::Affine(a.clone()), Layer::Affine(b.clone())],
        2,
        8,
    );
    let back = onnx::from_bytes(&f64_bytes(&n), "m.onnx").unwrap();
    assert_eq!(back.layers.len(), 1);
    let x = [0.25, -0.5];
    let want = apply(&b, &apply(&a, &x));
    for (g, w) in back.eval_f64(&x).iter().zip(&want) {
        assert!((g - w).abs() < 1e-12, "{g} {w}");
    }
    // 6 -> 1 -> 6 (a bottleneck): the product (6 x 6) is larger than the two (6 + 6):
    // two layers, the network's own arithmetic.
    let (a, b) = (random_affine(&mut r, 6, 1), random_affine(&mut r, 1, 6));
    let n = net(vec![Layer::Affine(a), Layer::Affine(b)], 6, 6);
    let back = onnx::from_bytes(&f64_bytes(&n), "b.onnx").unwrap();
    assert_eq!(back.layers, n.layers);
}

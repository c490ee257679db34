//! Every published ONNX network imports and agrees with onnxruntime (outputs produced by
//! bench/nn/onnx_expected.py, an independent runtime) on 1000 random inputs, to 1e-6
//! relative to max(1, |y|): onnxruntime computes in float32 (relative rounding about
//! 1e-7 per operation), samara in f64 from the same float32 weights.

use samara_nn::onnx;

use samara_testkit as support;
use support::reference;

fn check(stem: &str) -> f64 {
    let net = onnx::load(reference(&format!("{stem}.onnx"))).unwrap();
    let text = std::fs::read_to_string(format!(
        "{}/tests/data/{stem}.csv",
        env!("CARGO_MANIFEST_DIR")
    ))
    .unwrap();
    let (ni, no) = (net.n_inputs(), net.n_outputs());
    let mut worst = 0.0f64;
    let mut rows = 0;
    for line in text.lines().filter(|l| !l.starts_with('#')) {
        let v: Vec<f64> = line.split(',').map(|x| x.parse().unwrap()).collect();
        assert_eq!(v.len(), ni + no);
        let y = net.eval_f64(&v[..ni]);
        for k in 0..no {
            worst = worst.max((y[k] - v[ni + k]).abs() / v[ni + k].abs().max(1.0));
        }
        rows += 1;
    }
    assert_eq!(rows, 1000);
    worst
}

#[test]
fn published_networks_agree_with_onnxruntime() {
    for stem in [
        "base_model_norm",
        "adversarial_model_norm",
        "base_model_denorm",
        "adversarial_model_denorm",
        "merged_model_base",
    ] {
        let w = check(stem);
        eprintln!("{stem}: max relative |samara - onnxruntime| = {w:e}");
        assert!(w <= 1e-6, "{stem}: {w:e}");
    }
}

#[test]
fn denorm_networks_carry_their_normalisation() {
    let net = onnx::load(reference("base_model_denorm.onnx")).unwrap();
    let norm = net
        .input_norm
        .as_ref()
        .expect("Sub/Div recognised as input normalisation");
    let den = net
        .output_denorm
        .as_ref()
        .expect("Mul/Add recognised as output denormalisation");
    // Constants of Normalisation_Constants.csv (float32 in the graph): first input
    // x_n = (x - 0.967568147) / 2.522324921; output ex = 0.181 + 0.012 * out.
    assert!((norm.weight(0, 0) - 1.0 / 2.522324921).abs() < 1e-7);
    assert!((norm.b[0] + 0.967568147 / 2.522324921).abs() < 1e-7);
    assert!((den.weight(0, 0) - 0.012).abs() < 1e-9 && (den.b[0] - 0.181).abs() < 1e-8);
    let plain = onnx::load(reference("base_model_norm.onnx")).unwrap();
    assert!(plain.input_norm.is_none() && plain.output_denorm.is_none());
    assert_eq!(plain.layers.len(), 6);
}

#[test]
fn doubled_network_is_block_diagonal_sigmoid() {
    let net = onnx::load(reference("merged_model_base.onnx")).unwrap();
    assert_eq!((net.n_inputs(), net.n_outputs()), (12, 2));
    // Output 0 depends only on inputs 0..6: perturbing inputs 6..12 leaves it unchanged.
    let x: Vec<f64> = (0..12).map(|i| 0.05 * i as f64).collect();
    let mut x2 = x.clone();
    for v in &mut x2[6..] {
        *v += 0.3;
    }
    let (a, b) = (net.eval_f64(&x), net.eval_f64(&x2));
    assert_eq!(a[0], b[0]);
    assert_ne!(a[1], b[1]);
}

//! Issue 35 item 4: degenerate VNN-LIB queries are decided at once. A query whose answer
//! follows from bounds alone (y = relu(x0 + x1 - 1) is exactly 0 on [0, 0.5]^2, so
//! `Y_0 > 0` is impossible and `Y_0 >= 0` holds everywhere) or whose compared outputs are
//! the same expression (two identical rows of the last layer: `Y_0 - Y_1` is exactly 0)
//! used to run to the full `--timeout`. Expected verdicts by hand: the strict forms are
//! `unsat`, the non-strict ones `sat` (every point is a counterexample; the point given
//! is re-evaluated here through `samara_nn`).

use samara_nn::{onnx, Activation, Affine, Layer, Network};
use std::path::Path;
use std::time::Duration;

use crate::support;
use support::verify_vnnlib_json;

fn net(layers: Vec<Layer>, n_in: usize, n_out: usize) -> Network {
    Network {
        input_names: (0..n_in).map(|i| format!("x{i}")).collect(),
        output_names: (0..n_out).map(|i| format!("y{i}")).collect(),
        input_norm: None,
        layers,
        output_denorm: None,
    }
}

/// y = relu(x0 + x1 - 1), ending in the ReLU (`identity_after`: a 1x1 identity layer
/// after it, the same function).
fn relu_net(identity_after: bool) -> Network {
    let mut l = vec![
        Layer::Affine(Affine::new(2, 1, vec![1.0, 1.0], vec![-1.0])),
        Layer::Act(Activation::Relu),
    ];
    if identity_after {
        l.push(Layer::Affine(Affine::new(1, 1, vec![1.0], vec![0.0])));
    }
    net(l, 2, 1)
}

/// Two outputs computed by the same row of the last layer after a hidden ReLU layer.
fn equal_outputs_net() -> Network {
    let w1 = vec![0.7, -0.4, -0.3, 0.9, 0.5, 0.5, -0.8, 0.2];
    let b1 = vec![0.1, -0.2, 0.05, 0.3];
    let row = [0.6, -0.7, 0.25, 1.1];
    let w2: Vec<f64> = row.iter().chain(row.iter()).copied().collect();
    net(
        vec![
            Layer::Affine(Affine::new(2, 4, w1, b1)),
            Layer::Act(Activation::Relu),
            Layer::Affine(Affine::new(4, 2, w2, vec![0.125, 0.125])),
        ],
        2,
        2,
    )
}

fn write(dir: &Path, name: &str, n: &Network, assert: &str) -> (String, String) {
    let onnx_path = dir.join(format!("{name}.onnx"));
    onnx::save(
        n,
        &onnx_path,
        &onnx::ExportOptions {
            float64: true,
            ..Default::default()
        },
    )
    .unwrap();
    let mut text = String::new();
    for i in 0..n.n_inputs() {
        text += &format!("(declare-const X_{i} Real)\n");
    }
    for j in 0..n.n_outputs() {
        text += &format!("(declare-const Y_{j} Real)\n");
    }
    for i in 0..n.n_inputs() {
        text += &format!("(assert (>= X_{i} 0.0))\n(assert (<= X_{i} 0.5))\n");
    }
    text += &format!("(assert {assert})\n");
    let prop = dir.join(format!("{name}.vnnlib"));
    std::fs::write(&prop, text).unwrap();
    (onnx_path.display().to_string(), prop.display().to_string())
}

fn check(n: &Network, name: &str, assert: &str, want: &str, holds: impl Fn(&[f64]) -> bool) {
    let dir = tempfile::tempdir().unwrap();
    let (o, p) = write(dir.path(), name, n, assert);
    let (code, v, dt) = verify_vnnlib_json(&o, &p);
    assert_eq!(v["result"], want, "{name} {assert}: {v}");
    assert_eq!(code, Some(if want == "unsat" { 0 } else { 1 }), "{v}");
    assert!(dt < Duration::from_secs(1), "{name} {assert}: {dt:?} ({v})");
    if want == "sat" {
        let x: Vec<f64> = v["counterexample"]["inputs"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        assert!(x.iter().all(|x| (0.0..=0.5).contains(x)), "{x:?}");
        let y = n.eval_f64(&x);
        assert!(holds(&y), "{name} {assert}: the point {x:?} gives {y:?}");
    }
}

#[test]
fn a_relu_that_is_zero_on_the_whole_box_is_decided_at_once() {
    for identity_after in [false, true] {
        let n = relu_net(identity_after);
        check(&n, "relu", "(> Y_0 0.0)", "unsat", |_| false);
        check(&n, "relu", "(>= Y_0 0.0)", "sat", |y| y[0] >= 0.0);
        check(&n, "relu", "(<= Y_0 0.0)", "sat", |y| y[0] <= 0.0);
        check(&n, "relu", "(< Y_0 0.0)", "unsat", |_| false);
    }
}

#[test]
fn identical_outputs_compared_are_decided_at_once() {
    let n = equal_outputs_net();
    check(&n, "equal", "(> Y_0 Y_1)", "unsat", |_| false);
    check(&n, "equal", "(< Y_0 Y_1)", "unsat", |_| false);
    check(&n, "equal", "(>= Y_0 Y_1)", "sat", |y| y[0] >= y[1]);
    check(&n, "equal", "(<= Y_0 Y_1)", "sat", |y| y[0] <= y[1]);
}

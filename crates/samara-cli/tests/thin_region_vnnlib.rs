//! Issue 35 item 4, last sentence: a thin region is decided or `unknown (thin_region)` at
//! once, never a run to the time limit. The network outputs Y_0 = relu(s) and
//! Y_1 = relu(-s) with s = x0 - x1 on [0, 0.5]^2 (s changes sign on the box). By hand:
//! Y_0 > 0 needs s > 0 and Y_1 > 0 needs s < 0, so `(> Y_0 0) and (> Y_1 0)` has no point
//! (unsat), though the closure of its region is not empty (the diagonal x0 = x1, where
//! both are 0), which an input-split search cannot close. The non-strict variant
//! `(>= Y_0 0) and (>= Y_1 0)` holds everywhere, and `(> Y_0 0.25)` holds at
//! x = (0.5, 0) (Y_0 = 0.5): both sat, their points re-evaluated here through `samara_nn`.

use samara_nn::{onnx, Activation, Affine, Layer, Network};
use std::time::Duration;

use crate::support;
use support::verify_vnnlib_json;

fn split_net() -> Network {
    Network {
        input_names: vec!["x0".into(), "x1".into()],
        output_names: vec!["y0".into(), "y1".into()],
        input_norm: None,
        layers: vec![
            Layer::Affine(Affine::new(
                2,
                2,
                vec![1.0, -1.0, -1.0, 1.0],
                vec![0.0, 0.0],
            )),
            Layer::Act(Activation::Relu),
        ],
        output_denorm: None,
    }
}

/// Run `verify-vnnlib --json --timeout 20` on the network and `asserts` over
/// [0, 0.5]^2; (exit code, JSON, wall time).
fn run(asserts: &str) -> (Option<i32>, serde_json::Value, Duration) {
    let dir = tempfile::tempdir().unwrap();
    let o = dir.path().join("n.onnx");
    onnx::save(&split_net(), &o, &onnx::ExportOptions::default()).unwrap();
    let mut text = String::new();
    for v in ["X_0", "X_1", "Y_0", "Y_1"] {
        text += &format!("(declare-const {v} Real)\n");
    }
    for v in ["X_0", "X_1"] {
        text += &format!("(assert (>= {v} 0.0))\n(assert (<= {v} 0.5))\n");
    }
    text += asserts;
    let p = dir.path().join("p.vnnlib");
    std::fs::write(&p, text).unwrap();
    verify_vnnlib_json(o.to_str().unwrap(), p.to_str().unwrap())
}

#[test]
fn two_strict_relus_of_opposite_sign_are_decided_at_once() {
    let (code, v, dt) = run("(assert (> Y_0 0.0))\n(assert (> Y_1 0.0))\n");
    assert!(dt < Duration::from_secs(1), "{dt:?} {v}");
    match v["result"].as_str().unwrap() {
        "unsat" => assert_eq!(code, Some(0), "{v}"),
        "unknown" => {
            assert_eq!(v["unknown_reason"]["kind"], "thin_region", "{v}");
            assert_eq!(code, Some(1), "{v}");
        }
        r => panic!("{r}: never sat, the query has no point ({v})"),
    }
}

fn sat_point(v: &serde_json::Value) -> Vec<f64> {
    let x: Vec<f64> = v["counterexample"]["inputs"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    assert!(x.iter().all(|x| (0.0..=0.5).contains(x)), "{x:?}");
    split_net().eval_f64(&x)
}

#[test]
fn the_sat_variants_stay_sat() {
    let (code, v, dt) = run("(assert (>= Y_0 0.0))\n(assert (>= Y_1 0.0))\n");
    assert_eq!((v["result"].as_str(), code), (Some("sat"), Some(1)), "{v}");
    assert!(dt < Duration::from_secs(1), "{dt:?} {v}");
    let y = sat_point(&v);
    assert!(y[0] >= 0.0 && y[1] >= 0.0, "{y:?}");
    let (code, v, _) = run("(assert (> Y_0 0.25))\n(assert (>= Y_1 0.0))\n");
    assert_eq!((v["result"].as_str(), code), (Some("sat"), Some(1)), "{v}");
    let y = sat_point(&v);
    assert!(y[0] > 0.25 && y[1] >= 0.0, "{y:?}");
}

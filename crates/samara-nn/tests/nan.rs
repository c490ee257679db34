//! Issue 35 item 8: NaN in, NaN out. `f64::max(0, NaN)` is 0, so a ReLU written with
//! `max` turned an all-NaN input into 0.1089 on base_model_norm.onnx. Every evaluation
//! path (the f64 evaluator, the generic one over f64 and dual numbers, clamp layers) now
//! carries a NaN through; finite inputs give the same numbers as before (the published
//! networks' onnxruntime agreement is `onnx_reference.rs`).

use samara_nn::{onnx, Activation, Affine, Layer, Network};
use samara_num::{Dual, Scalar};

use samara_testkit as support;
use support::reference;

#[test]
fn nan_inputs_give_nan_outputs_on_every_path() {
    for stem in ["base_model_norm", "base_model_denorm", "merged_model_base"] {
        let net = onnx::load(reference(&format!("{stem}.onnx"))).unwrap();
        let (n, n_out) = (net.n_inputs(), net.n_outputs());
        for k in 0..n {
            // One NaN input among finite ones is enough to make the output NaN.
            let mut x = vec![0.5; n];
            x[k] = f64::NAN;
            for y in net.eval_f64(&x) {
                assert!(y.is_nan(), "{stem}: NaN at input {k} gave {y}");
            }
            // The generic path skips zero weights (sets: 0 * [-inf, inf]), so an output
            // of merged_model_base that does not depend on input k stays a number;
            // every output that does is NaN (each single-output network's one output).
            let y = net.eval::<f64>(&x);
            assert!(
                y.iter().any(|y| y.is_nan()),
                "{stem} (generic): NaN at input {k} gave {y:?}"
            );
            if n_out == 1 {
                assert!(y[0].is_nan());
            }
            let xd: Vec<Dual<1>> = x.iter().map(|&v| Dual::cst(v)).collect();
            let y = net.eval(&xd);
            assert!(
                y.iter().any(|y| y.v.is_nan()),
                "{stem} (dual): NaN at input {k}"
            );
            if n_out == 1 {
                assert!(y[0].v.is_nan());
            }
            let b = net.eval_batch_f64(&x, 1);
            assert!(b.iter().all(|y| y.is_nan()), "{stem} (batch): {b:?}");
        }
    }
}

#[test]
fn relu_and_clamp_layers_pass_nan_and_keep_their_finite_values() {
    // y = clamp(relu(x0 - x1), 0.25, 2): hand-computed values below.
    let net = Network {
        input_names: vec!["a".into(), "b".into()],
        output_names: vec!["y".into()],
        input_norm: None,
        layers: vec![
            Layer::Affine(Affine::new(2, 1, vec![1.0, -1.0], vec![0.0])),
            Layer::Act(Activation::Relu),
            Layer::Act(Activation::Clamp { lo: 0.25, hi: 2.0 }),
        ],
        output_denorm: None,
    };
    for (x, want) in [
        ([1.0, 3.0], 0.25),
        ([1.0, 0.0], 1.0),
        ([5.0, 0.0], 2.0),
        ([f64::INFINITY, 0.0], 2.0),
    ] {
        assert_eq!(net.eval_f64(&x), vec![want], "{x:?}");
        assert_eq!(net.eval::<f64>(&x), vec![want], "{x:?}");
    }
    for x in [
        [f64::NAN, 0.0],
        [0.0, f64::NAN],
        [f64::INFINITY, f64::INFINITY],
    ] {
        assert!(net.eval_f64(&x)[0].is_nan(), "{x:?}");
        assert!(net.eval::<f64>(&x)[0].is_nan(), "{x:?}");
    }
    assert!(Activation::Relu.apply_f64(f64::NAN).is_nan());
    assert!(Activation::Clamp { lo: 0.0, hi: 1.0 }
        .apply_f64(f64::NAN)
        .is_nan());
    assert_eq!(Activation::Relu.apply_f64(-0.0), 0.0);
}

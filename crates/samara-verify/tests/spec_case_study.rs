//! The case-study spec (models/alsomitra/alsomitra.spec): its P5 instances load from the
//! published data and verify.

use samara_spec::{Bindings, Spec};
use samara_verify::{prove, Prepared, Settings, Verdict};
use std::collections::HashMap;
use std::path::Path;

use samara_testkit::reference;

#[test]
fn p5_instances_come_from_the_published_data_and_verify() {
    let spec = Spec::read(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/alsomitra/alsomitra.spec"),
    )
    .unwrap();
    let mut b = Bindings::default();
    b.datasets
        .insert("train".into(), reference("Training_Data_Normalised.csv"));
    b.params.insert("eps".into(), 0.001);
    b.params.insert("L".into(), 0.01);
    let inst = spec.lower_prove("p5_lipschitz", &b).unwrap();
    assert_eq!(inst.len(), 360);
    let mut nets = HashMap::new();
    nets.insert(
        "f".to_string(),
        samara_nn::onnx::load(reference("base_model_norm.onnx")).unwrap(),
    );
    let prep = Prepared::new(&nets);
    let mut counts = (0, 0, 0);
    for i in inst.iter().take(20) {
        match prove(&i.query, &prep, &Settings::default()).unwrap() {
            Verdict::Proved => counts.0 += 1,
            Verdict::Violated(cx) => {
                // Re-check the counterexample by hand: |f(x1) - f(x0)| > L ||x1 - x0||_inf.
                let net = &nets["f"];
                let (x0, x1) = (&cx.point.inputs[0], &cx.point.inputs[1]);
                let (y0, y1) = (net.eval_f64(x0)[0], net.eval_f64(x1)[0]);
                let d = x0
                    .iter()
                    .zip(x1)
                    .map(|(a, b)| (a - b).abs())
                    .fold(0.0, f64::max);
                // In raw ex units: 0.012 * |out difference|.
                assert!(
                    0.012 * (y1 - y0).abs() > 0.01 * d,
                    "{}: not a counterexample",
                    i.label
                );
                counts.1 += 1;
            }
            Verdict::Unknown(_) => counts.2 += 1,
        }
    }
    eprintln!("p5_lipschitz first 20 points: {counts:?}");
    assert_eq!(counts.0 + counts.1 + counts.2, 20);
}

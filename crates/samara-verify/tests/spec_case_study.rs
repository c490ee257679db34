//! The case-study spec (models/alsomitra/alsomitra.spec) lowered by samara-spec gives the
//! same critical values as the hand-built queries of `samara_verify::case_study`, on the
//! published normalised networks, and the P5 instances load from the published data.

use samara_spec::{Bindings, Spec};
use samara_verify::case_study::{p1_to_p4, Units};
use samara_verify::{optimise, prove, Prepared, Settings, Verdict};
use std::collections::HashMap;
use std::path::Path;

fn reference(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../../shared/reference")
        .join(name)
}

#[test]
fn spec_and_hand_built_queries_agree_on_published_networks() {
    let spec = Spec::read(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/alsomitra/alsomitra.spec"),
    )
    .unwrap();
    let c = [
        0.967568147,
        -0.607397104,
        -0.356972794,
        -0.96847853,
        0.482420778,
        -41.68140527,
    ];
    let s = [
        2.522324921,
        0.564375713,
        0.406153017,
        0.900476013,
        41.23229622,
        45.87863879,
    ];
    let lo = c.to_vec();
    let hi: Vec<f64> = c.iter().zip(&s).map(|(a, b)| a + b).collect();
    let units = Units {
        c: c.to_vec(),
        s: s.to_vec(),
        c_out: 0.181,
        s_out: 0.012,
    };
    for file in ["base_model_norm.onnx", "adversarial_model_norm.onnx"] {
        let mut nets = HashMap::new();
        nets.insert(
            "f".to_string(),
            samara_nn::onnx::load(reference(file)).unwrap(),
        );
        let prep = Prepared::new(&nets);
        let hand = p1_to_p4("f", &units, &lo, &hi);
        for (k, name) in ["p1", "p2", "p3", "p4"].iter().enumerate() {
            let q = &spec
                .lower_critical(name, "ystar", &Bindings::default())
                .unwrap()[0]
                .query;
            let mut sup = q.clone();
            let mut inf = q.clone();
            if let samara_spec::normal::Goal::Optimise { sense, .. } = &mut inf.goal {
                *sense = samara_spec::normal::Sense::Min;
            }
            let (rs, ri) = (
                optimise(&sup, &prep, &Settings::default()).unwrap(),
                optimise(&inf, &prep, &Settings::default()).unwrap(),
            );
            let rh = optimise(&hand[k], &prep, &Settings::default()).unwrap();
            // P1, P2: the property holds above the supremum of counterexample ystar;
            // P3, P4: below the infimum (clipped at the parameter range [0, 100]).
            let from_spec = if k < 2 { rs.value } else { ri.value };
            let (a, b) = (from_spec.unwrap(), rh.value.unwrap().max(0.0));
            eprintln!("{file} {name}: spec {a:.9} hand {b:.9}");
            assert!(
                (a - b).abs() <= 1e-5 * (1.0 + b.abs()),
                "{file} {name}: spec {a} vs hand {b}"
            );
            let _ = &mut sup;
        }
    }
}

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

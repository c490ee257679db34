//! The application layer on a network whose answers are known in closed form:
//! f(a) = 2a on a in [0, 1], so max f = 2. `b <= 3` is proved, `b <= 1` is violated at
//! some a > 1/2, and the critical value of c in `b < c` is 2 (holds above). The typed
//! results read back from their JSON, and the messages name the caller's argument.

use samara_app::verify::{RowCounterexample, VerdictTag};
use samara_app::{critical_value, run_verify, AppError, Front, Holds, Loaded, VerdictRow};
use samara_nn::{Affine, Layer, Network};
use samara_spec::Spec;
use samara_verify::Settings;
use std::borrow::Cow;
use std::path::Path;
use std::time::Instant;

const SPEC: &str = "network f(a) -> (b)
domain f: a in [0, 1]
param c in [0, 10] = 5
property holds: a >= 0 => b <= 3
property fails: a >= 0 => b <= 1
property crit: a >= 0 => b < c
";

fn double(inputs: usize) -> Network {
    Network {
        input_names: (0..inputs).map(|i| format!("a{i}")).collect(),
        output_names: vec!["b".into()],
        input_norm: None,
        layers: vec![Layer::Affine(Affine::new(
            inputs,
            1,
            vec![2.0; inputs],
            vec![0.0],
        ))],
        output_denorm: None,
    }
}

fn spec() -> Spec {
    Spec::parse(SPEC, "t.spec", Path::new(".")).unwrap()
}

fn bound(spec: &Spec, front: Front) -> Loaded<'_> {
    let mut l = Loaded::new(Cow::Borrowed(spec), "t.spec".into(), front);
    l.bind_network("f", double(1), "networks[\"f\"]", None)
        .unwrap();
    l.finish("params").unwrap()
}

#[test]
fn verdicts_and_counterexample_of_the_doubling_network() {
    let s = spec();
    let l = bound(&s, Front::Python);
    // No normalisation line and none in the network: the units cannot be checked.
    assert_eq!(l.warnings.len(), 1);
    let run = run_verify(
        &l,
        None,
        &Settings::default(),
        Instant::now(),
        false,
        |_| {},
    )
    .unwrap();
    let rows: Vec<&VerdictRow> = run.rows().collect();
    assert_eq!(rows.len(), 3);
    assert_eq!(rows[0].verdict, VerdictTag::Proved);
    assert_eq!(rows[1].verdict, VerdictTag::Violated);
    let Some(RowCounterexample::Point { point, .. }) = &rows[1].counterexample else {
        panic!("{:?}", rows[1]);
    };
    let (a, b) = (point[0].values["a"], point[0].values["b"]);
    assert!(
        a > 0.5 && a <= 1.0 && (b - 2.0 * a).abs() < 1e-12,
        "{a} {b}"
    );
    // At the default c = 5 the parametric property holds.
    assert_eq!(rows[2].verdict, VerdictTag::Proved);
    assert!(!run.all_proved());
    // The typed rows read back from their JSON.
    let text = serde_json::to_string(&rows).unwrap();
    let back: Vec<VerdictRow> = serde_json::from_str(&text).unwrap();
    assert_eq!(back.iter().collect::<Vec<_>>(), rows);
}

#[test]
fn critical_value_is_the_maximum_of_the_network() {
    let s = spec();
    let l = bound(&s, Front::Cli);
    let c = critical_value(&l, "crit", "c", &Settings::default()).unwrap();
    assert_eq!(c.holds, Holds::Above, "{c:?}");
    assert!(c.complete && c.unknown_reason.is_none());
    let t = c.threshold.unwrap();
    assert!((t - 2.0).abs() < 1e-6, "{t}");
    assert!(c.critical.unwrap() <= t + 1e-12);
    let v = serde_json::to_value(&c).unwrap();
    assert_eq!(v["holds"], "above");
    let back: samara_app::CriticalValue = serde_json::from_value(v).unwrap();
    assert_eq!(back, c);
}

#[test]
fn messages_name_the_callers_argument() {
    let s = spec();
    for (front, label, noun) in [
        (Front::Cli, "--network f=two.onnx", "the file has 2 inputs"),
        (Front::Python, "networks[\"f\"]", "the network has 2 inputs"),
    ] {
        let mut l = Loaded::new(Cow::Borrowed(&s), "t.spec".into(), front);
        let Err(AppError::Input(m)) = l.bind_network("f", double(2), label, None) else {
            panic!("a 2-input network bound to f(a)");
        };
        assert!(
            m.starts_with(&format!("{label}: dimension mismatch: {noun}")),
            "{m}"
        );
    }
    let l = Loaded::new(Cow::Borrowed(&s), "t.spec".into(), Front::Python);
    let Err(AppError::Input(m)) = run_verify(
        &l,
        Some("holds"),
        &Settings::default(),
        Instant::now(),
        false,
        |_| {},
    ) else {
        panic!("no network bound");
    };
    assert!(m.contains("pass networks={\"f\": Network}"), "{m}");
    let mut l = Loaded::new(Cow::Borrowed(&s), "t.spec".into(), Front::Python);
    let Err(AppError::Input(m)) = l.bind_param("c", f64::NAN, "params[\"c\"]", None) else {
        panic!("NaN accepted");
    };
    assert_eq!(m, "params[\"c\"]: not a finite number; pass a finite value");
    l.bind_param("c", 50.0, "params[\"c\"]", None).unwrap();
    let Err(AppError::Input(m)) = l.finish("params") else {
        panic!("50 is outside [0, 10]");
    };
    assert!(m.starts_with("params: "), "{m}");
}

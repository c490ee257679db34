//! `samara check | verify | critical | robustness | export-vnnlib` end to end, with
//! exit codes (0 proved, 1 violated/unknown, 2 input error) and verdicts re-checked here
//! against the plain network evaluation.

use crate::support;
use support::samara;

use support::{reference_str as reference, SPEC};

#[test]
fn verify_exit_codes_and_counterexamples() {
    let net = format!("f={}", reference("base_model_norm.onnx"));
    // P1 above the critical value: proved, exit 0.
    let out = samara()
        .args([
            "verify",
            SPEC,
            "--property",
            "p1",
            "--param",
            "ystar=46",
            "--network",
            &net,
        ])
        .output()
        .unwrap();
    assert_eq!(
        out.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("proved"));
    // Below it: violated, exit 1, with a counterexample that is one.
    let out = samara()
        .args([
            "verify",
            SPEC,
            "--property",
            "p1",
            "--param",
            "ystar=10",
            "--network",
            &net,
            "--json",
        ])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v[0]["verdict"], "violated");
    let p = &v[0]["counterexample"]["point"][0]["values"];
    let (x, y, ex) = (
        p["x"].as_f64().unwrap(),
        p["y"].as_f64().unwrap(),
        p["ex"].as_f64().unwrap(),
    );
    assert!(y >= -x + 10.0 && ex < 0.187, "{p}");
    // Re-evaluate the network at the reported raw state (independent of the verifier).
    let netw = samara_nn::onnx::load(reference("base_model_norm.onnx")).unwrap();
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
    let names = ["v_xp", "v_yp", "omega", "theta", "x", "y"];
    let z: Vec<f64> = (0..6)
        .map(|k| (p[names[k]].as_f64().unwrap() - c[k]) / s[k])
        .collect();
    let ex_again = 0.181 + 0.012 * netw.eval_f64(&z)[0];
    assert!((ex_again - ex).abs() < 1e-9 && ex_again < 0.187);
}

#[test]
fn critical_values_and_vacuity() {
    let out = samara()
        .args([
            "critical",
            SPEC,
            "--property",
            "p1",
            "--param",
            "ystar",
            "--json",
            "--network",
        ])
        .arg(format!("f={}", reference("adversarial_model_norm.onnx")))
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["holds"], "above");
    let crit = v["critical"].as_f64().unwrap();
    let bound = v["bound"].as_f64().unwrap();
    assert!(
        crit > 20.0 && crit < 40.0 && bound >= crit && bound - crit < 1e-4,
        "{v}"
    );
    assert_eq!(v["vacuous"], false);
    // The naive network's P1 threshold is the largest x + y of the domain: vacuous.
    let out = samara()
        .args([
            "critical",
            SPEC,
            "--property",
            "p1",
            "--param",
            "ystar",
            "--json",
            "--network",
        ])
        .arg(format!("f={}", reference("base_model_norm.onnx")))
        .output()
        .unwrap();
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["vacuous"], true, "{v}");
    // x + y at most 41.714716998 + 4.19723352 over the declared domain.
    assert!((v["critical"].as_f64().unwrap() - (41.714716998 + 4.19723352)).abs() < 1e-6);
}

#[test]
fn input_errors_exit_2() {
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            vec![
                "verify".into(),
                SPEC.into(),
                "--property".into(),
                "p1".into(),
            ],
            "--network f=FILE",
        ),
        (
            vec![
                "verify".into(),
                SPEC.into(),
                "--property".into(),
                "p9".into(),
                "--network".into(),
                format!("f={}", reference("base_model_norm.onnx")),
            ],
            "no property named `p9`",
        ),
        (
            vec![
                "verify".into(),
                SPEC.into(),
                "--property".into(),
                "p1".into(),
                "--network".into(),
                format!("f={}", reference("merged_model_base.onnx")),
            ],
            "dimension mismatch",
        ),
        (
            vec![
                "critical".into(),
                SPEC.into(),
                "--property".into(),
                "p1".into(),
                "--param".into(),
                "eps".into(),
                "--network".into(),
                format!("f={}", reference("base_model_norm.onnx")),
            ],
            "has no range",
        ),
        (
            vec!["verify".into(), "/nonexistent.spec".into()],
            "cannot read the spec",
        ),
        (
            vec![
                "robustness".into(),
                "--network".into(),
                reference("merged_model_base.onnx"),
                "--data".into(),
                reference("Training_Data_Normalised.csv"),
            ],
            "12 inputs",
        ),
        (
            vec![
                "robustness".into(),
                "--network".into(),
                reference("merged_model_base.onnx"),
                "--data".into(),
                reference("dataset_inputs.idx"),
                "--reference".into(),
                "network".into(),
            ],
            "unsupported",
        ),
    ];
    for (args, needle) in cases {
        let out = samara().args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
    }
}

#[test]
fn check_and_export_vnnlib() {
    let out = samara().args(["check", SPEC]).output().unwrap();
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stdout).contains("property p3"));
    let dir = tempfile::tempdir().unwrap();
    // (Only p1: exporting every property without --network skips the relational P5
    // instances, which now fails with exit 1 instead of a silent exit 0.)
    let out = samara()
        .args(["export-vnnlib", SPEC, "--property", "p1", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = std::fs::read_to_string(dir.path().join("p1.vnnlib")).unwrap();
    assert!(text.contains("(declare-const X_5 Real)") && text.contains("(assert (or"));
    // Relational P5 instances: written over the stacked (doubled) network, ONNX included.
    let d2 = tempfile::tempdir().unwrap();
    let out = samara()
        .args([
            "export-vnnlib",
            SPEC,
            "--split-disjuncts",
            "--param",
            "eps=0.001",
            "--network",
        ])
        .arg(format!("f={}", reference("base_model_norm.onnx")))
        .arg("--dataset")
        .arg(format!(
            "train={}",
            reference("Training_Data_Normalised.csv")
        ))
        .arg("--out")
        .arg(d2.path())
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stacked = samara_nn::onnx::load(d2.path().join("fx2.onnx")).unwrap();
    assert_eq!((stacked.n_inputs(), stacked.n_outputs()), (12, 2));
    assert!(d2.path().join("p5_lipschitz_0__0.vnnlib").exists());
    assert!(d2.path().join("p1_0.vnnlib").exists());
    let bad_dir = tempfile::tempdir().unwrap();
    let bad = bad_dir.path().join("bad.spec");
    std::fs::write(&bad, "network f(a) -> (b)\nproperty p: aa >= 1 => b >= 0\n").unwrap();
    let out = samara().arg("check").arg(&bad).output().unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("bad.spec:2:13") && err.contains("did you mean `a`?"),
        "{err}"
    );
}

/// Issue 35 item 9. Above the critical value 45.91 of P1 on the naive network (the
/// largest x + y of the declared domain, 41.714716998 + 4.19723352, by hand from the
/// spec's domain) no domain point meets the premise `y >= -x + ystar`: the proof is
/// vacuous and says so; below it the premise is met and the report is not vacuous. A
/// value outside the declared range of `ystar` ([0, 100]) is refused with exit 2 naming
/// the parameter, the range and the spec line.
#[test]
fn empty_premises_are_vacuous_and_out_of_range_parameters_refused() {
    let net = format!("f={}", reference("base_model_norm.onnx"));
    let verify = |ystar: &str, property: &str| {
        let out = samara()
            .args([
                "verify",
                SPEC,
                "--property",
                property,
                "--json",
                "--network",
            ])
            .arg(&net)
            .arg("--param")
            .arg(format!("ystar={ystar}"))
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr).to_string();
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap_or_default();
        (out.status.code(), v, stderr)
    };
    let (code, v, err) = verify("50", "p1");
    assert_eq!(code, Some(0), "{err}");
    assert_eq!(v[0]["verdict"], "proved");
    assert_eq!(v[0]["vacuous"], true, "{v}");
    assert!(err.contains("vacuously"), "{err}");
    // P2 (y <= -x - ystar) at ystar = 50 is empty too: y + x >= -41.68140527 + 0.482420778.
    let (_, v, _) = verify("50", "p2");
    assert_eq!(v[0]["vacuous"], true, "{v}");
    // At ystar = 2 P2's premise is met (e.g. x = 1, y = -10): not vacuous, whatever
    // the verdict.
    let (_, v, _) = verify("2", "p2");
    assert_eq!(v[0]["vacuous"], false, "{v}");
    for bad in ["1000", "-0.5", "100.0001"] {
        let (code, _, err) = verify(bad, "p1");
        assert_eq!(code, Some(2), "ystar={bad}: {err}");
        assert!(
            err.contains("`ystar`")
                && err.contains("[0, 100]")
                && err.contains("alsomitra.spec:17")
                && err.contains(bad),
            "{err}"
        );
    }
    // The ends of the range are in it.
    let (code, _, err) = verify("100", "p1");
    assert_eq!(code, Some(0), "{err}");
}

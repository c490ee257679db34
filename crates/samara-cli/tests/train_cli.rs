//! `samara train`: JSON metrics, a loadable ONNX file, bit-identical reruns, and input
//! errors (empty or ragged CSV, bad method) with exit code 2.

use std::process::Command;

fn samara() -> Command {
    Command::new(env!("CARGO_BIN_EXE_samara"))
}

const DATA: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../../shared/reference/Training_Data.csv"
);

#[test]
fn trains_exports_and_flies() {
    let dir = tempfile::tempdir().unwrap();
    let net = dir.path().join("net.onnx");
    let out = samara()
        .args([
            "train",
            "--data",
            DATA,
            "--method",
            "adversarial",
            "--epochs",
            "100",
            "--json",
            "--out",
        ])
        .arg(&net)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let m: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert!(m["r2"].as_f64().unwrap() > 0.5, "{m}");
    assert!(dir.path().join("net.log.csv").exists());
    let first = std::fs::read(&net).unwrap();
    let again = samara()
        .args([
            "train",
            "--data",
            DATA,
            "--method",
            "adversarial",
            "--epochs",
            "100",
            "--out",
        ])
        .arg(&net)
        .output()
        .unwrap();
    assert!(again.status.success());
    assert_eq!(
        std::fs::read(&net).unwrap(),
        first,
        "same seed, same data: identical file"
    );
    let sim = samara()
        .args(["simulate", "--controller"])
        .arg(&net)
        .arg("--out")
        .arg(dir.path().join("sim"))
        .output()
        .unwrap();
    assert!(
        sim.status.success(),
        "{}",
        String::from_utf8_lossy(&sim.stderr)
    );
}

#[test]
fn bad_data_and_flags_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let cases: Vec<(&str, &str, Vec<&str>)> = vec![
        ("empty.csv", "", vec![]),
        ("ragged.csv", "1,2,3,4,5,6,7\n1,2,3\n", vec![]),
        (
            "good.csv",
            "1,2,3,4,5,6,7\n2,3,4,5,6,7,8\n",
            vec!["--method", "magic"],
        ),
        (
            "good2.csv",
            "1,2,3,4,5,6,7\n2,3,4,5,6,7,8\n",
            vec!["--arch", "6,x,1"],
        ),
    ];
    let needles = ["no data rows", "ragged", "magic", "--arch"];
    for ((name, body, extra), needle) in cases.into_iter().zip(needles) {
        let p = dir.path().join(name);
        std::fs::write(&p, body).unwrap();
        let out = samara()
            .args(["train", "--data"])
            .arg(&p)
            .args(&extra)
            .arg("--out")
            .arg(dir.path().join("n.onnx"))
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{name}: {err}");
        assert!(err.contains(needle), "{name}: {err}");
    }
    assert!(!dir.path().join("n.onnx").exists());
}

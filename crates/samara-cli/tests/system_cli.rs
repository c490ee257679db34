//! `samara simulate --system`: a shipped system file flown under a published network,
//! and the input errors (exit 2, message with the place, nothing left behind).

use std::path::{Path, PathBuf};

mod support;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn net() -> PathBuf {
    support::reference("base_model_denorm.onnx")
}

fn run(args: &[&str]) -> (i32, String, String) {
    let o = support::samara().args(args).output().unwrap();
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
fn alsomitra_system_file_runs_and_checks_its_goal() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let sys = repo().join("examples/archcomp/alsomitra_reduced.sys");
    let (code, stdout, stderr) = run(&[
        "simulate",
        "--system",
        sys.to_str().unwrap(),
        "--controller",
        net().to_str().unwrap(),
        "--samples",
        "5",
        "--out",
        out.to_str().unwrap(),
        "--json",
    ]);
    assert!(code == 0 || code == 1, "{stderr}");
    let v: serde_json::Value = serde_json::from_str(stdout.trim()).unwrap();
    assert_eq!(v["starts"], 5);
    // Exit 1 exactly when a flight violated the goal.
    assert_eq!(code == 1, !v["violations"].as_array().unwrap().is_empty());
    let csv = std::fs::read_to_string(out.join("trajectories.csv")).unwrap();
    // 5 starts x (40 periods x 10 points + 1) rows + header.
    assert_eq!(csv.lines().count(), 5 * 401 + 1);
}

#[test]
fn bad_system_inputs_exit_2_and_leave_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.sys");
    std::fs::write(&bad, "state x\ninput u\nx' = y + u\nperiod 1\nhorizon 2\n").unwrap();
    let tora = repo().join("examples/archcomp/tora.sys");
    let out = dir.path().join("o");
    for (sys, needle) in [
        (bad.to_str().unwrap(), "bad.sys:3:6"),
        (tora.to_str().unwrap(), "observes 4 values"),
        ("/nonexistent/x.sys", "cannot read"),
    ] {
        let (code, _, stderr) = run(&[
            "simulate",
            "--system",
            sys,
            "--controller",
            net().to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(code, 2, "{sys}: {stderr}");
        assert!(stderr.contains(needle), "{sys}: {stderr}");
        assert!(!out.exists(), "{sys}: output folder left behind");
    }
}

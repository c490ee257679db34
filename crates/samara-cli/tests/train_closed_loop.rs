//! `samara train --method closed-loop` (issue 18 item 2): the rounds in --json, the log,
//! the rounds figure, a network `samara reach` proves, and bad flags refused before
//! anything is written.

use crate::support;
use support::samara;

const SPEC: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../models/alsomitra/alsomitra.spec"
);

/// The published training data (fails naming the file when it is missing).
fn data() -> String {
    support::reference_str("Training_Data.csv")
}

#[test]
fn closed_loop_training_reports_its_rounds_and_reach_proves_the_network() {
    let dir = tempfile::tempdir().unwrap();
    let net = dir.path().join("cl.onnx");
    let out = samara()
        .args([
            "train",
            "--data",
            &data(),
            "--method",
            "closed-loop",
            "--json",
            "--spec",
            SPEC,
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
    // The shipped spec's loop is the published case (issue 12).
    assert_eq!(
        m["goal"],
        serde_json::json!({"ystar": 2.0, "from": null, "horizon": 20.0,
            "y0": [0.1 / 0.07, 0.3 / 0.07], "model": "reduced", "clip": [0.181, 0.193]})
    );
    assert_eq!(m["verdict"], "proved", "{m}");
    assert_eq!(m["proved"], true);
    assert!(m["r2"].as_f64().unwrap() >= 0.9, "{m}");
    let rounds = m["rounds"].as_array().unwrap();
    assert!(!rounds.is_empty());
    for k in [
        "loss",
        "r2",
        "verdict",
        "enclosure",
        "seconds",
        "starts",
        "added",
    ] {
        assert!(!rounds[0][k].is_null(), "round field {k}: {m}");
    }
    assert_eq!(rounds.last().unwrap()["verdict"], "proved");
    for f in ["cl.log.csv", "cl.rounds.png", "cl.rounds.svg"] {
        assert!(dir.path().join(f).exists(), "{f}");
    }
    let log = std::fs::read_to_string(dir.path().join("cl.log.csv")).unwrap();
    assert!(log.starts_with("round,steps,loss,mse,penalty,r2,starts,verdict"));
    assert_eq!(log.lines().count(), rounds.len() + 1);
    // samara reach, with its own default budget, proves the written network.
    let r = samara()
        .args(["reach", "--goal-ystar", "2", "--json", "--network"])
        .arg(&net)
        .arg("--out")
        .arg(dir.path().join("reach"))
        .output()
        .unwrap();
    let rj: serde_json::Value = serde_json::from_slice(&r.stdout).unwrap();
    assert_eq!(rj["verdict"], "proved", "{rj}");
    assert!(r.status.success());
}

#[test]
fn bad_closed_loop_flags_are_refused_before_writing() {
    let dir = tempfile::tempdir().unwrap();
    // A spec whose loop flies the full model, which closed-loop training does not fly.
    let full = std::fs::read_to_string(SPEC)
        .unwrap()
        .replace("model reduced, period 0.5", "model full, period 0.5");
    let full_spec = dir.path().join("full.spec").display().to_string();
    std::fs::write(&full_spec, full).unwrap();
    for (flags, needle) in [
        (vec!["--margin", "3"], "--margin"),
        (vec!["--goal-ystar", "0"], "--goal-ystar"),
        (vec!["--y0", "4:2"], "--y0"),
        (vec!["--rounds", "0"], "--rounds"),
        (vec!["--data-weight=-1"], "--data-weight"),
        (vec!["--goal-from", "25"], "--goal-from"),
        (
            vec!["--spec", SPEC, "--y0", "2:3"],
            "with --spec, closed-loop training flies the spec's loop",
        ),
        (
            vec!["--spec", SPEC, "--loop", "nope"],
            "states no loop `nope`",
        ),
        (vec!["--loop", "published"], "--spec"),
        (
            vec!["--spec", &full_spec],
            "loop `published`: closed-loop training flies the reduced model",
        ),
    ] {
        let sub = dir.path().join("new");
        let out = samara()
            .args([
                "train",
                "--data",
                &data(),
                "--method",
                "closed-loop",
                "--out",
            ])
            .arg(sub.join("cl.onnx"))
            .args(&flags)
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{flags:?}: {err}");
        assert!(err.contains(needle), "{flags:?}: {err}");
        assert!(!sub.exists(), "{flags:?} left {}", sub.display());
    }
}

//! End-to-end checks of `samara simulate`: the published data reproduced through the
//! binary, and bad inputs rejected with exit code 2 and no files left behind.

use std::path::Path;

use crate::support;
use support::{reference, samara};

fn reference_rows() -> Vec<Vec<f64>> {
    std::fs::read_to_string(reference("Training_Data.csv"))
        .unwrap()
        .lines()
        .filter(|l| !l.is_empty())
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect()
}

fn written_rows(dir: &Path) -> Vec<Vec<f64>> {
    let text = std::fs::read_to_string(dir.join("training_data.csv")).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next().unwrap(), "v_xp,v_yp,omega,theta,x,y,ex");
    lines
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect()
}

#[test]
fn default_run_reproduces_published_training_data() {
    let dir = tempfile::tempdir().unwrap();
    let out = samara()
        .args(["simulate", "--out"])
        .arg(dir.path())
        .arg("--json")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(summary["starts"].as_array().unwrap().len(), 9);
    let (a, b) = (written_rows(dir.path()), reference_rows());
    assert_eq!(a.len(), 360);
    let dev = a
        .iter()
        .zip(&b)
        .flat_map(|(r, s)| r.iter().zip(s).map(|(x, y)| (x - y).abs()))
        .fold(0.0, f64::max);
    assert!(dev <= 1e-12, "max deviation {dev:e}");
    for f in [
        "trajectories.csv",
        "normalisation.csv",
        "trajectories.png",
        "trajectories.svg",
    ] {
        assert!(dir.path().join(f).exists(), "{f} missing");
    }
    // normalisation.csv: min and range of the written data, checked independently here.
    let nc = std::fs::read_to_string(dir.path().join("normalisation.csv")).unwrap();
    let rows: Vec<Vec<f64>> = nc
        .lines()
        .skip(1)
        .map(|l| l.split(',').map(|v| v.parse().unwrap()).collect())
        .collect();
    for j in 0..7 {
        let lo = a.iter().map(|r| r[j]).fold(f64::INFINITY, f64::min);
        let hi = a.iter().map(|r| r[j]).fold(f64::NEG_INFINITY, f64::max);
        assert_eq!(rows[0][j], lo);
        assert_eq!(rows[1][j], hi - lo);
    }
}

fn assert_usage_error(args: &[&str], needle: &str) {
    let dir = tempfile::tempdir().unwrap();
    let out_dir = dir.path().join("out");
    let out = samara()
        .args(args)
        .arg("--out")
        .arg(&out_dir)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "args {args:?}: {err}");
    assert!(
        err.contains(needle),
        "args {args:?}: message {err:?} lacks {needle:?}"
    );
    assert!(
        !out_dir.exists(),
        "args {args:?} left an output directory behind"
    );
}

#[test]
fn bad_inputs_exit_2_with_a_message_and_no_files() {
    assert_usage_error(
        &["simulate", "--controller", "constant:0.2"],
        "outside the allowed range",
    );
    assert_usage_error(
        &["simulate", "--controller", "constant:abc"],
        "not a number",
    );
    assert_usage_error(&["simulate", "--horizon", "0"], "horizon must be positive");
    assert_usage_error(&["simulate", "--horizon", "-3"], "horizon");
    assert_usage_error(&["simulate", "--period", "0"], "period must be positive");
    assert_usage_error(&["simulate", "--horizon", "20.3"], "multiple of the period");
    assert_usage_error(
        &["simulate", "--model", "plate7"],
        "choose one of plate6, reduced, full",
    );
    assert_usage_error(&["simulate", "--y0", "1:2"], "START:END:COUNT");
    assert_usage_error(&["simulate", "--model", "reduced"], "filter state E");
}

#[test]
fn unwritable_output_directory_is_a_usage_error() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("a-file");
    std::fs::write(&file, b"x").unwrap();
    let out = samara()
        .args(["simulate", "--out"])
        .arg(file.join("sub"))
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("writable --out"));
}

#[test]
fn network_controller_flies_and_clips() {
    let dir = tempfile::tempdir().unwrap();
    let net = reference("base_model_denorm.onnx");
    let out = samara()
        .args(["simulate", "--controller"])
        .arg(&net)
        .arg("--out")
        .arg(dir.path())
        .arg("--json")
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let rows = written_rows(dir.path());
    assert_eq!(rows.len(), 360);
    // Every applied ex is inside the clip range, and the naive network saturates at 0.193
    // within its first steps (docs/model.md section 6): the clip binds there.
    assert!(rows.iter().all(|r| (0.181..=0.193).contains(&r[6])));
    assert!((0..9).any(|k| rows[k * 40..k * 40 + 4].iter().any(|r| r[6] == 0.193)));
    // Unclipped, the same network can leave the range.
    let dir2 = tempfile::tempdir().unwrap();
    let out = samara()
        .args(["simulate", "--no-clip", "--controller"])
        .arg(&net)
        .arg("--out")
        .arg(dir2.path())
        .output()
        .unwrap();
    assert!(out.status.success());
    let raw = written_rows(dir2.path());
    assert!(
        raw.iter().any(|r| r[6] > 0.193),
        "the unclipped network never exceeds 0.193"
    );
}

#[test]
fn wrong_network_shape_and_missing_file_exit_2() {
    assert_usage_error(
        &[
            "simulate",
            "--controller",
            reference("merged_model_base.onnx").to_str().unwrap(),
        ],
        "12 inputs",
    );
    assert_usage_error(
        &["simulate", "--controller", "/nonexistent/net.onnx"],
        "no such file",
    );
}

//! Issue 35, item 10: a network in normalised units (`base_model_norm.onnx`: inputs in
//! [0, 1], a normalised output; the reference README) flown where the raw-unit
//! controller is expected is warned about, on stderr and in the JSON's `warnings`, by
//! `samara simulate` and `samara reach`; the raw-unit file (`base_model_denorm.onnx`,
//! the same network with its normalisation layers) is not.

use serde_json::Value;
use std::ffi::OsStr;

use crate::support;
use support::{reference, samara};

fn run(args: &[&OsStr]) -> (Option<i32>, Value, String) {
    let o = samara().args(args).output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr).into_owned();
    let v = serde_json::from_slice(&o.stdout)
        .unwrap_or_else(|e| panic!("{e}: {}{err}", String::from_utf8_lossy(&o.stdout)));
    (o.status.code(), v, err)
}

fn check(warned: bool, v: &Value, err: &str) {
    let w = v["warnings"].as_array().unwrap_or_else(|| panic!("{v}"));
    if warned {
        assert_eq!(w.len(), 1, "{v}");
        let w = w[0].as_str().unwrap();
        for needle in [
            "base_model_norm.onnx",
            "outside [0.181, 0.193]",
            "normalised units",
            "_denorm",
        ] {
            assert!(w.contains(needle), "{needle:?} not in {w}");
        }
        assert!(err.contains(&format!("warning: {w}")), "{err}");
    } else {
        assert!(w.is_empty(), "{v}");
        assert!(!err.contains("warning"), "{err}");
    }
}

#[test]
fn simulate_warns_of_a_normalised_network() {
    let dir = tempfile::tempdir().unwrap();
    for (name, warned) in [
        ("base_model_norm.onnx", true),
        ("base_model_denorm.onnx", false),
    ] {
        let net = reference(name);
        let out = dir.path().join(name);
        let (code, v, err) = run(&[
            "simulate".as_ref(),
            "--controller".as_ref(),
            net.as_os_str(),
            "--horizon".as_ref(),
            "2".as_ref(),
            "--no-plot".as_ref(),
            "--json".as_ref(),
            "--out".as_ref(),
            out.as_os_str(),
        ]);
        assert_eq!(code, Some(0), "{name}: {err}");
        check(warned, &v, &err);
    }
}

#[test]
fn reach_warns_of_a_normalised_network() {
    let dir = tempfile::tempdir().unwrap();
    for (name, warned) in [
        ("base_model_norm.onnx", true),
        ("base_model_denorm.onnx", false),
    ] {
        let net = reference(name);
        let out = dir.path().join(name);
        let (_, v, err) = run(&[
            "reach".as_ref(),
            "--network".as_ref(),
            net.as_os_str(),
            "--horizon".as_ref(),
            "0.5".as_ref(),
            "--threads".as_ref(),
            "1".as_ref(),
            "--json".as_ref(),
            "--out".as_ref(),
            out.as_os_str(),
        ]);
        check(warned, &v, &err);
        let r: Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("reach.json")).unwrap())
                .unwrap();
        assert_eq!(r["warnings"], v["warnings"]);
    }
}

//! `samara verify-vnnlib --result` and `samara vnncomp` on ACAS Xu networks and
//! properties from VNN-COMP 2021 (fixtures in samara-verify's tests/data/acasxu; expected
//! verdicts: the competition's consensus, see its README). The result files are checked
//! in the competition's exact format, and a `sat` assignment is re-evaluated here through
//! `samara_nn` against the property.

use samara_spec::normal::Var;
use std::path::{Path, PathBuf};

use crate::support;
use support::samara;

fn data() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../samara-verify/tests/data/acasxu")
}

fn net(n: &str) -> PathBuf {
    data().join(format!("ACASXU_run2a_{n}_batch_2000.onnx"))
}

fn prop(p: &str) -> PathBuf {
    data().join(format!("{p}.vnnlib"))
}

fn run(args: &[&std::ffi::OsStr]) -> (Option<i32>, String, String) {
    let o = samara().args(args).output().unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// Parse a `sat` result file's assignment: every line `((X_0 v)`, ` (X_1 v)`, ...,
/// ` (Y_m v))`; returns the values by name, in order.
fn parse_assignment(text: &str) -> Vec<(String, f64)> {
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("sat"), "{text}");
    let body: Vec<&str> = lines.collect();
    assert!(!body.is_empty(), "{text}");
    let mut out = Vec::new();
    for (k, l) in body.iter().enumerate() {
        let open = if k == 0 { "((" } else { " (" };
        let close = if k + 1 == body.len() { "))" } else { ")" };
        assert!(
            l.starts_with(open) && l.ends_with(close),
            "line {k}: {l:?} in {text}"
        );
        let inner = &l[open.len()..l.len() - close.len()];
        let (name, v) = inner.split_once(' ').expect("`NAME value`");
        out.push((
            name.to_string(),
            v.parse::<f64>().expect("a decimal number"),
        ));
    }
    out
}

#[test]
fn result_files_in_the_competition_format() {
    let dir = tempfile::tempdir().unwrap();
    for (n, p, want) in [("1_1", "prop_1", "unsat"), ("1_2", "prop_2", "sat")] {
        let res = dir.path().join(format!("{n}_{p}.txt"));
        let (code, out, err) = run(&[
            "verify-vnnlib".as_ref(),
            "--network".as_ref(),
            net(n).as_os_str(),
            "--property".as_ref(),
            prop(p).as_os_str(),
            "--timeout".as_ref(),
            "120".as_ref(),
            "--result".as_ref(),
            res.as_os_str(),
        ]);
        assert_eq!(
            code,
            Some(if want == "unsat" { 0 } else { 1 }),
            "{out}{err}"
        );
        assert!(out.starts_with(want), "{out}");
        let text = std::fs::read_to_string(&res).unwrap();
        if want == "unsat" {
            assert_eq!(text, "unsat\n");
            continue;
        }
        // The file's assignment: X_0..X_4 then Y_0..Y_4.
        let a = parse_assignment(&text);
        let names: Vec<&str> = a.iter().map(|v| v.0.as_str()).collect();
        assert_eq!(
            names,
            ["X_0", "X_1", "X_2", "X_3", "X_4", "Y_0", "Y_1", "Y_2", "Y_3", "Y_4"]
        );
        let x: Vec<f64> = a[..5].iter().map(|v| v.1).collect();
        let y_file: Vec<f64> = a[5..].iter().map(|v| v.1).collect();
        // Re-evaluated here: the network's outputs at x are the file's, and (x, f(x))
        // satisfies every assertion of the property (its counterexample region).
        let network = samara_nn::onnx::load(net(n)).unwrap();
        let y = network.eval_f64(&x);
        assert_eq!(y, y_file, "the file's outputs are the f64 evaluation");
        let q = samara_spec::vnnlib::import(&std::fs::read_to_string(prop(p)).unwrap(), p, "f", p)
            .unwrap();
        for (i, (lo, hi)) in q.applications[0].input_box.iter().enumerate() {
            assert!(
                *lo <= x[i] && x[i] <= *hi,
                "X_{i} = {} outside [{lo}, {hi}]",
                x[i]
            );
        }
        let value = |v: Var| match v {
            Var::Input { index, .. } => x[index],
            Var::Output { index, .. } => y[index],
            Var::Free(_) => unreachable!(),
        };
        assert!(
            q.region
                .iter()
                .any(|conj| conj.iter().all(|c| c.holds(value, 0.0))),
            "{x:?} -> {y:?} does not satisfy {p}"
        );
    }
}

#[test]
fn vnncomp_runs_a_benchmark_csv() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("instances.csv");
    std::fs::write(
        &csv,
        "ACASXU_run2a_1_1_batch_2000.onnx,prop_1.vnnlib,116\n\
         ACASXU_run2a_1_2_batch_2000.onnx,prop_1.vnnlib,116\n\
         ACASXU_run2a_1_1_batch_2000.onnx,prop_2.vnnlib,116\n\
         ACASXU_run2a_1_2_batch_2000.onnx,prop_2.vnnlib,116\n",
    )
    .unwrap();
    let out = dir.path().join("results.csv");
    let (code, stdout, err) = run(&[
        "vnncomp".as_ref(),
        csv.as_os_str(),
        "--root".as_ref(),
        data().as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
        "--json".as_ref(),
    ]);
    assert_eq!(code, Some(0), "{stdout}{err}");
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    let got: Vec<&str> = v["instances"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["result"].as_str().unwrap())
        .collect();
    assert_eq!(got, ["unsat", "unsat", "unsat", "sat"]);
    assert_eq!(v["counts"]["unsat"], 3);
    assert_eq!(v["counts"]["sat"], 1);
    let text = std::fs::read_to_string(&out).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines[0], "onnx,vnnlib,timeout,result,seconds,engine,detail");
    assert_eq!(lines.len(), 5, "{text}");
    assert!(lines[4].starts_with("ACASXU_run2a_1_2_batch_2000.onnx,prop_2.vnnlib,116,sat,"));
    // --out onto an input is refused before anything runs.
    let (code, _, err) = run(&[
        "vnncomp".as_ref(),
        csv.as_os_str(),
        "--root".as_ref(),
        data().as_os_str(),
        "--out".as_ref(),
        csv.as_os_str(),
    ]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("--out") && err.contains("overwrite"), "{err}");
    // A bad CSV line is an input error naming the line.
    std::fs::write(
        &csv,
        "ACASXU_run2a_1_1_batch_2000.onnx,prop_1.vnnlib,116\nx.onnx,p.vnnlib\n",
    )
    .unwrap();
    let (code, _, err) = run(&[
        "vnncomp".as_ref(),
        csv.as_os_str(),
        "--root".as_ref(),
        data().as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("instances.csv:2:"), "{err}");
}

#[test]
fn bad_vnnlib_and_unsupported_operators_are_input_errors() {
    let dir = tempfile::tempdir().unwrap();
    // A syntax error on line 3.
    let bad = dir.path().join("bad.vnnlib");
    std::fs::write(
        &bad,
        "(declare-const X_0 Real)\n(declare-const Y_0 Real)\n(assert (<= X_0 0.5)\n",
    )
    .unwrap();
    let res = dir.path().join("r.txt");
    let (code, out, err) = run(&[
        "verify-vnnlib".as_ref(),
        "--network".as_ref(),
        net("1_1").as_os_str(),
        "--property".as_ref(),
        bad.as_os_str(),
        "--result".as_ref(),
        res.as_os_str(),
    ]);
    assert_eq!(code, Some(2), "{out}{err}");
    assert!(err.contains("bad.vnnlib:3:"), "{err}");
    assert!(!res.exists(), "no result file on an input error");
    // The ACAS Xu network with its ReLUs renamed to Selu (same length: the protobuf stays
    // valid): the operator is named.
    let bytes = std::fs::read(net("1_1")).unwrap();
    let mut patched = bytes.clone();
    for i in 0..patched.len().saturating_sub(4) {
        if &patched[i..i + 4] == b"Relu" {
            patched[i..i + 4].copy_from_slice(b"Selu");
        }
    }
    assert_ne!(bytes, patched);
    let onnx = dir.path().join("selu.onnx");
    std::fs::write(&onnx, &patched).unwrap();
    let (code, out, err) = run(&[
        "verify-vnnlib".as_ref(),
        "--network".as_ref(),
        onnx.as_os_str(),
        "--property".as_ref(),
        prop("prop_1").as_os_str(),
    ]);
    assert_eq!(code, Some(2), "{out}{err}");
    assert!(err.contains("`Selu`"), "{err}");
    // In a benchmark CSV: the line and the operator.
    let csv = dir.path().join("i.csv");
    std::fs::write(
        &csv,
        format!("{},{},10\n", onnx.display(), prop("prop_1").display()),
    )
    .unwrap();
    let (code, _, err) = run(&[
        "vnncomp".as_ref(),
        csv.as_os_str(),
        "--out".as_ref(),
        dir.path().join("o.csv").as_os_str(),
    ]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("i.csv:1") && err.contains("`Selu`"), "{err}");
    // The CSV line is named once, not once per layer of the error's path.
    assert_eq!(err.matches("i.csv:1").count(), 1, "{err}");
}

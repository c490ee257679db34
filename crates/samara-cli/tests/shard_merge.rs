//! `--shard I/N` and `samara merge`: the shards of a run, merged, give what one process
//! gives (robustness over the published training points; vnncomp on ACAS Xu fixtures);
//! bad `--shard` values and missing or duplicate shards are usage errors (exit 2).

use serde_json::Value;
use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::Command;

fn run(args: &[&OsStr]) -> (Option<i32>, String, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_samara"))
        .args(args)
        .output()
        .unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

fn reference() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/reference")
}

fn acasxu() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../samara-verify/tests/data/acasxu")
}

/// Drop the fields that legitimately differ between runs (wall times, the --out path).
fn strip(mut v: Value) -> Value {
    if let Some(m) = v.as_object_mut() {
        for k in ["seconds", "total_seconds", "out"] {
            m.remove(k);
        }
    }
    if let Some(rows) = v.get_mut("instances").and_then(Value::as_array_mut) {
        for r in rows {
            let r = r.as_object_mut().unwrap();
            r.remove("seconds");
            // Which counterexample a parallel search finds first varies from run to run
            // (sharded or not); that there is one does not.
            let cx = r["counterexample"].is_object();
            r.insert("counterexample".into(), cx.into());
        }
    }
    v
}

#[test]
fn robustness_shards_merge_to_the_unsharded_result() {
    let r = reference();
    let (net, data) = (
        r.join("base_model_norm.onnx"),
        r.join("Training_Data_Normalised.csv"),
    );
    if !data.exists() {
        eprintln!("skipped: {} not found", data.display());
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let common: Vec<&OsStr> = vec![
        "robustness".as_ref(),
        "--network".as_ref(),
        net.as_os_str(),
        "--data".as_ref(),
        data.as_os_str(),
        "--eps".as_ref(),
        "1e-4,1e-3".as_ref(),
        "--lipschitz".as_ref(),
        "1e-5,1e-3,1e-2".as_ref(),
    ];
    let full_csv = dir.path().join("full.csv");
    let mut args = common.clone();
    args.extend(["--json".as_ref(), "--out".as_ref(), full_csv.as_os_str()]);
    let (code, full, err) = run(&args);
    assert_eq!(code, Some(0), "{full}{err}");
    let mut files = Vec::new();
    for i in [2, 0, 1] {
        let f = dir.path().join(format!("s{i}.json"));
        let mut args = common.clone();
        let s = format!("{i}/3");
        args.extend([
            "--shard".as_ref(),
            s.as_ref(),
            "--out".as_ref(),
            f.as_os_str(),
        ]);
        let (code, o, err) = run(&args);
        assert_eq!(code, Some(0), "{o}{err}");
        files.push(f);
    }
    let merged_csv = dir.path().join("merged.csv");
    let mut args: Vec<&OsStr> = vec!["merge".as_ref(), "robustness".as_ref()];
    args.extend(files.iter().map(|f| f.as_os_str()));
    args.extend(["--json".as_ref(), "--out".as_ref(), merged_csv.as_os_str()]);
    let (code, merged, err) = run(&args);
    assert_eq!(code, Some(0), "{merged}{err}");
    let (a, b): (Value, Value) = (
        serde_json::from_str(&full).unwrap(),
        serde_json::from_str(&merged).unwrap(),
    );
    assert_eq!(a["points"], 360);
    assert_eq!(strip(a), strip(b));
    // The per-point CSV, digit for digit.
    assert_eq!(
        std::fs::read_to_string(&full_csv).unwrap(),
        std::fs::read_to_string(&merged_csv).unwrap()
    );
    // A missing shard and a duplicate one are named (exit 2).
    let (code, _, err) = run(&[
        "merge".as_ref(),
        "robustness".as_ref(),
        files[1].as_os_str(),
        files[2].as_os_str(),
    ]);
    assert_eq!(code, Some(2));
    assert!(err.contains("missing shard(s): 2/3"), "{err}");
    let (code, _, err) = run(&[
        "merge".as_ref(),
        "robustness".as_ref(),
        files[0].as_os_str(),
        files[1].as_os_str(),
        files[1].as_os_str(),
        files[2].as_os_str(),
    ]);
    assert_eq!(code, Some(2));
    assert!(err.contains("duplicate shard(s): 0/3"), "{err}");
    // A shard of another run (other radii) is refused.
    let other = dir.path().join("other.json");
    let mut args = common.clone();
    args[6] = "1e-2".as_ref();
    args.extend([
        "--shard".as_ref(),
        "0/3".as_ref(),
        "--out".as_ref(),
        other.as_os_str(),
    ]);
    let (code, o, err) = run(&args);
    assert_eq!(code, Some(0), "{o}{err}");
    let (code, _, err) = run(&[
        "merge".as_ref(),
        "robustness".as_ref(),
        other.as_os_str(),
        files[0].as_os_str(),
        files[2].as_os_str(),
    ]);
    assert_eq!(code, Some(2));
    assert!(err.contains("different runs"), "{err}");
}

#[test]
fn vnncomp_shards_merge_to_the_unsharded_result() {
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
    let root = acasxu();
    let vnncomp = |extra: &[&OsStr]| {
        let mut args: Vec<&OsStr> = vec![
            "vnncomp".as_ref(),
            csv.as_os_str(),
            "--root".as_ref(),
            root.as_os_str(),
        ];
        args.extend(extra);
        run(&args)
    };
    let full_csv = dir.path().join("full.csv");
    let (code, full, err) = vnncomp(&["--out".as_ref(), full_csv.as_os_str(), "--json".as_ref()]);
    assert_eq!(code, Some(0), "{full}{err}");
    let shards: Vec<PathBuf> = (0..2)
        .map(|i| dir.path().join(format!("part-{i}.json")))
        .collect();
    for (i, f) in shards.iter().enumerate() {
        let s = format!("{i}/2");
        let (code, o, err) = vnncomp(&[
            "--shard".as_ref(),
            s.as_ref(),
            "--out".as_ref(),
            f.as_os_str(),
        ]);
        assert_eq!(code, Some(0), "{o}{err}");
    }
    let merged_csv = dir.path().join("merged.csv");
    let (code, merged, err) = run(&[
        "merge".as_ref(),
        "vnncomp".as_ref(),
        shards[1].as_os_str(),
        shards[0].as_os_str(),
        "--out".as_ref(),
        merged_csv.as_os_str(),
        "--json".as_ref(),
    ]);
    assert_eq!(code, Some(0), "{merged}{err}");
    let (a, b): (Value, Value) = (
        serde_json::from_str(&full).unwrap(),
        serde_json::from_str(&merged).unwrap(),
    );
    assert_eq!(a["counts"]["unsat"], 3);
    // The merged rows are the shards' rows, digit for digit, in instance order.
    let mut parts = Vec::new();
    for f in &shards {
        let v: Value = serde_json::from_str(&std::fs::read_to_string(f).unwrap()).unwrap();
        for p in v["result"]["parts"].as_array().unwrap() {
            parts.push(serde_json::from_str::<Value>(p["row"].as_str().unwrap()).unwrap());
        }
    }
    assert_eq!(b["instances"].as_array().unwrap(), &parts);
    assert_eq!(strip(a), strip(b));
    // The results CSV: the same rows in instance order (the seconds column aside).
    let cols = |p: &Path| -> Vec<String> {
        std::fs::read_to_string(p)
            .unwrap()
            .lines()
            .map(|l| {
                // onnx, vnnlib, timeout, result, engine (not seconds; nor the detail,
                // which for sat says how the varying counterexample was checked).
                let f: Vec<&str> = l.split(',').collect();
                [f[0], f[1], f[2], f[3], f[5]].join(",")
            })
            .collect()
    };
    assert_eq!(cols(&full_csv), cols(&merged_csv));
    assert_eq!(cols(&merged_csv).len(), 5);
    // A missing shard is named (exit 2); the merge needs --out.
    let (code, _, err) = run(&[
        "merge".as_ref(),
        "vnncomp".as_ref(),
        shards[1].as_os_str(),
        "--out".as_ref(),
        merged_csv.as_os_str(),
    ]);
    assert_eq!(code, Some(2));
    assert!(err.contains("missing shard(s): 0/2"), "{err}");
    let (code, _, _) = run(&["merge".as_ref(), "vnncomp".as_ref(), shards[0].as_os_str()]);
    assert_eq!(code, Some(2));
}

#[test]
fn bad_shard_values_are_usage_errors() {
    let r = reference();
    let (net, data) = (r.join("base_model_norm.onnx"), r.join("x.csv"));
    for bad in ["3/3", "0/0", "-1/3", "1", "a/b", "1/"] {
        for cmd in ["robustness", "vnncomp"] {
            let args: Vec<&OsStr> = if cmd == "robustness" {
                vec![
                    cmd.as_ref(),
                    "--network".as_ref(),
                    net.as_os_str(),
                    "--data".as_ref(),
                    data.as_os_str(),
                    "--out".as_ref(),
                    "o.json".as_ref(),
                    "--shard".as_ref(),
                    bad.as_ref(),
                ]
            } else {
                vec![
                    cmd.as_ref(),
                    "i.csv".as_ref(),
                    "--out".as_ref(),
                    "o.json".as_ref(),
                    "--shard".as_ref(),
                    bad.as_ref(),
                ]
            };
            let (code, _, err) = run(&args);
            assert_eq!(code, Some(2), "{cmd} --shard {bad}: {err}");
            assert!(err.contains("--shard"), "{cmd} --shard {bad}: {err}");
        }
    }
    // --shard without --out.
    let (code, _, err) = run(&[
        "robustness".as_ref(),
        "--network".as_ref(),
        net.as_os_str(),
        "--data".as_ref(),
        data.as_os_str(),
        "--shard".as_ref(),
        "0/2".as_ref(),
    ]);
    assert_eq!(code, Some(2));
    assert!(err.contains("--shard needs --out"), "{err}");
}

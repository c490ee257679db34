//! `--shard I/N` and `samara merge`: the shards of a run, merged, give what one process
//! gives (robustness over the published training points; vnncomp on ACAS Xu fixtures;
//! reach on the published raw-unit controller, with the sub-box budget running out
//! during the refinement); bad `--shard` values and missing or duplicate shards are
//! usage errors (exit 2).

use serde_json::Value;
use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::Command;

use crate::support;
use support::reference;
use support::sealing::write_shard;

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
    let (net, data) = (
        reference("base_model_norm.onnx"),
        reference("Training_Data_Normalised.csv"),
    );
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
    // The merged rows are rebuilt from the shards' typed parts, digit for digit, in
    // instance order (no text copy is stored).
    let mut parts = Vec::new();
    for f in &shards {
        let v: Value = serde_json::from_str(&std::fs::read_to_string(f).unwrap()).unwrap();
        for p in v["result"]["parts"].as_array().unwrap() {
            assert!(p.get("csv").is_none() && p.get("row").is_none(), "{p}");
            parts.push(p.clone());
        }
    }
    let rows = b["instances"].as_array().unwrap();
    assert_eq!(rows.len(), parts.len());
    for (row, p) in rows.iter().zip(&parts) {
        for k in [
            "line", "onnx", "vnnlib", "timeout", "result", "seconds", "engine",
        ] {
            assert_eq!(row[k], p[k], "{k}: {row} vs {p}");
        }
    }
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
    let r = support::reference("base_model_norm.onnx");
    let r = r.parent().expect("a file in the reference folder");
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
    for bad in ["2/2", "1", "x/3"] {
        let (code, _, err) = run(&[
            "reach".as_ref(),
            "--network".as_ref(),
            net.as_os_str(),
            "--out".as_ref(),
            "o.json".as_ref(),
            "--shard".as_ref(),
            bad.as_ref(),
        ]);
        assert_eq!(code, Some(2), "reach --shard {bad}: {err}");
        assert!(err.contains("--shard"), "reach --shard {bad}: {err}");
    }
}

/// The published raw-unit controller (the network of the reach tests).
fn denorm_net() -> PathBuf {
    reference("base_model_denorm.onnx")
}

/// `samara reach --network NET ARGS... --threads 2` plus `extra`.
fn reach(net: &Path, args: &[&str], extra: &[&OsStr]) -> (Option<i32>, String, String) {
    let mut all: Vec<&OsStr> = vec!["reach".as_ref(), "--network".as_ref(), net.as_os_str()];
    all.extend(args.iter().map(OsStr::new));
    all.extend([OsStr::new("--threads"), OsStr::new("2")]);
    all.extend(extra);
    run(&all)
}

/// `reach --shard S --out FILE` with `args`; it must succeed. Returns its stdout.
fn reach_shard(net: &Path, args: &[&str], s: &str, file: &Path) -> String {
    let (c, o, e) = reach(
        net,
        args,
        &[
            "--shard".as_ref(),
            s.as_ref(),
            "--out".as_ref(),
            file.as_os_str(),
        ],
    );
    assert_eq!(c, Some(0), "shard {s}: {o}{e}");
    o
}

/// `reach.json` of a folder without its wall time.
fn reach_json(dir: &Path) -> Value {
    let text = std::fs::read_to_string(dir.join("reach.json")).unwrap();
    strip(serde_json::from_str(&text).unwrap())
}

/// Run `args` unsharded and as `n` shards (written in the order `order`, passed to the
/// merge in that order too), merge, and check the merge gives the one-process output:
/// reach.json (but `seconds`), the figures, the JSON summary and the exit code. Returns
/// the one-process reach.json.
fn sharded_equals_unsharded(
    args: &[&str],
    n: usize,
    order: &[usize],
    dir: &Path,
) -> (Value, Vec<PathBuf>) {
    std::fs::create_dir_all(dir).unwrap();
    let net = denorm_net();
    let full = dir.join("full");
    // Taylor-model runs shard the cells of their --grid and draw no figure.
    let taylor = args.contains(&"--grid");
    let word = if taylor { "cells" } else { "pieces" };
    let (code, summary, err) = reach(
        &net,
        args,
        &["--json".as_ref(), "--out".as_ref(), full.as_os_str()],
    );
    let files: Vec<PathBuf> = order
        .iter()
        .map(|i| {
            let f = dir.join(format!("part-{i}.json"));
            let s = format!("{i}/{n}");
            let o = reach_shard(&net, args, &s, &f);
            assert!(o.starts_with(&format!("shard {s}: {word}")), "{o}");
            f
        })
        .collect();
    let merged = dir.join("merged");
    let mut m: Vec<&OsStr> = vec!["merge".as_ref(), "reach".as_ref()];
    m.extend(files.iter().map(|f| f.as_os_str()));
    m.extend(["--json".as_ref(), "--out".as_ref(), merged.as_os_str()]);
    let (mcode, msummary, merr) = run(&m);
    assert_eq!(
        mcode, code,
        "merge: {msummary}{merr}\nunsharded: {summary}{err}"
    );
    let (mut a, mut b) = (reach_json(&full), reach_json(&merged));
    if taylor {
        // The result's own wall (one process) or compute (the shards' sum) time.
        for v in [&mut a, &mut b] {
            v["result"].as_object_mut().unwrap().remove("seconds");
        }
    }
    assert_eq!(a, b, "merged reach.json differs from the one-process one");
    assert_eq!(
        strip(serde_json::from_str(&summary).unwrap()),
        strip(serde_json::from_str(&msummary).unwrap())
    );
    for fig in ["reach.svg", "reach.png"].iter().filter(|_| !taylor) {
        assert!(
            std::fs::read(full.join(fig)).unwrap() == std::fs::read(merged.join(fig)).unwrap(),
            "{fig} differs"
        );
    }
    (a, files)
}

/// The height interval's 8 initial pieces, a goal window over the flight that the
/// sub-boxes crossing x + y = 2.45 leave undecided (so they are split), and a budget of 12
/// sub-boxes that runs out during the refinement: which sub-boxes are split depends on
/// the other shards' sub-boxes, and the merge replays it as one process does.
const BUDGETED: [&str; 10] = [
    "--y0",
    "2.0:2.2",
    "--horizon",
    "0.5",
    "--goal-ystar",
    "2.45",
    "--goal-from",
    "0",
    "--max-leaves",
    "12",
];

#[test]
fn reach_three_shards_merge_to_the_unsharded_result() {
    let dir = tempfile::tempdir().unwrap();
    let (r, files) = sharded_equals_unsharded(&BUDGETED, 3, &[2, 0, 1], dir.path());
    // A sampled flight leaves the band: the counterexample is a sampled start, the same
    // in every shard.
    assert_eq!(r["verdict"]["verdict"], "violated", "{}", r["verdict"]);
    assert!(r["verdict"]["counterexample"]["initial"].is_array());
    // The budget was spent on split sub-boxes (more than the 8 pieces, at most 12).
    assert_eq!(r["subproblems"], 12);
    assert_eq!(r["leaves"].as_array().unwrap().len(), 12);
    // Without the halves shard 1/3 flew, the run cannot be replayed: refused, naming the
    // first half it needs.
    let f1 = &files[2];
    let mut v: Value = serde_json::from_str(&std::fs::read_to_string(f1).unwrap()).unwrap();
    v["result"]["subboxes"]
        .as_array_mut()
        .unwrap()
        .retain(|b| b["key"].as_str().unwrap().ends_with(':'));
    write_shard(f1, v, true);
    let out = dir.path().join("cut");
    let mut m: Vec<&OsStr> = vec!["merge".as_ref(), "reach".as_ref()];
    m.extend(files.iter().map(|f| f.as_os_str()));
    m.extend(["--out".as_ref(), out.as_os_str()]);
    let (code, o, err) = run(&m);
    assert_eq!(code, Some(2), "{o}{err}");
    assert!(
        err.contains("which shard 1/3") && err.contains("cannot be merged exactly"),
        "{err}"
    );
    assert!(!out.exists());
}

#[test]
fn reach_two_shards_merge_to_the_unsharded_result() {
    let dir = tempfile::tempdir().unwrap();
    // One sample (the lower corner) violates nothing: unknown, with the enclosure's hull
    // in the reason.
    let mut args = BUDGETED.to_vec();
    args.extend(["--samples", "1"]);
    let (r, _) = sharded_equals_unsharded(&args, 2, &[1, 0], &dir.path().join("a"));
    assert_eq!(r["verdict"]["verdict"], "unknown", "{}", r["verdict"]);
    assert_eq!(r["subproblems"], 12);
    // Proved, nothing split.
    let (r, _) = sharded_equals_unsharded(
        &["--y0", "2.0:2.2", "--horizon", "0.5", "--goal-ystar", "100"],
        2,
        &[0, 1],
        &dir.path().join("b"),
    );
    assert_eq!(r["verdict"]["verdict"], "proved", "{}", r["verdict"]);
    assert_eq!(r["subproblems"], 4);
}

#[test]
fn reach_merge_refuses_shards_that_do_not_make_one_run() {
    let dir = tempfile::tempdir().unwrap();
    let net = denorm_net();
    let args = ["--y0", "2.0:2.1", "--horizon", "0.5", "--goal-ystar", "100"];
    let shard = |args: &[&str], s: &str, name: &str| -> PathBuf {
        let f = dir.path().join(name);
        reach_shard(&net, args, s, &f);
        f
    };
    let s0 = shard(&args, "0/2", "s0.json");
    let s1 = shard(&args, "1/2", "s1.json");
    let out = dir.path().join("out");
    let merge = |files: &[&Path]| {
        let mut m: Vec<&OsStr> = vec!["merge".as_ref(), "reach".as_ref()];
        m.extend(files.iter().map(|f| f.as_os_str()));
        m.extend(["--out".as_ref(), out.as_os_str()]);
        let (code, o, err) = run(&m);
        assert_eq!(code, Some(2), "{o}{err}");
        assert!(!out.exists(), "a refused merge left {}", out.display());
        err
    };
    let err = merge(&[&s1]);
    assert!(err.contains("missing shard(s): 0/2"), "{err}");
    let err = merge(&[&s0, &s1, &s0]);
    assert!(err.contains("duplicate shard(s): 0/2"), "{err}");
    // Another goal, another network: shards of different runs.
    let mut other = args.to_vec();
    other[5] = "50";
    let g1 = shard(&other, "1/2", "g1.json");
    let err = merge(&[&s0, &g1]);
    assert!(err.contains("different runs"), "{err}");
    // A shard of another network (the adversarially trained one) is of another run.
    let adv = reference("adversarial_model_denorm.onnx");
    let f = dir.path().join("n1.json");
    reach_shard(&adv, &args, "1/2", &f);
    let err = merge(&[&s0, &f]);
    assert!(err.contains("different runs"), "{err}");

    // A shard of a 3-shard run among a 2-shard run's.
    let t1 = shard(&args, "1/3", "t1.json");
    let err = merge(&[&s0, &t1]);
    assert!(
        err.contains("3-shard run mixed with a 2-shard run"),
        "{err}"
    );
    // A sub-box the run needs but its shard does not hold is named, not guessed.
    let mut v: Value = serde_json::from_str(&std::fs::read_to_string(&s1).unwrap()).unwrap();
    let gone = v["result"]["subboxes"].as_array_mut().unwrap().remove(0);
    let cut = dir.path().join("cut.json");
    write_shard(&cut, v, true);
    let err = merge(&[&s0, &cut]);
    assert!(
        err.contains(&format!(
            "piece {} of shard 1/2 is missing",
            gone["key"].as_str().unwrap()
        )),
        "{err}"
    );
    // The merge of reach needs --out (a folder).
    let (code, _, err) = run(&[
        "merge".as_ref(),
        "reach".as_ref(),
        s0.as_os_str(),
        s1.as_os_str(),
    ]);
    assert_eq!(code, Some(2));
    assert!(err.contains("--out DIR is required"), "{err}");
    // Taylor-model runs shard the cells of a --grid: without one, refused; --sets auto
    // (two kinds of set) is not sharded.
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let sys = root.join("examples/archcomp/tora.sys");
    let tora = root.join("crates/samara-reach/tests/data/archcomp/controller_tora.onnx");
    let f = dir.path().join("x.json");
    let shard_args: [&OsStr; 4] = [
        "--shard".as_ref(),
        "0/2".as_ref(),
        "--out".as_ref(),
        f.as_os_str(),
    ];
    let (code, o, err) = run(&[
        &[
            "reach".as_ref(),
            "--system".as_ref(),
            sys.as_os_str(),
            "--network".as_ref(),
            tora.as_os_str(),
        ][..],
        &shard_args[..],
    ]
    .concat());
    assert_eq!(code, Some(2), "{o}{err}");
    assert!(err.contains("needs --grid"), "{err}");
    for (sets, needle) in [
        ("taylor", "needs --grid"),
        ("auto", "--shard with --sets auto"),
    ] {
        let mut e: Vec<&OsStr> = vec!["--sets".as_ref(), sets.as_ref()];
        e.extend(shard_args);
        let (code, o, err) = reach(&net, &[], &e);
        assert_eq!(code, Some(2), "{o}{err}");
        assert!(err.contains(needle), "{err}");
    }
    assert!(!f.exists());
}

/// Taylor-model sets on a fixed grid (`--sets taylor --grid`): the shards' cells, merged
/// in any order of files, give the one-process reach.json (but `seconds`), JSON summary
/// and exit code; a cell range past the grid, a Taylor-model shard without a grid, and
/// shards of two different grids are refused (exit 2).
#[test]
fn reach_taylor_grid_shards_merge_to_the_unsharded_result() {
    let dir = tempfile::tempdir().unwrap();
    let args = [
        "--sets",
        "taylor",
        "--y0",
        "2.0:2.2",
        "--init",
        "theta=-0.002:0.002",
        "--horizon",
        "1",
        "--goal-ystar",
        "100",
        "--samples",
        "8",
        "--grid",
        "y=2",
        "--grid",
        "theta=2",
    ];
    let (r, files) = sharded_equals_unsharded(&args, 3, &[2, 0, 1], &dir.path().join("a"));
    assert_eq!(
        r["result"]["verdict"]["verdict"], "proved",
        "{}",
        r["result"]
    );
    assert_eq!(r["settings"]["grid"], serde_json::json!([1, 1, 1, 2, 1, 2]));
    assert_eq!(r["result"]["covered"], 1.0);
    let net = denorm_net();
    // Five shards of four cells: the first has none.
    let (code, _, err) = reach(
        &net,
        &args,
        &[
            "--shard".as_ref(),
            "0/5".as_ref(),
            "--out".as_ref(),
            dir.path().join("x.json").as_os_str(),
        ],
    );
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("the grid has 4 cells, fewer than the 5 shards"),
        "{err}"
    );
    let (code, _, err) = reach(
        &net,
        &args[..12],
        &[
            "--shard".as_ref(),
            "0/2".as_ref(),
            "--out".as_ref(),
            dir.path().join("x.json").as_os_str(),
        ],
    );
    assert_eq!(code, Some(2), "{err}");
    assert!(
        err.contains("--shard with Taylor-model sets needs --grid"),
        "{err}"
    );
    // Shard 1/3 of a grid along y only does not merge with the others.
    let mut other = args[..12].to_vec();
    other.extend(["--grid", "y=4"]);
    let f = dir.path().join("other.json");
    reach_shard(&net, &other, "1/3", &f);
    let out = dir.path().join("mixed");
    let (code, _, err) = run(&[
        "merge".as_ref(),
        "reach".as_ref(),
        files[1].as_os_str(),
        f.as_os_str(),
        files[2].as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert_eq!(code, Some(2), "{err}");
    assert!(err.contains("shards of different runs"), "{err}");
    assert!(!out.exists());
}

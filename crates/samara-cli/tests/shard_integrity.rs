//! Sealed shards (issue 35, items 5 and 6): a shard records the content digest of every
//! input of the whole run and a digest of its own payload; `samara merge` refuses (exit
//! 2, naming the shard file and what differs) shards of inputs edited between their runs,
//! shards edited after they were written, parts that contradict themselves or the
//! instances, and `sat` counterexamples that do not hold on the network; an honest merge
//! still gives the one-process output. For vnncomp, robustness and reach.

use serde_json::Value;
use std::ffi::OsStr;
use std::path::{Path, PathBuf};

use crate::support;
use support::sealing::write_shard as write;
use support::{reference, samara};

fn run<S: AsRef<OsStr>>(args: &[S]) -> (Option<i32>, String, String) {
    let o = samara().args(args).output().unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

fn read(p: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

/// `samara merge KIND FILES... --out OUT` must fail with exit 2; returns stderr.
fn merge_refused(kind: &str, files: &[&Path], out: &Path) -> String {
    let mut a: Vec<&OsStr> = vec!["merge".as_ref(), kind.as_ref()];
    a.extend(files.iter().map(|f| f.as_os_str()));
    a.extend(["--out".as_ref(), out.as_os_str()]);
    let (code, o, e) = run(&a);
    assert_eq!(code, Some(2), "merge {kind} should be refused: {o}{e}");
    e
}

/// A tiny benchmark in `dir`: the published 6-input network and two box properties over
/// X in [0, 0.1]^6, `Y_0 >= 1000` (unsat: far above the network's range there) and
/// `Y_0 <= 1000` (sat: every point), both decided at once.
fn benchmark(dir: &Path) -> PathBuf {
    std::fs::copy(reference("base_model_norm.onnx"), dir.join("net.onnx")).unwrap();
    for (name, goal) in [("u", "(>= Y_0 1000.0)"), ("s", "(<= Y_0 1000.0)")] {
        std::fs::write(dir.join(format!("{name}.vnnlib")), property(goal)).unwrap();
    }
    let csv = dir.join("instances.csv");
    std::fs::write(&csv, "net.onnx,u.vnnlib,30\nnet.onnx,s.vnnlib,30\n").unwrap();
    csv
}

fn property(goal: &str) -> String {
    let mut s = String::new();
    for i in 0..6 {
        s.push_str(&format!("(declare-const X_{i} Real)\n"));
    }
    s.push_str("(declare-const Y_0 Real)\n");
    for i in 0..6 {
        s.push_str(&format!(
            "(assert (>= X_{i} 0.0))\n(assert (<= X_{i} 0.1))\n"
        ));
    }
    s.push_str(&format!("(assert {goal})\n"));
    s
}

/// `samara vnncomp CSV --shard I/2 --out FILE` (exit 0).
fn vnncomp_shard(csv: &Path, i: usize, file: &Path, root: Option<&Path>) {
    let s = format!("{i}/2");
    let mut a: Vec<&OsStr> = vec![
        "vnncomp".as_ref(),
        csv.as_os_str(),
        "--shard".as_ref(),
        s.as_ref(),
        "--out".as_ref(),
        file.as_os_str(),
    ];
    if let Some(r) = root {
        a.extend(["--root".as_ref(), r.as_os_str()]);
    }
    let (code, o, e) = run(&a);
    assert_eq!(code, Some(0), "{o}{e}");
}

/// The results CSV without its wall-time column.
fn without_seconds(text: &str) -> Vec<String> {
    text.lines()
        .map(|l| {
            let mut f: Vec<&str> = l.split(',').collect();
            f.remove(4);
            f.join(",")
        })
        .collect()
}

/// A JSON summary without wall times and the --out path.
fn strip(mut v: Value) -> Value {
    let m = v.as_object_mut().unwrap();
    for k in ["seconds", "total_seconds", "out"] {
        m.remove(k);
    }
    if let Some(rows) = v.get_mut("instances").and_then(Value::as_array_mut) {
        for r in rows {
            r.as_object_mut().unwrap().remove("seconds");
        }
    }
    v
}

#[test]
fn vnncomp_honest_merge_equals_one_process() {
    let dir = tempfile::tempdir().unwrap();
    let csv = benchmark(dir.path());
    let full = dir.path().join("full.csv");
    let (code, one, e) = run(&[
        "vnncomp".as_ref(),
        csv.as_os_str(),
        "--out".as_ref(),
        full.as_os_str(),
        "--json".as_ref(),
    ]);
    assert_eq!(code, Some(0), "{one}{e}");
    let (s0, s1) = (dir.path().join("s0.json"), dir.path().join("s1.json"));
    vnncomp_shard(&csv, 0, &s0, None);
    vnncomp_shard(&csv, 1, &s1, None);
    let merged = dir.path().join("merged.csv");
    let (code, m, e) = run(&[
        "merge".as_ref(),
        "vnncomp".as_ref(),
        s1.as_os_str(),
        s0.as_os_str(),
        "--out".as_ref(),
        merged.as_os_str(),
        "--json".as_ref(),
    ]);
    assert_eq!(code, Some(0), "{m}{e}");
    let (a, b): (Value, Value) = (
        serde_json::from_str(&one).unwrap(),
        serde_json::from_str(&m).unwrap(),
    );
    let words: Vec<&Value> = a["instances"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| &r["result"])
        .collect();
    assert_eq!(words, ["unsat", "sat"]);
    // Everything but wall times, the counterexample included, digit for digit.
    assert_eq!(strip(a), strip(b));
    let (x, y) = (
        std::fs::read_to_string(&full).unwrap(),
        std::fs::read_to_string(&merged).unwrap(),
    );
    assert_eq!(without_seconds(&x), without_seconds(&y));
    assert_eq!(y.lines().count(), 3);
}

#[test]
fn vnncomp_merge_refuses_shards_of_edited_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let csv = benchmark(dir.path());
    let (s0, s1) = (dir.path().join("s0.json"), dir.path().join("s1.json"));
    let out = dir.path().join("merged.csv");
    // The case: shard 0/2 run, a property edited, shard 1/2 run.
    vnncomp_shard(&csv, 0, &s0, None);
    std::fs::write(dir.path().join("s.vnnlib"), property("(<= Y_0 -1000.0)")).unwrap();
    vnncomp_shard(&csv, 1, &s1, None);
    let e = merge_refused("vnncomp", &[&s0, &s1], &out);
    assert!(
        e.contains("s0.json")
            && e.contains("s1.json")
            && e.contains("input `s.vnnlib` changed between the shards' runs"),
        "{e}"
    );
    assert!(!out.exists());
    // Another --root holding the same files is another run.
    let other = dir.path().join("copy");
    std::fs::create_dir(&other).unwrap();
    for f in ["net.onnx", "u.vnnlib", "s.vnnlib"] {
        std::fs::copy(dir.path().join(f), other.join(f)).unwrap();
    }
    vnncomp_shard(&csv, 0, &s0, None);
    vnncomp_shard(&csv, 1, &s1, Some(&other));
    let e = merge_refused("vnncomp", &[&s0, &s1], &out);
    assert!(e.contains("setting `root`"), "{e}");
    // The network edited after both shards ran: the merge, re-checking the `sat`
    // counterexample, sees it.
    vnncomp_shard(&csv, 1, &s1, None);
    std::fs::write(dir.path().join("s.vnnlib"), property("(<= Y_0 1000.0)")).unwrap();
    vnncomp_shard(&csv, 0, &s0, None);
    vnncomp_shard(&csv, 1, &s1, None);
    let mut net = std::fs::read(dir.path().join("net.onnx")).unwrap();
    net.push(0);
    std::fs::write(dir.path().join("net.onnx"), net).unwrap();
    let e = merge_refused("vnncomp", &[&s0, &s1], &out);
    assert!(
        e.contains("s1.json")
            && e.contains("input `net.onnx`")
            && e.contains("changed since the shards ran"),
        "{e}"
    );
}

#[test]
fn vnncomp_merge_refuses_tampered_shards() {
    let dir = tempfile::tempdir().unwrap();
    let csv = benchmark(dir.path());
    let (s0, s1) = (dir.path().join("s0.json"), dir.path().join("s1.json"));
    vnncomp_shard(&csv, 0, &s0, None);
    vnncomp_shard(&csv, 1, &s1, None);
    let out = dir.path().join("merged.csv");
    let (v0, v1) = (read(&s0), read(&s1));
    let t = dir.path().join("t.json");
    // A flipped verdict, the file not re-sealed: the payload digest says so.
    let mut v = v0.clone();
    v["result"]["parts"][0]["result"] = "sat".into();
    write(&t, v, false);
    let e = merge_refused("vnncomp", &[&t, &s1], &out);
    assert!(
        e.contains("t.json") && e.contains("payload digest does not match"),
        "{e}"
    );
    // Re-sealed forgeries are caught by the typed checks.
    // `sat` with a null counterexample.
    let mut v = v0.clone();
    v["result"]["parts"][0]["result"] = "sat".into();
    write(&t, v, true);
    let e = merge_refused("vnncomp", &[&t, &s1], &out);
    assert!(
        e.contains("t.json: line 1") && e.contains("`sat` without a counterexample"),
        "{e}"
    );
    // A flipped verdict with a counterexample that does not hold (shard 1's point, which
    // is not in u.vnnlib's region).
    let mut v = v0.clone();
    v["result"]["parts"][0]["result"] = "sat".into();
    v["result"]["parts"][0]["counterexample"] = v1["result"]["parts"][0]["counterexample"].clone();
    write(&t, v, true);
    let e = merge_refused("vnncomp", &[&t, &s1], &out);
    assert!(
        e.contains("t.json: line 1") && e.contains("counterexample does not hold"),
        "{e}"
    );
    // A `sat` part whose outputs are not the network's at its point.
    let mut v = v1.clone();
    v["result"]["parts"][0]["counterexample"]["outputs"][0] = 0.5.into();
    write(&t, v, true);
    let e = merge_refused("vnncomp", &[&s0, &t], &out);
    assert!(
        e.contains("t.json: line 2") && e.contains("not the network's"),
        "{e}"
    );
    // An extra row (the same instance twice).
    let mut v = v1.clone();
    let p = v["result"]["parts"][0].clone();
    v["result"]["parts"].as_array_mut().unwrap().push(p);
    v["result"]["done"] = 2.into();
    write(&t, v, true);
    let e = merge_refused("vnncomp", &[&s0, &t], &out);
    assert!(
        e.contains("t.json") && e.contains("appears more than once"),
        "{e}"
    );
    // A part moved to another line.
    let mut v = v1.clone();
    v["result"]["parts"][0]["vnnlib"] = "u.vnnlib".into();
    write(&t, v, true);
    let e = merge_refused("vnncomp", &[&s0, &t], &out);
    assert!(
        e.contains("t.json") && e.contains("not the instances CSV's"),
        "{e}"
    );
    // A stored text copy of the row is not read: the merge output comes from the typed
    // fields (a `csv` field added by hand changes nothing).
    let mut v = v1.clone();
    v["result"]["parts"][0]["csv"] = "net.onnx,s.vnnlib,30,unsat,0.0,phase,\n".into();
    write(&t, v, true);
    let (code, o, e) = run(&[
        "merge".as_ref(),
        "vnncomp".as_ref(),
        s0.as_os_str(),
        t.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert_eq!(code, Some(0), "{o}{e}");
    let text = std::fs::read_to_string(&out).unwrap();
    assert_eq!(text.lines().count(), 3, "{text}");
    assert!(text.lines().nth(2).unwrap().contains(",sat,"), "{text}");
    assert!(!text.contains("unsat,0.0,phase"), "{text}");
}

/// The first `n` rows of the published normalised training data, in `dir`.
fn robustness_data(dir: &Path, n: usize) -> PathBuf {
    let text = std::fs::read_to_string(reference("Training_Data_Normalised.csv")).unwrap();
    let rows: Vec<&str> = text.lines().take(n).collect();
    let p = dir.join("data.csv");
    std::fs::write(&p, rows.join("\n") + "\n").unwrap();
    p
}

/// `samara robustness` on the copied network and `data` with two radii, plus `extra`.
fn robustness(dir: &Path, data: &Path, extra: &[&OsStr]) -> (Option<i32>, String, String) {
    let net = dir.join("net.onnx");
    if !net.exists() {
        std::fs::copy(reference("base_model_norm.onnx"), &net).unwrap();
    }
    let mut a: Vec<&OsStr> = vec![
        "robustness".as_ref(),
        "--network".as_ref(),
        net.as_os_str(),
        "--data".as_ref(),
        data.as_os_str(),
        "--eps".as_ref(),
        "1e-3,1e-2".as_ref(),
        "--lipschitz".as_ref(),
        "1e-3,1e-1".as_ref(),
    ];
    a.extend(extra);
    run(&a)
}

fn robustness_shard(dir: &Path, data: &Path, i: usize, file: &Path) {
    let s = format!("{i}/2");
    let (code, o, e) = robustness(
        dir,
        data,
        &[
            "--shard".as_ref(),
            s.as_ref(),
            "--out".as_ref(),
            file.as_os_str(),
        ],
    );
    assert_eq!(code, Some(0), "{o}{e}");
}

#[test]
fn robustness_merge_refuses_edited_inputs_and_tampered_shards() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let data = robustness_data(d, 6);
    let (s0, s1) = (d.join("s0.json"), d.join("s1.json"));
    let out = d.join("merged.csv");
    // Honest: the merge is the one-process run (the per-point CSV byte for byte).
    let full = d.join("full.csv");
    let (code, one, e) = robustness(
        d,
        &data,
        &["--json".as_ref(), "--out".as_ref(), full.as_os_str()],
    );
    assert_eq!(code, Some(0), "{one}{e}");
    robustness_shard(d, &data, 0, &s0);
    robustness_shard(d, &data, 1, &s1);
    let (code, m, e) = run(&[
        "merge".as_ref(),
        "robustness".as_ref(),
        s1.as_os_str(),
        s0.as_os_str(),
        "--json".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert_eq!(code, Some(0), "{m}{e}");
    assert_eq!(
        std::fs::read_to_string(&full).unwrap(),
        std::fs::read_to_string(&out).unwrap()
    );
    assert_eq!(
        strip(serde_json::from_str(&one).unwrap()),
        strip(serde_json::from_str(&m).unwrap())
    );
    std::fs::remove_file(&out).unwrap();
    let (v0, v1) = (read(&s0), read(&s1));
    let t = d.join("t.json");
    // Not re-sealed.
    let mut v = v1.clone();
    v["result"]["points"][0]["f_max"] = "0.5".into();
    write(&t, v, false);
    let e = merge_refused("robustness", &[&s0, &t], &out);
    assert!(
        e.contains("t.json") && e.contains("payload digest does not match"),
        "{e}"
    );
    // Re-sealed: a point twice, a point of another shard, bounds that cross.
    let mut v = v1.clone();
    let pts = v["result"]["points"].as_array_mut().unwrap();
    pts[1] = pts[0].clone();
    write(&t, v, true);
    let e = merge_refused("robustness", &[&s0, &t], &out);
    assert!(
        e.contains("t.json") && e.contains("appears more than once"),
        "{e}"
    );
    let mut v = v1.clone();
    v["result"]["points"][0] = v0["result"]["points"][0].clone();
    write(&t, v, true);
    let e = merge_refused("robustness", &[&s0, &t], &out);
    assert!(
        e.contains("t.json") && e.contains("is not of this shard's rows 3..6"),
        "{e}"
    );
    let mut v = v1.clone();
    let f_max = v["result"]["points"][0]["f_max"].clone();
    v["result"]["points"][0]["f_min"] = f_max;
    v["result"]["points"][0]["f_max"] = "-1e300".into();
    write(&t, v, true);
    let e = merge_refused("robustness", &[&s0, &t], &out);
    assert!(
        e.contains("t.json") && e.contains("contradict each other"),
        "{e}"
    );
    let mut v = v1.clone();
    v["result"]["points"].as_array_mut().unwrap().pop();
    write(&t, v, true);
    let e = merge_refused("robustness", &[&s0, &t], &out);
    assert!(e.contains("t.json") && e.contains("cut short"), "{e}");
    // The data edited between the shards' runs (a value changed, the row count kept).
    let text = std::fs::read_to_string(&data).unwrap();
    std::fs::write(&data, text.replacen("0.75", "0.5", 1)).unwrap();
    robustness_shard(d, &data, 1, &s1);
    let e = merge_refused("robustness", &[&s0, &s1], &out);
    assert!(
        e.contains("s0.json")
            && e.contains("s1.json")
            && e.contains("input `--data` changed between the shards' runs"),
        "{e}"
    );
    assert!(!out.exists());
}

/// `samara reach --network NET ARGS --shard I/2 --out FILE --threads 2` (exit 0).
fn reach_shard(net: &Path, args: &[&str], i: usize, file: &Path) {
    let s = format!("{i}/2");
    let mut a: Vec<&OsStr> = vec!["reach".as_ref(), "--network".as_ref(), net.as_os_str()];
    a.extend(args.iter().map(OsStr::new));
    a.extend([
        "--threads".as_ref(),
        "2".as_ref(),
        "--shard".as_ref(),
        s.as_ref(),
        "--out".as_ref(),
        file.as_os_str(),
    ]);
    let (code, o, e) = run(&a);
    assert_eq!(code, Some(0), "{o}{e}");
}

/// A short flight whose goal band the highest starts miss at once: violated, with a
/// sampled counterexample that every shard carries.
const VIOLATED: [&str; 8] = [
    "--y0",
    "2.0:2.1",
    "--horizon",
    "0.5",
    "--goal-ystar",
    "2.05",
    "--goal-from",
    "0",
];

#[test]
fn reach_merge_refuses_edited_inputs_and_tampered_shards() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let net = d.join("net.onnx");
    std::fs::copy(reference("base_model_denorm.onnx"), &net).unwrap();
    let (s0, s1) = (d.join("s0.json"), d.join("s1.json"));
    let out = d.join("merged");
    reach_shard(&net, &VIOLATED, 0, &s0);
    reach_shard(&net, &VIOLATED, 1, &s1);
    // Honest: merged, violated (exit 1), the counterexample re-checked.
    let (code, o, e) = run(&[
        "merge".as_ref(),
        "reach".as_ref(),
        s0.as_os_str(),
        s1.as_os_str(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    assert_eq!(code, Some(1), "{o}{e}");
    assert!(o.starts_with("violated"), "{o}");
    std::fs::remove_dir_all(&out).unwrap();
    let (v0, v1) = (read(&s0), read(&s1));
    assert!(v0["result"]["shared"]["violation"].is_object(), "{v0}");
    let (t0, t1) = (d.join("t0.json"), d.join("t1.json"));
    // Not re-sealed: a sub-box's enclosure narrowed.
    let mut v = v1.clone();
    v["result"]["subboxes"][0]["leaf"]["steps"][0]["x_plus_y"][0] = "0.0".into();
    write(&t1, v, false);
    let e = merge_refused("reach", &[&s0, &t1], &out);
    assert!(
        e.contains("t1.json") && e.contains("payload digest does not match"),
        "{e}"
    );
    // Re-sealed: the counterexample moved (in both shards, which must agree) so that its
    // flight no longer misses the goal where it says.
    for (v, t) in [(&v0, &t0), (&v1, &t1)] {
        let mut v = v.clone();
        v["result"]["shared"]["violation"]["x_plus_y"] = "3.5".into();
        write(t, v, true);
    }
    let e = merge_refused("reach", &[&t0, &t1], &out);
    assert!(
        e.contains("t0.json: the counterexample does not hold"),
        "{e}"
    );
    // The network replaced between the shards' runs.
    std::fs::copy(reference("adversarial_model_denorm.onnx"), &net).unwrap();
    reach_shard(&net, &VIOLATED, 1, &s1);
    let e = merge_refused("reach", &[&s0, &s1], &out);
    assert!(
        e.contains("s0.json")
            && e.contains("s1.json")
            && e.contains("input `--network` changed between the shards' runs"),
        "{e}"
    );
    // ... or after both ran: the merge's re-check reads it back.
    std::fs::copy(reference("base_model_denorm.onnx"), &net).unwrap();
    reach_shard(&net, &VIOLATED, 1, &s1);
    std::fs::copy(reference("adversarial_model_denorm.onnx"), &net).unwrap();
    let e = merge_refused("reach", &[&s0, &s1], &out);
    assert!(
        e.contains("input `--network`") && e.contains("changed since the shards ran"),
        "{e}"
    );
    assert!(!out.exists());
}

//! `samara reach --target-ratio R --grid ... --shard I/N` and `samara merge reach`: the
//! adaptive run's starting cells divided over shards, merged, give the one-process
//! `reach.json` (but the wall time), JSON summary and exit code (TORA, and the built-in
//! glider on a small set); a shard killed while it works resumes from its checkpoint
//! (`OUT.cells`) and still merges to the same result; a shard stopped by its budget exits
//! 1, is refused by the merge, and its checkpoint is refused by a run of other settings;
//! --shard without --grid is refused.
//!
//! The system: TORA (ARCH-COMP, the competition's controller) with its x1 and x3
//! intervals widened three times, a 6 s horizon and the band `|x1 + x2| <= 100` at the
//! end as the measure (reach_cli's adaptive test has 3 s). Target 1.1, 2 x 2 starting
//! cells: shard 0's cell 0 finishes in round 2, cell 2 in round 3, the window the kill uses.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use crate::support;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn widened_tora(dir: &Path) -> PathBuf {
    let tora = std::fs::read_to_string(root().join("examples/archcomp/tora.sys")).unwrap();
    let text = support::widened_tora(&tora, 6);
    let p = dir.join("tora_wide.sys");
    std::fs::write(&p, text).unwrap();
    p
}

fn reach_cmd(sys: &Path, extra: &[&str]) -> Command {
    reach_budget(sys, "64", extra)
}

/// `samara reach` of the test's adaptive run with the leaf budget `budget`.
fn reach_budget(sys: &Path, budget: &str, extra: &[&str]) -> Command {
    let net = root().join("crates/samara-reach/tests/data/archcomp/controller_tora.onnx");
    let mut c = Command::new(env!("CARGO_BIN_EXE_samara"));
    c.arg("reach")
        .arg("--system")
        .arg(sys)
        .arg("--network")
        .arg(net)
        .args([
            "--target-ratio",
            "1.1",
            "--order",
            "3",
            "--network-error",
            "symbolic:20",
            "--samples",
            "300",
            "--max-leaves",
            budget,
            "--grid",
            "x1=2",
            "--grid",
            "x3=2",
        ])
        .args(extra);
    c
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// `reach.json` without the result's wall (or summed) time.
fn reach_json(dir: &Path) -> Value {
    let mut v: Value =
        serde_json::from_slice(&std::fs::read(dir.join("reach.json")).unwrap()).unwrap();
    v["result"].as_object_mut().unwrap().remove("seconds");
    v
}

fn summary(o: &Output) -> Value {
    let mut v: Value = serde_json::from_slice(&o.stdout).unwrap();
    v.as_object_mut().unwrap().remove("seconds");
    v
}

fn merge(files: &[&Path], out: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_samara"))
        .args(["merge", "reach"])
        .args(files)
        .arg("--json")
        .arg("--out")
        .arg(out)
        .output()
        .unwrap()
}

#[test]
fn adaptive_shards_merge_to_the_one_process_result_and_a_killed_shard_resumes() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sys = widened_tora(d);
    let full = d.join("full");
    let one = reach_cmd(&sys, &["--threads", "2", "--json", "--out"])
        .arg(&full)
        .output()
        .unwrap();
    assert_eq!(one.status.code(), Some(0), "{}", text(&one));
    let whole = reach_json(&full);
    assert_eq!(whole["adaptive"]["met"], true, "{}", whole["adaptive"]);
    assert!(
        whole["adaptive"]["leaves"].as_u64().unwrap() > 4,
        "the target should need cuts: {}",
        whole["adaptive"]
    );

    // Two shards, written in the order 1, 0.
    let files: Vec<PathBuf> = (0..2).map(|i| d.join(format!("s{i}.json"))).collect();
    for i in [1, 0] {
        let o = reach_cmd(&sys, &["--threads", "1", "--shard", &format!("{i}/2")])
            .arg("--out")
            .arg(&files[i])
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(0), "{}", text(&o));
        let line = String::from_utf8_lossy(&o.stdout);
        assert!(
            line.starts_with(&format!("shard {i}/2: starting cells {i} mod 2 of 4")),
            "{line}"
        );
        // A finished shard keeps no checkpoint.
        assert!(!d.join(format!("s{i}.json.cells")).exists());
    }
    let merged = d.join("merged");
    let m = merge(&[&files[1], &files[0]], &merged);
    assert_eq!(m.status.code(), one.status.code(), "{}", text(&m));
    assert_eq!(reach_json(&merged), whole);
    assert_eq!(summary(&m), summary(&one));

    // Shard 0 killed once a starting cell is in its checkpoint, with half a line
    // written after it (the kill came mid-write); the rerun resumes from it.
    let killed = d.join("k0.json");
    let cp = d.join("k0.json.cells");
    let mut child = reach_cmd(&sys, &["--threads", "1", "--shard", "0/2", "--out"])
        .arg(&killed)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let t0 = Instant::now();
    let lines = |p: &Path| {
        std::fs::read_to_string(p)
            .map(|t| t.matches('\n').count())
            .unwrap_or(0)
    };
    while lines(&cp) < 2 {
        assert!(
            child.try_wait().unwrap().is_none(),
            "shard 0 ended before a starting cell was checkpointed"
        );
        assert!(t0.elapsed() < Duration::from_secs(300));
        std::thread::sleep(Duration::from_millis(2));
    }
    let was_running = child.try_wait().unwrap().is_none();
    child.kill().unwrap();
    child.wait().unwrap();
    assert!(was_running, "shard 0 finished before it could be killed");
    assert!(!killed.exists(), "a killed shard wrote its shard file");
    let kept = lines(&cp) - 1;
    {
        use std::io::Write;
        let mut f = std::fs::OpenOptions::new().append(true).open(&cp).unwrap();
        f.write_all(b"{\"root\": 2, \"rou").unwrap();
    }
    let o = reach_cmd(
        &sys,
        &["--threads", "1", "--json", "--shard", "0/2", "--out"],
    )
    .arg(&killed)
    .output()
    .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    let line: Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(line["resumed"].as_u64(), Some(kept as u64), "{line}");
    assert!(!cp.exists());
    let merged2 = d.join("merged2");
    let m2 = merge(&[&killed, &files[1]], &merged2);
    assert_eq!(m2.status.code(), one.status.code(), "{}", text(&m2));
    assert_eq!(reach_json(&merged2), whole);

    // Both shards with a budget of 2 leaves: shard 0 must cut a cell, so it stops
    // early: exit 1, its checkpoint kept; the merge refuses it. Run again with another
    // budget, the checkpoint (of the other settings) is refused, naming the setting.
    let b: Vec<PathBuf> = (0..2).map(|i| d.join(format!("b{i}.json"))).collect();
    let mut codes = Vec::new();
    for (i, f) in b.iter().enumerate() {
        let o = reach_budget(&sys, "2", &["--shard", &format!("{i}/2"), "--out"])
            .arg(f)
            .output()
            .unwrap();
        codes.push(o.status.code());
        if o.status.code() == Some(1) {
            assert!(text(&o).contains("stopped early"), "{}", text(&o));
            assert!(d.join(format!("b{i}.json.cells")).exists());
        }
    }
    assert_eq!(codes[0], Some(1), "shard 0 should stop at the budget");
    let refused = d.join("refused");
    let m3 = merge(&[&b[0], &b[1]], &refused);
    assert_eq!(m3.status.code(), Some(2), "{}", text(&m3));
    assert!(
        text(&m3).contains("shard 0 stopped splitting early"),
        "{}",
        text(&m3)
    );
    assert!(!refused.exists());
    let o = reach_cmd(&sys, &["--shard", "0/2", "--out"])
        .arg(&b[0])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(
        text(&o).contains("a checkpoint of another run or shard") && text(&o).contains("max_boxes"),
        "{}",
        text(&o)
    );

    // --shard without --grid.
    let net = root().join("crates/samara-reach/tests/data/archcomp/controller_tora.onnx");
    let o = Command::new(env!("CARGO_BIN_EXE_samara"))
        .arg("reach")
        .arg("--system")
        .arg(&sys)
        .arg("--network")
        .arg(net)
        .args(["--target-ratio", "2", "--shard", "0/2", "--out"])
        .arg(d.join("x.json"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(
        text(&o).contains("--shard with --target-ratio needs --grid"),
        "{}",
        text(&o)
    );
}

/// The built-in glider (the six-state set's route: no system file) on a small set: two
/// adaptive shards of a 2 x 2 start over theta and y, merged, give the one-process
/// `reach.json` (but the wall time) and exit code.
#[test]
fn builtin_glider_adaptive_shards_merge_to_the_one_process_result() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let net = support::reference("base_model_denorm.onnx");
    let glider = |extra: &[&str], out: &Path| {
        Command::new(env!("CARGO_BIN_EXE_samara"))
            .arg("reach")
            .arg("--network")
            .arg(&net)
            .args([
                "--y0",
                "2.0:2.2",
                "--init",
                "theta=-0.002:0.002",
                "--horizon",
                "1",
                "--samples",
                "50",
                "--order",
                "3",
                "--network-error",
                "symbolic:20",
                "--target-ratio",
                "1.5",
                "--grid",
                "theta=2",
                "--grid",
                "y=2",
                "--threads",
                "1",
            ])
            .args(extra)
            .arg("--out")
            .arg(out)
            .output()
            .unwrap()
    };
    let full = d.join("full");
    let one = glider(&[], &full);
    assert_eq!(one.status.code(), Some(0), "{}", text(&one));
    let files: Vec<PathBuf> = (0..2).map(|i| d.join(format!("g{i}.json"))).collect();
    for (i, f) in files.iter().enumerate() {
        let o = glider(&["--shard", &format!("{i}/2")], f);
        assert_eq!(o.status.code(), Some(0), "{}", text(&o));
    }
    let merged = d.join("merged");
    let m = merge(&[&files[0], &files[1]], &merged);
    assert_eq!(m.status.code(), Some(0), "{}", text(&m));
    let whole = reach_json(&full);
    assert_eq!(whole["system"], "built-in setting");
    assert_eq!(reach_json(&merged), whole);
}

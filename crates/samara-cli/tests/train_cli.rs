//! `samara train`: JSON metrics, a loadable ONNX file, bit-identical reruns, and input
//! errors (empty or ragged CSV, bad method) with exit code 2.

use crate::support;
use support::samara;

/// The published training data (fails naming the file when it is missing).
fn data() -> String {
    support::reference_str("Training_Data.csv")
}

#[test]
fn trains_exports_and_flies() {
    let dir = tempfile::tempdir().unwrap();
    let net = dir.path().join("net.onnx");
    let out = samara()
        .args([
            "train",
            "--data",
            &data(),
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
            &data(),
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

/// The published normalised training data (fails naming the file when it is missing).
fn normalised() -> String {
    support::reference_str("Training_Data_Normalised.csv")
}

fn run(args: &[&std::ffi::OsStr]) -> (Option<i32>, String, String) {
    let out = samara().arg("train").args(args).output().unwrap();
    (
        out.status.code(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn os<'a>(v: &'a [&'a str]) -> Vec<&'a std::ffi::OsStr> {
    v.iter().map(std::ffi::OsStr::new).collect()
}

/// Issue 18 item 1: seed 1 (plain, published setting) starts from a dead network, which
/// used to be returned with R^2 = -5.96 and exit 0; now training restarts, says so, and
/// the same seed still gives the same bytes.
#[test]
fn a_dead_start_is_restarted_reported_and_reproducible() {
    let dir = tempfile::tempdir().unwrap();
    let mut files = Vec::new();
    for k in 0..2 {
        let net = dir.path().join(format!("net{k}.onnx"));
        let (code, stdout, stderr) = run(&os(&[
            "--data",
            &normalised(),
            "--method",
            "plain",
            "--seed",
            "1",
            "--json",
            "--out",
            net.to_str().unwrap(),
        ]));
        assert_eq!(code, Some(0), "{stderr}");
        let m: serde_json::Value = serde_json::from_str(&stdout).unwrap();
        assert!(m["restarts"].as_u64().unwrap() >= 1, "{m}");
        let first = &m["restart_log"][0];
        assert_eq!(
            (first["seed"].as_u64(), first["epoch"].as_u64()),
            (Some(1), Some(0))
        );
        assert!(
            first["reason"].as_str().unwrap().contains("dead network"),
            "{m}"
        );
        assert!(m["r2"].as_f64().unwrap() >= 0.9, "{m}");
        files.push(std::fs::read(&net).unwrap());
    }
    assert_eq!(files[0], files[1], "same seed, same data: identical bytes");
    // Human output names the restart.
    let (code, _, stderr) = run(&os(&[
        "--data",
        &normalised(),
        "--seed",
        "1",
        "--out",
        dir.path().join("h.onnx").to_str().unwrap(),
    ]));
    assert_eq!(code, Some(0), "{stderr}");
    assert!(
        stderr.contains("after 1 restart") && stderr.contains("degenerate"),
        "{stderr}"
    );
}

/// When every attempt is degenerate the command fails with exit 1, names the problem,
/// and writes nothing (not even the folder it would have written into).
#[test]
fn no_recovery_exits_1_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let net = dir.path().join("new").join("sub").join("net.onnx");
    let (code, stdout, stderr) = run(&os(&[
        "--data",
        &normalised(),
        "--seed",
        "1",
        "--max-restarts",
        "0",
        "--json",
        "--out",
        net.to_str().unwrap(),
    ]));
    assert_eq!(code, Some(1), "{stderr}");
    assert!(stdout.is_empty(), "{stdout}");
    assert!(
        stderr.contains("dead network") && stderr.contains("--max-restarts"),
        "{stderr}"
    );
    assert!(
        !dir.path().join("new").exists(),
        "a failed run left a folder"
    );
}

/// Issue 17: every numeric flag is checked before training (exit 2, the flag named).
#[test]
fn out_of_range_flags_exit_2_naming_the_flag() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x").join("n.onnx");
    let cases: &[(&[&str], &str)] = &[
        (&["--method", "lipschitz", "--weight", "nan"], "--weight"),
        (&["--method", "plain", "--weight", "nan"], "--weight"),
        (&["--method", "dl2", "--weight=-1"], "--weight"),
        (
            &["--method", "lipschitz", "--lipschitz", "0"],
            "--lipschitz",
        ),
        (&["--lipschitz", "inf"], "--lipschitz"),
        (&["--epochs", "0"], "--epochs"),
        (&["--epochs", "100000000"], "--epochs"),
        (&["--batch", "0"], "--batch"),
        (&["--lr", "nan"], "--lr"),
        (&["--lr", "0"], "--lr"),
        (&["--lr", "inf"], "--lr"),
        (&["--eps", "nan"], "--eps"),
        (&["--eps=-0.1"], "--eps"),
        (&["--eps", "2"], "--eps"),
        (&["--arch", "6,0,1"], "--arch"),
        (&["--arch", "6,100000,1"], "--arch"),
        (&["--ystar", "nan"], "--ystar"),
        (&["--min-r2", "1"], "--min-r2"),
        (&["--min-r2", "nan"], "--min-r2"),
        (&["--max-restarts", "1000"], "--max-restarts"),
    ];
    let data = normalised();
    for (extra, needle) in cases {
        let mut args = vec!["--data", &data, "--out", out.to_str().unwrap()];
        args.extend_from_slice(extra);
        let (code, _, stderr) = run(&os(&args));
        assert_eq!(code, Some(2), "{extra:?}: {stderr}");
        assert!(stderr.contains(needle), "{extra:?}: {stderr}");
    }
    assert!(!dir.path().join("x").exists());
}

/// Issue 17: one row (or too few to hold out 2 test rows) is refused, saying how many
/// rows are needed; it used to exit 0 with NaN metrics.
#[test]
fn too_small_data_sets_exit_2_saying_how_many_rows_are_needed() {
    let dir = tempfile::tempdir().unwrap();
    let all = std::fs::read_to_string(normalised()).unwrap();
    for n in [1, 14] {
        let p = dir.path().join(format!("rows{n}.csv"));
        let body: String = all.lines().take(n).map(|l| format!("{l}\n")).collect();
        std::fs::write(&p, &body).unwrap();
        let out = dir.path().join("n.onnx");
        let (code, _, stderr) = run(&os(&[
            "--data",
            p.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]));
        assert_eq!(code, Some(2), "{n} rows: {stderr}");
        assert!(
            stderr.contains(&format!("have {n} rows")) && stderr.contains("at least 15"),
            "{stderr}"
        );
        assert!(!out.exists());
        assert_eq!(std::fs::read_to_string(&p).unwrap(), body);
    }
}

/// Issue 17: a NaN metric is an error (exit 1), never a silent success. 20 rows whose
/// output is a function of the inputs, but the 2 test rows (seed 0's split) are the same
/// row, so the test outputs do not vary and R^2 is undefined.
#[test]
fn a_nan_metric_exits_1() {
    let dir = tempfile::tempdir().unwrap();
    let (_, test) = samara_train::data::split(20, 0.1, 0);
    assert_eq!(test.len(), 2);
    let mut body = String::new();
    for i in 0..20 {
        let k = if test.contains(&i) { 3 } else { i };
        let x: Vec<f64> = (0..6)
            .map(|j| ((k * 7 + j * 3) % 11) as f64 / 10.0)
            .collect();
        let y = 0.1 + x.iter().sum::<f64>() / 60.0;
        let cells: Vec<String> = x.iter().chain([y].iter()).map(|v| v.to_string()).collect();
        body.push_str(&cells.join(","));
        body.push('\n');
    }
    let p = dir.path().join("d.csv");
    std::fs::write(&p, &body).unwrap();
    let out = dir.path().join("n.onnx");
    let (code, stdout, stderr) = run(&os(&[
        "--data",
        p.to_str().unwrap(),
        "--epochs",
        "200",
        "--min-r2",
        "0",
        "--json",
        "--out",
        out.to_str().unwrap(),
    ]));
    assert_eq!(code, Some(1), "{stdout}{stderr}");
    assert!(stderr.contains("R^2") && stderr.contains("NaN"), "{stderr}");
    assert!(!out.exists());
}

/// Issue 17: an output (--out, --log, or the default log next to --out) onto an input
/// (--data, --normalisation, --spec), or --log onto --out, is refused before training
/// (exit 2) and the input stays byte-for-byte the same.
#[test]
fn outputs_onto_inputs_are_refused_and_inputs_survive() {
    let dir = tempfile::tempdir().unwrap();
    let t = dir.path().join("t");
    std::fs::create_dir(&t).unwrap();
    let data = t.join("mydata.csv");
    std::fs::copy(normalised(), &data).unwrap();
    let norm = t.join("norm.csv");
    std::fs::copy(support::reference("Normalisation_Constants.csv"), &norm).unwrap();
    let spec = t.join("props.spec");
    std::fs::write(&spec, "not read before the output check\n").unwrap();
    let old_log = t.join("old.log.csv");
    std::fs::write(&old_log, "epoch,loss,test_rmse\n").unwrap();
    let snapshot = |p: &std::path::Path| std::fs::read(p).unwrap();
    let (d0, n0, s0, l0) = (
        snapshot(&data),
        snapshot(&norm),
        snapshot(&spec),
        snapshot(&old_log),
    );
    let p = |q: &std::path::Path| q.to_str().unwrap().to_string();
    let other = p(&t.join("net.onnx"));
    let dotted = p(&t.join("..").join("t").join("mydata.csv"));
    let cases: Vec<(Vec<String>, &str)> = vec![
        (vec!["--out".into(), p(&data)], "--out"),
        (vec!["--out".into(), dotted.clone()], "--data"),
        (
            vec!["--out".into(), other.clone(), "--log".into(), p(&data)],
            "--log",
        ),
        (
            vec!["--out".into(), other.clone(), "--log".into(), dotted],
            "--data",
        ),
        (
            vec!["--normalisation".into(), p(&norm), "--out".into(), p(&norm)],
            "--normalisation",
        ),
        (
            vec![
                "--normalisation".into(),
                p(&norm),
                "--out".into(),
                other.clone(),
                "--log".into(),
                p(&norm),
            ],
            "--normalisation",
        ),
        (
            vec!["--spec".into(), p(&spec), "--out".into(), p(&spec)],
            "--spec",
        ),
        (
            vec!["--out".into(), p(&old_log), "--log".into(), p(&old_log)],
            "same file as --out",
        ),
        // The default log of --out t/mydata.onnx would be t/mydata.log.csv: the input.
        (
            vec!["--out".into(), p(&t.join("mydata.onnx"))],
            "--log (default",
        ),
        (vec!["--out".into(), p(&t)], "is a folder"),
    ];
    // The last-but-one case needs the data under that name.
    let data_as_log = t.join("mydata.log.csv");
    std::fs::copy(normalised(), &data_as_log).unwrap();
    let dl0 = snapshot(&data_as_log);
    for (k, (extra, needle)) in cases.iter().enumerate() {
        let data_flag = if k == 8 { p(&data_as_log) } else { p(&data) };
        let mut args: Vec<String> = vec!["--data".into(), data_flag];
        args.extend(extra.iter().cloned());
        let argv: Vec<&std::ffi::OsStr> = args.iter().map(std::ffi::OsStr::new).collect();
        let (code, _, stderr) = run(&argv);
        assert_eq!(code, Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(needle), "{args:?}: {stderr}");
    }
    assert_eq!(snapshot(&data), d0);
    assert_eq!(snapshot(&norm), n0);
    assert_eq!(snapshot(&spec), s0);
    assert_eq!(snapshot(&old_log), l0);
    assert_eq!(snapshot(&data_as_log), dl0);
    assert!(!t.join("net.onnx").exists() && !t.join("mydata.onnx").exists());
    let mut names: Vec<_> = std::fs::read_dir(&t)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    assert_eq!(
        names,
        [
            "mydata.csv",
            "mydata.log.csv",
            "norm.csv",
            "old.log.csv",
            "props.spec"
        ]
    );
}

/// A successful run into a folder that does not exist yet creates it and keeps it.
#[test]
fn a_new_output_folder_is_created_and_kept_on_success() {
    let dir = tempfile::tempdir().unwrap();
    let net = dir.path().join("a").join("b").join("net.onnx");
    let (code, _, stderr) = run(&os(&[
        "--data",
        &normalised(),
        "--epochs",
        "300",
        "--out",
        net.to_str().unwrap(),
    ]));
    assert_eq!(code, Some(0), "{stderr}");
    assert!(net.exists() && dir.path().join("a/b/net.log.csv").exists());
}

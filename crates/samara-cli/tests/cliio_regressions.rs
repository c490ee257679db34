//! Regression tests of issue 17 ("never a wrong answer") for `simulate`, `reach`,
//! `reproduce` and the CLI shell: every case of the adversarial probe gets its exact exit
//! code, a needle of its message, and (where it applies) no files or folders left behind.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use crate::support;
use support::{reference, samara};

/// A copy of a published file in `dir` (tests never write next to the reference files).
fn copy_ref(dir: &Path, name: &str, as_name: &str) -> PathBuf {
    let p = dir.join(as_name);
    std::fs::copy(reference(name), &p).unwrap();
    p
}

fn run(args: &[&str]) -> Output {
    samara().args(args).output().unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Exit code 2, every needle in stderr, no panic or abort text.
fn assert_usage(o: &Output, needles: &[&str]) {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    for n in needles {
        assert!(e.contains(n), "missing {n:?} in: {e}");
    }
    assert!(
        !e.contains("panicked") && !e.contains("memory allocation"),
        "{e}"
    );
}

/// Run `args` + `--out DIR/new/out` and check usage error, needles, and that nothing
/// was created.
fn refused(args: &[&str], needles: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("new").join("out");
    let mut a: Vec<String> = args.iter().map(|s| s.to_string()).collect();
    a.push("--out".into());
    a.push(out.display().to_string());
    let o = output_within_20s(samara().args(&a));
    assert_usage(&o, needles);
    assert!(
        !dir.path().join("new").exists(),
        "{args:?} left a folder behind"
    );
}

/// `cmd.output()`, killed (and failed) after 20 s: a case that used to hang must not hang
/// the suite.
fn output_within_20s(cmd: &mut Command) -> Output {
    let dir = tempfile::tempdir().unwrap();
    let (o, e) = (dir.path().join("o"), dir.path().join("e"));
    let mut child = cmd
        .stdout(std::fs::File::create(&o).unwrap())
        .stderr(std::fs::File::create(&e).unwrap())
        .spawn()
        .unwrap();
    let t = std::time::Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if t.elapsed() > std::time::Duration::from_secs(20) {
            let _ = child.kill();
            let _ = child.wait();
            panic!("{cmd:?} ran longer than 20 s");
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    };
    Output {
        status,
        stdout: std::fs::read(&o).unwrap(),
        stderr: std::fs::read(&e).unwrap(),
    }
}

fn net() -> String {
    reference("base_model_denorm.onnx").display().to_string()
}

#[test]
fn simulate_huge_or_tiny_horizon_and_period_are_usage_errors() {
    refused(
        &["simulate", "--horizon", "1e308"],
        &["--horizon", "at most 100000"],
    );
    refused(
        &["simulate", "--horizon", "1e12"],
        &["--horizon", "control periods", "at most 100000"],
    );
    refused(
        &["simulate", "--period", "1e-300"],
        &["--period", "[0.001, 100]"],
    );
    refused(
        &["simulate", "--period", "1e6"],
        &["--period", "[0.001, 100]"],
    );
    // Less than one period used to give a flight with no steps (a panic in --json).
    refused(
        &["simulate", "--horizon", "1e-20", "--json"],
        &["horizon", "multiple of the period"],
    );
    for v in ["nan", "inf", "-inf", "-1", "0"] {
        refused(&["simulate", "--horizon", v], &["--horizon"]);
        refused(&["simulate", "--period", v], &["--period"]);
    }
}

#[test]
fn simulate_too_many_starts_or_rows_are_usage_errors() {
    refused(
        &["simulate", "--y0", "1:2:100000000"],
        &["--y0", "COUNT 100000000", "100000"],
    );
    refused(
        &["simulate", "--y0", "1:2:100000"],
        &["--y0/--horizon/--period", "trajectory rows", "at most 2e6"],
    );
    refused(
        &["simulate", "--y0", "1:2:18446744073709551616"],
        &["--y0", "START:END:COUNT"],
    );
    refused(&["simulate", "--y0", "1e308"], &["--y0", "[-1000, 1000]"]);
    refused(&["simulate", "--y0", "nan"], &["--y0", "finite"]);
    refused(&["simulate", "--y0", "1,inf"], &["--y0", "finite"]);
    refused(
        &["simulate", "--controller", "constant:nan"],
        &["--controller", "outside the allowed range"],
    );
}

#[test]
fn a_flight_that_leaves_the_model_range_is_an_error_not_a_hang_or_nan_results() {
    // Unclipped network output at y0 = 1000 drives the state to NaN: dp5 used to loop
    // forever, the other integrators wrote NaN trajectories and exited 0.
    for integ in ["dp5", "ode45", "tight", "rk4"] {
        refused(
            &[
                "simulate",
                "--controller",
                &net(),
                "--no-clip",
                "--y0",
                "1000",
                "--no-plot",
                "--integrator",
                integ,
            ],
            &["NaN or infinite", "t = 5.5", "drop --no-clip"],
        );
    }
}

#[test]
fn simulate_accepts_negative_heights_without_equals() {
    let dir = tempfile::tempdir().unwrap();
    let o = samara()
        .args([
            "simulate",
            "--y0",
            "-5",
            "--horizon",
            "1",
            "--no-plot",
            "--json",
            "--out",
        ])
        .arg(dir.path())
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["starts"][0]["y0"], -5.0);
    let o = samara()
        .args([
            "simulate",
            "--y0",
            "-1:2:3",
            "--horizon",
            "1",
            "--no-plot",
            "--json",
            "--out",
        ])
        .arg(dir.path())
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let y0: Vec<f64> = v["starts"]
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["y0"].as_f64().unwrap())
        .collect();
    assert_eq!(y0, vec![-1.0, 0.5, 2.0]);
}

#[test]
fn reach_huge_values_of_every_numeric_flag_are_usage_errors() {
    let n = net();
    fn with_base<'a>(base: &[&'a str], extra: &[&'a str]) -> Vec<&'a str> {
        base.iter().chain(extra).copied().collect()
    }
    let base = ["reach", "--network", n.as_str()];
    let with = |extra: &[&'static str]| with_base(&base, extra);
    refused(
        &with(&["--horizon", "1e308"]),
        &["--horizon", "at most 10000"],
    );
    refused(
        &with(&["--period", "1e-300"]),
        &["--period", "[0.001, 100]"],
    );
    refused(&with(&["--y0=-1e308:1e308"]), &["--y0", "[-1000, 1000]"]);
    refused(&with(&["--y0", "-1e308:1e308"]), &["--y0", "[-1000, 1000]"]);
    refused(&with(&["--y0", "nan"]), &["--y0", "finite"]);
    refused(&with(&["--y0", "3:2"]), &["--y0", "inverted"]);
    refused(
        &with(&["--init", "theta=-1e9:0"]),
        &["--init", "[-1000, 1000]"],
    );
    refused(&with(&["--init", "theta=nan:1"]), &["--init", "finite"]);
    refused(&with(&["--init", "v_xp=inf"]), &["--init", "finite"]);
    for v in ["nan", "inf", "-inf", "-1", "0"] {
        refused(&with(&["--horizon", v]), &["--horizon"]);
        refused(&with(&["--period", v]), &["--period"]);
    }
    for v in ["nan", "inf", "-1"] {
        refused(&with(&["--goal-ystar", v]), &["--goal-ystar"]);
        refused(
            &with(&["--goal-ystar", "2", "--goal-from", v]),
            &["--goal-from"],
        );
    }
    refused(
        &with(&["--goal-ystar", "2", "--goal-from", "1e9"]),
        &["--goal-from", "[0, horizon"],
    );
    refused(&with(&["--threads", "0"]), &["--threads 0"]);
    refused(
        &with(&["--threads", "100000"]),
        &["--threads", "at most 1024"],
    );
    refused(&with(&["--threads", "-1"]), &["--threads"]);
    refused(
        &with(&["--threads", "18446744073709551616"]),
        &["--threads"],
    );
    refused(&with(&["--max-leaves", "0"]), &["--max-leaves 0"]);
    refused(
        &with(&["--max-leaves", "1000000"]),
        &["--max-leaves", "at most 100000"],
    );
    refused(&with(&["--samples", "0"]), &["--samples 0"]);
    refused(
        &with(&["--samples", "1000000"]),
        &["--samples", "at most 100000"],
    );
    refused(
        &with(&["--samples", "100000"]),
        &["--samples", "sampled points", "at most 1e7"],
    );
}

#[test]
fn reach_accepts_a_negative_interval_without_equals() {
    let dir = tempfile::tempdir().unwrap();
    let o = samara()
        .args(["reach", "--network", &net()])
        .args([
            "--y0",
            "-1:-0.99",
            "--horizon",
            "0.5",
            "--samples",
            "4",
            "--json",
        ])
        .arg("--out")
        .arg(dir.path())
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let r: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("reach.json")).unwrap())
            .unwrap();
    assert_eq!(r["settings"]["init"]["y"][0], -1.0);
}

#[test]
fn outputs_never_overwrite_an_input() {
    let dir = tempfile::tempdir().unwrap();
    // simulate: the controller sits in --out under a name the run writes.
    let sneaky = copy_ref(dir.path(), "base_model_denorm.onnx", "trajectories.csv");
    let before = std::fs::read(&sneaky).unwrap();
    let o = samara()
        .args(["simulate", "--horizon", "1", "--no-plot", "--controller"])
        .arg(&sneaky)
        .arg("--out")
        .arg(dir.path())
        .output()
        .unwrap();
    assert_usage(&o, &["--out", "would overwrite the input --controller"]);
    assert_eq!(std::fs::read(&sneaky).unwrap(), before);
    // reach: --out equal to, or inside, the network file.
    let n = copy_ref(dir.path(), "base_model_denorm.onnx", "net.onnx");
    for out in [n.clone(), n.join("sub")] {
        let o = samara()
            .args(["reach", "--horizon", "0.5", "--network"])
            .arg(&n)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        assert_usage(&o, &["--out", "would overwrite the input --network"]);
        assert!(n.is_file());
    }
    // reproduce: --out equal to or inside --published, checked before any folder exists.
    let published = dir.path().join("published");
    std::fs::create_dir(&published).unwrap();
    copy_ref(&published, "Training_Data.csv", "Training_Data.csv");
    for out in [published.clone(), published.join("run")] {
        let o = samara()
            .args(["reproduce", "--quick", "--published"])
            .arg(&published)
            .arg("--out")
            .arg(&out)
            .output()
            .unwrap();
        assert_usage(&o, &["--out", "would overwrite the input --published"]);
    }
    let names: Vec<_> = std::fs::read_dir(&published).unwrap().collect();
    assert_eq!(names.len(), 1, "reproduce wrote into --published");
    // reproduce: a missing --published is refused before --out is created.
    let o = samara()
        .args(["reproduce", "--quick", "--published"])
        .arg(dir.path().join("missing"))
        .arg("--out")
        .arg(dir.path().join("rp"))
        .output()
        .unwrap();
    assert_usage(&o, &["--published", "no such directory"]);
    assert!(!dir.path().join("rp").exists());
}

#[test]
fn failing_runs_leave_no_output_folder() {
    let dir = tempfile::tempdir().unwrap();
    let garbage = dir.path().join("garbage.onnx");
    std::fs::write(&garbage, b"not a network").unwrap();
    let g = garbage.display().to_string();
    refused(
        &["simulate", "--horizon", "1", "--controller", &g],
        &["--controller", "not a valid ONNX model"],
    );
    refused(
        &["reach", "--horizon", "0.5", "--network", &g],
        &["--network", "not a valid ONNX model"],
    );
    refused(
        &["reach", "--network", "missing.onnx"],
        &["--network missing.onnx", "no such file"],
    );
    refused(
        &["simulate", "--controller", "missing.onnx"],
        &["--controller missing.onnx", "no such file"],
    );
}

#[test]
fn an_os_error_is_printed_once() {
    let dir = tempfile::tempdir().unwrap();
    let outs = tempfile::tempdir().unwrap();
    // A directory where a network file is expected: the OS error used to appear twice.
    for args in [
        vec!["simulate", "--controller"],
        vec!["reach", "--horizon", "0.5", "--network"],
    ] {
        let o = samara()
            .args(&args)
            .arg(dir.path())
            .arg("--out")
            .arg(outs.path().join("o"))
            .output()
            .unwrap();
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{e}");
        assert_eq!(e.matches("os error").count(), 1, "{e}");
    }
    // An --out that cannot be created (samara-report's guard error carries its source).
    for args in [
        vec!["simulate", "--horizon", "1"],
        vec!["reach", "--horizon", "0.5", "--network", &net()],
    ] {
        let o = samara()
            .args(&args)
            .args(["--out", "/dev/null/x"])
            .output()
            .unwrap();
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{e}");
        assert_eq!(e.matches("os error").count(), 1, "{e}");
        assert!(e.contains("choose a writable --out"), "{e}");
    }
}

#[test]
fn data_reader_messages_name_the_file_without_a_zero_place() {
    let dir = tempfile::tempdir().unwrap();
    let idx = dir.path().join("empty.idx");
    std::fs::write(&idx, [0u8, 0, 0x0D, 2, 0, 0, 0, 0, 0, 0, 0, 7]).unwrap();
    let o = samara()
        .args(["robustness", "--network"])
        .arg(reference("base_model_norm.onnx"))
        .arg("--data")
        .arg(&idx)
        .output()
        .unwrap();
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains("empty.idx: "), "{e}");
    assert!(!e.contains(":0:") && !e.contains("0:0"), "{e}");
}

#[test]
fn every_subcommand_help_has_examples_and_exit_codes() {
    for cmd in [
        "simulate",
        "train",
        "check",
        "verify",
        "critical",
        "robustness",
        "verify-vnnlib",
        "export-vnnlib",
        "reach",
        "reproduce",
        "completions",
    ] {
        let o = run(&[cmd, "--help"]);
        let s = String::from_utf8_lossy(&o.stdout);
        assert_eq!(o.status.code(), Some(0), "{cmd}");
        assert!(
            s.contains("Examples:") && s.contains("samara "),
            "{cmd}: {s}"
        );
        assert!(s.contains("Exit codes: 0 success, 1"), "{cmd}: {s}");
    }
    let o = run(&["--help"]);
    assert!(String::from_utf8_lossy(&o.stdout).contains("Exit codes"));
}

#[test]
fn completions_for_every_shell() {
    for sh in ["bash", "zsh", "fish", "powershell", "elvish"] {
        let o = run(&["completions", sh]);
        assert_eq!(o.status.code(), Some(0), "{sh}");
        let s = String::from_utf8_lossy(&o.stdout);
        assert!(s.contains("samara") && s.contains("reach"), "{sh}");
    }
    assert_usage(&run(&["completions", "tcsh"]), &["invalid value 'tcsh'"]);
}

#[test]
fn reach_samples_periods_that_0_05_does_not_divide_and_says_when_none_is_finite() {
    let dir = tempfile::tempdir().unwrap();
    // Period 0.03: the sampled flights used an output step of 0.05, which does not divide
    // it, so every one failed and the range printed as [inf, -inf].
    let o = samara()
        .args(["reach", "--network", &net()])
        .args([
            "--y0",
            "2:2.01",
            "--period",
            "0.03",
            "--horizon",
            "0.06",
            "--json",
        ])
        .arg("--out")
        .arg(dir.path().join("a"))
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let lo = v["sampled_x_plus_y"][0].as_f64().unwrap();
    let hi = v["sampled_x_plus_y"][1].as_f64().unwrap();
    assert!(lo.is_finite() && hi.is_finite() && lo <= hi, "{v}");
    // v_xp = 0: the model is singular (atan(v_yp / v_xp)); no sampled flight stays finite.
    let o = samara()
        .args(["reach", "--network", &net()])
        .args(["--y0", "2:2.01", "--init", "v_xp=0", "--horizon", "0.5"])
        .args(["--max-leaves", "2", "--samples", "4"])
        .arg("--out")
        .arg(dir.path().join("b"))
        .output()
        .unwrap();
    let line = String::from_utf8_lossy(&o.stdout);
    assert!(matches!(o.status.code(), Some(0 | 1)), "{}", stderr(&o));
    assert!(
        line.contains("sampled: none") && !line.contains("inf, -inf"),
        "{line}"
    );
}

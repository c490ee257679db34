//! `samara reach --system` on a discrete-time file (VerticalCAS, the nine networks of
//! samara-reach's fixtures): verdicts and exit codes, and the input errors (exit 2).

use std::path::{Path, PathBuf};

use crate::support;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn nets() -> PathBuf {
    repo().join("crates/samara-reach/tests/data/archcomp/vcas")
}

fn run(args: &[&str]) -> (i32, String, String) {
    let o = support::samara().args(args).output().unwrap();
    (
        o.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

fn reach(sys: &Path, extra: &[&str], out: &Path) -> (i32, String, String) {
    let nets = nets();
    let mut a = vec![
        "reach",
        "--system",
        sys.to_str().unwrap(),
        "--network",
        nets.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--json",
    ];
    a.extend_from_slice(extra);
    run(&a)
}

#[test]
fn vcas_verdicts_and_exit_codes() {
    let dir = tempfile::tempdir().unwrap();
    // The competition's normalisation (hdot0 / 5000), as run.sh derives it.
    let src = std::fs::read_to_string(repo().join("examples/archcomp/vcas.sys")).unwrap();
    let comp = dir.path().join("vcas_competition.sys");
    std::fs::write(
        &comp,
        src.replace("param hdot_norm = 200\n", "param hdot_norm = 5000\n"),
    )
    .unwrap();
    let out = dir.path().join("a");
    let (code, stdout, stderr) = reach(
        &comp,
        &["--init", "hdot0=-22.5", "--choice", "middle"],
        &out,
    );
    assert_eq!(code, 0, "{stdout}{stderr}");
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(v["verdict"], "proved");
    assert!(out.join("reach.json").is_file());
    let out = dir.path().join("b");
    let (code, stdout, stderr) = reach(
        &comp,
        &["--init", "hdot0=-25.5", "--choice", "middle"],
        &out,
    );
    assert_eq!(code, 1, "{stdout}{stderr}");
    let v: serde_json::Value = serde_json::from_str(&stdout).unwrap();
    assert_eq!(v["verdict"], "violated");
}

#[test]
fn vcas_input_errors_exit_2() {
    let dir = tempfile::tempdir().unwrap();
    let sys = repo().join("examples/archcomp/vcas.sys");
    let out = dir.path().join("o");
    let (code, _, stderr) = reach(&sys, &["--choice", "worst"], &out);
    assert_eq!(code, 2, "{stderr}");
    assert!(
        stderr.contains("--choice worst: give all, middle, min or max"),
        "{stderr}"
    );
    let (code, _, stderr) = reach(&sys, &["--init", "hd=1"], &out);
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("`hd` is not a state"), "{stderr}");
    let (code, _, stderr) = reach(&sys, &["--order", "3"], &out);
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("--order"), "{stderr}");
    // One network where the file asks for one per advisory.
    let one = nets().join("VertCAS_noResp_pra01_v9_20HU_200.nnet");
    let (code, _, stderr) = run(&[
        "reach",
        "--system",
        sys.to_str().unwrap(),
        "--network",
        one.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 2, "{stderr}");
    assert!(stderr.contains("needs 9 network(s)"), "{stderr}");
    assert!(!out.exists());
    // --choice on a continuous file.
    let tora = repo().join("examples/archcomp/tora.sys");
    let (code, _, stderr) = run(&[
        "reach",
        "--system",
        tora.to_str().unwrap(),
        "--network",
        one.to_str().unwrap(),
        "--choice",
        "all",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 2, "{stderr}");
    assert!(
        stderr.contains("--choice applies to discrete-time"),
        "{stderr}"
    );
}

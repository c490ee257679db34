//! Issue 35 follow-up: printing into a closed stdout (`samara ... --json | head -c 10`)
//! used to panic with "failed printing to stdout: Broken pipe". The program must end
//! quietly instead: no panic message on stderr, exit code 0 (as ripgrep does).

use samara_nn::{onnx, Activation, Affine, Layer, Network};
use std::io::Read;
use std::process::Stdio;

use crate::support;
use support::samara;

/// Run `samara args`, read at most `keep` bytes of its stdout, close the pipe, and return
/// (exit code, stderr).
fn run_and_close_stdout_early(args: &[&str], keep: usize) -> (Option<i32>, String) {
    let mut child = samara()
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut out = child.stdout.take().unwrap();
    let mut buf = vec![0u8; keep];
    out.read_exact(&mut buf).unwrap();
    drop(out); // the read end is closed: every later write gets EPIPE
               // (with keep = 0, before the program has printed anything)
    let mut err = String::new();
    child
        .stderr
        .take()
        .unwrap()
        .read_to_string(&mut err)
        .unwrap();
    let status = child.wait().unwrap();
    (status.code(), err)
}

#[test]
fn a_closed_stdout_ends_the_program_quietly() {
    // Closed before anything is printed: the first write already gets EPIPE.
    let (code, err) = run_and_close_stdout_early(&["completions", "bash"], 0);
    assert!(!err.contains("panicked"), "{err}");
    assert!(err.is_empty(), "{err}");
    assert_eq!(code, Some(0), "{err}");
}

#[test]
fn verify_vnnlib_json_into_a_closed_pipe_does_not_panic() {
    let dir = tempfile::tempdir().unwrap();
    let net = Network {
        input_names: vec!["x0".into()],
        output_names: vec!["y0".into()],
        input_norm: None,
        layers: vec![
            Layer::Affine(Affine::new(1, 1, vec![1.0], vec![0.0])),
            Layer::Act(Activation::Relu),
        ],
        output_denorm: None,
    };
    let o = dir.path().join("n.onnx");
    onnx::save(&net, &o, &onnx::ExportOptions::default()).unwrap();
    let p = dir.path().join("p.vnnlib");
    std::fs::write(
        &p,
        "(declare-const X_0 Real)\n(declare-const Y_0 Real)\n\
         (assert (>= X_0 -1.0))\n(assert (<= X_0 1.0))\n(assert (< Y_0 0.0))\n",
    )
    .unwrap();
    let args = [
        "verify-vnnlib",
        "--network",
        o.to_str().unwrap(),
        "--property",
        p.to_str().unwrap(),
        "--json",
    ];
    let (code, err) = run_and_close_stdout_early(&args, 0);
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(code, Some(0), "{err}");
}

//! Helpers shared by the CLI test files: the binary under test and the published
//! reference files.
#![allow(dead_code)] // each test file uses its own subset

use std::process::Command;

pub mod sealing;

/// The shipped case-study spec, `models/alsomitra/alsomitra.spec`.
pub const SPEC: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../models/alsomitra/alsomitra.spec"
);

/// A published reference file as a path string (fails, never skips, when it is
/// missing).
#[allow(unused_imports)] // each test file uses its own subset
pub use samara_testkit::{published_dir, reference, reference_str};

/// The `samara` binary built for these tests.
pub fn samara() -> Command {
    Command::new(env!("CARGO_BIN_EXE_samara"))
}

/// Run `samara ARGS`; (exit code, stdout, stderr, wall time).
pub fn timed(args: &[&str]) -> (Option<i32>, String, String, std::time::Duration) {
    let t0 = std::time::Instant::now();
    let o = samara().args(args).output().unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
        t0.elapsed(),
    )
}

/// The JSON a run printed on stdout, after asserting it exited 0 (its stderr in the
/// failure message).
pub fn json_of_success(o: &std::process::Output) -> serde_json::Value {
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    serde_json::from_slice(&o.stdout).unwrap()
}

/// Run `samara verify-vnnlib --json --timeout 20` on a network and a property file;
/// (exit code, the JSON printed, wall time). Fails with the output when it is not JSON.
pub fn verify_vnnlib_json(
    onnx: &str,
    prop: &str,
) -> (Option<i32>, serde_json::Value, std::time::Duration) {
    let t0 = std::time::Instant::now();
    let o = samara()
        .args(["verify-vnnlib", "--network", onnx, "--property", prop])
        .args(["--timeout", "20", "--json"])
        .output()
        .unwrap();
    let dt = t0.elapsed();
    let v = serde_json::from_slice(&o.stdout).unwrap_or_else(|_| {
        panic!(
            "{}{}",
            String::from_utf8_lossy(&o.stdout),
            String::from_utf8_lossy(&o.stderr)
        )
    });
    (o.status.code(), v, dt)
}

/// ARCH-COMP's TORA (`examples/archcomp/tora.sys`, text `tora`) with its x1 and x3
/// intervals widened three times, the horizon `horizon` and the band `|x1 + x2| <= 100`
/// at the end in place of its goals: a measure for the adaptive tests (`--target-ratio`).
pub fn widened_tora(tora: &str, horizon: u32) -> String {
    tora.replace("horizon 20", &format!("horizon {horizon}"))
        .replace("init x1 in [0.6, 0.7]", "init x1 in [0.5, 0.8]")
        .replace("init x3 in [-0.4, -0.3]", "init x3 in [-0.5, -0.2]")
        .lines()
        .filter(|l| !l.starts_with("goal"))
        .map(|l| format!("{l}\n"))
        .collect::<String>()
        + "goal band |x1 + x2| <= 100 at end\n"
}

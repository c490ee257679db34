//! Issue 35, item 7: a zonotope run without a goal whose sets stop before the horizon
//! has no result; it must not look like success. The case (the reduced model,
//! a small box around level flight, --horizon 20) loses the enclosure within the first
//! periods; here the same box over --horizon 0.5 with one sub-box loses it at once
//! (t = 0.37), and Taylor-model sets (`--sets auto`'s second try) enclose it.

use serde_json::Value;
use std::ffi::OsStr;
use std::path::Path;

use crate::support;
use support::{reference, samara};

const BOX: [&str; 16] = [
    "--model",
    "reduced",
    "--init",
    "v_xp=0.99:1.01",
    "--init",
    "v_yp=-0.01:0.01",
    "--init",
    "omega=-0.01:0.01",
    "--init",
    "theta=-0.01:0.01",
    "--init",
    "x=-0.05:0.05",
    "--horizon",
    "0.5",
    "--max-leaves",
    "1",
];

fn reach(out: &Path, extra: &[&str]) -> (Option<i32>, String, String) {
    let net = reference("base_model_denorm.onnx");
    let mut a: Vec<&OsStr> = vec!["reach".as_ref(), "--network".as_ref(), net.as_os_str()];
    a.extend(BOX.iter().map(OsStr::new));
    a.extend(extra.iter().map(OsStr::new));
    a.extend([
        "--threads".as_ref(),
        "1".as_ref(),
        "--out".as_ref(),
        out.as_os_str(),
    ]);
    let o = samara().args(a).output().unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stdout).into_owned(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
fn a_lost_enclosure_without_a_goal_exits_1_naming_where() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("z");
    let (code, o, e) = reach(&out, &[]);
    assert_eq!(code, Some(1), "{o}{e}");
    // The line names the sub-box, its initial box, the control period and the time.
    assert!(
        o.starts_with("none: x + y at t = 0.5 in [-inf, inf]"),
        "{o}"
    );
    for needle in [
        "no result: the enclosure was lost before the horizon t = 0.5 in 1 of 1 sub-boxes",
        "sub-box 1 of 1 (v_xp in [0.99, 1.01],",
        "in control period 1 (t in [0, 0.5])",
        "no validated enclosure at t = ",
    ] {
        assert!(o.contains(needle), "{needle:?} not in {o}");
    }
    // The JSON says the same, in reach.json and in the summary.
    let v: Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("reach.json")).unwrap()).unwrap();
    assert_eq!(v["verdict"]["verdict"], "none");
    assert!(v["leaves"][0]["failure"].is_string());
    assert!(
        v["enclosure_lost"]
            .as_str()
            .unwrap()
            .contains("control period 1"),
        "{}",
        v["enclosure_lost"]
    );
    let out2 = dir.path().join("z2");
    let (code, o, e) = reach(&out2, &["--json"]);
    assert_eq!(code, Some(1), "{o}{e}");
    let s: Value = serde_json::from_str(&o).unwrap();
    assert_eq!(s["enclosure_lost"], v["enclosure_lost"]);
}

#[test]
fn sets_auto_goes_on_to_taylor_models_when_zonotopes_lose_the_enclosure() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("a");
    let (code, o, e) = reach(&out, &["--sets", "auto"]);
    assert!(
        e.contains("--sets auto: the zonotope sets left the goal unknown or lost the enclosure"),
        "{e}"
    );
    // The zonotope run's files stay; the Taylor-model run's are beside them, and it is
    // the result: the whole box enclosed to the horizon (exit 0).
    assert!(out.join("reach.json").exists());
    let t: Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("taylor").join("reach.json")).unwrap(),
    )
    .unwrap();
    assert_eq!(code, Some(0), "{o}{e}");
    assert_eq!(t["result"]["covered"], 1.0, "{}", t["result"]);
}

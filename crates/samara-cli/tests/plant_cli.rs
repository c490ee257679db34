//! Issue 35's plant cases end to end, through the `samara` binary:
//! - one meaning of a plant (item 1): the plant whose reset `reach --system` used to
//!   fire at the horizon is never `proved`, and `simulate --system` shows the flight
//!   that violates its goal;
//! - time limits (item 3): a sliding-mode plant, whose field points at the switch `x =
//!   0` from both sides, stalls every integrator (the step size collapses on the
//!   discontinuity); `reach --system` still comes back within `--timeout` plus the larger
//!   of 1 s and one control period, with `unknown (timeout)` and exit code 1;
//! - discontinuous dynamics (item 4): `simulate --system` on it names the switch.

use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::support;

/// A network with `n` inputs and 1 output, `u = 0.1 relu(sum of inputs) + 0.05`, as
/// ONNX.
fn small_network(dir: &Path, n: usize) -> PathBuf {
    use samara_nn::{Activation, Affine, Layer, Network};
    let net = Network {
        input_names: (0..n).map(|i| format!("x{i}")).collect(),
        output_names: vec!["u".into()],
        input_norm: None,
        layers: vec![
            Layer::Affine(Affine::new(n, 1, vec![1.0; n], vec![0.0])),
            Layer::Act(Activation::Relu),
            Layer::Affine(Affine::new(1, 1, vec![0.1], vec![0.05])),
        ],
        output_denorm: None,
    };
    let p = dir.join(format!("c{n}.onnx"));
    samara_nn::onnx::save(&net, &p, &Default::default()).unwrap();
    p
}

/// The sliding-mode plant of issue 35: `x' = y + 0.5` left of 0, `y - 0.5` right of it,
/// with `|y| < 0.5` throughout, so every flight from the box reaches `x = 0` and slides
/// along it.
pub const SLIDE: &str = "state x, y\ninput u\n\
    x' = if x < 0 then y + 0.5 else y - 0.5\ny' = 0.01 * u\nperiod 0.5\nhorizon 5\n\
    actuate u = net[0]\ninit x in [-0.1, 0.1]\ninit y in [-0.1, 0.1]\n\
    goal band x <= 1 always\n";

/// A temporary folder with `slide.sys` and `c.onnx`, and an output path inside it (the
/// folder lives as long as the first value).
fn slide_files() -> (tempfile::TempDir, PathBuf, PathBuf, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let sys = dir.path().join("slide.sys");
    std::fs::write(&sys, SLIDE).unwrap();
    let net = small_network(dir.path(), 2);
    let out = dir.path().join("o");
    (dir, sys, net, out)
}

#[test]
fn sliding_mode_reach_returns_within_the_timeout() {
    let (_dir, sys, net, out) = slide_files();
    let timeout = 2.0;
    let start = Instant::now();
    let o = support::samara()
        .args(["reach", "--system"])
        .arg(&sys)
        .arg("--network")
        .arg(&net)
        .args(["--timeout", "2", "--json", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let wall = start.elapsed().as_secs_f64();
    let stdout = String::from_utf8_lossy(&o.stdout);
    let stderr = String::from_utf8_lossy(&o.stderr);
    eprintln!("{wall:.2} s\n{stdout}\n{stderr}");
    // The promise: timeout + max(1 s, one period of 0.5 s).
    assert!(wall <= timeout + 1.0, "{wall:.2} s");
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    let v: serde_json::Value = serde_json::from_str(stdout.trim()).unwrap();
    assert_eq!(v["verdict"]["verdict"], "unknown", "{v}");
    let reason = v["verdict"]["reason"].as_str().unwrap();
    assert!(reason.starts_with("timeout after 2."), "{reason}");
    // The falsification flights collapse on the switch; the reason names it.
    assert!(reason.contains("slide.sys:3:6"), "{reason}");
}

/// Discontinuous dynamics get a diagnosis (issue 35, item 4): `samara simulate
/// --system` on the sliding-mode plant exits 2 at once with a message naming the
/// collapse, its time, the `if` with its place in the file, and the fixes, not "the
/// state became NaN or infinite"; nothing is left in the output folder.
#[test]
fn sliding_mode_simulate_names_the_switch() {
    let (_dir, sys, net, out) = slide_files();
    let start = Instant::now();
    let o = support::samara()
        .args(["simulate", "--system"])
        .arg(&sys)
        .arg("--controller")
        .arg(&net)
        .args(["--samples", "3", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    let wall = start.elapsed().as_secs_f64();
    let stderr = String::from_utf8_lossy(&o.stderr);
    eprintln!("{wall:.2} s\n{stderr}");
    assert_eq!(o.status.code(), Some(2), "{stderr}");
    assert!(wall < 5.0, "{wall:.2} s");
    for needle in [
        "step size collapsed at t = ",
        "slide.sys:3:6",
        "x' = if x < 0 then y + 0.5 else y - 0.5",
        "tanh",
        "hysteresis",
    ] {
        assert!(stderr.contains(needle), "missing {needle:?}: {stderr}");
    }
    assert!(!stderr.contains("NaN or infinite"), "{stderr}");
    assert!(!out.exists(), "a failed run leaves no output folder");
}

/// The plant of issue 35 (item 1): `acc` integrates a spike around x = 0.3123 and is
/// reset at every control instant; the goal asks it to be near 0 at the horizon.
fn spike(init_x: &str) -> String {
    format!(
        "state x, acc\ninput u\nx' = 1e-6 * u\nacc' = max(0, 1 - 1e8 * (x - 0.3123)^2)\n\
         reset acc = 0\nperiod 0.5\nhorizon 2\nobserve x\nactuate u = net[0]\n\
         init x {init_x}\ninit acc = 0\ngoal band acc <= 0.000001 at end\n"
    )
}

/// `reach --system` on the spike plant over x in [-1, 1] said `proved` (exit 0) before
/// the fix; with one falsification flight (which misses the spike) the sets decide and
/// must not prove it. `simulate --system` from x = 0.3123 ends with acc about 0.5 (the
/// last period's integral of the spike, closed form) and exits 1 for the violated goal.
#[test]
fn reset_plant_reach_never_proves_what_simulate_violates() {
    let dir = tempfile::tempdir().unwrap();
    let sys = dir.path().join("spike.sys");
    std::fs::write(&sys, spike("in [-1, 1]")).unwrap();
    let net = small_network(dir.path(), 1);
    let o = support::samara()
        .args(["reach", "--system"])
        .arg(&sys)
        .arg("--network")
        .arg(&net)
        .args([
            "--samples",
            "1",
            "--max-leaves",
            "2",
            "--network-error",
            "interval",
        ])
        .args(["--json", "--out"])
        .arg(dir.path().join("r"))
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    let v: serde_json::Value = serde_json::from_str(stdout.trim())
        .unwrap_or_else(|e| panic!("{e}: {stdout} {}", String::from_utf8_lossy(&o.stderr)));
    let verdict = v["verdict"]["verdict"].as_str().unwrap();
    assert!(verdict == "unknown" || verdict == "violated", "{v}");
    assert_eq!(o.status.code(), Some(1), "{v}");
    let point = dir.path().join("point.sys");
    std::fs::write(&point, spike("= 0.3123")).unwrap();
    let o = support::samara()
        .args(["simulate", "--system"])
        .arg(&point)
        .arg("--controller")
        .arg(&net)
        .args(["--samples", "1", "--json", "--out"])
        .arg(dir.path().join("s"))
        .output()
        .unwrap();
    assert_eq!(
        o.status.code(),
        Some(1),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let csv = std::fs::read_to_string(dir.path().join("s/trajectories.csv")).unwrap();
    let last: Vec<f64> = csv
        .lines()
        .last()
        .unwrap()
        .split(',')
        .map(|v| v.parse().unwrap())
        .collect();
    // start, t, x, acc, u
    assert_eq!(last[1], 2.0);
    assert!(
        (last[3] - 0.5).abs() < 1e-4,
        "acc at the horizon {}",
        last[3]
    );
}

//! Issue 35, time limits: every command given an input built to stall it returns within
//! its `--timeout` plus 1 s, with `unknown (timeout)` and exit 1. The limits are kept
//! small (1-2 s) so these tests are fast.

use samara_nn::{onnx, Activation, Affine, Layer, Network};
use std::path::Path;
use std::time::Duration;

use crate::support;
use support::timed;

/// A VNN-COMP-style MNIST classifier: 784 inputs, two dense layers of 256 ReLUs, 10
/// outputs, seeded He-style random weights (a fixed xorshift, so the file is the same
/// on every run).
fn mnist_like() -> Network {
    dense_classifier(&[784, 256, 256, 10])
}

/// A dense ReLU classifier with layer widths `dims` and seeded He-style random weights.
fn dense_classifier(dims: &[usize]) -> Network {
    let mut state = 0x9E37_79B9_7F4A_7C15u64;
    let mut next = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    let mut layers = Vec::new();
    for (k, w) in dims.windows(2).enumerate() {
        let (i, o) = (w[0], w[1]);
        let scale = (6.0 / i as f64).sqrt();
        layers.push(Layer::Affine(Affine::new(
            i,
            o,
            (0..i * o).map(|_| next() * scale).collect(),
            (0..o).map(|_| next() * 0.1).collect(),
        )));
        if k + 2 < dims.len() {
            layers.push(Layer::Act(Activation::Relu));
        }
    }
    let (n_in, n_out) = (dims[0], dims[dims.len() - 1]);
    Network {
        input_names: (0..n_in).map(|i| format!("x{i}")).collect(),
        output_names: (0..n_out).map(|i| format!("y{i}")).collect(),
        input_norm: None,
        layers,
        output_denorm: None,
    }
}

/// The network and a property around a seeded "image": an L-infinity ball of radius
/// `eps` clipped to [0, 1]; counterexample: some output at least the network's own top
/// output at the image (a disjunction of 9, `threshold = None`), or some output at least
/// `threshold` (a disjunction of 10; 3.0 is far above what the search can settle in a
/// few seconds at radius 0.03: it stalls).
fn write_mnist(dir: &Path, eps: f64, threshold: Option<f64>) -> (String, String) {
    write_classifier(dir, mnist_like(), eps, threshold)
}

/// [`write_mnist`] for any classifier `net` with 10 outputs.
fn write_classifier(
    dir: &Path,
    net: Network,
    eps: f64,
    threshold: Option<f64>,
) -> (String, String) {
    let n_in = net.input_names.len();
    let img: Vec<f64> = (0..n_in)
        .map(|i| ((i * 7919 % 997) as f64 / 997.0).powi(3))
        .collect();
    let y = net.eval_f64(&img);
    let top = (0..10).max_by(|a, b| y[*a].total_cmp(&y[*b])).unwrap();
    let path = dir.join("mnist.onnx");
    onnx::save(&net, &path, &onnx::ExportOptions::default()).unwrap();
    let mut t = String::new();
    for i in 0..n_in {
        t += &format!("(declare-const X_{i} Real)\n");
    }
    for j in 0..10 {
        t += &format!("(declare-const Y_{j} Real)\n");
    }
    for (i, v) in img.iter().enumerate() {
        t += &format!(
            "(assert (>= X_{i} {}))\n(assert (<= X_{i} {}))\n",
            (v - eps).max(0.0),
            (v + eps).min(1.0)
        );
    }
    t += "(assert (or\n";
    for j in (0..10).filter(|j| *j != top || threshold.is_some()) {
        match threshold {
            Some(c) => t += &format!("  (and (>= Y_{j} {c:?}))\n"),
            None => t += &format!("  (and (>= Y_{j} Y_{top}))\n"),
        }
    }
    t += "))\n";
    let prop = dir.join("mnist.vnnlib");
    std::fs::write(&prop, t).unwrap();
    (path.display().to_string(), prop.display().to_string())
}

/// `verify-vnnlib --timeout SECONDS`, asserted to return within SECONDS + 1;
/// (exit code, stdout, stderr).
fn vnnlib_within(net: &str, prop: &str, seconds: u64) -> (Option<i32>, String, String) {
    let limit = seconds.to_string();
    let args = [
        "verify-vnnlib",
        "--network",
        net,
        "--property",
        prop,
        "--timeout",
        &limit,
    ];
    let (code, out, err, dt) = timed(&args);
    assert!(dt < Duration::from_secs(seconds + 1), "{dt:?}: {out}{err}");
    (code, out, err)
}

/// The look-ahead of the input-split search bounded both halves of all 784 inputs by
/// full CROWN without looking at the clock (minutes per piece), alpha-CROWN's steps and
/// the forward pass did not either, and a counterexample was re-checked in rational
/// arithmetic (seconds at this size): `--timeout 2` ran past 120 s.
#[test]
fn verify_vnnlib_on_an_mnist_size_classifier_keeps_its_time_limit() {
    let dir = tempfile::tempdir().unwrap();
    for (threshold, name) in [(Some(3.0), "stalling"), (None, "robustness")] {
        let (net, prop) = write_mnist(dir.path(), 0.03, threshold);
        let (code, out, err) = vnnlib_within(&net, &prop, 2);
        // A cut-short search says timeout (exit 1); a found point is sat (exit 1).
        if threshold.is_some() {
            assert!(
                out.starts_with("timeout")
                    || out.starts_with("unknown")
                    || out.starts_with("unsat"),
                "{name}: {out}{err}"
            );
        }
        let want = if out.starts_with("unsat") { 0 } else { 1 };
        assert_eq!(code, Some(want), "{name}: {out}{err}");
    }
}

/// A CIFAR-size dense classifier (3,072 inputs, two layers of 1,024 ReLUs): the bound
/// pass that settles constant output constraints ran once per disjunct (nine times) and
/// without a clock, and preparing the network was not counted, so `--timeout 1` took
/// 2.5 s on oval21's cifar_wide (issue 37). Each step now counts against the limit.
#[test]
fn verify_vnnlib_on_a_cifar_size_classifier_keeps_its_time_limit() {
    let dir = tempfile::tempdir().unwrap();
    let net = dense_classifier(&[3072, 1024, 1024, 10]);
    let (net, prop) = write_classifier(dir.path(), net, 0.01, None);
    let (code, out, err) = vnnlib_within(&net, &prop, 1);
    let want = if out.starts_with("unsat") { 0 } else { 1 };
    assert_eq!(code, Some(want), "{out}{err}");
}

use support::{reference_str as reference, SPEC};

/// `critical` ran each of its two searches with the whole limit (20.0 s for
/// `--timeout 10` on this network); `verify` gave every instance of a data-set property
/// the whole limit (360 instances); `robustness` gave every point's searches the whole
/// limit and enumerated up to 2^14 activation patterns per point without a clock. Each
/// `--timeout` is now a deadline for the command.
#[test]
fn critical_verify_and_robustness_take_the_timeout_as_a_deadline() {
    let net = reference("goedel_lipschitz_norm.onnx");
    let f = format!("f={net}");
    let data = reference("Training_Data_Normalised.csv");
    let runs: Vec<(&str, Vec<&str>)> = vec![
        // P1 on this network completes in about 0.2 s (release) since the one engine:
        // a 10 ms deadline is what cuts it short.
        (
            "critical",
            vec![
                "critical",
                SPEC,
                "--property",
                "p1",
                "--param",
                "ystar",
                "--network",
                &f,
                "--timeout",
                "0.01",
            ],
        ),
        (
            "verify",
            vec![
                "verify",
                SPEC,
                "--property",
                "p5_lipschitz",
                "--network",
                &f,
                "--timeout",
                "1",
            ],
        ),
        (
            "robustness",
            vec![
                "robustness",
                "--network",
                &net,
                "--data",
                &data,
                "--eps",
                "0.01,0.05",
                "--timeout",
                "1",
            ],
        ),
    ];
    for (name, args) in runs {
        let (code, out, err, dt) = timed(&args);
        assert!(dt < Duration::from_secs(2), "{name}: {dt:?}: {out}{err}");
        // The robustness table exits 0 with its unknown points counted (its exit code
        // is not a verdict); critical and verify exit 1 on unknown.
        if name != "robustness" {
            assert_eq!(code, Some(1), "{name}: {out}{err}");
        }
        assert!(
            out.contains("unknown") || out.contains("timeout"),
            "{name}: {out}{err}"
        );
    }
}

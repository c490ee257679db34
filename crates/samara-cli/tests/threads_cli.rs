//! `--threads N` on the verification commands: the same verdicts and values with one
//! worker as with two (the engines batch their searches in a fixed order), and a bad
//! count refused naming the flag.

use crate::support;
use support::samara;
use support::{reference_str as reference, SPEC};

/// The document without its wall times.
fn without_times(v: &mut serde_json::Value) {
    match v {
        serde_json::Value::Object(m) => {
            m.remove("seconds");
            m.remove("total_seconds");
            m.values_mut().for_each(without_times);
        }
        serde_json::Value::Array(a) => a.iter_mut().for_each(without_times),
        _ => {}
    }
}

fn run_json(args: &[&str]) -> serde_json::Value {
    let out = samara().args(args).output().unwrap();
    assert!(
        matches!(out.status.code(), Some(0) | Some(1)),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    without_times(&mut v);
    v
}

#[test]
fn one_and_two_threads_give_the_same_answers() {
    let net = format!("f={}", reference("adversarial_model_norm.onnx"));
    for cmd in [
        vec!["critical", SPEC, "--property", "p1", "--param", "ystar"],
        vec!["verify", SPEC, "--property", "p1", "--param", "ystar=20"],
        vec!["verify", SPEC, "--property", "p5"],
    ] {
        let mut docs = Vec::new();
        for t in ["1", "2"] {
            let mut a = cmd.clone();
            a.extend(["--network", &net, "--json", "--threads", t]);
            docs.push(run_json(&a));
        }
        assert_eq!(docs[0], docs[1], "{cmd:?}");
    }
}

#[test]
fn a_bad_thread_count_is_refused_naming_the_flag() {
    for t in ["0", "5000"] {
        let out = samara()
            .args(["verify", SPEC, "--property", "p1", "--threads", t])
            .output()
            .unwrap();
        assert_eq!(out.status.code(), Some(2));
        assert!(String::from_utf8_lossy(&out.stderr).contains("--threads"));
    }
}

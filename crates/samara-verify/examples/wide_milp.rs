//! P1-P4 critical values of raw-unit 6-input networks by samara's exact engine and by the
//! HiGHS big-M MILP (`samara_verify::milp`), with times (bench/verify/wide.sh).
//! Usage: cargo run --release -p samara-verify --features highs --example wide_milp -- [--timeout S] [--only pK] NET.onnx...
//! (HiGHS stops at `samara_verify::milp::TIME_LIMIT_S` per disjunct: an error row then).

#[path = "../tests/support/case_study.rs"]
mod case_study;

use case_study::p1_to_p4;
use samara_verify::milp::optimise_milp;
use samara_verify::net::PwlNet;
use samara_verify::{optimise, Prepared, Settings, Timeout};
use std::collections::HashMap;
use std::time::Instant;

fn main() {
    println!(
        "network,property,samara_value,samara_bound,samara_complete,samara_s,highs_value,highs_s"
    );
    // `--timeout S` (first) bounds samara's search per property (default 600 s).
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let mut timeout = Timeout::from_secs(600);
    if args.first().map(String::as_str) == Some("--timeout") && args.len() >= 2 {
        let secs: f64 = args[1].parse().expect("--timeout S: a number of seconds");
        timeout = Timeout::from_secs_f64(secs).expect("--timeout S: seconds >= 0");
        args.drain(..2);
    }
    // `--only pK` (next) computes one property.
    let mut only: Option<String> = None;
    if args.first().map(String::as_str) == Some("--only") && args.len() >= 2 {
        only = Some(args[1].clone());
        args.drain(..2);
    }
    for path in args {
        let net = samara_nn::onnx::load(&path).expect("an ONNX network");
        let mut nets = HashMap::new();
        nets.insert("f".to_string(), net);
        let prep = Prepared::new(&nets);
        let pwl: HashMap<String, PwlNet> = nets
            .iter()
            .map(|(k, v)| (k.clone(), PwlNet::from_network(v).expect("a ReLU network")))
            .collect();
        let name = std::path::Path::new(&path)
            .file_stem()
            .unwrap()
            .to_string_lossy()
            .into_owned();
        // P1-P4 lowered from models/alsomitra/alsomitra.spec, with the network in raw units
        // (networks that carry their own normalisation layers) or, for a `*_norm.onnx`
        // file (normalised inputs and output, like the published ones), in the spec's
        // normalised units.
        let raw = !name.ends_with("_norm");
        for q in p1_to_p4(raw) {
            if only.as_ref().is_some_and(|o| *o != q.name) {
                continue;
            }
            let t = Instant::now();
            let ours = optimise(
                &q,
                &prep,
                &Settings {
                    timeout,
                    ..Default::default()
                },
            )
            .expect("a well-formed query");
            let ts = t.elapsed().as_secs_f64();
            let t = Instant::now();
            let theirs = optimise_milp(&q, &pwl);
            let th = t.elapsed().as_secs_f64();
            let fmt = |v: Option<f64>| v.map_or("empty".into(), |v| format!("{v:.9}"));
            println!(
                "{name},{},{},{:.9},{},{ts:.3},{},{th:.3}",
                q.name,
                fmt(ours.value),
                ours.bound,
                ours.complete,
                match theirs {
                    Ok(v) => fmt(v),
                    Err(e) => format!("error: {e}"),
                }
            );
        }
    }
}

//! P1-P4 critical values of networks in the case study's normalised units by
//! `samara_verify::optimise`, with times and node counts:
//! `cargo run --release -p samara-verify --example critical_opt -- NET.onnx... [--timeout S]
//! [--only pK] [--raw]` (`--raw`: networks in raw units, which normalise themselves).

#[path = "../tests/support/case_study.rs"]
mod case_study;

use samara_verify::{optimise, Prepared, Settings, Timeout};
use std::collections::HashMap;
use std::time::Instant;

fn main() {
    let mut timeout = Timeout::from_secs(60);
    let mut files = Vec::new();
    let mut only: Option<String> = None;
    let mut raw = false;
    let mut it = std::env::args().skip(1);
    while let Some(a) = it.next() {
        match a.as_str() {
            "--timeout" => {
                timeout = it
                    .next()
                    .and_then(|t| t.parse().ok())
                    .and_then(|t| Timeout::from_secs_f64(t).ok())
                    .expect("--timeout S: seconds >= 0")
            }
            "--only" => only = it.next(),
            "--raw" => raw = true,
            f => files.push(f.to_string()),
        }
    }
    println!("network,property,value,bound,complete,attained,nodes,seconds");
    for path in files {
        let net = samara_nn::onnx::load(&path).expect("an ONNX network");
        let mut nets = HashMap::new();
        nets.insert("f".to_string(), net);
        let prep = Prepared::new(&nets);
        for q in case_study::p1_to_p4(raw) {
            if only.as_ref().is_some_and(|o| *o != q.name) {
                continue;
            }
            let t = Instant::now();
            let c = optimise(
                &q,
                &prep,
                &Settings {
                    timeout,
                    ..Default::default()
                },
            )
            .expect("a well-formed query");
            println!(
                "{path},{},{:?},{:.9},{},{},{},{:.3},{:?}",
                q.name,
                c.value,
                c.bound,
                c.complete,
                c.attained,
                c.nodes,
                t.elapsed().as_secs_f64(),
                c.unknown
            );
        }
    }
}

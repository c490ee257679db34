//! P1-P4 critical values for networks with the case study's conventions:
//! `cargo run --release -p samara-verify --example critical_table -- REFERENCE_DIR
//! [--raw NET.onnx ...] [--only-raw]`
//! (`--raw`: more networks in raw units, e.g. a 6-64-32-1 one trained by samara).
//! The properties, units and domain are those of models/alsomitra/alsomitra.spec.

use samara_verify::{optimise, Prepared, Settings};
use std::collections::HashMap;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut dir = std::path::PathBuf::from("../shared/reference");
    let mut files: Vec<String> = [
        "base_model_norm.onnx",
        "adversarial_model_norm.onnx",
        "base_model_denorm.onnx",
        "adversarial_model_denorm.onnx",
    ]
    .iter()
    .map(|f| f.to_string())
    .collect();
    let mut raw_extra = Vec::new();
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--raw" => raw_extra.push(it.next().expect("--raw PATH").clone()),
            "--only-raw" => files.clear(),
            d => dir = d.into(),
        }
    }
    files.extend(raw_extra);
    let settings = Settings::default();
    let mut total = 0.0;
    for file in &files {
        let net = samara_nn::onnx::load(dir.join(file)).unwrap();
        let raw = file.contains("denorm") || !file.contains("_norm");
        let mut nets = HashMap::new();
        nets.insert("f".to_string(), net);
        let prep = Prepared::new(&nets);
        let t = std::time::Instant::now();
        for q in p1_to_p4(raw) {
            let r = optimise(&q, &prep, &settings).unwrap();
            println!(
                "{file:32} {}: critical {:>12} bound {:>12.6} attained {} complete {} vacuous {} domain {:>10} nodes {} {:.3}s",
                q.name,
                r.value.map(|v| format!("{v:.6}")).unwrap_or("none".into()),
                r.bound,
                r.attained,
                r.complete,
                r.vacuous,
                r.domain_extreme.map(|v| format!("{v:.4}")).unwrap_or("-".into()),
                r.nodes,
                r.seconds
            );
        }
        let secs = t.elapsed().as_secs_f64();
        total += secs;
        println!("{file}: table in {secs:.3} s");
    }
    println!("all tables in {total:.3} s");
}

/// P1-P4 of models/alsomitra/alsomitra.spec as critical queries of `ystar` (P1, P2 hold
/// above the supremum, P3, P4 below the infimum), for a network in the spec's units or,
/// with `raw`, one taking raw inputs and giving raw outputs.
fn p1_to_p4(raw: bool) -> Vec<samara_spec::normal::Query> {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../models/alsomitra/alsomitra.spec");
    let mut spec = samara_spec::Spec::read(&path).unwrap();
    if raw {
        spec.networks[0].in_norm = None;
        spec.networks[0].out_norm = None;
    }
    ["p1", "p2", "p3", "p4"]
        .iter()
        .map(|p| {
            let mut q = spec
                .lower_critical(p, "ystar", &samara_spec::Bindings::default())
                .unwrap()
                .remove(0)
                .query;
            if let samara_spec::normal::Goal::Optimise { sense, .. } = &mut q.goal {
                if *p == "p3" || *p == "p4" {
                    *sense = samara_spec::normal::Sense::Min;
                }
            }
            q
        })
        .collect()
}

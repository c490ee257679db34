//! P1-P4 critical values for networks with the case study's conventions:
//! `cargo run --release -p samara-verify --example critical_table -- REFERENCE_DIR`.

use samara_verify::case_study::{p1_to_p4, Units};
use samara_verify::{optimise, Prepared, Settings};
use std::collections::HashMap;

fn main() {
    let dir = std::path::PathBuf::from(
        std::env::args()
            .nth(1)
            .unwrap_or_else(|| "../shared/reference".into()),
    );
    let text = std::fs::read_to_string(dir.join("Normalisation_Constants.csv")).unwrap();
    let rows: Vec<Vec<f64>> = text
        .lines()
        .map(|l| l.split(',').map(|v| v.trim().parse().unwrap()).collect())
        .collect();
    let (c, s) = (rows[0][..6].to_vec(), rows[1][..6].to_vec());
    let lo = c.clone();
    let hi: Vec<f64> = c.iter().zip(&s).map(|(a, b)| a + b).collect();
    for file in [
        "base_model_norm.onnx",
        "adversarial_model_norm.onnx",
        "base_model_denorm.onnx",
        "adversarial_model_denorm.onnx",
    ] {
        let net = samara_nn::onnx::load(dir.join(file)).unwrap();
        let units = if file.contains("denorm") {
            Units::raw()
        } else {
            Units {
                c: c.clone(),
                s: s.clone(),
                c_out: 0.181,
                s_out: 0.012,
            }
        };
        let mut nets = HashMap::new();
        nets.insert("f".to_string(), net);
        let prep = Prepared::new(&nets);
        let t = std::time::Instant::now();
        for q in p1_to_p4("f", &units, &lo, &hi) {
            let r = optimise(&q, &prep, &Settings::default()).unwrap();
            println!(
                "{file:32} {}: critical {:>12} bound {:>12.6} attained {} vacuous {} domain {:>10} nodes {} {:.3}s",
                q.name,
                r.value.map(|v| format!("{v:.6}")).unwrap_or("none".into()),
                r.bound,
                r.attained,
                r.vacuous,
                r.domain_extreme.map(|v| format!("{v:.4}")).unwrap_or("-".into()),
                r.nodes,
                r.seconds
            );
        }
        println!("{file}: table in {:.3} s", t.elapsed().as_secs_f64());
    }
}

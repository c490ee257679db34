//! Trains every method on a data file and prints the accuracy/robustness trade-off:
//! `cargo run --release -p samara-train --example tradeoff -- DATA.csv [EPOCHS] [EPS]`.

use samara_train::{
    case_study_spec, read_table, spec_properties, train, Attack, Logic, Method, MinMax,
    TrainOptions,
};
use std::time::Instant;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let path = args
        .get(1)
        .map(String::as_str)
        .unwrap_or("../shared/reference/Training_Data.csv");
    let epochs: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(1000);
    let eps: f64 = args.get(3).and_then(|s| s.parse().ok()).unwrap_or(0.005);
    let data = read_table(std::path::Path::new(path)).expect("data");
    let mm = MinMax::of(&data);
    // P1-P4 of models/alsomitra/alsomitra.spec over the data's box.
    let domain = (0..6)
        .map(|j| (mm.min[j], mm.min[j] + mm.range[j]))
        .collect();
    let names = ["p1", "p2", "p3", "p4"].map(String::from);
    let props = spec_properties(
        &case_study_spec(),
        &names,
        &Default::default(),
        &mm,
        Some(domain),
    )
    .expect("P1-P4 train");
    let methods = vec![
        Method::Plain,
        Method::Adversarial(Attack::Fgsm),
        Method::Adversarial(Attack::Pgd { steps: 10 }),
        Method::Lipschitz {
            l: 0.5,
            weight: 10.0,
        },
        Method::Properties {
            logic: Logic::Dl2,
            props: props.clone(),
            weight: 1.0,
        },
        Method::Properties {
            logic: Logic::Goedel,
            props,
            weight: 1.0,
        },
    ];
    println!(
        "| method | R^2 | RMSE | MAE | worst attack dev (ex) | mean attack dev (ex) | seconds |"
    );
    println!("|---|---|---|---|---|---|---|");
    for m in methods {
        let label = match &m {
            Method::Adversarial(Attack::Pgd { .. }) => "adversarial (PGD)".to_string(),
            Method::Adversarial(Attack::Fgsm) => "adversarial (FGSM)".to_string(),
            other => other.name().to_string(),
        };
        let o = TrainOptions {
            epochs,
            eps,
            method: m,
            ..Default::default()
        };
        let t = Instant::now();
        let r = train(&data, Some(&mm), &o).expect("train");
        let s = t.elapsed().as_secs_f64();
        let k = &r.metrics;
        println!(
            "| {label} | {:.4} | {:.2e} | {:.2e} | {:.2e} | {:.2e} | {s:.3} |",
            k.r2, k.rmse, k.mae, k.attack_worst, k.attack_mean
        );
    }
}

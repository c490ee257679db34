//! Trains every method on a data file and prints the accuracy/robustness trade-off:
//! `cargo run --release -p samara-train --example tradeoff -- DATA.csv [EPOCHS] [EPS]`.

use samara_train::{
    case_study, read_table, train, Attack, Logic, Method, MinMax, TrainOptions, Units,
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
    let units = Units {
        c: mm.min[..6].to_vec(),
        s: mm.range[..6].to_vec(),
        c_out: mm.min[6],
        s_out: mm.range[6],
    };
    let lo: Vec<f64> = mm.min[..6].to_vec();
    let hi: Vec<f64> = (0..6).map(|j| mm.min[j] + mm.range[j]).collect();
    let props = case_study(&units, &lo, &hi, 2.0);
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

//! Closed-loop training on a data file, with the rounds printed:
//! `cargo run --release -p samara-train --example cegis -- DATA.csv [STEPS] [LR] [WEIGHT] [BOUND] [STEP] [SEED]`;
//! `... -- check NET.onnx [N]`: N (1000) plate6 flights from sampled starts of the published
//! interval, |x + y| at t = 20 against 2.

use samara_train::{read_table, train_closed_loop, CegisOptions};

fn main() {
    let a: Vec<String> = std::env::args().collect();
    if a[1] == "check" {
        let net = samara_nn::onnx::load(&a[2]).expect("network");
        let n = a.get(3).and_then(|s| s.parse().ok()).unwrap_or(1000);
        let t = std::time::Instant::now();
        let c = samara_train::cegis::check_flights(
            &net,
            samara_plant::Model::Plate6,
            (0.1 / 0.07, 0.3 / 0.07),
            n,
            7,
            Some(samara_plant::EX_RANGE),
            20.0,
            2.0,
        )
        .expect("flights");
        println!("{c:?} in {:.1} s", t.elapsed().as_secs_f64());
        return;
    }
    let data = read_table(std::path::Path::new(&a[1])).expect("data");
    let mut o = CegisOptions {
        progress: true,
        ..Default::default()
    };
    let f = |i: usize| a.get(i).and_then(|s| s.parse::<f64>().ok());
    if let Some(v) = f(2) {
        o.steps_per_round = v as usize;
    }
    if let Some(v) = f(3) {
        o.lr = v;
    }
    if let Some(v) = f(4) {
        o.data_weight = v;
    }
    if let Some(v) = f(5) {
        o.loss.bound = v;
    }
    if let Some(v) = f(6) {
        o.loss.step = v;
    }
    if let Some(v) = f(7) {
        o.pretrain.seed = v as u64;
    }
    let out = train_closed_loop(&data, None, &o).expect("training");
    println!(
        "proved {} r2 {:.4} enclosure {:?} rounds {} pretrain {:.1}s total {:.1}s",
        out.proved,
        out.r2,
        out.reach.final_x_plus_y,
        out.rounds.len(),
        out.pretrain_seconds,
        out.seconds
    );
}

//! The published reachability setting on one network:
//! `cargo run --release -p samara-reach --example published -- NET.onnx [reduced|plate6|full] [ystar]`
use samara_plant::Model;
use samara_reach::{reach, Goal, ReachSettings};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let net = samara_nn::onnx::load(&args[1]).expect("network");
    let model =
        Model::from_name(args.get(2).map(|s| s.as_str()).unwrap_or("reduced")).expect("model");
    let mut s = ReachSettings::published(model);
    s.goal = Some(Goal {
        ystar: args
            .get(3)
            .map(|v| v.parse().expect("ystar"))
            .unwrap_or(2.0),
        from: None,
    });
    if let Ok(v) = std::env::var("Y0") {
        let (a, b) = v.split_once(':').unwrap();
        s.init[5] = (a.parse().unwrap(), b.parse().unwrap());
    }
    if let Ok(v) = std::env::var("SPLITS") {
        s.initial_splits = v.parse().unwrap();
    }
    if let Ok(v) = std::env::var("DEV") {
        s.max_control_dev = v.parse().unwrap();
    }
    if let Ok(v) = std::env::var("LEAVES") {
        s.max_leaves = v.parse().unwrap();
    }
    let r = reach(&net, &s).expect("reach");
    let mut taylor = 0;
    let mut fb = 0;
    for l in &r.leaves {
        taylor += l.flow_steps.0;
        fb += l.flow_steps.1;
    }
    println!(
        "verdict {:?}\nfinal x+y {:?} sampled {:?} ratio {:.3}\nleaves {} taylor steps {} fallback {}\nseconds {:.2}",
        r.verdict, r.final_x_plus_y, r.sampled_x_plus_y, r.width_ratio(), r.subproblems(), taylor, fb, r.seconds
    );
    for l in r.leaves.iter().take(3) {
        if let Some(f) = &l.failure {
            println!("failure: {f}");
        }
    }
}

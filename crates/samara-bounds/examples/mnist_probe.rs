//! A development probe of the search on one VNN-COMP image robustness instance (the
//! mnistfc shape: an input box `X_i in [lo, hi]` and a disjunction `Y_j >= Y_label`),
//! without the CLI: `cargo run --release -p samara-bounds --example mnist_probe --
//! NET.onnx PROP.vnnlib SECONDS`. Prints the outcome and the wall time; set
//! `SAMARA_SEARCH_PROFILE=1` for the search's profile. Only the two assertion shapes of
//! those files are read (`(assert (<= X_i v))`, `(assert (>= X_i v))`, `(and (>= Y_j
//! Y_k))`); `samara vnncomp` is the real reader.

use samara_bounds::pwl::PwlNet;
use samara_bounds::search::{self, Case, OutputConstraint};
use samara_bounds::symbolic::Objective;
use std::time::{Duration, Instant};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 4 {
        eprintln!("usage: mnist_probe NET.onnx PROP.vnnlib SECONDS");
        std::process::exit(2);
    }
    let net = samara_nn::load(&args[1]).expect("network loads");
    let pwl = PwlNet::from_network(&net).expect("piecewise linear");
    let text = std::fs::read_to_string(&args[2]).expect("property reads");
    let n = pwl.n_inputs();
    let no = pwl.n_outputs();
    let (mut lo, mut hi) = (vec![f64::NEG_INFINITY; n], vec![f64::INFINITY; n]);
    let mut cases = Vec::new();
    for line in text.lines() {
        let t: Vec<&str> = line
            .split(|c: char| c == '(' || c == ')' || c.is_whitespace())
            .filter(|s| !s.is_empty())
            .collect();
        if t.len() == 4 && t[0] == "assert" && t[2].starts_with("X_") {
            let i: usize = t[2][2..].parse().expect("index");
            let v: f64 = t[3].parse().expect("value");
            if t[1] == "<=" {
                hi[i] = v;
            } else {
                lo[i] = v;
            }
        } else if t.len() == 4 && t[0] == "and" && t[1] == ">=" && t[2].starts_with("Y_") {
            // Y_j >= Y_k: Y_k - Y_j <= 0.
            let j: usize = t[2][2..].parse().expect("index");
            let k: usize = t[3][2..].parse().expect("index");
            let mut c = vec![0.0; no];
            c[k] = 1.0;
            c[j] = -1.0;
            cases.push(OutputConstraint {
                obj: Objective { c, d: 0.0 },
                strict: false,
            });
        }
    }
    let cases: Vec<Case> = cases
        .into_iter()
        .map(|k| Case {
            lo: lo.clone(),
            hi: hi.clone(),
            constraints: vec![k],
        })
        .collect();
    let secs: f64 = args[3].parse().expect("seconds");
    let s = search::Settings {
        timeout: samara_num::Timeout::from_duration(Duration::from_secs_f64(secs)),
        ..Default::default()
    };
    let t0 = Instant::now();
    let (o, st) = search::solve(&pwl.maps, &cases, &s);
    let what = match &o {
        search::Outcome::Violated(p) => format!("sat (case {})", p.case),
        o => format!("{o:?}"),
    };
    println!(
        "{} {}: {what} in {:.2} s, {} pieces",
        args[1].rsplit('/').next().unwrap_or(""),
        args[2].rsplit('/').next().unwrap_or(""),
        t0.elapsed().as_secs_f64(),
        st.pieces
    );
}

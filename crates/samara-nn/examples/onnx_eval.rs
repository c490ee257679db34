//! Evaluate an ONNX network on the inputs of a CSV file (one sample a row, the input
//! tensor's entries row-major), twice: by the graph evaluation and by the chain the
//! verifier reads (the lowering), and print one CSV row of outputs each, prefixed `g,`
//! and `c,`. A network that cannot be lowered prints the reason on stderr and only `g`
//! rows. Used by bench/vnncomp/check_onnx.py to compare with onnxruntime.
//!
//! `cargo run --release -p samara-nn --example onnx_eval -- NET.onnx INPUTS.csv`

use std::process::ExitCode;
use std::time::Instant;

fn main() -> ExitCode {
    let args: Vec<String> = std::env::args().collect();
    if args.len() != 3 {
        eprintln!("usage: onnx_eval NET.onnx INPUTS.csv");
        return ExitCode::from(2);
    }
    let t0 = Instant::now();
    let graph = match samara_nn::onnx::load_graph(&args[1]) {
        Ok(g) => g,
        Err(e) => {
            eprintln!("error: {e}");
            return ExitCode::from(2);
        }
    };
    let t_graph = t0.elapsed().as_secs_f64();
    let t1 = Instant::now();
    let chain = match samara_nn::onnx::load(&args[1]) {
        Ok(n) => Some(n),
        Err(e) => {
            eprintln!("not lowered: {e}");
            None
        }
    };
    eprintln!(
        "import {t_graph:.2} s, chain load {:.2} s, chain layers {}",
        t1.elapsed().as_secs_f64(),
        chain.as_ref().map_or(0, |n| n.layers.len())
    );
    let text = match std::fs::read_to_string(&args[2]) {
        Ok(t) => t,
        Err(e) => {
            eprintln!("error: {}: {e}", args[2]);
            return ExitCode::from(2);
        }
    };
    let row = |v: &[f64]| {
        v.iter()
            .map(|x| format!("{x:e}"))
            .collect::<Vec<_>>()
            .join(",")
    };
    for (k, line) in text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
    {
        let x: Vec<f64> = match line.split(',').map(|s| s.trim().parse()).collect() {
            Ok(x) => x,
            Err(e) => {
                eprintln!("error: {}:{}: {e}", args[2], k + 1);
                return ExitCode::from(2);
            }
        };
        match graph.eval_f64(&x) {
            Ok(y) => println!("g,{}", row(&y)),
            Err(e) => {
                eprintln!("error: {}:{}: {e}", args[2], k + 1);
                return ExitCode::from(2);
            }
        }
        if let Some(n) = &chain {
            if n.n_inputs() == x.len() {
                println!("c,{}", row(&n.eval_f64(&x)));
            }
        }
    }
    ExitCode::SUCCESS
}

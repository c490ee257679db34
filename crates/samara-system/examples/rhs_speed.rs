//! Time per right-hand side evaluation of the glider: the built-in plant
//! (`samara-plant`), the same equations read from `examples/archcomp/alsomitra_plate6.sys`,
//! and the file with a reused value buffer. A measurement, not a test: it prints and
//! checks nothing.
//!
//! `cargo run --release -p samara-system --example rhs_speed [-- EVALUATIONS]`

use samara_plant::{Model, Plant};
use samara_system::System;
use std::path::PathBuf;
use std::time::Instant;

fn main() {
    let n: usize = match std::env::args().nth(1) {
        None => 200_000,
        Some(a) => match a.parse() {
            Ok(n) if n > 0 => n,
            _ => {
                eprintln!("rhs_speed: EVALUATIONS must be a positive integer, got {a:?}");
                std::process::exit(2);
            }
        },
    };
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples/archcomp/alsomitra_plate6.sys");
    let sys = match System::from_file(&path) {
        Ok(s) => s,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(2);
        }
    };
    let plant = Plant::new(Model::Plate6);
    let s = [1.1, 0.2, 0.3, -0.2, 1.0, 2.0, 0.1];
    let mut o = [0.0; 7];
    let t = Instant::now();
    for i in 0..n {
        plant.rhs(&s, &(0.19 + i as f64 * 1e-9), &mut o);
    }
    let a = t.elapsed().as_secs_f64() / n as f64;
    let t = Instant::now();
    for i in 0..n {
        sys.rhs(&s, &[0.19 + i as f64 * 1e-9], &mut o);
    }
    let b = t.elapsed().as_secs_f64() / n as f64;
    let mut scratch = Vec::new();
    let t = Instant::now();
    for i in 0..n {
        sys.rhs_with(&mut scratch, &s, &[0.19 + i as f64 * 1e-9], &mut o);
    }
    let c = t.elapsed().as_secs_f64() / n as f64;
    println!(
        "rhs ({n} evaluations): built-in {:.0} ns, file {:.0} ns, file with buffer {:.0} ns ({} instructions)",
        a * 1e9,
        b * 1e9,
        c * 1e9,
        sys.rhs_graph().ops.len()
    );
}

//! Times the tight-mode closed loop without any file output:
//! `cargo run --release -p samara-sim --example sim_speed -- [RUNS]`.
//! Prints wall seconds for the 9 PID flights and for RUNS constant-ex flights.

use samara_plant::{Model, Plant};
use samara_sim::{
    fly, initial_state, published_starts, ConstantController, Integrator, LoopSettings,
    PidController,
};
use std::time::Instant;

fn main() {
    let runs: usize = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(1000);
    let plant = Plant::new(Model::Plate6);
    let settings = LoopSettings {
        integrator: Integrator::Dop853(Default::default()),
        output_step: None,
        ..Default::default()
    };
    let t = Instant::now();
    let mut evals = 0;
    for y0 in published_starts() {
        evals += fly(
            &plant,
            &mut PidController::default(),
            &initial_state(&plant, y0),
            &settings,
        )
        .unwrap()
        .evals;
    }
    let pid = t.elapsed().as_secs_f64();
    // Same LCG-free spacing as the benchmark: evenly spread y0 in [1.4286, 4.2857].
    let t = Instant::now();
    let mut evals_c = 0;
    for i in 0..runs {
        let y0 = 1.4286 + (4.2857 - 1.4286) * (i as f64 + 0.5) / runs as f64;
        evals_c += fly(
            &plant,
            &mut ConstantController(0.187),
            &initial_state(&plant, y0),
            &settings,
        )
        .unwrap()
        .evals;
    }
    let cst = t.elapsed().as_secs_f64();
    println!(
        "pid_9_flights_s {pid:.6} evals {evals} ns_per_eval {:.1}",
        pid * 1e9 / evals as f64
    );
    println!(
        "constant_{runs}_flights_s {cst:.6} evals {evals_c} ns_per_eval {:.1}",
        cst * 1e9 / evals_c as f64
    );
}

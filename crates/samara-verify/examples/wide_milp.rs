//! P1-P4 critical values of raw-unit 6-input networks by samara's exact engine and by the
//! HiGHS big-M MILP (`samara_verify::milp`), with times (bench/verify/wide.sh).
//! Usage: cargo run --release -p samara-verify --features highs --example wide_milp -- [--timeout S] [--only pK] [--fix C] [--no-sweep] [--tol T] NET.onnx...
//! `--timeout S` (default 600) bounds each property's samara search and, separately, its
//! whole HiGHS computation (LP bounds and MILP: an error row then). CSV columns: network,
//! property, samara's value, bound, completeness and wall seconds, HiGHS's value and wall
//! seconds, then HiGHS's dual bound, the process CPU seconds of each engine (user +
//! system, from /proc/self/stat), the ReLUs unstable after CROWN, the MILP's binaries,
//! the bound LPs and their simplex iterations, and the wall seconds of HiGHS's two phases.

#[path = "../tests/support/case_study.rs"]
mod case_study;

use case_study::p1_to_p4;
use samara_verify::milp::{optimise_milp_with, MilpOptions};
use samara_verify::net::PwlNet;
use samara_verify::{optimise, Prepared, Settings, Timeout};
use std::collections::HashMap;
use std::time::Instant;

/// User + system CPU seconds of this process so far (all threads), from /proc/self/stat
/// (clock ticks of 1/100 s); NaN where that file is missing.
fn cpu_seconds() -> f64 {
    let Ok(s) = std::fs::read_to_string("/proc/self/stat") else {
        return f64::NAN;
    };
    // Fields after the command name (which may hold spaces) in parentheses: utime and
    // stime are the 12th and 13th of them.
    let rest = s.rsplit_once(')').map_or("", |r| r.1);
    let f: Vec<&str> = rest.split_whitespace().collect();
    let tick = |i: usize| {
        f.get(i)
            .and_then(|v| v.parse::<f64>().ok())
            .unwrap_or(f64::NAN)
    };
    (tick(11) + tick(12)) / 100.0
}

fn main() {
    println!(
        "network,property,samara_value,samara_bound,samara_complete,samara_s,highs_value,highs_s,\
         highs_bound,samara_cpu_s,highs_cpu_s,unstable_crown,binaries,lp_solves,lp_iterations,\
         highs_bound_s,highs_milp_s"
    );
    // `--timeout S` (first) bounds samara's search per property (default 600 s).
    let mut args: Vec<String> = std::env::args().skip(1).collect();
    let mut timeout = Timeout::from_secs(600);
    // `--no-sweep` (anywhere) leaves out the output-constrained bound sweep.
    let sweep = !args.iter().any(|a| a == "--no-sweep");
    args.retain(|a| a != "--no-sweep");
    // `--tol T` (anywhere): HiGHS's MIP and primal feasibility tolerances.
    let mut tol = None;
    if let Some(i) = args.iter().position(|a| a == "--tol") {
        tol = Some(
            args.get(i + 1)
                .and_then(|t| t.parse::<f64>().ok())
                .expect("--tol T: a number"),
        );
        args.drain(i..i + 2);
    }
    let mut milp = MilpOptions {
        time_limit: 600.0,
        sweep,
        feasibility_tolerance: tol,
    };
    if args.first().map(String::as_str) == Some("--timeout") && args.len() >= 2 {
        let secs: f64 = args[1].parse().expect("--timeout S: a number of seconds");
        timeout = Timeout::from_secs_f64(secs).expect("--timeout S: seconds >= 0");
        milp.time_limit = secs;
        args.drain(..2);
    }
    // `--only pK` (next) computes one property.
    let mut only: Option<String> = None;
    if args.first().map(String::as_str) == Some("--only") && args.len() >= 2 {
        only = Some(args[1].clone());
        args.drain(..2);
    }
    // `--fix C` (next) pins the free parameter (ystar) to C in both engines: HiGHS's
    // MILP is then a feasibility question on a sliver of the box (value C: a
    // counterexample exists at ystar = C; empty: none), which its LP bounds handle far
    // better than the optimisation over every ystar. Bracketing samara's critical value
    // v with C = v -+ d checks it to d.
    let mut fix: Option<f64> = None;
    if args.first().map(String::as_str) == Some("--fix") && args.len() >= 2 {
        fix = Some(args[1].parse().expect("--fix C: a number"));
        args.drain(..2);
    }
    for path in args {
        let net = samara_nn::onnx::load(&path).expect("an ONNX network");
        let mut nets = HashMap::new();
        nets.insert("f".to_string(), net);
        let prep = Prepared::new(&nets);
        let pwl: HashMap<String, PwlNet> = nets
            .iter()
            .map(|(k, v)| (k.clone(), PwlNet::from_network(v).expect("a ReLU network")))
            .collect();
        let name = std::path::Path::new(&path)
            .file_stem()
            .unwrap()
            .to_string_lossy()
            .into_owned();
        // P1-P4 lowered from models/alsomitra/alsomitra.spec, with the network in raw units
        // (networks that carry their own normalisation layers) or, for a `*_norm.onnx`
        // file (normalised inputs and output, like the published ones), in the spec's
        // normalised units.
        let raw = !name.ends_with("_norm");
        for mut q in p1_to_p4(raw) {
            if only.as_ref().is_some_and(|o| *o != q.name) {
                continue;
            }
            if let Some(c) = fix {
                for f in &mut q.free_vars {
                    (f.1, f.2) = (c, c);
                }
            }
            let (t, c) = (Instant::now(), cpu_seconds());
            let ours = optimise(
                &q,
                &prep,
                &Settings {
                    timeout,
                    ..Default::default()
                },
            )
            .expect("a well-formed query");
            let (ts, cs) = (t.elapsed().as_secs_f64(), cpu_seconds() - c);
            let (t, c) = (Instant::now(), cpu_seconds());
            let theirs = optimise_milp_with(&q, &pwl, &milp);
            let (th, ch) = (t.elapsed().as_secs_f64(), cpu_seconds() - c);
            let fmt = |v: Option<f64>| v.map_or("empty".into(), |v| format!("{v:.9}"));
            let (hv, hb, st) = match theirs {
                Ok(o) => (fmt(o.value), fmt(o.bound), Some(o.stats)),
                Err(e) => (format!("error: {e}"), "-".into(), None),
            };
            let st = st.map_or("-,-,-,-,-,-".into(), |s| {
                format!(
                    "{},{},{},{},{:.3},{:.3}",
                    s.unstable_crown,
                    s.binaries,
                    s.lp_solves,
                    s.lp_iterations,
                    s.bound_seconds,
                    s.milp_seconds
                )
            });
            println!(
                "{name},{},{},{:.9},{},{ts:.3},{hv},{th:.3},{hb},{cs:.2},{ch:.2},{st}",
                q.name,
                fmt(ours.value),
                ours.bound,
                ours.complete,
            );
        }
    }
}

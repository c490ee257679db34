//! Standing differential test of the two meanings of a plant (issue 35, item 1): for
//! random system files generated from a seed, and for every file under `examples/`, the
//! reachable sets of `samara_reach::system::reach_system` (the entry point of `samara
//! reach --system`: Taylor-model sets, validated flowpipe, CROWN network step) must
//! contain the flights of `samara_system::sim::fly` (the simulator of `samara simulate
//! --system`: DOP853, f64, no sets) at every control instant, at the horizon and at every
//! output time inside its period's box; a `proved` goal must hold on every flight and a
//! `violated` goal must really be missed by its witness flight.
//!
//! The generated plants have 1 to 3 states and 1 or 2 inputs; their equations mix linear,
//! polynomial, `sin`, `cos`, `tanh`, `exp`, `sqrt` (also near 0), `if`, `min`, `max`,
//! `abs` and `sign` terms (a
//! damping term keeps them bounded); some observe affine maps of the states, some clip
//! their inputs, some reset a state every period; the controller is a small random
//! network (ReLU or tanh, built in memory); goals of every kind (`reach`, `avoid`,
//! `band`, affine or not) and every `when` (`at end`, `always`, `eventually`, with and
//! without windows) are drawn around the centre flight so that all three verdicts occur.
//!
//! Tolerance: a flight's state `v` of state `i` counts as inside `[lo, hi]` when it lies
//! within `1e-7 * (1 + s_i)` of it, `s_i` the largest `|x_i|` over the plant's flights.
//! DOP853 runs at rtol 1e-10 / atol 1e-12; over these horizons (at most 5 periods of at
//! most 0.5 s, Lipschitz constants of a few units) its global error stays below ~1e-9 of
//! the state scale, a hundred times smaller than the tolerance, which in turn is far
//! below the enclosures' widths (a set that misses a flight by more is a real bug).
//!
//! Plants the simulator cannot fly (a sliding mode on an `if` or `sign`: the step
//! collapses, `samara_sim::Collapse`) are counted as skipped, at most 5 %. With
//! `DIFF_SLOW=1` the run prints every plant whose centre flight takes over 0.2 s or whose
//! reach run over 0.5 s (how the 44 s `sign` chattering of docs/simulation.md was found).

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use samara_nn::{Activation, Network};
use samara_reach::system::SystemViolation;
use samara_reach::system::{
    reach_system, starts, NetworkError, SystemReach, SystemReachError, SystemReachSettings,
    SystemVerdict,
};
use samara_system::sim::{fly, goals_hold, SystemFlight};
use samara_system::System;
use std::fmt::Write;
use std::path::Path;

/// A goal expression evaluated at a state (f64).
type StateFn = Box<dyn Fn(&[f64]) -> f64>;

/// Relative tolerance of containment (see the module documentation).
const TOL: f64 = 1e-7;

/// One random term of an equation, over states `x0..x{n-1}` and inputs `u0..u{m-1}`.
fn term(rng: &mut ChaCha8Rng, n: usize, m: usize) -> String {
    let x = |rng: &mut ChaCha8Rng| format!("x{}", rng.gen_range(0..n));
    let c = rng.gen_range(-1.0..1.0f64);
    let v = rng.gen_range(-0.5..0.5f64);
    let body = match rng.gen_range(0..15) {
        0 => x(rng),
        1 => format!("{} * {}", x(rng), x(rng)),
        2 => format!("{}^2", x(rng)),
        3 => format!("sin({})", x(rng)),
        4 => format!("cos({})", x(rng)),
        5 => format!("tanh(2 * {})", x(rng)),
        6 => format!("u{}", rng.gen_range(0..m)),
        7 => format!(
            "(if {} < {v} then {} else {})",
            x(rng),
            x(rng),
            rng.gen_range(-1.0..1.0f64)
        ),
        8 => format!("min({}, {}, {v})", x(rng), x(rng)),
        9 => format!("max({}, {v})", x(rng)),
        10 => format!("abs({} - {v})", x(rng)),
        11 => format!("exp(0.3 * {})", x(rng)),
        12 => format!("sqrt(1 + {}^2)", x(rng)),
        13 => format!("sqrt(0.01 + {}^2)", x(rng)),
        _ => format!("0.3 * sign({} - {v})", x(rng)),
    };
    format!("{c} * {body}")
}

/// A random plant without goals: its text, and the network dimensions it needs.
fn plant_text(rng: &mut ChaCha8Rng) -> (String, usize) {
    let n = rng.gen_range(1..=3);
    let m = rng.gen_range(1..=2usize);
    let mut s = String::new();
    let names: Vec<String> = (0..n).map(|i| format!("x{i}")).collect();
    writeln!(s, "state {}", names.join(", ")).unwrap();
    let inputs: Vec<String> = (0..m).map(|k| format!("u{k}")).collect();
    writeln!(s, "input {}", inputs.join(", ")).unwrap();
    for i in 0..n {
        let mut e = format!("-{} * x{i}", rng.gen_range(0.2..1.0f64));
        // Every input drives some state.
        for k in (0..m).filter(|k| k % n == i) {
            write!(e, " + {} * u{k}", rng.gen_range(-1.0..1.0f64)).unwrap();
        }
        for _ in 0..rng.gen_range(1..=3) {
            write!(e, " + {}", term(rng, n, m)).unwrap();
        }
        writeln!(s, "x{i}' = {e}").unwrap();
    }
    let period = [0.1, 0.2, 0.25, 0.5][rng.gen_range(0..4)];
    let steps = rng.gen_range(2..=5);
    writeln!(s, "period {period}\nhorizon {steps} * {period}").unwrap();
    let n_obs = if rng.gen_bool(0.3) {
        let k = rng.gen_range(1..=n + 1);
        let obs: Vec<String> = (0..k)
            .map(|j| {
                format!(
                    "{} * x{} + {}",
                    rng.gen_range(0.5..2.0f64),
                    j % n,
                    rng.gen_range(-0.5..0.5f64)
                )
            })
            .collect();
        writeln!(s, "observe {}", obs.join(", ")).unwrap();
        k
    } else {
        n
    };
    for k in 0..m {
        write!(
            s,
            "actuate u{k} = {} * net[{k}]",
            rng.gen_range(0.5..2.0f64)
        )
        .unwrap();
        if rng.gen_bool(0.4) {
            let lo = rng.gen_range(-1.0..0.0f64);
            write!(s, " clip [{lo}, {}]", lo + rng.gen_range(0.1..1.5f64)).unwrap();
        }
        s.push('\n');
    }
    if n >= 2 && rng.gen_bool(0.3) {
        writeln!(s, "reset x{} = {}", n - 1, rng.gen_range(-0.5..0.5f64)).unwrap();
    }
    for i in 0..n {
        let c = rng.gen_range(-1.0..1.0f64);
        if rng.gen_bool(0.2) {
            writeln!(s, "init x{i} = {c}").unwrap();
        } else {
            let w = if rng.gen_bool(0.2) {
                rng.gen_range(0.1..0.3f64)
            } else {
                rng.gen_range(0.001..0.1f64)
            };
            writeln!(s, "init x{i} in [{}, {}]", c - w, c + w).unwrap();
        }
    }
    (s, n_obs)
}

/// Goal lines drawn around the centre flight `f`: bounds at the flight's range along
/// the goal's expression, widened or narrowed by a random margin.
fn goal_lines(rng: &mut ChaCha8Rng, sys: &System, f: &SystemFlight) -> String {
    let n = sys.dim();
    let h = sys.horizon;
    let period = sys.period;
    let mut s = String::new();
    for _ in 0..rng.gen_range(0..=2) {
        let steps = sys.steps();
        let (t1, t2) = {
            let a = rng.gen_range(0..=steps);
            let b = rng.gen_range(a..=steps);
            (a as f64 * period, b as f64 * period)
        };
        let (when, lo_t, hi_t) = match rng.gen_range(0..5) {
            0 => ("at end".to_string(), h, h),
            1 => ("always".to_string(), 0.0, h),
            2 => (format!("always [{t1}, {t2}]"), t1, t2),
            3 => ("eventually".to_string(), 0.0, h),
            _ => (format!("eventually [{t1}, {t2}]"), t1, t2),
        };
        let j = rng.gen_range(0..n);
        let (expr, g): (String, StateFn) = match rng.gen_range(0..3) {
            0 => (format!("x{j}"), Box::new(move |x: &[f64]| x[j])),
            1 => {
                let k = (j + 1) % n;
                (
                    format!("x{j} - 0.5 * x{k}"),
                    Box::new(move |x: &[f64]| x[j] - 0.5 * x[k]),
                )
            }
            _ => (format!("x{j}^2"), Box::new(move |x: &[f64]| x[j] * x[j])),
        };
        let eps = 1e-9 * h.max(1.0);
        let vals: Vec<f64> =
            f.t.iter()
                .zip(&f.states)
                .filter(|(t, _)| **t >= lo_t - eps && **t <= hi_t + eps)
                .map(|(_, x)| g(x))
                .collect();
        let lo = vals.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = vals.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if !(lo.is_finite() && hi.is_finite()) {
            continue;
        }
        let margin = rng.gen_range(-0.05..0.3f64) * (1.0 + hi - lo);
        let (a, b) = (lo - margin, hi + margin);
        let (a, b) = if a <= b { (a, b) } else { (b, a) };
        let line = match (
            rng.gen_range(0..4),
            expr.starts_with('x') && expr.len() <= 3,
        ) {
            (0, true) => format!("reach {expr} in [{a}, {b}]"),
            (1, true) => {
                // Avoid a box beside the flight's range.
                format!("avoid {expr} in [{}, {}]", b + 0.01, b + 1.0)
            }
            (2, _) => format!("band {expr} <= {b}"),
            (3, _) => format!("band {expr} >= {a}"),
            _ => format!("band {expr} in [{a}, {b}]"),
        };
        writeln!(s, "goal {line} {when}").unwrap();
    }
    s
}

/// What one plant's check found.
#[derive(Default, Debug)]
struct Tally {
    plants: usize,
    skipped: usize,
    to_horizon: usize,
    points: usize,
    proved: usize,
    violated: usize,
    unknown: usize,
    no_goal: usize,
    slowest: f64,
    reach_seconds: f64,
    check_seconds: f64,
}

/// Reach settings of the differential runs: small budgets (this checks soundness, not
/// precision) and a wall-clock cap per plant; the Taylor-model order (2 to 4) and the
/// network step's error (interval remainders, or symbolic ones for one plant in four,
/// with the re-parameterisations they bring) vary with the seed.
fn settings(seed: u64) -> SystemReachSettings {
    SystemReachSettings {
        order: 2 + (seed % 2) as usize,
        max_boxes: 3,
        samples: 4,
        seed,
        timeout: samara_num::Timeout::from_secs_f64(3.0).unwrap(),
        network_error: Some(if seed % 4 == 3 {
            NetworkError::Symbolic { extra: 6 }
        } else {
            NetworkError::Interval
        }),
        ..Default::default()
    }
}

/// Check the sets of `r` against flights from `n_flights` starts of `sys` (the centre,
/// the corners, random points) and the verdict against those flights; panics naming the
/// plant on any failure.
fn check(
    name: &str,
    sys: &System,
    net: &Network,
    r: &SystemReach,
    n_flights: usize,
    seed: u64,
    tally: &mut Tally,
) {
    let eval = |x: &[f64]| net.eval_f64(x);
    let mut flights: Vec<(Vec<f64>, SystemFlight)> = Vec::new();
    for x0 in starts(sys, n_flights, seed) {
        match fly(sys, &eval, &x0, 10) {
            Ok(f) => flights.push((x0, f)),
            Err(_) => {
                tally.skipped += 1;
                return;
            }
        }
    }
    let mut scale = vec![1.0f64; sys.dim()];
    for (_, f) in &flights {
        for x in &f.states {
            for (s, v) in scale.iter_mut().zip(x) {
                *s = s.max(1.0 + v.abs());
            }
        }
    }
    let inside = |i: usize, v: f64, b: [f64; 2]| {
        let tol = TOL * scale[i];
        v >= b[0] - tol && v <= b[1] + tol
    };
    let steps = sys.steps();
    if r.leaves
        .iter()
        .all(|l| l.failure.is_none() && l.instants.len() == steps + 1)
    {
        tally.to_horizon += 1;
    }
    for (x0, f) in &flights {
        let leaf = r
            .leaves
            .iter()
            .find(|l| l.init.iter().zip(x0).all(|(b, v)| b[0] <= *v && *v <= b[1]))
            .unwrap_or_else(|| panic!("{name}: no sub-box holds the start {x0:?}"));
        // Every state of `x` (at time `t`) inside `row`, the set called `what`.
        let assert_in = |row: &[[f64; 2]], x: &[f64], t: f64, what: &str| {
            for (i, v) in x.iter().enumerate() {
                assert!(
                    inside(i, *v, row[i]),
                    "{name}: start {x0:?}: state {i} = {v} at t = {t} outside {what} {:?}\n{}",
                    row[i],
                    sys.source()
                );
            }
        };
        for (t, x) in f.t.iter().zip(&f.states) {
            let kf = t / sys.period;
            let k = kf.round() as usize;
            if (kf - k as f64).abs() < 1e-9 && k < leaf.instants.len() {
                assert_in(&leaf.instants[k], x, *t, "the instant's set");
                tally.points += 1;
            }
            if *t > 0.0 {
                // The period that ends at or contains t.
                let p = (kf - 1e-9).floor().max(0.0) as usize;
                if p < leaf.periods.len() {
                    assert_in(&leaf.periods[p], x, *t, "the period's box");
                    tally.points += 1;
                }
            }
        }
    }
    match &r.verdict {
        SystemVerdict::Proved => {
            tally.proved += 1;
            for (x0, f) in &flights {
                assert!(
                    goals_hold(sys, f).iter().all(|h| *h),
                    "{name}: proved, but the flight from {x0:?} misses a goal\n{}",
                    sys.source()
                );
            }
        }
        SystemVerdict::Violated(SystemViolation { initial, goal }) => {
            tally.violated += 1;
            let f = fly(sys, &eval, initial, 10).unwrap();
            let gi = sys
                .goals
                .iter()
                .position(|g| &g.text == goal)
                .unwrap_or_else(|| panic!("{name}: violated goal `{goal}` is not in the file"));
            assert!(
                !goals_hold(sys, &f)[gi],
                "{name}: `{goal}` violated, but the witness flight from {initial:?} meets it\n{}",
                sys.source()
            );
        }
        SystemVerdict::Unknown { .. } => tally.unknown += 1,
        SystemVerdict::NoGoal => tally.no_goal += 1,
    }
    tally.plants += 1;
}

/// Generate plant `idx` of `seed`, run reach on it and check it against the simulator.
fn one_plant(seed: u64, idx: u64, n_flights: usize, tally: &mut Tally) {
    let mut rng = ChaCha8Rng::seed_from_u64(seed.wrapping_mul(1_000_003).wrapping_add(idx));
    let (text, n_obs) = plant_text(&mut rng);
    let name = format!("plant {idx} of seed {seed}");
    let base = System::parse(&text, "gen.sys").unwrap_or_else(|e| panic!("{name}: {e}\n{text}"));
    let act = if rng.gen_bool(0.5) {
        Activation::Relu
    } else {
        Activation::Tanh
    };
    let hidden = rng.gen_range(2..=6);
    let net = Network::random_mlp(&[n_obs, hidden, base.n_inputs()], act, 0.8, 0.3, &mut rng);
    let eval = |x: &[f64]| net.eval_f64(x);
    let centre: Vec<f64> = base.init.iter().map(|(l, h)| 0.5 * (l + h)).collect();
    let t_fly = std::time::Instant::now();
    let base_f = fly(&base, &eval, &centre, 10);
    if std::env::var_os("DIFF_SLOW").is_some() && t_fly.elapsed().as_secs_f64() > 0.2 {
        eprintln!(
            "{name}: centre flight {:.2} s {:?}\n{text}",
            t_fly.elapsed().as_secs_f64(),
            base_f.as_ref().err()
        );
    }
    let Ok(f) = base_f else {
        // As below: the simulator cannot fly this plant.
        tally.skipped += 1;
        return;
    };
    let text = text + &goal_lines(&mut rng, &base, &f);
    let sys = System::parse(&text, "gen.sys").unwrap_or_else(|e| panic!("{name}: {e}\n{text}"));
    let started = std::time::Instant::now();
    let r = match reach_system(&sys, &net, &settings(idx)) {
        Ok(r) => r,
        // A flight the simulator cannot finish (a sliding mode: the step size
        // collapses on an `if` whose field points at the switch from both sides).
        Err(SystemReachError::Simulation(_)) => {
            tally.skipped += 1;
            return;
        }
        Err(e) => panic!("{name}: {e}\n{text}"),
    };
    tally.slowest = tally.slowest.max(started.elapsed().as_secs_f64());
    tally.reach_seconds += started.elapsed().as_secs_f64();
    if std::env::var_os("DIFF_SLOW").is_some() && started.elapsed().as_secs_f64() > 0.5 {
        eprintln!(
            "{name}: {:.2} s {:?}\n{text}",
            started.elapsed().as_secs_f64(),
            r.verdict
        );
    }
    let started = std::time::Instant::now();
    check(&name, &sys, &net, &r, n_flights, idx, tally);
    tally.check_seconds += started.elapsed().as_secs_f64();
}

fn run_generated(seed: u64, count: u64, n_flights: usize) -> Tally {
    let mut tally = Tally::default();
    for idx in 0..count {
        one_plant(seed, idx, n_flights, &mut tally);
    }
    eprintln!("{tally:?}");
    assert!(
        tally.skipped * 20 <= count as usize,
        "more than 5 % of the plants do not fly: {tally:?}"
    );
    tally
}

#[test]
fn generated_plants_sets_contain_flights_and_verdicts_hold() {
    let t = run_generated(35, 210, 10);
    assert!(t.plants >= 200, "{t:?}");
    // The test is not vacuous: most plants are enclosed to the horizon, and each
    // verdict occurs.
    assert!(t.to_horizon >= 100, "{t:?}");
    assert!(t.proved > 0 && t.violated > 0 && t.no_goal > 0, "{t:?}");
}

#[test]
#[ignore = "5,000 generated plants: about 20 minutes in release on 2 shared cores; run with --ignored --release"]
fn five_thousand_generated_plants() {
    let t = run_generated(3535, 5000, 16);
    assert!(t.plants >= 4750, "{t:?}");
}

/// Every shipped system file, flown for at most 3 periods under a small random network of
/// its shape (goals dropped: their windows are the full horizon's), its sets against
/// flights from the centre, corners and random starts.
#[test]
fn example_files_sets_contain_flights() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
    let mut files = Vec::new();
    let mut stack = vec![dir];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else if p.extension().is_some_and(|x| x == "sys") {
                files.push(p);
            }
        }
    }
    files.sort();
    assert!(files.len() >= 10, "{files:?}");
    let mut tally = Tally::default();
    for (k, p) in files.iter().enumerate() {
        let mut sys = System::from_file(p).unwrap();
        if sys.is_discrete() {
            // No flow to integrate: discrete files (vcas.sys) have their own containment
            // tests against simulated pilots (tests/discrete.rs).
            continue;
        }
        sys.horizon = sys.period * sys.steps().min(3) as f64;
        sys.goals.clear();
        let mut rng = ChaCha8Rng::seed_from_u64(k as u64);
        let net = Network::random_mlp(
            &[sys.n_observed(), 4, sys.n_net_outputs],
            Activation::Tanh,
            0.05,
            0.05,
            &mut rng,
        );
        let r = reach_system(&sys, &net, &settings(k as u64)).unwrap();
        check(
            &p.display().to_string(),
            &sys,
            &net,
            &r,
            8,
            k as u64,
            &mut tally,
        );
    }
    eprintln!("{tally:?}");
}

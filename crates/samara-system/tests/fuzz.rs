//! Seeded fuzzing of the system parser: mutations of the shipped files, token soups and
//! deep nesting. No input may panic; an accepted system must evaluate (f64, intervals,
//! duals, Taylor series) without panicking. CI runs a bounded number of cases with a
//! fixed seed; `cargo test -p samara-system --test all fuzz:: -- --ignored` runs 10,000.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use samara_num::{Interval, Series};
use samara_system::System;
use std::path::PathBuf;
use std::time::Instant;

fn corpus() -> Vec<String> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../examples/archcomp");
    let mut v: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "sys"))
        .collect();
    v.sort();
    v.iter()
        .map(|p| std::fs::read_to_string(p).unwrap())
        .collect()
}

const VOCAB: &[&str] = &[
    "state",
    "input",
    "param",
    "let",
    "period",
    "horizon",
    "observe",
    "actuate",
    "reset",
    "init",
    "goal",
    "reach",
    "avoid",
    "band",
    "at",
    "end",
    "always",
    "eventually",
    "in",
    "clip",
    "if",
    "then",
    "else",
    "net",
    "[",
    "]",
    "(",
    ")",
    ",",
    "'",
    "=",
    "+",
    "-",
    "*",
    "/",
    "^",
    "<",
    "<=",
    ">",
    ">=",
    "|",
    "\n",
    "\\\n",
    "x",
    "y",
    "v",
    "u",
    "k",
    "pi",
    "0",
    "1",
    "-0",
    "0.5",
    "1e308",
    "1e-320",
    "2",
    "3",
    "65536",
    "1e999",
    "sin",
    "cos",
    "tan",
    "log",
    "sqrt",
    "exp",
    "abs",
    "sign",
    "min",
    "max",
    "atan",
    "tanh",
    "#",
    "é",
    "\t",
    "x'",
    "net[0]",
    "net[70000]",
];

fn mutate(rng: &mut ChaCha8Rng, src: &str) -> String {
    let mut s: Vec<char> = src.chars().collect();
    for _ in 0..rng.gen_range(1..6) {
        let n = s.len().max(1);
        match rng.gen_range(0..7) {
            0 if !s.is_empty() => {
                let a = rng.gen_range(0..n);
                let b = (a + rng.gen_range(1..20)).min(s.len());
                s.drain(a..b);
            }
            1 => {
                let a = rng.gen_range(0..=s.len());
                let t = VOCAB[rng.gen_range(0..VOCAB.len())];
                for (k, c) in t.chars().enumerate() {
                    s.insert(a + k, c);
                }
            }
            2 => {
                // duplicate or drop a whole line
                let text: String = s.iter().collect();
                let mut lines: Vec<&str> = text.lines().collect();
                if !lines.is_empty() {
                    let i = rng.gen_range(0..lines.len());
                    if rng.gen_bool(0.5) {
                        lines.insert(i, lines[i]);
                    } else {
                        lines.remove(i);
                    }
                }
                s = (lines.join("\n") + "\n").chars().collect();
            }
            3 if !s.is_empty() => {
                let a = rng.gen_range(0..n);
                s[a] = *[' ', '(', ')', '0', '/', '^', '\n', 'x', '-', '[']
                    .get(rng.gen_range(0..10))
                    .unwrap();
            }
            4 => {
                // deep nesting around a random point
                let a = rng.gen_range(0..=s.len());
                let d = rng.gen_range(1..400);
                let open = ["(", "-", "sin(", "x^"][rng.gen_range(0..4)];
                let mut ins: String = open.repeat(d);
                ins.push('x');
                if open.ends_with('(') {
                    ins.push_str(&")".repeat(d));
                }
                for (k, c) in ins.chars().enumerate() {
                    s.insert(a + k, c);
                }
            }
            5 => {
                // replace a number-ish character run with an extreme number
                let a = rng.gen_range(0..=s.len());
                let t = ["0", "1e308", "-1e308", "1e-310", "0.0", "3", "1e5"][rng.gen_range(0..7)];
                for (k, c) in t.chars().enumerate() {
                    s.insert(a + k, c);
                }
            }
            _ => {}
        }
    }
    s.into_iter().collect()
}

fn soup(rng: &mut ChaCha8Rng) -> String {
    let n = rng.gen_range(1..200);
    (0..n)
        .map(|_| VOCAB[rng.gen_range(0..VOCAB.len())])
        .collect::<Vec<_>>()
        .join(if rng.gen_bool(0.5) { " " } else { "" })
}

/// Everything an accepted system offers, on a few inputs.
fn exercise(sys: &System, rng: &mut ChaCha8Rng) {
    let (n, m) = (sys.dim(), sys.n_inputs());
    let x: Vec<f64> = (0..n).map(|_| rng.gen_range(-3.0..3.0)).collect();
    let u: Vec<f64> = (0..m).map(|_| rng.gen_range(-3.0..3.0)).collect();
    let mut o = vec![0.0; n];
    sys.rhs(&x, &u, &mut o);
    let _ = sys.jacobian(&x, &u);
    let xi: Vec<Interval> = x.iter().map(|&v| Interval::new(v - 0.1, v + 0.1)).collect();
    let ui: Vec<Interval> = u.iter().map(|&v| Interval::point(v)).collect();
    let mut oi = vec![Interval::point(0.0); n];
    sys.rhs(&xi, &ui, &mut oi);
    let xs: Vec<Series<Interval, 4>> = xi.iter().map(|&v| Series::var(v)).collect();
    let us: Vec<Series<Interval, 4>> = ui.iter().map(|&v| Series::constant(v)).collect();
    let mut os = vec![Series::<Interval, 4>::constant(Interval::point(0.0)); n];
    sys.rhs(&xs, &us, &mut os);
    let mut obs = vec![0.0; sys.n_observed()];
    sys.observe(&x, &mut obs);
    let net: Vec<f64> = (0..sys.n_net_outputs)
        .map(|_| rng.gen_range(-3.0..3.0))
        .collect();
    let mut uu = vec![0.0; m];
    sys.actuate(&net, &mut uu);
    let _ = sys.observe_affine();
    let _ = sys.actuate_affine();
    let mut y = x.clone();
    sys.apply_resets(&mut y);
    for g in &sys.goals {
        let _ = g.holds(&x);
        let _ = g.decide(&xi);
    }
}

/// Run `cases` seeded cases; returns (accepted, rejected, seconds).
fn run(cases: usize, seed: u64) -> (usize, usize, f64) {
    let corpus = corpus();
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let (mut ok, mut bad) = (0, 0);
    let t0 = Instant::now();
    for case in 0..cases {
        let src = match case % 10 {
            0..=6 => {
                let base = &corpus[rng.gen_range(0..corpus.len())];
                mutate(&mut rng, base)
            }
            7 | 8 => soup(&mut rng),
            _ => {
                let d = rng.gen_range(200..5000);
                let open =
                    ["(", "-", "sqrt(", "x^", "if x < 0 then ", "min(x,"][rng.gen_range(0..6)];
                format!("state x\nx' = {}x\n", open.repeat(d))
            }
        };
        let r = std::panic::catch_unwind(|| {
            let mut r2 = ChaCha8Rng::seed_from_u64(case as u64);
            match System::parse(&src, "fuzz.sys") {
                Ok(sys) => {
                    exercise(&sys, &mut r2);
                    true
                }
                Err(e) => {
                    let shown = e.to_string();
                    assert!(!shown.is_empty() && !e.message.is_empty());
                    assert!(e.pos.line <= src.lines().count().max(1));
                    false
                }
            }
        });
        match r {
            Ok(true) => ok += 1,
            Ok(false) => bad += 1,
            Err(_) => panic!("case {case} (seed {seed}) panicked on:\n{src}"),
        }
    }
    (ok, bad, t0.elapsed().as_secs_f64())
}

#[test]
fn fuzz_ci() {
    let (ok, bad, secs) = run(2000, 15);
    eprintln!("fuzz (CI): 2000 cases, {ok} accepted, {bad} rejected with an error, {secs:.2} s");
    assert!(ok > 0 && bad > 0);
}

#[test]
#[ignore = "10,000 fuzz cases (the CI runs 2,000 in fuzz_ci); run with --ignored"]
fn fuzz_10k() {
    let (ok, bad, secs) = run(10_000, 2026);
    eprintln!("fuzz (10k): 10000 cases, {ok} accepted, {bad} rejected with an error, {secs:.2} s");
}

//! A standing fuzz suite for the spec parser, checker and lowering and the VNN-LIB
//! reader: random token soups and mutations (byte flips, insertions, deletions,
//! duplications, truncations, deep nesting, huge numbers) of the bundled
//! `models/alsomitra/alsomitra.spec` and of a VNN-COMP-style VNN-LIB file. Property:
//! never a panic, each case terminates quickly, and the answer is `Ok` or an error whose
//! message starts with `file:line:col: ` (line, column >= 1).
//!
//! In CI (debug) 256 cases per input kind run through proptest (fixed seed). The `#[ignore]`d
//! `fuzz_10000_cases_per_kind` runs 10,000 seeded cases per input kind and prints the
//! counts:
//!
//! ```text
//! cargo test --release -p samara-spec --test all fuzz:: -- --ignored --nocapture
//! ```

use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use samara_spec::{syntax, vnnlib, Bindings, Spec};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

const SPEC: &str = include_str!("../../../models/alsomitra/alsomitra.spec");
const VNNLIB: &str = include_str!("data/acas_like.vnnlib");
const TWO_BOXES: &str = include_str!("data/two_boxes.vnnlib");

/// The longest a case may take: 1 s (release); debug builds on a shared CI machine
/// get 5 s.
fn case_limit() -> Duration {
    Duration::from_secs(if cfg!(debug_assertions) { 5 } else { 1 })
}

/// A directory (three levels below a temporary root) with a three-row data set where
/// the case-study spec's `dataset train` points (`../../../shared/reference/
/// Training_Data_Normalised.csv`, inside the temporary root) and under its older name
/// `training_data_normalised.csv`, so that mutated specs lower their data-set
/// properties too.
fn data_dir() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let root = std::env::temp_dir().join(format!("samara-spec-fuzz-{}", std::process::id()));
        let dir = root.join("a/b/c");
        let shared = root.join("shared/reference");
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::create_dir_all(&shared).unwrap();
        let rows = "0,0.55,0.21,1,0,0.93,0.75\n0.08,0.12,0.08,0.82,0.01,0.93,1\n0.25,0,0.36,0.67,0.02,0.92,1\n";
        std::fs::write(dir.join("training_data_normalised.csv"), rows).unwrap();
        std::fs::write(shared.join("Training_Data_Normalised.csv"), rows).unwrap();
        dir
    })
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Kind {
    SpecSoup,
    SpecMutation,
    SpecGrammar,
    VnnSoup,
    VnnMutation,
    VnnGrammar,
}

const KINDS: [Kind; 6] = [
    Kind::SpecSoup,
    Kind::SpecMutation,
    Kind::SpecGrammar,
    Kind::VnnSoup,
    Kind::VnnMutation,
    Kind::VnnGrammar,
];

const SPEC_TOKENS: &[&str] = &[
    "network",
    "f",
    "g",
    "(",
    ")",
    "->",
    "normalise",
    "input",
    "output",
    "min",
    "range",
    "offset",
    "scale",
    "from",
    "domain",
    "data",
    "dataset",
    "param",
    "property",
    "loop",
    "of",
    "start",
    "goal",
    "model",
    "period",
    "horizon",
    "clip",
    "at",
    "published",
    "reduced",
    "for",
    "in",
    "ball",
    "norm",
    "and",
    "or",
    "not",
    "=>",
    "<=",
    ">=",
    "<",
    ">",
    "==",
    "=",
    "+",
    "-",
    "*",
    "/",
    "|",
    "[",
    "]",
    ",",
    ":",
    ".",
    "x",
    "y",
    "ex",
    "theta",
    "omega",
    "v_xp",
    "v_yp",
    "ystar",
    "eps",
    "L",
    "x0",
    "x1",
    "f(x1)",
    "x0.ex",
    "norm(x1 - x0)",
    "p1",
    "0",
    "1",
    "0.187",
    "-41.68",
    "1e-3",
    "1e999",
    "1e308",
    "99999999999999999999",
    "0.0",
    "\"a.csv\"",
    "\"",
    "train",
    "normalised",
    "#",
    "\\\n",
    "\n",
    "\n",
    "@",
    "é",
    "\t",
    "'",
];

const VNN_TOKENS: &[&str] = &[
    "(",
    "(",
    ")",
    ")",
    "declare-const",
    "declare-fun",
    "assert",
    "Real",
    "Int",
    "X_0",
    "X_1",
    "X_4",
    "X_6",
    "Y_0",
    "Y_1",
    "Y_4",
    "X_99999999999999999999",
    "X_01",
    "X_",
    "Y_-1",
    "and",
    "or",
    "not",
    "<=",
    ">=",
    "<",
    ">",
    "=",
    "+",
    "-",
    "*",
    "/",
    "0",
    "1",
    "-0.5",
    "0.6",
    "1e999",
    "-1e999",
    "inf",
    "NaN",
    "1e308",
    "1e-320",
    ";",
    "\n",
    "\"",
    "|",
    "()",
    "check-sat",
];

fn soup(rng: &mut ChaCha8Rng, tokens: &[&str], prefix: &str) -> String {
    let mut s = String::new();
    if rng.gen_bool(0.5) {
        s.push_str(prefix);
    }
    for _ in 0..rng.gen_range(0..200) {
        s.push_str(tokens[rng.gen_range(0..tokens.len())]);
        s.push(if rng.gen_bool(0.9) { ' ' } else { '\n' });
    }
    s
}

/// 1 to 8 random edits of `base` (bytes; the result may not be UTF-8).
fn mutate(rng: &mut ChaCha8Rng, base: &str, tokens: &[&str], open: &str, close: &str) -> Vec<u8> {
    let mut b = base.as_bytes().to_vec();
    let edits = if rng.gen_bool(0.7) {
        rng.gen_range(1..=2)
    } else {
        rng.gen_range(3..=8)
    };
    for _ in 0..edits {
        let n = b.len();
        let at = rng.gen_range(0..=n);
        match rng.gen_range(0..9) {
            0 if n > 0 => {
                let i = rng.gen_range(0..n);
                b[i] = if rng.gen_bool(0.5) {
                    b[i] ^ (1 << rng.gen_range(0..8))
                } else {
                    rng.gen()
                };
            }
            1 | 2 => {
                let t = tokens[rng.gen_range(0..tokens.len())];
                b.splice(at..at, format!(" {t} ").into_bytes());
            }
            3 => {
                let end = (at + rng.gen_range(0..40)).min(n);
                b.drain(at..end);
            }
            4 if n > 0 => {
                let from = rng.gen_range(0..n);
                let end = (from + rng.gen_range(0..200)).min(n);
                let piece: Vec<u8> = b[from..end].to_vec();
                let times = if rng.gen_bool(0.1) { 200 } else { 1 };
                for _ in 0..times {
                    b.splice(at..at, piece.iter().copied());
                }
            }
            5 => b.truncate(at),
            6 => {
                // Deep nesting around a random point.
                let k = if rng.gen_bool(0.5) {
                    rng.gen_range(1..300)
                } else {
                    rng.gen_range(300..20_000)
                };
                let end = rng.gen_range(at..=n);
                b.splice(end..end, close.repeat(k).into_bytes());
                b.splice(at..at, open.repeat(k).into_bytes());
            }
            7 => {
                let digits = rng.gen_range(1..400);
                let num: String = (0..digits)
                    .map(|_| char::from(b'0' + rng.gen_range(0..10u8)))
                    .collect();
                let e = if rng.gen_bool(0.5) {
                    format!("e{}", rng.gen_range(-400i32..400))
                } else {
                    String::new()
                };
                b.splice(at..at, format!(" {num}{e} ").into_bytes());
            }
            _ => {
                // Replace a digit run's neighbourhood with a sign flip or a dot.
                let t = [b"-".as_slice(), b".", b"(", b")", b"\n", b" "][rng.gen_range(0..6)];
                b.splice(at..at, t.iter().copied());
            }
        }
    }
    b
}

const NAMES: &[&str] = &[
    "x",
    "y",
    "ex",
    "theta",
    "omega",
    "v_xp",
    "v_yp",
    "ystar",
    "eps",
    "L",
    "f(x1)",
    "x0.ex",
    "x1.x",
    "f(x0)",
    "norm(x1 - x0)",
    "zz",
];

/// A random spec expression (mostly well formed).
fn spec_expr(rng: &mut ChaCha8Rng, depth: u32) -> String {
    if depth == 0 || rng.gen_bool(0.3) {
        return if rng.gen_bool(0.4) {
            format!("{}", rng.gen_range(-50.0..50.0f64) as f32)
        } else {
            NAMES[rng.gen_range(0..NAMES.len())].to_string()
        };
    }
    let d = depth - 1;
    match rng.gen_range(0..7) {
        0 => format!("-{}", spec_expr(rng, d)),
        1 => format!("({})", spec_expr(rng, d)),
        2 => format!("|{}|", spec_expr(rng, d)),
        3 => format!("{} + {}", spec_expr(rng, d), spec_expr(rng, d)),
        4 => format!("{} - {}", spec_expr(rng, d), spec_expr(rng, d)),
        5 => format!("{} * {}", spec_expr(rng, d), spec_expr(rng, d)),
        _ => format!("{} / {}", spec_expr(rng, d), spec_expr(rng, d)),
    }
}

/// A random spec formula (mostly well formed).
fn spec_formula(rng: &mut ChaCha8Rng, depth: u32) -> String {
    const RELS: [&str; 5] = ["<=", "<", ">=", ">", "=="];
    if depth == 0 || rng.gen_bool(0.3) {
        let mut s = spec_expr(rng, 3);
        for _ in 0..rng.gen_range(1..=2) {
            s = format!("{s} {} {}", RELS[rng.gen_range(0..5)], spec_expr(rng, 3));
        }
        return s;
    }
    let d = depth - 1;
    match rng.gen_range(0..5) {
        0 => format!("not {}", spec_formula(rng, d)),
        1 => format!("({})", spec_formula(rng, d)),
        2 => format!("{} and {}", spec_formula(rng, d), spec_formula(rng, d)),
        3 => format!("{} or {}", spec_formula(rng, d), spec_formula(rng, d)),
        _ => format!("{} => {}", spec_formula(rng, d), spec_formula(rng, d)),
    }
}

/// A random VNN-LIB term over `n` inputs and `m` outputs (sometimes out of range).
fn vnn_term(rng: &mut ChaCha8Rng, n: usize, m: usize, depth: u32) -> String {
    if depth == 0 || rng.gen_bool(0.4) {
        return match rng.gen_range(0..3) {
            0 => format!("{}", rng.gen_range(-5.0..5.0f64) as f32),
            1 => format!("X_{}", rng.gen_range(0..n + 1)),
            _ => format!("Y_{}", rng.gen_range(0..m + 1)),
        };
    }
    let d = depth - 1;
    match rng.gen_range(0..4) {
        0 => format!("(+ {} {})", vnn_term(rng, n, m, d), vnn_term(rng, n, m, d)),
        1 => format!("(- {} {})", vnn_term(rng, n, m, d), vnn_term(rng, n, m, d)),
        2 => format!("(- {})", vnn_term(rng, n, m, d)),
        _ => format!("(* {} {})", rng.gen_range(-3..4), vnn_term(rng, n, m, d)),
    }
}

fn vnn_formula(rng: &mut ChaCha8Rng, n: usize, m: usize, depth: u32) -> String {
    const OPS: [&str; 5] = ["<=", "<", ">=", ">", "="];
    if depth == 0 || rng.gen_bool(0.4) {
        return format!(
            "({} {} {})",
            OPS[rng.gen_range(0..5)],
            vnn_term(rng, n, m, 2),
            vnn_term(rng, n, m, 2)
        );
    }
    let k = rng.gen_range(0..4);
    let parts: Vec<String> = (0..k).map(|_| vnn_formula(rng, n, m, depth - 1)).collect();
    format!(
        "({} {})",
        if rng.gen_bool(0.5) { "and" } else { "or" },
        parts.join(" ")
    )
}

fn input(kind: Kind, seed: u64) -> Vec<u8> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    match kind {
        Kind::SpecSoup => soup(
            &mut rng,
            SPEC_TOKENS,
            "network f(v_xp, v_yp, omega, theta, x, y) -> (ex)\nparam ystar in [0, 100] = 2\nproperty p: ",
        )
        .into_bytes(),
        Kind::SpecMutation => mutate(&mut rng, SPEC, SPEC_TOKENS, "(", ")"),
        Kind::SpecGrammar => {
            let head: String = SPEC
                .lines()
                .filter(|l| !l.starts_with("property"))
                .map(|l| format!("{l}\n"))
                .collect();
            let binders = if rng.gen_bool(0.3) {
                "for x0 in data train, for x1 in ball(x0, eps), "
            } else {
                ""
            };
            let depth = rng.gen_range(0..6);
            format!(
                "{head}property g: {binders}{}\n",
                spec_formula(&mut rng, depth)
            )
            .into_bytes()
        }
        Kind::VnnGrammar => {
            let (n, m) = (rng.gen_range(1..6), rng.gen_range(1..6));
            let mut s = String::new();
            for i in 0..n {
                s.push_str(&format!("(declare-const X_{i} Real)\n"));
            }
            for j in 0..m {
                s.push_str(&format!("(declare-const Y_{j} Real)\n"));
            }
            for _ in 0..rng.gen_range(0..8) {
                let depth = rng.gen_range(0..5);
                s.push_str(&format!("(assert {})\n", vnn_formula(&mut rng, n, m, depth)));
            }
            s.into_bytes()
        }
        Kind::VnnSoup => soup(
            &mut rng,
            VNN_TOKENS,
            "(declare-const X_0 Real)\n(declare-const X_1 Real)\n(declare-const Y_0 Real)\n(assert ",
        )
        .into_bytes(),
        Kind::VnnMutation => {
            let base = if rng.gen_bool(0.5) { VNNLIB } else { TWO_BOXES };
            mutate(&mut rng, base, VNN_TOKENS, "(and ", ")")
        }
    }
}

/// The error's position, checked against its message.
fn located(msg: &str, file: &str, line: usize, col: usize) -> Result<(), String> {
    let head = format!("{file}:{line}:{col}: ");
    if line >= 1 && col >= 1 && msg.starts_with(&head) {
        Ok(())
    } else {
        Err(format!("error without a line:col: {msg}"))
    }
}

/// Parse, check and lower (every property; every ranged parameter's critical query).
fn spec_case(bytes: &[u8]) -> Result<bool, String> {
    let file = "fuzz.spec";
    let check = |e: samara_spec::SpecError| {
        let m = e.to_string();
        located(&m, file, e.pos.line, e.pos.col)
    };
    let text = match syntax::decode(bytes, file) {
        Ok(t) => t,
        Err(e) => return check(e).map(|_| false),
    };
    let spec = match Spec::parse(text, file, data_dir()) {
        Ok(s) => s,
        Err(e) => return check(e).map(|_| false),
    };
    let _ = format!("{:?}", spec.properties);
    let mut b = Bindings::default();
    b.params.insert("ystar".into(), 1.0);
    let ranged: Vec<String> = spec
        .params
        .iter()
        .filter(|(_, d)| d.range.is_some())
        .map(|(n, _)| n.clone())
        .collect();
    let mut ok = true;
    for p in spec.property_names() {
        if let Err(e) = spec.lower_prove(p, &b) {
            check(e)?;
            ok = false;
        }
        for param in &ranged {
            if let Err(e) = spec.lower_critical(p, param, &b) {
                check(e)?;
                ok = false;
            }
        }
    }
    Ok(ok)
}

fn vnn_case(bytes: &[u8]) -> Result<bool, String> {
    let file = "fuzz.vnnlib";
    match vnnlib::read_bytes(bytes, file, "f", "q") {
        Ok(p) => {
            let q = &p.query;
            let (n, m) = p.declared();
            let app = &q.applications[0];
            if app.n_inputs != n || app.n_outputs != m || app.input_box.len() != n {
                return Err("declared counts disagree with the query".into());
            }
            // Every variable is declared.
            for c in q.region.iter().flatten() {
                for (v, k) in &c.expr.terms {
                    let fine = match v {
                        samara_spec::normal::Var::Input { index, .. } => *index < n,
                        samara_spec::normal::Var::Output { index, .. } => *index < m,
                        samara_spec::normal::Var::Free(_) => false,
                    };
                    if !fine || !k.is_finite() {
                        return Err(format!("bad term {v:?} * {k}"));
                    }
                }
            }
            Ok(true)
        }
        Err(e @ vnnlib::VnnlibError::Parse { .. }) => {
            let m = e.to_string();
            let vnnlib::VnnlibError::Parse { line, col, .. } = e else {
                unreachable!()
            };
            located(&m, file, line, col).map(|_| false)
        }
        Err(e) => Err(format!("unexpected error kind: {e}")),
    }
}

#[derive(Debug, PartialEq)]
enum Outcome {
    Ok,
    Err,
    Panic(String),
    Wrong(String),
}

fn run_case(kind: Kind, seed: u64) -> (Outcome, Duration) {
    let bytes = input(kind, seed);
    let t = Instant::now();
    let r = std::panic::catch_unwind(|| match kind {
        Kind::SpecSoup | Kind::SpecMutation | Kind::SpecGrammar => spec_case(&bytes),
        Kind::VnnSoup | Kind::VnnMutation | Kind::VnnGrammar => vnn_case(&bytes),
    });
    let dt = t.elapsed();
    let o = match r {
        Ok(Ok(true)) => Outcome::Ok,
        Ok(Ok(false)) => Outcome::Err,
        Ok(Err(m)) => Outcome::Wrong(m),
        Err(p) => Outcome::Panic(
            p.downcast_ref::<String>()
                .cloned()
                .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default(),
        ),
    };
    (o, dt)
}

fn check(kind: Kind, seed: u64) -> Result<(), TestCaseError> {
    let (o, dt) = run_case(kind, seed);
    prop_assert!(
        matches!(o, Outcome::Ok | Outcome::Err),
        "{kind:?} seed {seed}: {o:?}"
    );
    prop_assert!(dt < case_limit(), "{kind:?} seed {seed}: {dt:?}");
    Ok(())
}

proptest! {
    // A fixed seed: CI runs the same cases every time (no flaky timing); the ignored
    // 10,000-case run below explores further.
    #![proptest_config(ProptestConfig {
        cases: 256,
        failure_persistence: None,
        rng_seed: proptest::test_runner::RngSeed::Fixed(0x05a4_da2a),
        ..ProptestConfig::default()
    })]
    #[test]
    fn spec_token_soup(seed in any::<u64>()) { check(Kind::SpecSoup, seed)?; }
    #[test]
    fn spec_mutations(seed in any::<u64>()) { check(Kind::SpecMutation, seed)?; }
    #[test]
    fn spec_grammar(seed in any::<u64>()) { check(Kind::SpecGrammar, seed)?; }
    #[test]
    fn vnnlib_token_soup(seed in any::<u64>()) { check(Kind::VnnSoup, seed)?; }
    #[test]
    fn vnnlib_grammar(seed in any::<u64>()) { check(Kind::VnnGrammar, seed)?; }
    #[test]
    fn vnnlib_mutations(seed in any::<u64>()) { check(Kind::VnnMutation, seed)?; }
}

/// The unmutated inputs are accepted (so mutations start from valid files).
#[test]
fn the_seeds_are_valid() {
    assert_eq!(spec_case(SPEC.as_bytes()), Ok(true));
    assert_eq!(vnn_case(VNNLIB.as_bytes()), Ok(true));
    assert_eq!(vnn_case(TWO_BOXES.as_bytes()), Ok(true));
}

#[test]
#[ignore = "long: 10,000 cases per input kind; run in release with --ignored --nocapture"]
fn fuzz_10000_cases_per_kind() {
    let n: u64 = std::env::var("SAMARA_FUZZ_CASES")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(10_000);
    let mut bad = Vec::new();
    for kind in KINDS {
        let (mut ok, mut err, mut panics, mut wrong) = (0, 0, 0, 0);
        let mut max = (Duration::ZERO, 0u64);
        let t0 = Instant::now();
        for i in 0..n {
            let seed = 0x5a4d_0000_0000 + i;
            let (o, dt) = run_case(kind, seed);
            if dt > max.0 {
                max = (dt, seed);
            }
            match o {
                Outcome::Ok => ok += 1,
                Outcome::Err => err += 1,
                Outcome::Panic(m) => {
                    panics += 1;
                    bad.push(format!("{kind:?} seed {seed}: panic {m}"));
                }
                Outcome::Wrong(m) => {
                    wrong += 1;
                    bad.push(format!("{kind:?} seed {seed}: {}", &m[..m.len().min(300)]));
                }
            }
        }
        println!(
            "{kind:?}: {n} cases, {ok} ok, {err} errors, {panics} panics, {wrong} errors without line:col, max {:.1} ms (seed {}), total {:.1} s",
            max.0.as_secs_f64() * 1e3,
            max.1,
            t0.elapsed().as_secs_f64()
        );
        if max.0 >= case_limit() {
            bad.push(format!("{kind:?}: a case took {:?}", max.0));
        }
    }
    assert!(bad.is_empty(), "{}", bad.join("\n"));
}

/// Reproduce one case: `SAMARA_FUZZ_KIND=SpecGrammar SAMARA_FUZZ_SEED=123 cargo test
/// -p samara-spec --test all fuzz::show_case -- --ignored --nocapture` prints the input, the
/// outcome and the time.
#[test]
#[ignore = "prints one case named by SAMARA_FUZZ_KIND and SAMARA_FUZZ_SEED"]
fn show_case() {
    let kind = std::env::var("SAMARA_FUZZ_KIND").unwrap_or_default();
    let seed = std::env::var("SAMARA_FUZZ_SEED")
        .ok()
        .and_then(|s| s.parse::<u64>().ok());
    let (Some(kind), Some(seed)) = (KINDS.into_iter().find(|k| format!("{k:?}") == kind), seed)
    else {
        println!("show_case: set SAMARA_FUZZ_KIND (one of {KINDS:?}) and SAMARA_FUZZ_SEED");
        return;
    };
    let bytes = input(kind, seed);
    println!(
        "{}",
        String::from_utf8_lossy(&bytes[..bytes.len().min(4000)])
    );
    let (o, dt) = run_case(kind, seed);
    println!("{o:?} in {dt:?}");
}

//! Issue 17, "never a wrong answer": hostile specs and VNN-LIB files get an error naming
//! the file and line:column, never a panic, a stack overflow or a hang. Tests run on
//! threads with the default 2 MiB stack; `on_stack` also runs a case on an explicit
//! 2 MiB and 8 MiB (the main thread's) stack.

use samara_spec::syntax::MAX_DEPTH;
use samara_spec::{vnnlib, Bindings, Spec};
use std::path::Path;
use std::time::{Duration, Instant};

const HEAD: &str = "network f(a, b) -> (y)\n";

/// Run `f` on a thread with a `mb` MiB stack and return its result.
fn on_stack<T: Send + 'static>(mb: usize, f: impl FnOnce() -> T + Send + 'static) -> T {
    std::thread::Builder::new()
        .stack_size(mb << 20)
        .spawn(f)
        .unwrap()
        .join()
        .unwrap()
}

/// Parse, check and lower every property (default bindings); the first error as text.
fn run(src: &str) -> Result<(), String> {
    let spec = Spec::parse(src, "t.spec", Path::new(".")).map_err(|e| e.to_string())?;
    for p in spec.property_names() {
        let _ = format!("{:?}", spec.properties);
        spec.lower_prove(p, &Bindings::default())
            .map_err(|e| e.to_string())?;
    }
    Ok(())
}

fn err(src: &str) -> String {
    let t = Instant::now();
    let e = run(src).unwrap_err();
    assert!(t.elapsed() < Duration::from_secs(5), "slow: {e}");
    e
}

fn both_stacks(src: String, needle: &'static str) {
    for mb in [2, 8] {
        let s = src.clone();
        let e = on_stack(mb, move || err(&s));
        assert!(e.contains(needle), "{e}");
    }
}

#[test]
fn deep_nesting_is_refused_with_the_limit() {
    let n = 10_000;
    let src = format!(
        "{HEAD}property p: {}a{} >= 0\n",
        "(".repeat(n),
        ")".repeat(n)
    );
    both_stacks(src, "t.spec:2:");
    let e = err(&format!(
        "{HEAD}property p: {}a{} >= 0\n",
        "(".repeat(n),
        ")".repeat(n)
    ));
    assert!(
        e.contains(&format!("nesting deeper than {MAX_DEPTH} levels")),
        "{e}"
    );
    for (open, close) in [("|", "|"), ("-", ""), ("not ", "")] {
        let inner = if open == "not " { "a >= 0" } else { "a" };
        let tail = if open == "not " { "" } else { " >= 0" };
        let src = format!(
            "{HEAD}property p: {}{inner}{}{tail}\n",
            open.repeat(n),
            close.repeat(n)
        );
        both_stacks(src, "nesting deeper than 256 levels");
    }
    let src = format!("{HEAD}property p: {}a >= 0\n", "a >= 0 => ".repeat(n));
    both_stacks(src, "nesting deeper than 256 levels");
}

#[test]
fn nesting_up_to_the_limit_is_accepted_and_lowered() {
    // Just inside the limit: parses, checks, lowers (and drops) on a 2 MiB stack.
    let d = MAX_DEPTH - 10;
    let src = format!(
        "{HEAD}property p: {}a{} >= 0 => y <= 1\n",
        "(".repeat(d),
        ")".repeat(d)
    );
    on_stack(2, move || run(&src).unwrap());
    let src = format!("{HEAD}property p: {}a >= 0\n", "not ".repeat(d));
    on_stack(2, move || run(&src).unwrap());
    let src = format!("{HEAD}property p: {}a >= 0\n", "- ".repeat(d - 2));
    on_stack(2, move || run(&src).unwrap());
    let src = format!("{HEAD}property p: {}a >= y\n", "a >= 0 => ".repeat(d - 2));
    on_stack(2, move || run(&src).unwrap());
    let src = format!(
        "{HEAD}property p: {}a{} >= y\n",
        "|(".repeat(d / 2),
        ")|".repeat(d / 2)
    );
    on_stack(2, move || run(&src).unwrap_err());
}

#[test]
fn a_flat_sum_of_many_terms_is_fine() {
    for n in [10_000, 100_000] {
        let terms: Vec<String> = (0..n).map(|i| format!("{} * a", i % 7)).collect();
        let src = format!(
            "{HEAD}property p: {} - y >= 0 => y <= 1\n",
            terms.join(" + ")
        );
        let prods = vec!["1"; n].join(" * ");
        let src2 = format!("{HEAD}property p: {prods} * a / 3 >= y\n");
        for src in [src, src2] {
            let t = Instant::now();
            on_stack(2, move || run(&src).unwrap());
            assert!(t.elapsed() < Duration::from_secs(10));
        }
    }
    // 2^10000 overflows: refused, not an infinite coefficient.
    let src = format!(
        "{HEAD}property p: {} * a >= y\n",
        vec!["2"; 10_000].join(" * ")
    );
    let e = err(&src);
    assert!(
        e.contains("t.spec:2:1") && e.contains("not a finite number"),
        "{}",
        &e[..200]
    );
}

#[test]
fn thirty_absolute_values_are_refused_before_expanding() {
    let terms: Vec<String> = (0..30).map(|i| format!("|a - {i}|")).collect();
    let src = format!("{HEAD}property wide: {} <= y\n", terms.join(" + "));
    let t = Instant::now();
    let e = err(&src);
    assert!(t.elapsed() < Duration::from_secs(1), "{:?}", t.elapsed());
    assert!(
        e.contains("t.spec:2:1")
            && e.contains("property `wide` expands to 1073741824 cases")
            && e.contains("cap of 4096"),
        "{e}"
    );
    // Saturating count: 2^200 does not wrap.
    let terms: Vec<String> = (0..200).map(|i| format!("|a - {i}|")).collect();
    let e = err(&format!("{HEAD}property w: {} <= y\n", terms.join(" + ")));
    assert!(e.contains("more than 10^19 cases"), "{e}");
    // 12 absolute values (4096 cases) are fine.
    let terms: Vec<String> = (0..12).map(|i| format!("|a - {i}|")).collect();
    run(&format!("{HEAD}property w: {} <= y\n", terms.join(" + "))).unwrap();
}

#[test]
fn non_finite_literals_are_refused() {
    for lit in ["1e999", "1.5e400", "99999999999999999999e300"] {
        let e = err(&format!("{HEAD}property p: a <= {lit} => y <= 1\n"));
        assert!(
            e.contains("t.spec:2:18") && e.contains(&format!("`{lit}` is not a finite number")),
            "{e}"
        );
        let e = err(&format!("{HEAD}domain f: a in [0, {lit}]\n"));
        assert!(e.contains("t.spec:2:"), "{e}");
    }
    // Tiny literals are finite (they round to 0 or a subnormal): accepted.
    run(&format!("{HEAD}property p: a <= 1e-999 => y <= 1\n")).unwrap();
}

#[test]
fn a_parameter_default_outside_its_range_is_refused() {
    let e = err(&format!("{HEAD}param t in [0, 1] = 2\n"));
    assert!(
        e.contains("t.spec:2:1")
            && e.contains("the default 2 of parameter `t` is outside its range [0, 1]"),
        "{e}"
    );
    run(&format!(
        "{HEAD}param t in [0, 1] = 1\nproperty p: a >= t => y >= 0\n"
    ))
    .unwrap();
    let e = err(&format!("{HEAD}param t = 1\nparam t = 2\n"));
    assert!(
        e.contains("t.spec:3:1") && e.contains("declared twice"),
        "{e}"
    );
    let e = err(&format!("{HEAD}param a = 1\n"));
    assert!(
        e.contains("t.spec:2:1") && e.contains("name of an input"),
        "{e}"
    );
}

#[test]
fn no_message_prints_a_zero_position() {
    let s = Spec::parse(
        &format!("{HEAD}property p: a >= 0 => y >= 0\n"),
        "t.spec",
        Path::new("."),
    )
    .unwrap();
    let e = s
        .lower_prove("q", &Bindings::default())
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("t.spec: no property named `q`"), "{e}");
    let e = Spec::read(Path::new("/nonexistent/x.spec"))
        .unwrap_err()
        .to_string();
    assert!(
        e.starts_with("/nonexistent/x.spec: cannot read the spec"),
        "{e}"
    );
    for e in [
        err(""),
        err("\n\n"),
        err("# only a comment"),
        err(&format!("{HEAD}property p: a >= 0 => y >= 0 and \"open\n")),
        err(&format!("{HEAD}property p: a >= 0 => (y >= 0\n")),
    ] {
        assert!(!e.contains(":0:") && e.starts_with("t.spec:"), "{e}");
    }
    // A continuation at the very end of the file is fine.
    run(&format!("{HEAD}property p: a >= 0 => y >= 0 \\")).unwrap();
}

#[test]
fn invalid_utf8_is_an_error_with_its_position() {
    let dir = std::env::temp_dir().join(format!("samara-spec-utf8-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("bad.spec");
    std::fs::write(&path, b"network f(a) -> (y)\nproperty p: a >= \xff0\n").unwrap();
    let e = Spec::read(&path).unwrap_err();
    assert_eq!((e.pos.line, e.pos.col), (2, 18), "{e}");
    assert!(e.to_string().contains("not UTF-8"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn long_lines_are_shown_around_the_error() {
    let pad = "a + ".repeat(2000);
    let e = err(&format!("{HEAD}property p: {pad}a @ 1 >= 0\n"));
    let shown = e.lines().nth(1).unwrap();
    assert!(shown.len() < 200 && shown.contains("a @ 1"), "{shown}");
}

// ---------------------------------------------------------------- VNN-LIB

fn vnn(text: &str) -> Result<vnnlib::Property, String> {
    vnnlib::read(text, "p.vnnlib", "f", "p").map_err(|e| e.to_string())
}

fn vnn_err(text: &str) -> String {
    let t = Instant::now();
    let e = vnn(text).unwrap_err();
    assert!(t.elapsed() < Duration::from_secs(5), "slow: {e}");
    e
}

const ACAS: &str = include_str!("data/acas_like.vnnlib");
const TWO_BOXES: &str = include_str!("data/two_boxes.vnnlib");
const DECL: &str = "(declare-const X_0 Real)\n(declare-const Y_0 Real)\n";

#[test]
fn vnncomp_style_files_are_read() {
    let p = vnn(ACAS).unwrap();
    assert_eq!(p.declared(), (5, 5));
    let b = &p.query.applications[0].input_box;
    assert_eq!(b[0], (0.6, 0.68));
    assert_eq!(b[4], (-0.5, -0.45));
    assert_eq!(p.query.region.len(), 4);
    assert!(p.query.region.iter().all(|c| c.len() == 1));
    // Input disjunction: both boxes stay in the region; the box is their hull.
    let p = vnn(TWO_BOXES).unwrap();
    assert_eq!(p.declared(), (2, 2));
    assert_eq!(p.query.region.len(), 2);
    assert!(p.query.region.iter().all(|c| c.len() == 6));
    assert_eq!(
        p.query.applications[0].input_box,
        vec![(-0.1, 0.7), (-0.5, 0.5)]
    );
}

#[test]
fn undeclared_variables_are_refused() {
    let e = vnn_err(&format!("{DECL}(assert (> Y_1 0.5))\n"));
    assert!(
        e.contains("p.vnnlib:3:12")
            && e.contains("`Y_1` is not declared (the file declares only Y_0)"),
        "{e}"
    );
    let e = vnn_err(&ACAS.replace("(assert (<= X_4 -0.45))", "(assert (<= X_6 -0.45))"));
    assert!(
        e.contains("`X_6` is not declared (the file declares X_0 .. X_4)")
            && e.contains("p.vnnlib:27:13"),
        "{e}"
    );
    // Gaps, repeats, and names other than X_i / Y_j.
    let e =
        vnn_err("(declare-const X_0 Real)\n(declare-const X_2 Real)\n(declare-const Y_0 Real)\n");
    assert!(
        e.contains("p.vnnlib:2:16") && e.contains("`X_2` is declared but `X_1` is not"),
        "{e}"
    );
    let e = vnn_err(&format!("{DECL}(declare-const X_0 Real)\n"));
    assert!(
        e.contains("p.vnnlib:3:16") && e.contains("declared twice (first at 1:16)"),
        "{e}"
    );
    let e = vnn_err(&format!("{DECL}(declare-const Z Real)\n"));
    assert!(
        e.contains("p.vnnlib:3:16") && e.contains("only inputs X_0"),
        "{e}"
    );
    let e = vnn_err(&format!("{DECL}(declare-const X_01 Real)\n"));
    assert!(e.contains("bad variable `X_01`"), "{e}");
    let e = vnn_err(&format!("{DECL}(declare-const X_1 Int)\n"));
    assert!(e.contains("only Real"), "{e}");
    let e = vnn_err("(declare-const Y_0 Real)\n(assert (<= Y_0 1))\n");
    assert!(
        e.contains("p.vnnlib:1:1") && e.contains("declares no X variable"),
        "{e}"
    );
    let e = vnn_err(&format!("{DECL}(assert (<= X_99999999999999999999 1))\n"));
    assert!(
        e.contains("p.vnnlib:3:13") && e.contains("beyond the cap"),
        "{e}"
    );
    let e = vnn_err(&format!("{DECL}(declare-const X_99999999 Real)\n"));
    assert!(e.contains("beyond the cap of 16777216 variables"), "{e}");
    let e = vnn_err(&format!("{DECL}(declare-const X_9999999 Real)\n"));
    assert!(
        e.contains("`X_9999999` is declared but `X_1` is not"),
        "{e}"
    );
}

#[test]
fn deep_vnnlib_nesting_is_refused() {
    let n = 50_000;
    let text = format!(
        "{DECL}(assert {}(<= X_0 1){})\n",
        "(and ".repeat(n),
        ")".repeat(n)
    );
    for mb in [2, 8] {
        let t = text.clone();
        let e = on_stack(mb, move || vnn_err(&t));
        assert!(
            e.contains("p.vnnlib:3:") && e.contains("deeper than 256"),
            "{e}"
        );
    }
    // Up to the limit is fine, on a 2 MiB stack.
    let d = vnnlib::MAX_DEPTH - 3;
    let text = format!(
        "{DECL}(assert {}(<= X_0 1){})\n",
        "(and ".repeat(d),
        ")".repeat(d)
    );
    on_stack(2, move || vnn(&text).unwrap());
    let text = format!(
        "{DECL}(assert (<= {}X_0{} 1))\n",
        "(- ".repeat(d),
        ")".repeat(d)
    );
    on_stack(2, move || vnn(&text).unwrap());
}

#[test]
fn vnnlib_products_of_disjunctions_are_counted_before_expanding() {
    let ors: String = (0..30)
        .map(|i| format!("(assert (or (<= Y_0 {i}) (>= Y_0 {}))) \n", i + 100))
        .collect();
    let t = Instant::now();
    let e = vnn_err(&format!("{DECL}{ors}"));
    assert!(t.elapsed() < Duration::from_secs(1));
    assert!(
        e.contains("p.vnnlib:3:9") && e.contains("1073741824 cases") && e.contains("cap of 65536"),
        "{e}"
    );
    let inner: String = (0..30)
        .map(|i| format!("(or (<= Y_0 {i}) (>= Y_0 {}))", i + 100))
        .collect();
    let e = vnn_err(&format!("{DECL}(assert (or (and {inner}) (<= Y_0 0)))\n"));
    assert!(e.contains("1073741825 cases"), "{e}");
}

#[test]
fn vnnlib_numbers_must_be_finite() {
    for lit in ["1e999", "-1e400", "inf", "NaN", "-infinity"] {
        let e = vnn_err(&format!("{DECL}(assert (<= X_0 {lit}))\n"));
        assert!(
            e.contains("p.vnnlib:3:17") && e.contains(&format!("`{lit}` is not a finite number")),
            "{e}"
        );
    }
    let e = vnn_err(&format!("{DECL}(assert (<= (* 1e300 1e300 X_0) 1))\n"));
    assert!(e.contains("p.vnnlib:3:9") && e.contains("overflows"), "{e}");
}

#[test]
fn malformed_vnnlib_is_an_error_with_a_position() {
    for (text, at, needle) in [
        ("", "1:1", "declares no X variable"),
        ("; nothing\n", "1:1", "declares no X variable"),
        ("(assert (<= X_0 1.0)", "1:1", "is not closed"),
        ("(declare-const X_0 Real))", "1:25", "unbalanced `)`"),
        (
            "(declare-const X_0 Real)\n(assert (<= X_0 \"1))\n",
            "2:17",
            "strings",
        ),
        (
            "(declare-const X_0 Real)\n(assert |x|)\n",
            "2:9",
            "quoted symbols",
        ),
        (
            "(declare-const X_0 Real)\n(declare-const Y_0 Real)\n(assert (<= (-) 1))\n",
            "3:13",
            "`-` needs",
        ),
        (
            "(declare-const X_0 Real)\n(declare-const Y_0 Real)\n(assert)\n",
            "3:1",
            "takes one formula",
        ),
        (
            "(declare-const X_0 Real)\n(declare-const Y_0 Real)\n(assert (<= X_0 1) (<= X_0 2))\n",
            "3:1",
            "takes one formula",
        ),
        (
            "(declare-const X_0 Real)\n(declare-const Y_0 Real)\n(assert X_0)\n",
            "3:9",
            "expected a formula",
        ),
        (
            "(declare-const X_0 Real)\n(declare-const Y_0 Real)\n(assert (not (<= X_0 1)))\n",
            "3:9",
            "unsupported connective `not`",
        ),
        (
            "(declare-const X_0 Real)\n(declare-const Y_0 Real)\n(assert (<= (* X_0 Y_0) 1))\n",
            "3:13",
            "nonlinear",
        ),
        (
            "(declare-const X_0 Real)\n(declare-const Y_0 Real)\n(assert (<= X_0 1 2))\n",
            "3:9",
            "takes two arguments",
        ),
        (
            "(declare-const X_0 Real)\n(declare-const Y_0 Real)\n(assert (<= (X_0) 1))\n",
            "3:13",
            "unsupported term `(X_0 ...)`",
        ),
        (
            "(declare-const X_0 Real)\n(declare-const Y_0 Real)\n(assert (<= () 1))\n",
            "3:13",
            "expected an operator",
        ),
        (
            "(declare-const X_0 Real)\n(declare-const Y_0 Real)\nX_0\n",
            "3:1",
            "expected a command",
        ),
        (
            "(declare-const X_0 Real)\n(declare-const Y_0 Real)\n(push 1)\n",
            "3:1",
            "unsupported command `push`",
        ),
    ] {
        let e = vnn_err(text);
        assert!(
            e.starts_with(&format!("p.vnnlib:{at}: ")) && e.contains(needle),
            "{text:?}: {e}"
        );
    }
    let e = vnnlib::read_bytes(
        b"(declare-const X_0 Real)\n(assert (<= X_0 \xff))",
        "p.vnnlib",
        "f",
        "p",
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.starts_with("p.vnnlib:2:17: ") && e.contains("not UTF-8"),
        "{e}"
    );
}

#[test]
fn long_unknown_names_do_not_hang_the_suggestions() {
    let a = "p".repeat(100_000);
    let b = "q".repeat(100_000);
    let t = Instant::now();
    let e = err(&format!(
        "{HEAD}param {a} = 1\nproperty p: {b} >= 0 => y >= 0\n"
    ));
    assert!(t.elapsed() < Duration::from_secs(2), "{:?}", t.elapsed());
    assert!(
        e.contains("t.spec:3:13") && e.contains("unknown name"),
        "{}",
        &e[..100]
    );
}

#[test]
fn many_inputs_and_many_disjuncts_are_read_in_linear_time() {
    let n = 100_000;
    let mut text: String = (0..n)
        .map(|i| format!("(declare-const X_{i} Real)\n"))
        .collect();
    text.push_str("(declare-const Y_0 Real)\n(assert (or");
    for k in 0..5000 {
        text.push_str(&format!(" (and (<= X_{} {k}) (>= Y_0 0))", k % 7));
    }
    text.push_str("))\n");
    let t = Instant::now();
    let p = vnn(&text).unwrap();
    assert!(t.elapsed() < Duration::from_secs(10), "{:?}", t.elapsed());
    assert_eq!(p.declared(), (n, 1));
    assert_eq!(p.query.region.len(), 5000);
    // X_0 .. X_6 are each bounded in some disjuncts only: no box bound.
    assert!(p.query.applications[0].input_box[0].1.is_infinite());
}

#[test]
fn mixed_nesting_near_the_limit_fits_a_2_mib_stack() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(17);
    let mut cases = Vec::new();
    for _ in 0..40 {
        let d = rng.gen_range(MAX_DEPTH - 20..MAX_DEPTH + 20);
        let (mut open, mut close) = (String::new(), String::new());
        let mut in_expr = false;
        for _ in 0..d {
            let pick = if in_expr {
                rng.gen_range(0..3)
            } else {
                rng.gen_range(0..5)
            };
            match pick {
                0 => {
                    open.push('(');
                    close.insert(0, ')');
                }
                1 => {
                    open.push('|');
                    close.insert(0, '|');
                    in_expr = true;
                }
                2 => {
                    open.push('-');
                    in_expr = true;
                }
                3 => open.push_str("not "),
                _ => open.push_str("a >= 0 => "),
            }
        }
        let body = if in_expr { "a" } else { "a >= 0" };
        let tail = if in_expr { " >= 0" } else { "" };
        cases.push(format!("{HEAD}property p: {open}{body}{close}{tail}\n"));
    }
    on_stack(2, move || {
        for c in cases {
            let _ = run(&c);
        }
    });
}

#[test]
fn a_ball_radius_with_many_cases_is_refused_before_expanding() {
    let r: Vec<String> = (0..40).map(|_| "|eps|".to_string()).collect();
    let src = format!(
        "{HEAD}param eps = 0.1\ndataset d = \"d.csv\"\nproperty p: for x0 in data d, for x1 in ball(x0, {}), f(x1) >= 0\n",
        r.join(" + ")
    );
    let t = Instant::now();
    let e = err(&src);
    assert!(t.elapsed() < Duration::from_secs(1), "{:?}", t.elapsed());
    assert!(
        e.contains("t.spec:4:") && e.contains("expected a constant"),
        "{e}"
    );
}

#[test]
fn strict_and_scaled_input_bounds_stay_exact() {
    use samara_spec::normal::Cmp;
    let p = vnn(&format!(
        "{DECL}(assert (< X_0 1))\n(assert (<= (* 3 X_0) 1))\n(assert (>= X_0 -1))\n"
    ))
    .unwrap();
    let b = p.query.applications[0].input_box[0];
    assert_eq!(
        b.0, -1.0,
        "a plain bound is exact and lives in the box only"
    );
    assert!(b.1 >= 1.0 / 3.0 && b.1 < 0.3334, "rounded outward: {b:?}");
    let c = &p.query.region[0];
    assert_eq!(c.len(), 2, "{c:?}");
    assert!(
        c.iter().any(|k| k.cmp == Cmp::Lt),
        "the strict bound stays: {c:?}"
    );
}

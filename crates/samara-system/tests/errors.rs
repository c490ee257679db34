//! The system language's errors: file:line:column, a message and a fix.

use samara_system::{System, SystemError};

const BASE: &str = "state x, v
input u
param k = 2
let s = sin(x)
x' = v
v' = -k * s + u
period 0.1
horizon 1
actuate u = net[0]
init x in [0, 0.1]
init v = 0
goal reach x in [-1, 1] at end
";

fn fails(src: &str) -> SystemError {
    match System::parse(src, "t.sys") {
        Ok(_) => panic!("accepted:\n{src}"),
        Err(e) => e,
    }
}

fn with(line: usize, text: &str) -> String {
    let mut v: Vec<&str> = BASE.lines().collect();
    v[line - 1] = text;
    v.join("\n") + "\n"
}

#[test]
fn base_is_valid() {
    let s = System::parse(BASE, "t.sys").unwrap();
    let mut o = [0.0; 2];
    s.rhs(&[0.5, 1.0], &[0.1], &mut o);
    assert_eq!(o, [1.0, -2.0 * 0.5f64.sin() + 0.1]);
    assert_eq!(s.rhs_graph().ops.len(), 6); // x, v, u, sin(x), sin(x) * -2, + u
}

#[test]
fn unknown_name_with_suggestion() {
    let e = fails(&with(6, "v' = -k * sx + u"));
    assert_eq!((e.pos.line, e.pos.col), (6, 11));
    assert!(e.message.contains("unknown name `sx`"), "{e}");
    assert!(e.hint.contains("did you mean `s`?"), "{e}");
    let shown = e.to_string();
    assert!(
        shown.starts_with("t.sys:6:11: unknown name `sx`"),
        "{shown}"
    );
    assert!(
        shown.contains("  | v' = -k * sx + u\n  |           ^"),
        "{shown}"
    );
}

#[test]
fn wrong_arity() {
    let e = fails(&with(4, "let s = sin(x, v)"));
    assert_eq!((e.pos.line, e.pos.col), (4, 9));
    assert!(e.message.contains("`sin` takes 1 argument, got 2"), "{e}");
    let e = fails(&with(4, "let s = max(x)"));
    assert!(
        e.message.contains("`max` takes 2 to 64 arguments, got 1"),
        "{e}"
    );
    let e = fails(&with(4, "let s = sine(x)"));
    assert!(
        e.message.contains("unknown function `sine`") && e.hint.contains("`sin`"),
        "{e}"
    );
}

#[test]
fn undefined_state() {
    let e = fails(&with(5, "xx' = v"));
    assert_eq!((e.pos.line, e.pos.col), (5, 1));
    assert!(e.message.contains("undefined state `xx`"), "{e}");
    assert!(e.hint.contains("did you mean `x'`"), "{e}");
    let e = fails(&with(5, "# no equation for x"));
    assert!(
        e.message.contains("state `x` has no equation") && e.hint.contains("x' ="),
        "{e}"
    );
}

#[test]
fn division_by_a_literal_zero() {
    let e = fails(&with(6, "v' = -k * s / 0 + u"));
    assert_eq!((e.pos.line, e.pos.col), (6, 13));
    assert!(e.message.contains("division by zero"), "{e}");
    let e = fails(&with(6, "v' = u / (k - 2)"));
    assert!(e.message.contains("division by zero"), "{e}");
    let e = fails(&with(6, "v' = x^-1 + 0^-2"));
    assert!(e.message.contains("division by zero"), "{e}");
}

#[test]
fn other_errors_have_positions_and_fixes() {
    let cases: &[(&str, usize, &str)] = &[
        ("v' = -k * s + u)", 6, "expected the end of the statement"),
        ("v' = -k * s + 1e999", 6, "overflows"),
        ("v' = -k * s + 2u", 6, "cannot follow the number"),
        ("period -1", 7, "positive"),
        ("horizon 1.05", 8, "multiple of the period"),
        ("actuate w = net[0]", 9, "not an input"),
        ("init x in [1, 0]", 10, "empty"),
        ("init q = 0", 11, "not a state"),
        (
            "goal reach x in [-1, 1] always [0, 2]",
            12,
            "not inside [0, 1]",
        ),
        (
            "goal reach x in [-1, 1]",
            12,
            "expected when the goal is checked",
        ),
        ("param k = x", 3, "is a state"),
        ("param k = log(-1)", 3, "finite"),
        ("let s = sin(x) $", 4, "unexpected character"),
        ("stat y", 1, "unknown statement"),
        ("let sin = 2", 4, "reserved"),
        ("let s = w * 2", 4, "unknown name"),
        ("let s = t + 1", 4, "defined later"),
        ("goal band |x + u| <= 1 at end", 12, "is an input"),
    ];
    for (text, line, needle) in cases {
        let src = with(*line, text)
            + if *text == "let s = t + 1" {
                "let t = 1\n"
            } else {
                ""
            };
        let e = fails(&src);
        assert!(e.message.contains(needle), "{text}: {e}");
        assert!(e.pos.line == *line || e.pos.line == 0, "{text}: {e}");
        assert!(!e.hint.is_empty(), "{text}: no fix: {e}");
    }
}

#[test]
fn limits() {
    let deep = format!("{}x{}", "(".repeat(300), ")".repeat(300));
    let e = fails(&with(5, &format!("x' = {deep}")));
    assert!(e.message.contains("deeper than 256"), "{e}");
    let ok = format!("{}x{}", "(".repeat(250), ")".repeat(250));
    System::parse(&with(5, &format!("x' = {ok}")), "t.sys").unwrap();
    let e = fails(&with(5, &format!("x' = {}x", "-".repeat(100_000))));
    assert!(e.message.contains("deeper than 256"), "{e}");
    // Long flat sums are fine (they are chains, not deep trees).
    let long = vec!["x"; 50_000].join(" + ");
    System::parse(&with(5, &format!("x' = {long}")), "t.sys").unwrap();
    let huge = "#".repeat(samara_system::MAX_SOURCE_BYTES + 1);
    assert!(fails(&huge).message.contains("limit"));
}

#[test]
fn overrides() {
    let s = System::parse(BASE, "t.sys").unwrap();
    let t = s.with_params(&[("k", 3.0)]).unwrap();
    let mut o = [0.0; 2];
    t.rhs(&[0.5, 1.0], &[0.0], &mut o);
    assert_eq!(o[1], -3.0 * 0.5f64.sin());
    let e = s.with_params(&[("kk", 1.0)]).unwrap_err();
    assert!(
        e.message.contains("no parameter `kk`") && e.hint.contains("`k`"),
        "{e}"
    );
}

#[test]
fn the_documented_example_parses() {
    let p = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../docs/system.md");
    let doc = std::fs::read_to_string(p).unwrap();
    let start = doc.find("```text\n").unwrap() + 8;
    let end = start + doc[start..].find("```").unwrap();
    let s = System::parse(&doc[start..end], "system.md").unwrap_or_else(|e| panic!("{e}"));
    assert_eq!((s.dim(), s.n_inputs(), s.steps()), (2, 1, 20));
    let mut u = [0.0];
    s.actuate(&[5.0], &mut u);
    assert_eq!(u[0], 3.0);
    assert_eq!(s.param("gl"), Some(2.0));
    assert_eq!(s.with_params(&[("g", 2.0)]).unwrap().param("gl"), Some(4.0));
}

//! The property language: the case-study properties lower to regions that match direct
//! hand-written predicates; errors point at file:line:column with a fix; VNN-LIB round
//! trips; random input never panics.

use proptest::prelude::*;
use rand::{Rng, SeedableRng};
use samara_spec::normal::{Cmp, Constraint, Var};
use samara_spec::{vnnlib, Bindings, Spec};
use std::path::Path;

use samara_testkit as support;

const C: [f64; 6] = [
    0.967568147,
    -0.607397104,
    -0.356972794,
    -0.96847853,
    0.482420778,
    -41.68140527,
];
const S: [f64; 6] = [
    2.522324921,
    0.564375713,
    0.406153017,
    0.900476013,
    41.23229622,
    45.87863879,
];

fn spec_path() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/alsomitra/alsomitra.spec")
}

fn case_study() -> Spec {
    Spec::read(&spec_path()).unwrap()
}

/// not P_k at a raw state and raw ex, written directly from the paper's statements.
fn counterexample(k: usize, s: &[f64], ex: f64, ystar: f64) -> bool {
    let (vyp, omega, theta, x, y) = (s[1], s[2], s[3], s[4], s[5]);
    match k {
        1 => y >= -x + ystar && ex < 0.187,
        2 => y <= -x - ystar && ex > 0.187,
        3 => {
            (-x - ystar <= y && y <= -x + ystar && (-0.786..=-0.747).contains(&theta))
                && !(0.184..=0.19).contains(&ex)
        }
        _ => (-x <= y && y <= -x + ystar && omega <= -0.12 && vyp <= -0.3) && ex > 0.187,
    }
}

#[test]
fn case_study_regions_match_hand_written_predicates() {
    let spec = case_study();
    let mut b = Bindings::default();
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    for ystar in [0.5, 2.0, 10.0] {
        b.params.insert("ystar".into(), ystar);
        for k in 1..=4 {
            let q = &spec.lower_prove(&format!("p{k}"), &b).unwrap()[0].query;
            assert_eq!(q.applications.len(), 1);
            let mut agree = 0;
            for _ in 0..4000 {
                // Raw state in the domain, biased towards the band around y = -x.
                let mut s: Vec<f64> = (0..6)
                    .map(|j| C[j] + S[j] * r.gen_range(0.0..1.0))
                    .collect();
                s[5] = (-s[4] + r.gen_range(-1.5 * ystar..1.5 * ystar)).clamp(C[5], C[5] + S[5]);
                if r.gen_bool(0.3) {
                    s[3] = r.gen_range(-0.8..-0.73);
                }
                let ex = r.gen_range(0.18..0.194);
                let z: Vec<f64> = (0..6).map(|j| (s[j] - C[j]) / S[j]).collect();
                let out = (ex - 0.181) / 0.012;
                let value = |v: Var| match v {
                    Var::Input { index, .. } => z[index],
                    Var::Output { .. } => out,
                    Var::Free(_) => unreachable!(),
                };
                // Rounding of the unit conversion: skip points within 1e-9 of a boundary.
                let near = q
                    .region
                    .iter()
                    .flatten()
                    .any(|c: &Constraint| c.expr.eval(value).abs() < 1e-9);
                if near {
                    continue;
                }
                let inside = q
                    .region
                    .iter()
                    .any(|conj| conj.iter().all(|c| c.holds(value, 0.0)));
                assert_eq!(
                    inside,
                    counterexample(k, &s, ex, ystar),
                    "p{k} ystar {ystar} at {s:?} ex {ex}"
                );
                agree += 1;
            }
            assert!(agree > 3000);
        }
    }
}

fn err(src: &str) -> String {
    Spec::parse(src, "t.spec", Path::new("."))
        .unwrap_err()
        .to_string()
}

const HEAD: &str = "network f(v_xp, v_yp, omega, theta, x, y) -> (ex)\nparam ystar = 2\n";

#[test]
fn errors_name_the_place_and_the_fix() {
    let e = err(&format!("{HEAD}property p: thetaa >= 0 => ex <= 0.19\n"));
    assert!(
        e.contains("t.spec:3:13")
            && e.contains("unknown name `thetaa`")
            && e.contains("did you mean `theta`?"),
        "{e}"
    );
    assert!(
        e.contains("  | property p: thetaa") && e.contains("^"),
        "{e}"
    );
    let e = err(&format!("{HEAD}property p: x * y >= 0 => ex <= 0.19\n"));
    assert!(
        e.contains("nonlinear term") && e.contains("t.spec:3:15"),
        "{e}"
    );
    let e = err(&format!(
        "{HEAD}normalise f input min [1, 2] range [1, 1]\n"
    ));
    assert!(
        e.contains("dimension mismatch") && e.contains("6 inputs"),
        "{e}"
    );
    let e = err(&format!("{HEAD}property p: y >= -x + ystar => ex >= \n"));
    assert!(
        e.contains("t.spec:3:38") && e.contains("expected a number, a name"),
        "{e}"
    );
    let e = err(&format!(
        "{HEAD}property p: y >= -x + ystar => f(q) >= 0.1\n"
    ));
    assert!(e.contains("unknown name `q`"), "{e}");
    let e = err("network f(a) -> (b)\nproperty p: a >= 1 => b @ 2\n");
    assert!(e.contains("unexpected character `@`"), "{e}");
    // A parameter without a value is an error when lowering, not when checking.
    let s = Spec::parse(
        "network f(a) -> (b)\nparam t\nproperty p: a >= t => b >= 0\n",
        "t.spec",
        Path::new("."),
    )
    .unwrap();
    let e = s
        .lower_prove("p", &Bindings::default())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("parameter `t` is not bound") && e.contains("--param t=VALUE"),
        "{e}"
    );
    let e = s
        .lower_critical("p", "t", &Bindings::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("has no range"), "{e}");
    // Network files that do not match the declaration.
    let mut b = Bindings::default();
    b.params.insert("t".into(), 1.0);
    b.network_dims.insert("f".into(), (2, 1));
    let e = s.lower_prove("p", &b).unwrap_err().to_string();
    assert!(
        e.contains("dimension mismatch") && e.contains("the file has 2"),
        "{e}"
    );
}

fn sorted(q: &samara_spec::normal::Query) -> Vec<Vec<String>> {
    let mut v: Vec<Vec<String>> = q
        .region
        .iter()
        .map(|c| {
            let mut s: Vec<String> = c
                .iter()
                .map(|k| {
                    let e = k.expr.clone().normalised();
                    let terms: Vec<String> = e
                        .terms
                        .iter()
                        .map(|(v, c)| format!("{v:?}*{c:.15e}"))
                        .collect();
                    format!("{} {:.15e} {:?}", terms.join("+"), e.constant, k.cmp)
                })
                .collect();
            s.sort();
            s
        })
        .collect();
    v.sort();
    v
}

#[test]
fn vnnlib_round_trip_keeps_the_normal_form() {
    let spec = case_study();
    let mut b = Bindings::default();
    b.params.insert("ystar".into(), 2.0);
    for k in 1..=4 {
        let q = spec
            .lower_prove(&format!("p{k}"), &b)
            .unwrap()
            .remove(0)
            .query;
        let text = vnnlib::export(&q).unwrap();
        let back = vnnlib::import(&text, "rt.vnnlib", "f", &q.name).unwrap();
        // The box comes back, tightened (soundly) by input bounds that every case of
        // the region holds (p3's theta bounds, p4's omega and v_yp bounds).
        let (bb, qb) = (
            &back.applications[0].input_box,
            &q.applications[0].input_box,
        );
        assert_eq!(bb.len(), qb.len());
        for (b, o) in bb.iter().zip(qb) {
            assert!(o.0 <= b.0 && b.1 <= o.1, "p{k}: {b:?} not within {o:?}");
        }
        if k <= 2 {
            assert_eq!(bb, qb, "p{k}");
        }
        assert_eq!(sorted(&back), sorted(&q), "p{k}");
    }
    // Relational queries cannot be written as VNN-LIB: a clear error.
    b.datasets.insert(
        "train".into(),
        support::reference("Training_Data_Normalised.csv"),
    );
    let q5 = spec
        .lower_prove("p5_lipschitz", &b)
        .unwrap()
        .remove(0)
        .query;
    assert!(vnnlib::export(&q5)
        .unwrap_err()
        .to_string()
        .contains("calls networks 2 times"));
    let _ = Cmp::Le;
}

#[test]
fn vnnlib_import_of_a_vnncomp_style_file() {
    let text = "; acas-like\n(declare-const X_0 Real)\n(declare-const X_1 Real)\n(declare-const Y_0 Real)\n(declare-const Y_1 Real)\n\
                (assert (<= X_0 0.5))\n(assert (>= X_0 -0.5))\n(assert (<= X_1 1.0))\n(assert (>= X_1 0.0))\n\
                (assert (<= (+ X_0 (* 2.0 X_1)) 1.0))\n(assert (or (and (>= Y_0 Y_1)) (and (<= Y_0 (- 3.5)))))\n";
    let q = vnnlib::import(text, "a.vnnlib", "net", "a").unwrap();
    assert_eq!(q.applications[0].input_box, vec![(-0.5, 0.5), (0.0, 1.0)]);
    assert_eq!(q.region.len(), 2);
    assert!(
        q.region.iter().all(|c| c.len() == 2),
        "the general input constraint joins every disjunct"
    );
    assert!(vnnlib::import("(assert (<= X_0 1.0)", "b.vnnlib", "n", "b")
        .unwrap_err()
        .to_string()
        .contains("unbalanced"));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(300))]
    #[test]
    fn random_text_never_panics(s in "\\PC{0,200}") {
        let _ = Spec::parse(&s, "fuzz.spec", Path::new("."));
        let _ = vnnlib::import(&s, "fuzz.vnnlib", "f", "q");
    }

    #[test]
    fn mutated_case_study_never_panics(cut in 0usize..3000, len in 0usize..12, ins in "[-+*/()|<=>a-z0-9 .,:\\[\\]]{0,4}") {
        let src = std::fs::read_to_string(spec_path()).unwrap();
        let mut chars: Vec<char> = src.chars().collect();
        let at = cut % chars.len();
        let end = (at + len).min(chars.len());
        chars.splice(at..end, ins.chars());
        let text: String = chars.into_iter().collect();
        if let Ok(spec) = Spec::parse(&text, "m.spec", Path::new(".")) {
            let mut b = Bindings::default();
            b.params.insert("ystar".into(), 1.0);
            for p in spec.property_names() {
                let _ = spec.lower_prove(p, &b);
                let _ = spec.lower_critical(p, "ystar", &b);
            }
        }
    }
}

#[test]
fn constants_file_gives_the_same_normal_form_as_inline_constants() {
    let consts = support::reference("Normalisation_Constants.csv");
    let src = std::fs::read_to_string(spec_path()).unwrap();
    // Replace the three normalise lines by one `normalise f from` line.
    let mut out = Vec::new();
    let mut skip = false;
    for line in src.lines() {
        if line.starts_with("normalise f input") {
            out.push(format!("normalise f from \"{}\"", consts.display()));
            skip = line.ends_with('\\');
            continue;
        }
        if skip {
            skip = line.ends_with('\\');
            continue;
        }
        if line.starts_with("normalise f output") {
            continue;
        }
        out.push(line.to_string());
    }
    let alt = Spec::parse(&out.join("\n"), "alt.spec", Path::new(".")).unwrap();
    let mut b = Bindings::default();
    b.params.insert("ystar".into(), 2.0);
    for k in 1..=4 {
        let a = alt
            .lower_prove(&format!("p{k}"), &b)
            .unwrap()
            .remove(0)
            .query;
        let c = case_study()
            .lower_prove(&format!("p{k}"), &b)
            .unwrap()
            .remove(0)
            .query;
        assert_eq!(sorted(&a), sorted(&c), "p{k}");
    }
    let e = Spec::parse(
        "network f(a, b) -> (y)\nnormalise f from \"/nonexistent/c.csv\"\n",
        "t.spec",
        Path::new("."),
    )
    .unwrap_err()
    .to_string();
    assert!(
        e.contains("t.spec:2:1") && e.contains("normalisation constants"),
        "{e}"
    );
}

#[test]
fn relational_queries_export_over_the_stacked_network() {
    let spec = case_study();
    let mut b = Bindings::default();
    b.datasets.insert(
        "train".into(),
        support::reference("Training_Data_Normalised.csv"),
    );
    let q = spec
        .lower_prove("p5_lipschitz", &b)
        .unwrap()
        .remove(3)
        .query;
    let (sq, k) = vnnlib::stack_applications(&q).unwrap();
    assert_eq!(
        (k, sq.applications[0].n_inputs, sq.applications[0].n_outputs),
        (2, 12, 2)
    );
    let net = samara_nn::onnx::load(support::reference("base_model_norm.onnx")).unwrap();
    let stacked = net.stacked(2);
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(8);
    let mut inside = 0;
    for _ in 0..3000 {
        let x: Vec<Vec<f64>> = q
            .applications
            .iter()
            .map(|a| {
                a.input_box
                    .iter()
                    .map(|(l, h)| if l == h { *l } else { r.gen_range(*l..*h) })
                    .collect()
            })
            .collect();
        let y: Vec<Vec<f64>> = x.iter().map(|xi| net.eval_f64(xi)).collect();
        let flat: Vec<f64> = x.concat();
        let ys = stacked.eval_f64(&flat);
        let orig = q.region.iter().any(|c| {
            c.iter().all(|k| {
                k.holds(
                    |v| match v {
                        Var::Input { app, index } => x[app][index],
                        Var::Output { app, index } => y[app][index],
                        Var::Free(_) => 0.0,
                    },
                    0.0,
                )
            })
        });
        let st = sq.region.iter().any(|c| {
            c.iter().all(|k| {
                k.holds(
                    |v| match v {
                        Var::Input { index, .. } => flat[index],
                        Var::Output { index, .. } => ys[index],
                        Var::Free(_) => 0.0,
                    },
                    0.0,
                )
            })
        });
        assert_eq!(orig, st);
        inside += usize::from(orig);
    }
    assert!(
        inside > 0,
        "no sample inside the region: the test would be vacuous"
    );
    let text = vnnlib::export(&sq).unwrap();
    assert!(
        text.contains("(declare-const X_11 Real)") && text.contains("(declare-const Y_1 Real)")
    );
    assert_eq!(vnnlib::split_disjuncts(&sq).len(), sq.region.len());
}

//! Critical queries of P1-P4 against the paper's statements: a point `(state, ex)` with
//! the parameter value `t` lies in the critical query's region exactly when it is a
//! counterexample to the property with `ystar = t` (checked at random points and values,
//! with a predicate written here from the paper), and the region is monotone in `t` in
//! the direction `docs/spec.md` states (P1, P2 closed downwards: they hold above the
//! supremum; P3, P4 closed upwards: they hold below the infimum). Also: data sets in IDX
//! give the same balls as the CSV up to float32 rounding.

use rand::{Rng, SeedableRng};
use samara_spec::normal::{Cmp, Var};
use samara_spec::{Bindings, Spec};
use std::path::Path;

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

fn spec() -> Spec {
    Spec::read(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/alsomitra/alsomitra.spec"))
        .unwrap()
}

use samara_testkit as support;
use support::reference;

/// Counterexample to P_k with ystar = t, from the paper's statements (raw units).
fn counterexample(k: usize, s: &[f64], ex: f64, t: f64) -> bool {
    let (vyp, omega, theta, x, y) = (s[1], s[2], s[3], s[4], s[5]);
    match k {
        1 => y >= -x + t && ex < 0.187,
        2 => y <= -x - t && ex > 0.187,
        3 => {
            -x - t <= y
                && y <= -x + t
                && (-0.786..=-0.747).contains(&theta)
                && !(0.184..=0.19).contains(&ex)
        }
        _ => -x <= y && y <= -x + t && omega <= -0.12 && vyp <= -0.3 && ex > 0.187,
    }
}

#[test]
fn critical_regions_are_the_counterexamples_for_each_parameter_value() {
    let spec = spec();
    let b = Bindings::default();
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(21);
    for k in 1..=4 {
        let inst = spec.lower_critical(&format!("p{k}"), "ystar", &b).unwrap();
        let q = &inst[0].query;
        assert_eq!(q.free_vars.len(), 1);
        assert_eq!(
            (q.free_vars[0].1, q.free_vars[0].2),
            (0.0, 100.0),
            "the declared range"
        );
        // Direction: the sign of the parameter's coefficient in every constraint.
        let signs: Vec<f64> = q
            .region
            .iter()
            .flatten()
            .flat_map(|c| {
                assert_ne!(c.cmp, Cmp::Eq);
                c.expr
                    .terms
                    .iter()
                    .filter(|(v, _)| *v == Var::Free(0))
                    .map(|(_, a)| a.signum())
            })
            .collect();
        assert!(!signs.is_empty());
        let want = if k <= 2 { 1.0 } else { -1.0 };
        assert!(signs.iter().all(|s| *s == want), "p{k}: {signs:?}");
        let (mut yes, mut no) = (0, 0);
        for _ in 0..6000 {
            let mut s: Vec<f64> = (0..6)
                .map(|j| C[j] + S[j] * r.gen_range(0.0..1.0))
                .collect();
            let t = r.gen_range(0.0..20.0);
            s[5] = (-s[4] + r.gen_range(-1.5 * t - 1.0..1.5 * t + 1.0)).clamp(C[5], C[5] + S[5]);
            if r.gen_bool(0.4) {
                s[3] = r.gen_range(-0.8..-0.73);
            }
            let ex = r.gen_range(0.18..0.194);
            let z: Vec<f64> = (0..6).map(|j| (s[j] - C[j]) / S[j]).collect();
            let out = (ex - 0.181) / 0.012;
            let value = |v: Var| match v {
                Var::Input { index, .. } => z[index],
                Var::Output { .. } => out,
                Var::Free(_) => t,
            };
            if q.region
                .iter()
                .flatten()
                .any(|c| !c.expr.terms.is_empty() && c.expr.eval(value).abs() < 1e-9)
            {
                continue;
            }
            let inside = q
                .region
                .iter()
                .any(|d| d.iter().all(|c| c.holds(value, 0.0)));
            assert_eq!(
                inside,
                counterexample(k, &s, ex, t),
                "p{k} t {t} at {s:?} ex {ex}"
            );
            if inside {
                yes += 1
            } else {
                no += 1
            }
        }
        assert!(yes > 100 && no > 1000, "p{k}: {yes} {no}");
    }
}

/// The IDX inputs (each point written twice, float32) against the CSV: same balls.
#[test]
fn idx_data_set_gives_the_csv_balls_up_to_float32() {
    let spec = spec();
    let mut b = Bindings::default();
    b.params.insert("eps".into(), 0.005);
    b.params.insert("L".into(), 0.01);
    b.datasets
        .insert("train".into(), reference("Training_Data_Normalised.csv"));
    let from_csv = spec.lower_prove("p5_lipschitz", &b).unwrap();
    b.datasets
        .insert("train".into(), reference("dataset_inputs.idx"));
    let from_idx = spec.lower_prove("p5_lipschitz", &b).unwrap();
    assert_eq!(from_csv.len(), 360);
    assert_eq!(from_idx.len(), 360);
    for (a, c) in from_csv.iter().zip(&from_idx) {
        for (x, y) in a.query.applications.iter().zip(&c.query.applications) {
            for (p, q) in x.input_box.iter().zip(&y.input_box) {
                assert!(
                    (p.0 - q.0).abs() < 1e-6 && (p.1 - q.1).abs() < 1e-6,
                    "{}",
                    a.label
                );
            }
        }
        assert_eq!(a.query.region.len(), c.query.region.len());
    }
}

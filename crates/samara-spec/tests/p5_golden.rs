//! P5 (local robustness around each training point) against predicates written directly
//! from the paper's statements, on the published data: the instance count, the input box
//! of the ball application (eps-ball intersected with the domain, recomputed here from
//! the CSV), and the counterexample region's membership at random points, for both the
//! published form `|f(x') - label| <= L / eps` and the Lipschitz form
//! `|f(x') - f(x)| <= L * ||x' - x||_inf`. Also the VNN-LIB round trip of P5 instances.

use rand::{Rng, SeedableRng};
use samara_spec::normal::{Cmp, Query, Var};
use samara_spec::{vnnlib, Bindings, Spec};
use std::path::Path;

use samara_testkit as support;
use support::reference;

fn spec() -> Spec {
    Spec::read(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/alsomitra/alsomitra.spec"))
        .unwrap()
}

/// The normalised training rows (6 inputs, then the normalised ex), read here by hand.
fn rows() -> Vec<Vec<f64>> {
    std::fs::read_to_string(reference("Training_Data_Normalised.csv"))
        .unwrap()
        .lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| l.split(',').map(|v| v.trim().parse().unwrap()).collect())
        .collect()
}

fn bindings(eps: f64, l: f64) -> Bindings {
    let mut b = Bindings::default();
    b.params.insert("eps".into(), eps);
    b.params.insert("L".into(), l);
    b.params.insert("ystar".into(), 2.0);
    b.datasets
        .insert("train".into(), reference("Training_Data_Normalised.csv"));
    b
}

fn ex(out: f64) -> f64 {
    0.181 + 0.012 * out
}

/// Whether the region contains the point, `None` if it lies within 1e-12 of a boundary
/// (where the rounding of the unit conversion may decide); constant constraints (the
/// case split of the norm compares a coordinate with itself) are never near.
fn member(q: &Query, value: &dyn Fn(Var) -> f64) -> Option<bool> {
    if q.region
        .iter()
        .flatten()
        .any(|c| !c.expr.terms.is_empty() && c.expr.eval(value).abs() < 1e-12)
    {
        return None;
    }
    Some(
        q.region
            .iter()
            .any(|d| d.iter().all(|c| c.holds(value, 0.0))),
    )
}

#[test]
fn p5_published_form_matches_the_paper_statement() {
    let data = rows();
    let (eps, l) = (0.01, 2e-5); // L / eps = 2e-3 in ex, inside the outputs' spread
    let inst = spec().lower_prove("p5", &bindings(eps, l)).unwrap();
    assert_eq!(inst.len(), data.len(), "one instance per training point");
    assert_eq!(inst.len(), 360);
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let (mut inside, mut outside) = (0, 0);
    for i in (0..360).step_by(7) {
        let q = &inst[i].query;
        assert_eq!(
            q.applications.len(),
            1,
            "f(x1) only: the label is a constant"
        );
        let z0 = &data[i][..6];
        let label = ex(data[i][6]);
        // The ball intersected with the domain [0, 1]^6 (C to C + S in raw units).
        let bx = &q.applications[0].input_box;
        for k in 0..6 {
            assert!(
                (bx[k].0 - (z0[k] - eps).max(0.0)).abs() < 1e-9,
                "row {i} input {k}"
            );
            assert!(
                (bx[k].1 - (z0[k] + eps).min(1.0)).abs() < 1e-9,
                "row {i} input {k}"
            );
        }
        for _ in 0..200 {
            let z: Vec<f64> = (0..6).map(|k| r.gen_range(bx[k].0..=bx[k].1)).collect();
            let out = (label - 0.181) / 0.012 + r.gen_range(-0.4..0.4);
            let value = |v: Var| match v {
                Var::Input { index, .. } => z[index],
                Var::Output { .. } => out,
                Var::Free(_) => unreachable!(),
            };
            let hand = (ex(out) - label).abs() > l / eps;
            if let Some(m) = member(q, &value) {
                assert_eq!(m, hand, "row {i}: ex {} label {label}", ex(out));
                if m {
                    inside += 1
                } else {
                    outside += 1
                }
            }
        }
    }
    assert!(inside > 500 && outside > 500, "{inside} {outside}");
}

#[test]
fn p5_lipschitz_form_matches_the_paper_statement() {
    let data = rows();
    let (eps, l) = (0.01, 0.02);
    let inst = spec()
        .lower_prove("p5_lipschitz", &bindings(eps, l))
        .unwrap();
    assert_eq!(inst.len(), 360);
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(12);
    let (mut inside, mut outside) = (0, 0);
    for i in (0..360).step_by(11) {
        let q = &inst[i].query;
        assert_eq!(q.applications.len(), 2, "f(x1) and f(x0)");
        // The application at the data point has a degenerate box at the point.
        let pinned = q
            .applications
            .iter()
            .position(|a| a.input_box.iter().all(|(lo, hi)| lo == hi))
            .expect("f(x0) is pinned");
        let z0 = &data[i][..6];
        for (k, (lo, _)) in q.applications[pinned].input_box.iter().enumerate() {
            assert!((lo - z0[k]).abs() < 1e-12);
        }
        let ball = 1 - pinned;
        let bx = q.applications[ball].input_box.clone();
        for _ in 0..200 {
            let z: Vec<f64> = (0..6).map(|k| r.gen_range(bx[k].0..=bx[k].1)).collect();
            let (o1, o0) = (r.gen_range(0.0..1.0), r.gen_range(0.0..1.0));
            let o1 = o0 + (o1 - 0.5) * 0.05;
            let value = |v: Var| match v {
                Var::Input { app, index } if app == ball => z[index],
                Var::Input { index, .. } => z0[index],
                Var::Output { app, .. } if app == ball => o1,
                Var::Output { .. } => o0,
                Var::Free(_) => unreachable!(),
            };
            let dist = (0..6).map(|k| (z[k] - z0[k]).abs()).fold(0.0, f64::max);
            let hand = (ex(o1) - ex(o0)).abs() > l * dist;
            if let Some(m) = member(q, &value) {
                assert_eq!(m, hand, "row {i}");
                if m {
                    inside += 1
                } else {
                    outside += 1
                }
            }
        }
    }
    assert!(inside > 300 && outside > 300, "{inside} {outside}");
}

/// Canonical text of a normal form: each disjunct's constraints printed and sorted.
fn canonical(q: &Query) -> Vec<Vec<String>> {
    let mut v: Vec<Vec<String>> = q
        .region
        .iter()
        .map(|d| {
            let mut c: Vec<String> = d
                .iter()
                .map(|c| {
                    let e = c.expr.clone().normalised();
                    let op = match c.cmp {
                        Cmp::Le => "<=",
                        Cmp::Lt => "<",
                        Cmp::Eq => "==",
                    };
                    format!("{:?} {:?} {op}", e.terms, e.constant)
                })
                .collect();
            c.sort();
            c
        })
        .collect();
    v.sort();
    v
}

#[test]
fn p5_instances_round_trip_through_vnnlib() {
    let inst = spec().lower_prove("p5", &bindings(0.005, 1e-5)).unwrap();
    for i in [0, 1, 100, 359] {
        let q = &inst[i].query;
        let text = vnnlib::export(q).unwrap();
        let back = vnnlib::import(&text, "p5.vnnlib", "f", &q.name).unwrap();
        assert_eq!(
            back.applications[0].input_box, q.applications[0].input_box,
            "p5[{i}]"
        );
        assert_eq!(canonical(&back), canonical(q), "p5[{i}]");
    }
}

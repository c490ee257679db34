//! LP-based bound tightening ([`samara_verify::tighten`]) is sound and changes no answer:
//! on random small ReLU (and clamp) networks the tightened pre-activation bounds contain
//! the pre-activations of thousands of sampled inputs (also under fixed phases and
//! input constraints), are never looser than the interval + DeepPoly bounds they start
//! from, and critical values and verdicts with tightening on equal those with it off.

use rand::{Rng, SeedableRng};
use samara_nn::{Activation, Layer, Network};
use samara_spec::normal::{Application, Cmp, Constraint, Goal, LinExpr, Query, Sense, Var};
#[path = "support/case_study.rs"]
mod case_study;
use case_study::p1_to_p4;
use samara_testkit as reference_files;
use samara_verify::net::PwlNet;
use samara_verify::tighten::{base_bounds, lp_tighten, InputConstraint, LpTighten};
use samara_verify::{optimise, prove, Prepared, Settings, Verdict};
use std::collections::HashMap;

fn net(r: &mut impl Rng, dims: &[usize], clamp: bool) -> Network {
    let mut n = Network::random_mlp(dims, Activation::Relu, 1.0, 0.3, r);
    if clamp {
        n.layers
            .push(Layer::Act(Activation::Clamp { lo: -0.2, hi: 0.3 }));
    }
    n
}

/// Pre-activations of every map at `x`.
fn pre_activations(p: &PwlNet, x: &[f64]) -> Vec<Vec<f64>> {
    let mut a = x.to_vec();
    let mut out = Vec::new();
    for (m, relu) in &p.maps {
        let mut z = vec![0.0; m.out];
        m.apply_f64(&a, &mut z);
        a = if *relu {
            z.iter().map(|v| v.max(0.0)).collect()
        } else {
            z.clone()
        };
        out.push(z);
    }
    out
}

fn relu_layers(p: &PwlNet) -> Vec<usize> {
    (0..p.maps.len()).filter(|&k| p.maps[k].1).collect()
}

#[test]
fn tightened_bounds_contain_samples_and_are_no_looser_than_deeppoly() {
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(5);
    let (mut improved, mut stabilised, mut checked) = (0, 0, 0usize);
    for case in 0..24 {
        let dims: &[usize] = match case % 3 {
            0 => &[4, 12, 10, 3],
            1 => &[3, 16, 12, 8, 1],
            _ => &[5, 10, 10, 2],
        };
        let n_in = dims[0];
        let p = PwlNet::from_network(&net(&mut r, dims, case % 4 == 1)).unwrap();
        let xl: Vec<f64> = (0..n_in).map(|_| r.gen_range(-1.0..0.0)).collect();
        let xh: Vec<f64> = xl.iter().map(|l| l + r.gen_range(0.2..1.5)).collect();
        let sample = |r: &mut rand_chacha::ChaCha8Rng| -> Vec<f64> {
            xl.iter()
                .zip(&xh)
                .map(|(l, h)| r.gen_range(*l..=*h))
                .collect()
        };
        let relus = relu_layers(&p);
        // Variants: plain box; a half-space on the inputs; phases fixed as at a
        // random point for a few neurons of the first two ReLU layers.
        for variant in 0..3 {
            let mut inputs = Vec::new();
            let mut fixed: Vec<Vec<i8>> = relus.iter().map(|&k| vec![0; p.maps[k].0.out]).collect();
            if variant == 1 {
                let a: Vec<f64> = (0..n_in).map(|_| r.gen_range(-1.0..1.0)).collect();
                let c = sample(&mut r);
                let rhs: f64 = a.iter().zip(&c).map(|(a, x)| a * x).sum();
                inputs.push(InputConstraint {
                    row: a.iter().copied().enumerate().collect(),
                    rhs,
                    eq: false,
                });
            }
            if variant == 2 {
                let z = pre_activations(&p, &sample(&mut r));
                for (ri, &k) in relus.iter().enumerate().take(2) {
                    for _ in 0..2 {
                        let i = r.gen_range(0..p.maps[k].0.out);
                        fixed[ri][i] = if z[k][i] >= 0.0 { 1 } else { -1 };
                    }
                }
            }
            let Some((blo, bhi)) = base_bounds(&p, &xl, &xh, &fixed) else {
                continue;
            };
            let (mut lo, mut hi) = (blo.clone(), bhi.clone());
            let st = lp_tighten(&p, &xl, &xh, &inputs, &fixed, &mut lo, &mut hi, true)
                .expect("a sampled point lies in the node: it is not empty");
            improved += st.improved;
            stabilised += st.stabilised;
            for k in 0..p.maps.len() {
                for i in 0..lo[k].len() {
                    assert!(
                        lo[k][i] >= blo[k][i] && hi[k][i] <= bhi[k][i],
                        "case {case}/{variant}: map {k} neuron {i} looser than DeepPoly"
                    );
                }
            }
            // The same with the LPs solved one after another: the same bounds.
            let (mut slo, mut shi) = (blo.clone(), bhi.clone());
            lp_tighten(&p, &xl, &xh, &inputs, &fixed, &mut slo, &mut shi, false).unwrap();
            assert_eq!((&slo, &shi), (&lo, &hi), "case {case}/{variant}");
            let mut kept = 0;
            for _ in 0..20_000 {
                let x = sample(&mut r);
                if inputs
                    .iter()
                    .any(|c| c.row.iter().map(|(j, a)| a * x[*j]).sum::<f64>() > c.rhs)
                {
                    continue;
                }
                let z = pre_activations(&p, &x);
                let in_node = relus.iter().enumerate().all(|(ri, &k)| {
                    (0..fixed[ri].len()).all(|i| match fixed[ri][i] {
                        1 => z[k][i] >= 0.0,
                        -1 => z[k][i] <= 0.0,
                        _ => true,
                    })
                });
                if !in_node {
                    continue;
                }
                kept += 1;
                for k in 0..p.maps.len() {
                    for i in 0..z[k].len() {
                        assert!(
                            lo[k][i] <= z[k][i] && z[k][i] <= hi[k][i],
                            "case {case}/{variant}: map {k} neuron {i}: {} not in [{}, {}]",
                            z[k][i],
                            lo[k][i],
                            hi[k][i]
                        );
                    }
                }
            }
            assert!(
                kept >= 100,
                "case {case}/{variant}: only {kept} samples kept"
            );
            checked += kept;
        }
    }
    // The test means something: the LPs did tighten, and made neurons stable.
    assert!(improved > 100, "only {improved} neurons improved");
    assert!(stabilised > 5, "only {stabilised} neurons stabilised");
    assert!(checked > 500_000, "{checked}");
}

/// A first-layer neuron is only tightened when input constraints exist, and an
/// inconsistent node (input constraint against the box) is reported empty.
#[test]
fn inconsistent_inputs_make_the_node_empty() {
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(9);
    let p = PwlNet::from_network(&net(&mut r, &[3, 6, 4, 1], false)).unwrap();
    let (xl, xh) = (vec![-1.0; 3], vec![1.0; 3]);
    let fixed: Vec<Vec<i8>> = vec![vec![0; 6], vec![0; 4]];
    let (mut lo, mut hi) = base_bounds(&p, &xl, &xh, &fixed).unwrap();
    // x0 + x1 + x2 <= -3.5 is impossible in [-1, 1]^3.
    let bad = InputConstraint {
        row: vec![(0, 1.0), (1, 1.0), (2, 1.0)],
        rhs: -3.5,
        eq: false,
    };
    assert!(lp_tighten(&p, &xl, &xh, &[bad], &fixed, &mut lo, &mut hi, true).is_none());
}

fn app(n: usize) -> Application {
    Application {
        network: "f".into(),
        n_inputs: n,
        n_outputs: 1,
        input_box: vec![(-1.0, 1.0); n],
    }
}

fn input_le(a: &[f64], t: f64) -> Constraint {
    Constraint {
        expr: LinExpr {
            terms: a
                .iter()
                .enumerate()
                .map(|(k, c)| (Var::Input { app: 0, index: k }, *c))
                .collect(),
            constant: -t,
        },
        cmp: Cmp::Le,
    }
}

/// Delayed root tightening, the root at once, and every node down to depth 3.
fn modes() -> [LpTighten; 3] {
    [LpTighten::Root, LpTighten::Depth(0), LpTighten::Depth(3)]
}

fn with(t: LpTighten) -> Settings {
    Settings {
        lp_tighten: t,
        ..Default::default()
    }
}

#[test]
fn critical_values_and_verdicts_do_not_change() {
    let mut r = rand_chacha::ChaCha8Rng::seed_from_u64(17);
    for case in 0..20 {
        let n = 3 + case % 2;
        let dims = [n, 8, 6, 1];
        let f = net(&mut r, &dims, case % 5 == 0);
        let mut nets = HashMap::new();
        nets.insert("f".to_string(), f.clone());
        let prep = Prepared::new(&nets);
        let a: Vec<f64> = (0..n).map(|_| r.gen_range(-1.0..1.0)).collect();
        let pre = vec![input_le(&a, r.gen_range(-0.5..0.5))];
        for sense in [Sense::Max, Sense::Min] {
            // Objective: the output, or the output plus an input (as P1-P4 mix them).
            let mut terms = vec![(Var::Output { app: 0, index: 0 }, 1.0)];
            if case % 3 == 0 {
                terms.push((Var::Input { app: 0, index: 0 }, 0.5));
            }
            let q = Query {
                name: format!("c{case}"),
                applications: vec![app(n)],
                free_vars: vec![],
                region: vec![pre.clone()],
                goal: Goal::Optimise {
                    objective: LinExpr {
                        terms,
                        constant: 0.0,
                    },
                    sense,
                    label: "y".into(),
                },
            };
            let off = optimise(&q, &prep, &Settings::default()).unwrap();
            assert!(off.complete, "case {case}: {:?}", off.unknown);
            for t in modes() {
                let on = optimise(&q, &prep, &with(t)).unwrap();
                assert!(on.complete, "case {case} {t:?}");
                let (a, b) = (off.value.unwrap(), on.value.unwrap());
                assert!(
                    (a - b).abs() <= 1e-6 && (off.bound - on.bound).abs() <= 1e-6,
                    "case {case} {t:?} {sense:?}: off {a} (bound {}), on {b} (bound {})",
                    off.bound,
                    on.bound
                );
                let w = on.witness.as_ref().unwrap();
                assert_eq!(f.eval_f64(&w.inputs[0])[0], w.outputs[0][0]);
            }
            // Prove "pre => y <= t" (for Max) around the critical value: same verdicts.
            if sense == Sense::Max && case % 3 != 0 {
                for t in [off.bound + 1e-6, off.value.unwrap() - 1e-3] {
                    let mut region = pre.clone();
                    region.push(Constraint {
                        expr: LinExpr {
                            terms: vec![(Var::Output { app: 0, index: 0 }, -1.0)],
                            constant: t,
                        },
                        cmp: Cmp::Lt,
                    });
                    let pq = Query {
                        name: format!("p{case}"),
                        applications: vec![app(n)],
                        free_vars: vec![],
                        region: vec![region],
                        goal: Goal::Prove,
                    };
                    let v0 = prove(&pq, &prep, &Settings::default()).unwrap();
                    for tm in modes() {
                        let v1 = prove(&pq, &prep, &with(tm)).unwrap();
                        match (&v0, &v1) {
                            (Verdict::Proved, Verdict::Proved) => {}
                            (Verdict::Violated(_), Verdict::Violated(c)) => {
                                assert!(f.eval_f64(&c.point.inputs[0])[0] > t)
                            }
                            _ => panic!("case {case} {tm:?} t {t}: {v0:?} vs {v1:?}; critical {:?} bound {}", off.value, off.bound),
                        }
                    }
                }
            }
        }
    }
}

/// The case study's P1-P4 critical values (as models/alsomitra/alsomitra.spec states
/// them) on the published networks, with tightening on and off (fails with a message
/// when `../shared/reference` is absent).
#[test]
fn case_study_critical_values_do_not_change() {
    for file in ["adversarial_model_norm.onnx", "base_model_denorm.onnx"] {
        let f = samara_nn::onnx::load(reference_files::reference(file)).unwrap();
        let mut nets = HashMap::new();
        nets.insert("f".to_string(), f);
        let prep = Prepared::new(&nets);
        for (q, t) in p1_to_p4(file.contains("denorm"))
            .into_iter()
            .flat_map(|q| [(q.clone(), LpTighten::Root), (q, LpTighten::Depth(0))])
        {
            let off = optimise(&q, &prep, &Settings::default()).unwrap();
            let on = optimise(&q, &prep, &with(t)).unwrap();
            // (`complete` also requires no thin leaves, which P4's boundary has.)
            assert_eq!(off.complete, on.complete, "{file} {} {t:?}", q.name);
            let (a, b) = (off.value.unwrap(), on.value.unwrap());
            assert!(
                (a - b).abs() <= 1e-6 && (off.bound - on.bound).abs() <= 1e-6,
                "{file} {} {t:?}: off {a} / {}, on {b} / {}",
                q.name,
                off.bound,
                on.bound
            );
        }
    }
}

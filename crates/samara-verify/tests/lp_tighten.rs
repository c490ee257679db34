//! LP-based bound tightening ([`samara_verify::tighten`]) is sound and changes no answer:
//! on random small ReLU (and clamp) networks the tightened pre-activation bounds contain
//! the pre-activations of thousands of sampled inputs (also under fixed phases and
//! input constraints), are never looser than the interval + DeepPoly bounds they start
//! from. (The tests that critical values and verdicts did not change with tightening
//! on went with the ReLU-phase search that applied it.)

use rand::{Rng, SeedableRng};
use samara_nn::{Activation, Layer, Network};
use samara_verify::net::PwlNet;
use samara_verify::tighten::{base_bounds, lp_tighten, InputConstraint};

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

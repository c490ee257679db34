//! Helpers shared by the integration test files of samara-bounds (`use crate::support;`).

use rand::Rng;
use rand_chacha::ChaCha8Rng;
use samara_bounds::search::{Case, OutputConstraint};
use samara_bounds::symbolic::Objective;
use samara_nn::{Activation, Affine, Layer, Network};

/// The ReLU chain of a network of affine and ReLU layers, as [`samara_bounds::search`]
/// reads it: each affine map with whether a ReLU follows it.
pub fn chain(net: &Network) -> Vec<(Affine, bool)> {
    let mut maps: Vec<(Affine, bool)> = Vec::new();
    for l in net.raw_layers() {
        match l {
            Layer::Affine(a) => maps.push((a, false)),
            Layer::Act(Activation::Relu) => maps.last_mut().unwrap().1 = true,
            other => panic!("unexpected {other:?}"),
        }
    }
    maps
}

/// The `k`-th sample of the box: every `every`-th is the lower corner, the one after it
/// the upper corner (bounds are tightest to break there), the others uniform.
pub fn sample(rng: &mut ChaCha8Rng, lo: &[f64], hi: &[f64], k: usize, every: usize) -> Vec<f64> {
    lo.iter()
        .zip(hi)
        .map(|(a, b)| match k % every {
            0 => *a,
            1 => *b,
            _ => rng.gen_range(*a..=*b),
        })
        .collect()
}

/// One case over `[lo, hi]` whose single constraint is `c . y - t <= 0`.
pub fn threshold_case(lo: &[f64], hi: &[f64], c: &[f64], t: f64) -> Vec<Case> {
    vec![Case {
        lo: lo.to_vec(),
        hi: hi.to_vec(),
        constraints: vec![OutputConstraint {
            obj: Objective {
                c: c.to_vec(),
                d: -t,
            },
            strict: false,
        }],
    }]
}

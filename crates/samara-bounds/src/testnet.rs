//! Random ReLU chains and their f64 pre-activations for the unit tests of the search
//! modules (`phases`, `relusplit`): one copy instead of one per test module.

use rand::Rng;
use samara_nn::Affine;

/// A random chain of affine maps with the given widths (weights in [-1, 1], biases in
/// [-0.5, 0.5]), every map but the last followed by a ReLU.
pub(crate) fn random_maps(
    rng: &mut rand_chacha::ChaCha8Rng,
    widths: &[usize],
) -> Vec<(Affine, bool)> {
    let last = widths.len() - 2;
    (0..widths.len() - 1)
        .map(|k| {
            let (inp, out) = (widths[k], widths[k + 1]);
            let w = (0..inp * out).map(|_| rng.gen_range(-1.0..1.0)).collect();
            let b = (0..out).map(|_| rng.gen_range(-0.5..0.5)).collect();
            (Affine::new(inp, out, w, b), k < last)
        })
        .collect()
}

/// Every map's output at `x` (before its ReLU), in f64.
pub(crate) fn pre_activations(maps: &[(Affine, bool)], x: &[f64]) -> Vec<Vec<f64>> {
    let mut z = x.to_vec();
    let mut out = Vec::new();
    for (m, r) in maps {
        let mut o = vec![0.0; m.out];
        m.apply_f64(&z, &mut o);
        out.push(o.clone());
        if *r {
            o.iter_mut().for_each(|v| *v = v.max(0.0));
        }
        z = o;
    }
    out
}

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

/// The vertices of the 2-input polygon `{x in [lo, hi] : f(x) >= 0 for each line (f,
/// true), f(x) <= 0 for each (f, false)}`, `f(x) = f[0] x0 + f[1] x1 + f[2]`: every
/// intersection of two of its lines or box sides that satisfies them all, within
/// `box_tol` of the box and `line_tol (1 + |f|_1)` of each line. The tests' independent
/// exact computation (a linear function's extremes over the polygon are at vertices).
pub(crate) fn region_vertices(
    lo: &[f64],
    hi: &[f64],
    lines: &[([f64; 3], bool)],
    box_tol: f64,
    line_tol: f64,
) -> Vec<[f64; 2]> {
    let inside = |x: [f64; 2]| {
        (0..2).all(|k| x[k] >= lo[k] - box_tol && x[k] <= hi[k] + box_tol)
            && lines.iter().all(|(f, on)| {
                let v = f[0] * x[0] + f[1] * x[1] + f[2];
                let s = line_tol * (1.0 + f[0].abs() + f[1].abs() + f[2].abs());
                if *on {
                    v >= -s
                } else {
                    v <= s
                }
            })
    };
    let mut all: Vec<[f64; 3]> = vec![
        [1.0, 0.0, -lo[0]],
        [1.0, 0.0, -hi[0]],
        [0.0, 1.0, -lo[1]],
        [0.0, 1.0, -hi[1]],
    ];
    all.extend(lines.iter().map(|l| l.0));
    let mut verts = Vec::new();
    for p in 0..all.len() {
        for q in p + 1..all.len() {
            let (a, b) = (all[p], all[q]);
            let det = a[0] * b[1] - a[1] * b[0];
            if det.abs() < 1e-12 {
                continue;
            }
            let x = [
                (-a[2] * b[1] + b[2] * a[1]) / det,
                (-a[0] * b[2] + b[0] * a[2]) / det,
            ];
            if inside(x) {
                verts.push(x);
            }
        }
    }
    verts
}

/// The affine map `m` applied to functions of a 2-input `x`, each `(a0, a1, b)` for
/// `a0 x0 + a1 x1 + b`: the pre-activations of `m` as such functions, given its inputs'.
/// The tests' exact references follow a network along one activation pattern with it.
pub(crate) fn affine_of_2d(m: &Affine, cur: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let mut z = vec![[0.0; 3]; m.out];
    for (i, zi) in z.iter_mut().enumerate() {
        zi[2] = m.b[i];
        for (k, ck) in cur.iter().enumerate() {
            let w = m.weight(i, k);
            for e in 0..3 {
                zi[e] += w * ck[e];
            }
        }
    }
    z
}

//! CROWN's pull-back of one neuron (Zhang et al., NeurIPS 2018) that visits only the
//! neurons its coefficients reach: [`super::backward_core`]'s operations for a unit
//! objective `+-z_i`, in its order, over the non-zero coefficients of each layer
//! (ascending) instead of every neuron of it.
//!
//! On a network whose maps are sparse (stored as [`samara_nn::ir::Row::Sparse`] rows)
//! a neuron depends on few neurons of each earlier layer: in the two-level lattice
//! networks of `tllverifybench` (Ferlez et al.) a min or max unit reads two neurons of
//! the layer below, so a pull-back from the first min layer touches four of the
//! thousands of neurons in the layers below it. The dense pull-back clears and scans
//! every layer's full width per neuron, which made CROWN's intermediate bounds the
//! whole cost of a piece there.
//!
//! Same bounds as [`super::backward_core`] with CROWN's slopes, given row magnitudes
//! and no split multipliers: the coefficients that are skipped are exactly 0 (the dense
//! loop skips them too, or adds `+-0` products, which change no sum started at `+0`),
//! and every sum runs over the same terms in the same order, so each rounding bound is
//! the one proved there.

use super::{gamma, inflate, relu, Linear};
use samara_nn::Affine;

/// Reusable buffers of [`pull_unit`]: a dense vector per width with the positions
/// written, cleared after use.
#[derive(Default)]
pub(super) struct Scratch {
    nu: Vec<f64>,
    mark: Vec<bool>,
    touched: Vec<usize>,
    mu: Vec<f64>,
    idx: Vec<usize>,
}

/// The lower linear bound over the box of `sign * z_i`, `z_i` output `i` of the last map
/// of `maps`, pulled back through `maps` with CROWN's relaxation of the ReLUs from the
/// bounds `pre` (`slopes[j][t]` the chord slope of unstable neuron `t` of `pre[j]`) and
/// the rounding bound from the row magnitudes `rowmag` ([`super::row_magnitude`]).
pub(super) fn pull_unit(
    maps: &[(Affine, bool)],
    pre: &[Vec<(f64, f64)>],
    i: usize,
    sign: f64,
    rowmag: &[Vec<f64>],
    slopes: &[Vec<f64>],
    s: &mut Scratch,
) -> Linear {
    // mu: the current coefficients, non-zero only at `idx` (ascending).
    s.mu.clear();
    s.idx.clear();
    s.mu.push(sign);
    s.idx.push(i);
    let mut cst: f64 = 0.0;
    let mut err: f64 = 0.0;
    let n_in = maps[0].0.inp;
    for j in (0..maps.len()).rev() {
        let m = &maps[j].0;
        let k = m.out + 1;
        if s.nu.len() < m.inp {
            s.nu.resize(m.inp, 0.0);
            s.mark.resize(m.inp, false);
        }
        s.touched.clear();
        let mut cmag = cst.abs();
        let mut wmag = 0.0;
        for (&t, &mi) in s.idx.iter().zip(&s.mu) {
            if mi == 0.0 {
                continue;
            }
            let p = mi * m.b[t];
            cst += p;
            cmag += p.abs();
            wmag += mi.abs() * rowmag[j][t];
            let (nu, mark, touched) = (&mut s.nu, &mut s.mark, &mut s.touched);
            m.row(t).for_each_nonzero(|c, w| {
                nu[c] += mi * w;
                if !mark[c] {
                    mark[c] = true;
                    touched.push(c);
                }
            });
        }
        err += gamma(k) * (cmag + wmag);
        s.touched.sort_unstable();
        s.mu.clear();
        s.idx.clear();
        let relu_below = j > 0 && maps[j - 1].1;
        for &t in &s.touched {
            let v = s.nu[t];
            s.nu[t] = 0.0;
            s.mark[t] = false;
            if !relu_below {
                s.idx.push(t);
                s.mu.push(v);
                continue;
            }
            // `super::relax_relu` for one neuron, without alpha.
            let (l, u) = pre[j - 1][t];
            if v == 0.0 || u <= 0.0 {
                continue;
            }
            let z = if l >= 0.0 {
                v
            } else if v < 0.0 {
                let sl = slopes[j - 1][t];
                let z = v * sl;
                let c = -(v * sl) * l;
                cst += c;
                err += 2.0 * f64::EPSILON * (z.abs() * l.abs().max(u.abs()) + c.abs())
                    + f64::EPSILON * cst.abs();
                z
            } else if relu::default_lower_slope(l, u) == 1.0 {
                v
            } else {
                continue;
            };
            s.idx.push(t);
            s.mu.push(z);
        }
    }
    let mut coef = vec![0.0; n_in];
    for (&t, &v) in s.idx.iter().zip(&s.mu) {
        coef[t] = v;
    }
    Linear {
        coef,
        cst,
        slack: inflate(err),
    }
}

#[cfg(test)]
pub(super) mod tests {
    use super::super::{
        backward_core, crown_pre_until, hidden_pre, input_magnitudes, row_magnitude, Mags,
    };
    use super::*;
    use crate::testnet::pre_activations;
    use rand::{Rng, SeedableRng};

    /// A random chain shaped like a lowered two-level lattice network (Ferlez et al.):
    /// 2 inputs, a dense first map, then maps whose every output reads two outputs of
    /// the layer below, a ReLU after every second map, widths halving; stored sparse.
    pub(crate) fn lattice_like(
        rng: &mut rand_chacha::ChaCha8Rng,
        w0: usize,
    ) -> Vec<(Affine, bool)> {
        let mut maps = Vec::new();
        let w = (0..2 * w0).map(|_| rng.gen_range(-1.0..1.0)).collect();
        let b = (0..w0).map(|_| rng.gen_range(-0.5..0.5)).collect();
        maps.push((Affine::new(2, w0, w, b), true));
        let mut width = w0;
        let mut relu = false;
        while width > 1 {
            let out = if relu { width } else { width / 2 };
            let rows = (0..out)
                .map(|_| {
                    let a = rng.gen_range(0..width);
                    let c = (a + 1 + rng.gen_range(0..width - 1)) % width;
                    let (a, c) = (a.min(c), a.max(c));
                    vec![(a, rng.gen_range(-1.5..1.5)), (c, rng.gen_range(-1.5..1.5))]
                })
                .collect();
            let b = (0..out).map(|_| rng.gen_range(-0.2..0.2)).collect();
            maps.push((Affine::from_rows(width, rows, b), relu));
            width = out;
            relu = !relu;
        }
        if maps.last().is_some_and(|m| m.1) {
            let n = maps.last().map(|m| m.0.out).unwrap_or(1);
            maps.push((Affine::from_rows(n, vec![vec![(0, 1.0)]], vec![0.0]), false));
        }
        maps
    }

    #[test]
    fn pull_unit_is_backward_core_bit_for_bit() {
        // The reference: `backward_core` with a dense unit objective, CROWN's slopes and
        // the row magnitudes, layer by layer as CROWN's intermediate bounds run.
        let mut compared = 0;
        for seed in 0..24u64 {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
            let mut maps = lattice_like(&mut rng, [8, 16, 64][seed as usize % 3]);
            if seed % 4 == 3 {
                // Dense storage of the same maps (the first map is dense already).
                maps = maps.iter().map(|(m, r)| (m.densified(), *r)).collect();
            }
            let width = [0.05, 0.5, 2.0][(seed / 3) as usize % 3];
            let lo: Vec<f64> = (0..2).map(|_| rng.gen_range(-1.0..1.0)).collect();
            let hi: Vec<f64> = lo.iter().map(|v| v + width).collect();
            let fwd = hidden_pre(&maps, &lo, &hi, None);
            let mut pre: Vec<Vec<(f64, f64)>> = Vec::new();
            let mut rowmag: Vec<Vec<f64>> = Vec::new();
            let mut slopes: Vec<Vec<f64>> = Vec::new();
            let mut s = Scratch::default();
            for k in 0..maps.len() - 1 {
                let sub = &maps[..=k];
                let inmax = input_magnitudes(sub, &pre, &lo, &hi, k + 1);
                for (j, im) in inmax.iter().enumerate().skip(rowmag.len()) {
                    rowmag.push(row_magnitude(&maps[j].0, None, im));
                }
                let mut layer = Vec::new();
                for i in 0..maps[k].0.out {
                    let (fl, fu) = fwd[k][i];
                    if fl >= 0.0 || fu <= 0.0 {
                        layer.push((fl, fu));
                        continue;
                    }
                    let mut c = vec![0.0; maps[k].0.out];
                    let rm = Mags::Rows(&rowmag);
                    let mut fs = Vec::new();
                    for sign in [1.0, -1.0] {
                        c[i] = sign;
                        let want =
                            backward_core(sub, &pre, &c, 0.0, None, None, rm, None, Some(&slopes));
                        let got = pull_unit(sub, &pre, i, sign, &rowmag, &slopes, &mut s);
                        let same = want.coef.len() == got.coef.len()
                            && want
                                .coef
                                .iter()
                                .zip(&got.coef)
                                .all(|(a, b)| a.to_bits() == b.to_bits())
                            && want.cst.to_bits() == got.cst.to_bits()
                            && want.slack.to_bits() == got.slack.to_bits();
                        assert!(same, "seed {seed} layer {k} neuron {i}: {want:?} {got:?}");
                        compared += 1;
                        fs.push(got);
                    }
                    let (l, u) = (fs[0].min_over(&lo, &hi), -fs[1].min_over(&lo, &hi));
                    layer.push((l.max(fl), u.min(fu)));
                }
                slopes.push(
                    layer
                        .iter()
                        .map(|&(l, u)| match l < 0.0 && u > 0.0 {
                            true => relu::chord_slope_up(l, u),
                            false => 0.0,
                        })
                        .collect(),
                );
                pre.push(layer);
            }
        }
        assert!(compared > 500, "only {compared} pull-backs compared");
    }

    #[test]
    fn crown_bounds_of_sparse_chains_hold_at_sampled_points() {
        // CROWN's intermediate bounds over sparse maps (through `pull_unit`) against
        // the f64 evaluation of 10,000 points of the box, on lattice-like chains and on
        // the same maps stored dense (the batched pull-backs): both hold every value.
        for seed in 0..6u64 {
            let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(100 + seed);
            let sparse = lattice_like(&mut rng, [16, 64][seed as usize % 2]);
            let dense: Vec<(Affine, bool)> =
                sparse.iter().map(|(m, r)| (m.densified(), *r)).collect();
            let width = [0.1, 1.0, 3.0][(seed / 2) as usize % 3];
            let lo: Vec<f64> = (0..2).map(|_| rng.gen_range(-1.0..1.0)).collect();
            let hi: Vec<f64> = lo.iter().map(|v| v + width).collect();
            let bounds: Vec<Vec<Vec<(f64, f64)>>> = [&sparse, &dense]
                .iter()
                .map(|maps| {
                    let fwd = hidden_pre(maps, &lo, &hi, None);
                    crown_pre_until(maps, &lo, &hi, &fwd, None)
                })
                .collect();
            for _ in 0..10_000 {
                let x: Vec<f64> = lo
                    .iter()
                    .zip(&hi)
                    .map(|(a, b)| rng.gen_range(*a..=*b))
                    .collect();
                let z = pre_activations(&sparse, &x);
                for b in &bounds {
                    for (k, (zk, bk)) in z.iter().zip(b).enumerate() {
                        for (i, (v, (l, u))) in zk.iter().zip(bk).enumerate() {
                            let tol = 1e-12 * (1.0 + v.abs());
                            assert!(
                                *l <= v + tol && v - tol <= *u,
                                "seed {seed} layer {k} neuron {i}: {v} outside [{l}, {u}]"
                            );
                        }
                    }
                }
            }
        }
    }
}

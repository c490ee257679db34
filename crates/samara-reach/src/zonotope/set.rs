//! Zonotopes `c + G xi`, `xi in [-1, 1]^k`, with the first `n_param` generators tied to
//! the initial-set parameters (never reduced, so a sub-box of the initial set keeps its
//! exact dependence), the others "noise" from remainders (reduced by Girard's method,
//! HSCC 2005). Sums of magnitudes are rounded up so that boxes enclose soundly.

// Numeric kernels index several arrays by one index; the explicit forms mirror the formulas.
#![allow(clippy::assign_op_pattern, clippy::needless_range_loop)]

use samara_num::Interval;

/// Relative widening of a sum of `k` rounded terms (samara-num's one definition).
pub(crate) use samara_num::round::gamma;

/// `sum |v_i|`, rounded up.
pub(crate) fn abs_sum_up(v: impl Iterator<Item = f64>) -> f64 {
    let mut s = 0.0;
    let mut k = 0;
    for x in v {
        s += x.abs();
        k += 1;
    }
    (s * (1.0 + gamma(k))).next_up()
}

/// A zonotope in `dim` dimensions.
#[derive(Clone, Debug, PartialEq)]
pub struct Zonotope {
    /// Centre.
    pub c: Vec<f64>,
    /// Generators (each of length `dim`); the first `n_param` are the parameters.
    pub gens: Vec<Vec<f64>>,
    /// Number of parameter generators.
    pub n_param: usize,
}

impl Zonotope {
    /// Dimension.
    pub fn dim(&self) -> usize {
        self.c.len()
    }

    /// Radius per row, `sum_k |g_k|`, rounded up.
    pub fn radius(&self) -> Vec<f64> {
        (0..self.dim())
            .map(|i| abs_sum_up(self.gens.iter().map(|g| g[i])))
            .collect()
    }

    /// Radius per row of the noise generators only.
    pub fn noise_radius(&self) -> Vec<f64> {
        (0..self.dim())
            .map(|i| abs_sum_up(self.gens[self.n_param..].iter().map(|g| g[i])))
            .collect()
    }

    /// The interval hull (outward rounded).
    pub fn bbox(&self) -> Vec<Interval> {
        let r = self.radius();
        self.c
            .iter()
            .zip(r)
            .map(|(c, r)| Interval {
                lo: (c - r).next_down(),
                hi: (c + r).next_up(),
            })
            .collect()
    }

    /// Enclosure of the linear functional `a . x` over the zonotope.
    pub fn range_of(&self, a: &[f64]) -> Interval {
        let dot = |v: &[f64]| -> (f64, f64) {
            let s: f64 = v.iter().zip(a).map(|(x, y)| x * y).sum();
            let m = abs_sum_up(v.iter().zip(a).map(|(x, y)| x * y));
            (s, m * gamma(a.len()))
        };
        let (c, ec) = dot(&self.c);
        let mut r = ec;
        for g in &self.gens {
            let (s, e) = dot(g);
            r += s.abs() + e;
        }
        let r = (r * (1.0 + gamma(self.gens.len()))).next_up();
        Interval {
            lo: (c - r).next_down(),
            hi: (c + r).next_up(),
        }
    }

    /// Enclosure of `x + y` (rows 4 and 5).
    pub fn x_plus_y(&self) -> Interval {
        let mut a = vec![0.0; self.dim()];
        a[4] = 1.0;
        a[5] = 1.0;
        self.range_of(&a)
    }

    /// Add a box `[-r_i, r_i]` (one axis-aligned generator per nonzero row).
    pub fn add_box(&mut self, r: &[f64]) {
        for (i, &ri) in r.iter().enumerate() {
            if ri > 0.0 {
                let mut g = vec![0.0; self.dim()];
                g[i] = ri;
                self.gens.push(g);
            }
        }
    }

    /// Keep at most `max_noise` noise generators: the ones with the smallest
    /// `||g||_1 - ||g||_inf` are replaced by their box (Girard 2005).
    pub fn reduce(&mut self, max_noise: usize) {
        let np = self.n_param;
        let noise = self.gens.len() - np;
        if noise <= max_noise {
            return;
        }
        let d = self.dim();
        // Keep max_noise - d of the worst-to-box, box the rest into d generators.
        let keep = max_noise.saturating_sub(d);
        let key = |g: &Vec<f64>| {
            let l1: f64 = g.iter().map(|x| x.abs()).sum();
            let li = g.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            l1 - li
        };
        // Each key computed once (not twice per comparison); the same stable sort on
        // the same keys, so the same order.
        let keys: Vec<f64> = self.gens.iter().map(key).collect();
        let mut idx: Vec<usize> = (np..self.gens.len()).collect();
        idx.sort_by(|&a, &b| keys[b].total_cmp(&keys[a]));
        let (kept, boxed) = idx.split_at(keep.min(idx.len()));
        let mut r = vec![0.0; d];
        for (i, ri) in r.iter_mut().enumerate() {
            *ri = abs_sum_up(boxed.iter().map(|&k| self.gens[k][i]));
        }
        // The generators are moved, not copied, into their new order; the boxed ones'
        // storage holds the new box generators.
        let mut old = std::mem::take(&mut self.gens);
        let mut gens: Vec<Vec<f64>> = Vec::with_capacity(np + kept.len() + d);
        gens.extend(old[..np].iter_mut().map(std::mem::take));
        gens.extend(kept.iter().map(|&k| std::mem::take(&mut old[k])));
        let mut spare = boxed.iter().map(|&k| std::mem::take(&mut old[k]));
        for (i, &ri) in r.iter().enumerate() {
            if ri > 0.0 {
                let mut g = spare.next().unwrap_or_default();
                g.clear();
                g.resize(d, 0.0);
                g[i] = ri;
                gens.push(g);
            }
        }
        self.gens = gens;
    }

    /// Split along parameter generator `j`: `xi_j in [-1, 0]` and `[0, 1]`, exactly.
    pub fn split(&self, j: usize) -> (Zonotope, Zonotope) {
        let mut a = self.clone();
        let mut b = self.clone();
        let g = &self.gens[j];
        for i in 0..self.dim() {
            let h = 0.5 * g[i];
            a.c[i] -= h;
            b.c[i] += h;
            a.gens[j][i] = h;
            b.gens[j][i] = h;
        }
        // c +- g/2 and g/2 are rounded: cover the error with a small box.
        let e: Vec<f64> = (0..self.dim())
            .map(|i| ((self.c[i].abs() + g[i].abs()) * f64::EPSILON).next_up())
            .collect();
        a.add_box(&e);
        b.add_box(&e);
        (a, b)
    }

    /// Whether `x` lies in the zonotope given the parameter coordinates `xi_p` of the
    /// first `n_param` generators (noise generators as a box), with tolerance `tol`.
    pub fn contains_with_params(&self, x: &[f64], xi_p: &[f64], tol: f64) -> bool {
        let nr = self.noise_radius();
        (0..self.dim()).all(|i| {
            let mut v = self.c[i];
            for (j, xj) in xi_p.iter().enumerate() {
                v += self.gens[j][i] * xj;
            }
            (x[i] - v).abs() <= nr[i] + tol
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reduce_and_split_enclose() {
        let z = Zonotope {
            c: vec![1.0, -2.0, 0.5],
            gens: vec![
                vec![0.3, 0.1, 0.0],
                vec![0.01, -0.02, 0.03],
                vec![0.0, 0.04, -0.01],
                vec![0.02, 0.0, 0.02],
                vec![-0.01, 0.01, 0.01],
            ],
            n_param: 1,
        };
        let mut r = z.clone();
        r.reduce(3);
        assert!(r.gens.len() <= 4);
        let (a, b) = z.split(0);
        // Points of z lie in r, and in a or b.
        for s in 0..200 {
            let xi: Vec<f64> = (0..5)
                .map(|k| (((s * 7 + k * 13) % 21) as f64 / 10.0) - 1.0)
                .collect();
            let x: Vec<f64> = (0..3)
                .map(|i| z.c[i] + (0..5).map(|k| z.gens[k][i] * xi[k]).sum::<f64>())
                .collect();
            let bb = r.bbox();
            assert!((0..3).all(|i| bb[i].contains(x[i])));
            let half = if xi[0] <= 0.0 { &a } else { &b };
            let bh = half.bbox();
            assert!((0..3).all(|i| bh[i].contains(x[i])));
            let xs = if xi[0] <= 0.0 {
                2.0 * xi[0] + 1.0
            } else {
                2.0 * xi[0] - 1.0
            };
            assert!(half.contains_with_params(&x, &[xs], 1e-12));
        }
    }
}

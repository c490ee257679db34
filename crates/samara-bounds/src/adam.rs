//! Adam (Kingma & Ba, ICLR 2015): projected ascent steps with per-parameter moment
//! estimates, the optimiser of alpha-CROWN's slopes and beta-CROWN's multipliers (Xu et
//! al., ICLR 2021; Wang et al., NeurIPS 2021). It only steers the choice of slopes and
//! multipliers; every bound is computed rigorously afterwards from the values chosen.

/// Adam's moment estimates for one set of parameters.
pub(crate) struct Adam {
    m: Vec<Vec<f64>>,
    v: Vec<Vec<f64>>,
}

impl Adam {
    pub(crate) fn new(like: &[Vec<f64>]) -> Self {
        let z: Vec<Vec<f64>> = like.iter().map(|a| vec![0.0; a.len()]).collect();
        Adam { m: z.clone(), v: z }
    }

    /// One ascent step of size `lr[j]` on entry `(j, t)` where `keep(j, t)`, then `proj`.
    pub(crate) fn step(
        &mut self,
        x: &mut [Vec<f64>],
        g: &[Vec<f64>],
        it: usize,
        lr: &[f64],
        keep: impl Fn(usize, usize) -> bool,
        proj: impl Fn(usize, usize, f64) -> f64,
    ) {
        let (b1, b2) = (0.9f64, 0.999f64);
        let c1 = 1.0 - b1.powi(it as i32 + 1);
        let c2 = 1.0 - b2.powi(it as i32 + 1);
        for j in 0..x.len() {
            for t in 0..x[j].len() {
                if !keep(j, t) {
                    continue;
                }
                let gi = g[j][t];
                let m = &mut self.m[j][t];
                let v = &mut self.v[j][t];
                *m = b1 * *m + (1.0 - b1) * gi;
                *v = b2 * *v + (1.0 - b2) * gi * gi;
                let d = lr[j] * (*m / c1) / ((*v / c2).sqrt() + 1e-12);
                x[j][t] = proj(j, t, x[j][t] + d);
            }
        }
    }
}

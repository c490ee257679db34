//! Classical fixed-step Runge-Kutta of order 4 (Kutta 1901), over any [`Scalar`]: `f64`
//! for simulation, dual numbers for training's differentiable flights. The step is
//! shrunk so an integer number of steps lands exactly on the end time.

use samara_num::Scalar;

/// RK4 with its stage buffers, kept between calls so that a loop over many periods
/// allocates once.
#[derive(Clone, Debug)]
pub struct Rk4<S> {
    k1: Vec<S>,
    k2: Vec<S>,
    k3: Vec<S>,
    k4: Vec<S>,
    tmp: Vec<S>,
}

impl<S: Scalar> Rk4<S> {
    /// Buffers for `n` states.
    pub fn new(n: usize) -> Self {
        let z = vec![S::cst(0.0); n];
        Rk4 {
            k1: z.clone(),
            k2: z.clone(),
            k3: z.clone(),
            k4: z.clone(),
            tmp: z,
        }
    }

    /// Integrate `y' = f(y)` from `t0` to `tf` with about `h`-sized steps (exactly
    /// `ceil((tf - t0) / h)` equal steps). Returns the number of steps.
    pub fn integrate<F>(&mut self, mut f: F, y: &mut [S], t0: f64, tf: f64, h: f64) -> usize
    where
        F: FnMut(&[S], &mut [S]),
    {
        let n = y.len();
        if self.tmp.len() != n {
            *self = Rk4::new(n);
        }
        let steps = ((tf - t0) / h).abs().ceil().max(1.0) as usize;
        let h = (tf - t0) / steps as f64;
        let Rk4 {
            k1,
            k2,
            k3,
            k4,
            tmp,
        } = self;
        for _ in 0..steps {
            f(y, k1);
            for i in 0..n {
                tmp[i] = y[i].clone() + k1[i].clone() * (0.5 * h);
            }
            f(tmp, k2);
            for i in 0..n {
                tmp[i] = y[i].clone() + k2[i].clone() * (0.5 * h);
            }
            f(tmp, k3);
            for i in 0..n {
                tmp[i] = y[i].clone() + k3[i].clone() * h;
            }
            f(tmp, k4);
            for i in 0..n {
                let incr =
                    (k1[i].clone() + k2[i].clone() * 2.0 + k3[i].clone() * 2.0 + k4[i].clone())
                        * (h / 6.0);
                y[i] += incr;
            }
        }
        steps
    }
}

/// [`Rk4::integrate`] on `f64` with fresh buffers.
pub fn integrate<F>(f: F, y: &mut [f64], t0: f64, tf: f64, h: f64) -> usize
where
    F: FnMut(&[f64], &mut [f64]),
{
    Rk4::new(y.len()).integrate(f, y, t0, tf, h)
}

#[cfg(test)]
mod tests {
    #[test]
    fn fourth_order_convergence() {
        let run = |h: f64| {
            let mut y = [1.0];
            super::integrate(|y, d| d[0] = -y[0], &mut y, 0.0, 1.0, h);
            (y[0] - (-1.0f64).exp()).abs()
        };
        let (e1, e2) = (run(0.1), run(0.05));
        let order = (e1 / e2).log2();
        assert!((order - 4.0).abs() < 0.2, "observed order {order}");
    }

    /// One RK4 over any `Scalar`: on dual numbers its value part is the `f64` run bit
    /// for bit (the same operations in the same order), and its derivative with respect
    /// to the initial state matches the exact flow's, `d/dy0 (y0 e^{-t}) = e^{-t}`, to the
    /// method's error.
    #[test]
    fn dual_runs_carry_the_f64_values_and_the_flows_derivative() {
        use super::Rk4;
        use samara_num::{Dual, Scalar};
        fn f<S: Scalar>(y: &[S], d: &mut [S]) {
            d[0] = -y[0].clone();
            d[1] = y[0].clone() * y[1].sin();
        }
        let mut f64_run = [0.7, -0.3];
        super::integrate(f::<f64>, &mut f64_run, 0.0, 1.3, 0.01);
        let mut y = [Dual::<1>::var(0.7, 0), Dual::<1>::constant(-0.3)];
        Rk4::new(2).integrate(f::<Dual<1>>, &mut y, 0.0, 1.3, 0.01);
        assert_eq!(y[0].v.to_bits(), f64_run[0].to_bits());
        assert_eq!(y[1].v.to_bits(), f64_run[1].to_bits());
        assert!((y[0].d[0] - (-1.3f64).exp()).abs() < 1e-9, "{:?}", y[0].d);
    }
}

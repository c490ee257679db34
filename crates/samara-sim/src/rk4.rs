//! Classical fixed-step Runge-Kutta of order 4 (Kutta 1901). The step is shrunk so an
//! integer number of steps lands exactly on the end time.

/// Integrate `y' = f(y)` from `t0` to `tf` with about `h`-sized steps (exactly
/// `ceil((tf - t0) / h)` equal steps). Returns the number of steps.
pub fn integrate<F>(mut f: F, y: &mut [f64], t0: f64, tf: f64, h: f64) -> usize
where
    F: FnMut(&[f64], &mut [f64]),
{
    let n = y.len();
    let steps = ((tf - t0) / h).abs().ceil().max(1.0) as usize;
    let h = (tf - t0) / steps as f64;
    let mut k1 = vec![0.0; n];
    let mut k2 = vec![0.0; n];
    let mut k3 = vec![0.0; n];
    let mut k4 = vec![0.0; n];
    let mut tmp = vec![0.0; n];
    for _ in 0..steps {
        f(y, &mut k1);
        for i in 0..n {
            tmp[i] = y[i] + 0.5 * h * k1[i];
        }
        f(&tmp, &mut k2);
        for i in 0..n {
            tmp[i] = y[i] + 0.5 * h * k2[i];
        }
        f(&tmp, &mut k3);
        for i in 0..n {
            tmp[i] = y[i] + h * k3[i];
        }
        f(&tmp, &mut k4);
        for i in 0..n {
            y[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
    }
    steps
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
}

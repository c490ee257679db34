//! The backward (CROWN) bound's floating-point slack covers the rounding of its constant
//! when that constant is large: a running constant of 1e16 absorbs small bias terms with
//! round-to-nearest errors of up to one ulp (2.0 at 1e16) per addition, which the bound
//! must count. Checked against exact integer arithmetic (every number here is a multiple
//! of 0.5 below 2^62, so i128 in units of 0.5 is exact).

use samara_bounds::symbolic::{backward_lower, Objective};
use samara_nn::Affine;

#[test]
fn a_large_objective_constant_does_not_swallow_the_rounding_of_the_biases() {
    for (n, bias, d) in [
        (8usize, 1.5f64, 1e16f64),
        (16, 1.5, 1e16),
        (33, 0.5, 9.007199254740993e15),
        (5, 1.5, -1e16),
        (64, 3.5, 2.5e16),
    ] {
        // One map, no ReLU: f(x) = b for every output; x ranges over [0, 0].
        let m = Affine::new(1, n, vec![0.0; n], vec![bias; n]);
        let maps = vec![(m, false)];
        let obj = Objective { c: vec![1.0; n], d };
        let lin = backward_lower(&maps, &[], &obj, &[0.0], &[0.0]);
        let lb = lin.min_over(&[0.0], &[0.0]);
        // Exact value of c . f(x) + d, in units of 0.5.
        let exact = (d * 2.0) as i128 + (n as i128) * ((bias * 2.0) as i128);
        let lb2 = (lb * 2.0).floor() as i128;
        assert!(
            lb2 <= exact,
            "n = {n}, bias = {bias}, d = {d}: lower bound {lb} above the exact {}",
            exact as f64 / 2.0
        );
    }
}

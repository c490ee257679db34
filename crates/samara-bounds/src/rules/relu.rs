//! ReLU, `a = max(z, 0)` over a pre-activation range `[l, u]`.
//!
//! - Interval rule: `[max(l, 0), max(u, 0)]` (exact in f64).
//! - Stable neurons (`l >= 0`: identity; `u <= 0`: zero) are passed exactly; the rules
//!   below are for an unstable one, `l < 0 < u`.
//! - Upper line: the chord of the triangle relaxation (Ehlers, ATVA 2017),
//!   `a <= s (z - l)` with `s = u / (u - l)`; sound for every `s >= u / (u - l)` since
//!   `z - l >= 0` on the range, so a bound takes [`chord_slope_up`], rounded up.
//! - Lower lines: `a >= alpha z` for any `alpha in [0, 1]` ([`alpha_range`]);
//!   CROWN's default (Zhang et al., NeurIPS 2018) is the one losing less area,
//!   1 if `u > -l` else 0 ([`default_lower_slope`]); alpha-CROWN optimises it.
//! - The chord's largest distance above the function, at `z = 0`: `u (-l) / (u - l)`
//!   ([`gap`], BaBSR's intercept score, Bunel et al., JMLR 2020).

use samara_num::round::{down, up};

/// The interval rule: `relu([l, u])`.
#[inline]
pub fn interval(l: f64, u: f64) -> (f64, f64) {
    (l.max(0.0), u.max(0.0))
}

/// Whether a neuron with pre-activation range `[l, u]` is unstable (`l < 0 < u`).
#[inline]
pub fn unstable(l: f64, u: f64) -> bool {
    l < 0.0 && u > 0.0
}

/// The chord's slope `u / (u - l)` in f64, for values that only steer a search (slope
/// choices, scores), never a bound.
#[inline]
pub fn chord_slope(l: f64, u: f64) -> f64 {
    u / (u - l)
}

/// A slope `s >= u / (u - l)` in exact arithmetic (the difference rounded down, the
/// quotient up), so that `s (z - l)` bounds `relu(z)` from above on `[l, u]`.
#[inline]
pub fn chord_slope_up(l: f64, u: f64) -> f64 {
    up(u / down(u - l))
}

/// The chord's value `u (z - l) / (u - l)` at `z` in f64 (to score a split, never a bound).
#[inline]
pub fn chord_at(l: f64, u: f64, z: f64) -> f64 {
    u * (z - l) / (u - l)
}

/// CROWN's default lower slope: 1 (`a >= z`) if `u > -l`, else 0 (`a >= 0`).
#[inline]
pub fn default_lower_slope(l: f64, u: f64) -> f64 {
    if u > -l {
        1.0
    } else {
        0.0
    }
}

/// The sound range of an optimisable lower slope: `alpha` projected onto `[0, 1]`.
#[inline]
pub fn alpha_range(alpha: f64) -> f64 {
    alpha.clamp(0.0, 1.0)
}

/// The chord's largest gap above `relu` on `[l, u]`, `u (-l) / (u - l)` (at `z = 0`), in f64.
#[inline]
pub fn gap(l: f64, u: f64) -> f64 {
    u * (-l) / (u - l)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The chord with the rounded-up slope is above `relu` at the ends and at the kink
    /// of many random ranges (checked in exact rational arithmetic by hand: at `z = l`
    /// it is 0, at `z = u` it is `s (u - l) >= u` and at 0 it is `-s l >= gap`), and the
    /// lower lines of every slope in the range stay below.
    #[test]
    fn chord_and_lower_lines_enclose_relu() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let mut next = || rng.gen::<f64>();
        for _ in 0..20_000 {
            let scale = [1e-6, 1.0, 1e3][(next() * 3.0) as usize % 3];
            let (l, u) = (-scale * (next() + 1e-9), scale * (next() + 1e-9));
            assert!(unstable(l, u));
            let s = chord_slope_up(l, u);
            assert!(s >= chord_slope(l, u));
            // s (u - l) >= u: compare with the exactly-rounded product bounds.
            assert!(s * (u - l) >= u * (1.0 - 4.0 * f64::EPSILON));
            assert!(-s * l >= gap(l, u) * (1.0 - 4.0 * f64::EPSILON));
            for z in [l, 0.5 * l, 0.0, 0.5 * u, u] {
                for a in [0.0, 0.3, 1.0, default_lower_slope(l, u)] {
                    assert!(alpha_range(a) * z <= z.max(0.0));
                }
            }
        }
        assert_eq!(interval(-1.0, 2.0), (0.0, 2.0));
        assert_eq!(default_lower_slope(-1.0, 2.0), 1.0);
        assert_eq!(default_lower_slope(-2.0, 1.0), 0.0);
        assert_eq!(alpha_range(1.5), 1.0);
        assert_eq!(gap(-1.0, 3.0), 0.75);
    }
}

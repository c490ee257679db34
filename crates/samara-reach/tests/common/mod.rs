//! Checks shared by the containment tests.

use samara_reach::system::SystemLeaf;

/// The sub-boxes `leaves` tile the initial set `init`: each lies inside it, no two
/// overlap (in the parameters of nonzero width, every pair is separated along some
/// axis), and their volumes add up to the whole (relative to the initial widths;
/// bisection halves exactly). A proof over sub-boxes is a proof of the set only if they
/// cover it.
pub fn assert_tiles_leaves(init: &[(f64, f64)], leaves: &[SystemLeaf]) {
    let dims: Vec<usize> = (0..init.len()).filter(|&i| init[i].1 > init[i].0).collect();
    let mut volume = 0.0;
    for (k, a) in leaves.iter().enumerate() {
        let mut v = 1.0;
        for (i, &(lo, hi)) in init.iter().enumerate() {
            assert!(
                lo <= a.init[i][0] && a.init[i][1] <= hi,
                "sub-box {k} leaves the set"
            );
            if hi > lo {
                v *= (a.init[i][1] - a.init[i][0]) / (hi - lo);
            }
        }
        volume += v;
        for b in &leaves[k + 1..] {
            assert!(
                dims.iter()
                    .any(|&i| a.init[i][1] <= b.init[i][0] || b.init[i][1] <= a.init[i][0]),
                "sub-boxes overlap: {:?} and {:?}",
                a.init,
                b.init
            );
        }
    }
    assert!(
        (volume - 1.0).abs() < 1e-12,
        "the sub-boxes cover {volume} of the set"
    );
}

/// The sub-box of `leaves` that holds the start `x0` (the first, on a shared face).
pub fn leaf_of<'a>(leaves: &'a [SystemLeaf], x0: &[f64]) -> &'a SystemLeaf {
    leaves
        .iter()
        .find(|l| l.init.iter().zip(x0).all(|(b, v)| b[0] <= *v && *v <= b[1]))
        .expect("the sub-boxes cover the initial set")
}

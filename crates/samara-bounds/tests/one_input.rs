//! The search on one input with many disjuncts, each over its own small interval (the
//! shape of nn4sys's properties, issue 37): the look-ahead's only split, its halves
//! bounded by the forward symbolic pass, and the attacks sized by the cost of a step.
//! The network is a tent of a tent, `y = T(2 T(x) - 0.5)` with
//! `T(u) = relu(u) + relu(-u) - 2 relu(u - 1)` (`|u|` up to 1, `2 - u` after): piecewise
//! linear, so its maximum over an interval, computed by hand here, is at an end or at a
//! kink (`x` = 0 and 1, where `T(x)` bends, and where `T(x)` is 0.25 or 0.75, where the
//! outer tent bends: +-0.25, +-0.75, 1.25, 1.75).

use samara_bounds::search::{solve, Case, Outcome, OutputConstraint, Settings};
use samara_bounds::symbolic::Objective;
use samara_nn::Affine;

fn tent_maps() -> Vec<(Affine, bool)> {
    let first = Affine::new(1, 3, vec![1.0, -1.0, 1.0], vec![0.0, 0.0, -1.0]);
    // u = 2 T(x) - 0.5 = 2 (h0 + h1 - 2 h2) - 0.5, then relu(u), relu(-u), relu(u - 1).
    let w = vec![2.0, 2.0, -4.0, -2.0, -2.0, 4.0, 2.0, 2.0, -4.0];
    let second = Affine::new(3, 3, w, vec![-0.5, 0.5, -1.5]);
    let out = Affine::new(3, 1, vec![1.0, 1.0, -2.0], vec![0.0]);
    vec![(first, true), (second, true), (out, false)]
}

fn t(u: f64) -> f64 {
    if u <= 1.0 {
        u.abs()
    } else {
        2.0 - u
    }
}

fn tent(x: f64) -> f64 {
    t(2.0 * t(x) - 0.5)
}

/// The network's maximum over `[a, b]`: at an end or at a kink inside.
fn tent_max(a: f64, b: f64) -> f64 {
    [-0.75, -0.25, 0.0, 0.25, 0.75, 1.0, 1.25, 1.75]
        .into_iter()
        .filter(|k| a <= *k && *k <= b)
        .chain([a, b])
        .map(tent)
        .fold(f64::NEG_INFINITY, f64::max)
}

/// 40 disjuncts "`y >= t_k` on `[a_k, a_k + width]`", `a_k = -1 + 0.075 k`, `t_k` the
/// interval's maximum plus `excess` (for the disjunct `sat_at`, minus it).
fn cases(width: f64, excess: f64, sat_at: Option<usize>) -> Vec<Case> {
    (0..40)
        .map(|k| {
            let a = -1.0 + 0.075 * k as f64;
            let b = a + width;
            let t = match sat_at == Some(k) {
                true => tent_max(a, b) - excess,
                false => tent_max(a, b) + excess,
            };
            Case {
                lo: vec![a],
                hi: vec![b],
                // y >= t, as -y + t <= 0.
                constraints: vec![OutputConstraint {
                    obj: Objective {
                        c: vec![-1.0],
                        d: t,
                    },
                    strict: false,
                }],
            }
        })
        .collect()
}

/// Input splitting only: with its 6 ReLUs every box would go to phase splitting.
fn settings() -> Settings {
    Settings {
        timeout: samara_num::Timeout::none(),
        max_pieces: 100_000,
        phase_max_unstable: 0,
        ..Default::default()
    }
}

#[test]
fn one_input_disjuncts_above_every_maximum_are_proved() {
    for (width, excess) in [(0.07, 1e-2), (0.07, 1e-6), (0.9, 1e-6)] {
        let (o, st) = solve(&tent_maps(), &cases(width, excess, None), &settings());
        assert!(matches!(o, Outcome::Proved), "{width} {excess}: {o:?}");
        if width > 0.5 {
            // Some interval was split (the look-ahead ran), not only the 40 roots.
            assert!(st.pieces > 40, "{st:?}");
        }
    }
}

#[test]
fn one_input_point_below_one_maximum_is_found_in_its_disjunct() {
    // The disjunct over [0.95, 1.02] holds the kink at 1; the one over [-1, -0.93] its
    // maximum at an end.
    for (k, width, excess) in [(26, 0.07, 1e-3), (0, 0.07, 1e-3), (13, 0.9, 1e-6)] {
        let cs = cases(width, excess, Some(k));
        match solve(&tent_maps(), &cs, &settings()).0 {
            Outcome::Violated(p) => {
                assert_eq!(p.case, k);
                let (a, b) = (cs[k].lo[0], cs[k].hi[0]);
                assert!(a <= p.x[0] && p.x[0] <= b, "{p:?}");
                let t = tent_max(a, b) - excess;
                assert!(tent(p.x[0]) >= t - 1e-12, "{p:?}: tent {}", tent(p.x[0]));
            }
            o => panic!("disjunct {k}, {width} {excess}: {o:?}"),
        }
    }
}

//! The economies of the incremental expansion (`samara_system::taylor`) that claim the
//! same numbers, checked bit for bit against the computation they replace:
//! - a cosine beside a sine of the same operand reads the sine's companion row: the
//!   series of a graph with both equal those of the graph run on series once per order
//!   (`samara_num::Series`, whose `sin_cos` computes the pair itself);
//! - `merge_common` (common subexpressions once, unused instructions dropped) gives the
//!   series of the graph as recorded;
//! - `solution_series_pair_in` (interval duals to one order, intervals continued from
//!   their value parts) gives the series of the two separate expansions;
//! - `record_checked` calls a recording universal only where no branch was asked;
//! - a scratch reused across expansions (its tables not reset) expands as a fresh one.

use crate::taylor::{glider_state, series_loop, K, UPTO};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use samara_num::{IDual, Interval};
use samara_plant::{Model, Plant};
use samara_system::taylor::{
    merge_common, record, record_checked, solution_series, solution_series_pair_in,
    solution_series_trimmed_in, SeriesScratch,
};
use samara_system::System;

/// Dual directions: the glider's up to seven states and ex.
const N: usize = 8;

/// Bit patterns of an interval (`-0` and `+0` told apart).
fn bits(x: &Interval) -> (u64, u64) {
    (x.lo.to_bits(), x.hi.to_bits())
}

fn dual_bits<const M: usize>(x: &IDual<M>) -> Vec<(u64, u64)> {
    std::iter::once(&x.v).chain(x.d.iter()).map(bits).collect()
}

fn interval_box(r: &mut ChaCha8Rng, centre: &[f64], radius: f64) -> Vec<Interval> {
    centre
        .iter()
        .map(|&v| {
            let w = radius * r.gen_range(0.1..1.0);
            Interval::new(v - w, v + w)
        })
        .collect()
}

#[test]
fn a_sine_and_a_cosine_of_one_operand_are_the_series_pair() {
    // sin and cos of the same operands in both orders (cos first for `a`), a sine
    // without its cosine, and a cosine of a sum.
    let sys = System::parse(
        "
state a, b
input u
a' = sin(b) * cos(b) + cos(a) * u - sin(a + b)
b' = cos(b) - sin(a) * a + cos(a + b) + sin(u * b)
period 1
horizon 1
observe a, b
actuate u = net[0]
init a in [0, 1]
init b in [0, 1]
",
        "trig.sys",
    )
    .expect("parses");
    let g = sys.rhs_graph();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    for _ in 0..300 {
        let c = [rng.gen_range(-3.0..3.0), rng.gen_range(-3.0..3.0)];
        let bx = interval_box(&mut rng, &c, 0.2);
        let bu = [Interval::point(rng.gen_range(-1.0..1.0))];
        let got = solution_series::<Interval, K>(g, &bx, &bu, UPTO).expect("supported");
        let want = series_loop::<Interval>(g, &bx, &bu, UPTO);
        for j in 0..2 {
            for i in 0..=UPTO {
                assert_eq!(
                    bits(&got[j].c[i]),
                    bits(&want[j].c[i]),
                    "state {j} order {i}"
                );
            }
        }
    }
}

#[test]
fn merged_recordings_expand_to_the_same_numbers() {
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    for model in [Model::Reduced, Model::Plate6, Model::Full] {
        let plant = Plant::new(model);
        let d = plant.dim();
        let mut compared = 0;
        for _ in 0..100 {
            let (s, u) = glider_state(&mut rng, d);
            let ex = u[0];
            let bx = interval_box(&mut rng, &s, 1e-3);
            let be = [Interval::new(ex - 1e-4, ex)];
            let Some(g) = record(&bx, &be, d, |x, u, out| plant.rhs(x, &u[0], out)) else {
                continue;
            };
            let merged = merge_common(&g);
            assert!(merged.ops.len() < g.ops.len(), "{model:?}: nothing merged");
            let a = solution_series::<Interval, K>(&g, &bx, &be, UPTO).expect("supported");
            let b = solution_series::<Interval, K>(&merged, &bx, &be, UPTO).expect("supported");
            for j in 0..d {
                assert_eq!(a[j].bad, b[j].bad);
                for i in 0..=UPTO {
                    assert_eq!(bits(&a[j].c[i]), bits(&b[j].c[i]), "{model:?} {j} {i}");
                }
            }
            compared += 1;
        }
        assert!(compared > 50, "{model:?}: {compared} recordings");
    }
}

#[test]
fn recordings_are_universal_only_without_branches() {
    let mut rng = ChaCha8Rng::seed_from_u64(13);
    for model in [Model::Reduced, Model::Plate6, Model::Full] {
        let plant = Plant::new(model);
        let d = plant.dim();
        let (s, u) = glider_state(&mut rng, d);
        let ex = u[0];
        let (g, universal) =
            record_checked(&s, &[ex], d, |x, u, out| plant.rhs(x, &u[0], out)).expect("records");
        // The full model decides |omega| and the quadrants on signs; the others have
        // no branch (their |omega| is smoothed).
        assert_eq!(universal, model != Model::Full, "{model:?}");
        if universal {
            // Universal: the recording at any other point is the same graph.
            for _ in 0..50 {
                let (p, u) = glider_state(&mut rng, d);
                let e = u[0];
                let h = record(&p, &[e], d, |x, u, out| plant.rhs(x, &u[0], out)).expect("records");
                assert_eq!(g, h, "{model:?}");
            }
        }
    }
}

#[test]
fn the_pair_expansion_is_the_two_expansions() {
    let mut rng = ChaCha8Rng::seed_from_u64(17);
    let (upto_d, upto_i) = (5, 7);
    let mut sd = SeriesScratch::<IDual<N>>::default();
    let mut si = SeriesScratch::<Interval>::default();
    for model in [Model::Reduced, Model::Plate6, Model::Full] {
        let plant = Plant::new(model);
        let d = plant.dim();
        let mut compared = 0;
        for trial in 0..100 {
            let (s, u) = glider_state(&mut rng, d);
            let ex = u[0];
            let radius = if trial % 4 == 3 { 0.3 } else { 1e-3 };
            let bx = interval_box(&mut rng, &s, radius);
            let be = [Interval::new(ex - 1e-4, ex)];
            let Some(g) = record(&bx, &be, d, |x, u, out| plant.rhs(x, &u[0], out)) else {
                continue;
            };
            let seeds: Vec<IDual<N>> = bx
                .iter()
                .enumerate()
                .map(|(k, v)| IDual::var(*v, k))
                .collect();
            let ue = [IDual::<N>::var(be[0], N - 1)];
            let (pd, pi) = solution_series_pair_in::<IDual<N>, Interval, 6, K>(
                &g,
                &seeds,
                &ue,
                upto_d,
                upto_i,
                &|x| x.v,
                &mut sd,
                &mut si,
            )
            .expect("supported");
            let wd = solution_series::<IDual<N>, 6>(&g, &seeds, &ue, upto_d).expect("supported");
            let wi = solution_series::<Interval, K>(&g, &bx, &be, upto_i).expect("supported");
            for j in 0..d {
                assert_eq!((pd[j].bad, pi[j].bad), (wd[j].bad, wi[j].bad), "{model:?}");
                assert_eq!((pd[j].n, pi[j].n), (wd[j].n, wi[j].n));
                for i in 0..=upto_d {
                    assert_eq!(
                        dual_bits(&pd[j].c[i]),
                        dual_bits(&wd[j].c[i]),
                        "{model:?} {j} {i}"
                    );
                }
                for i in 0..=upto_i {
                    assert_eq!(bits(&pi[j].c[i]), bits(&wi[j].c[i]), "{model:?} {j} {i}");
                }
            }
            compared += 1;
        }
        assert!(compared > 50, "{model:?}: {compared} recordings");
    }
}

/// One scratch reused across expansions of different graphs and orders (what an
/// earlier expansion leaves in the tables is never read) gives the series of fresh
/// tables, bit for bit.
#[test]
fn a_reused_scratch_expands_as_a_fresh_one() {
    let mut rng = ChaCha8Rng::seed_from_u64(19);
    let mut sc = SeriesScratch::<Interval>::default();
    for trial in 0..300 {
        let model = [Model::Reduced, Model::Plate6, Model::Full][trial % 3];
        let plant = Plant::new(model);
        let d = plant.dim();
        let (s, u) = glider_state(&mut rng, d);
        let ex = u[0];
        let bx = interval_box(&mut rng, &s, 1e-3);
        let be = [Interval::new(ex - 1e-4, ex)];
        let Some(g) = record(&bx, &be, d, |x, u, out| plant.rhs(x, &u[0], out)) else {
            continue;
        };
        let upto = 3 + trial % 6;
        let keep: &dyn Fn(usize, Interval) -> Interval = &|_, v| v;
        let reused = solution_series_trimmed_in::<Interval, K>(&g, &bx, &be, upto, keep, &mut sc)
            .expect("supported");
        let fresh = solution_series::<Interval, K>(&g, &bx, &be, upto).expect("supported");
        for j in 0..d {
            assert_eq!(reused[j].bad, fresh[j].bad);
            for i in 0..=upto {
                assert_eq!(
                    bits(&reused[j].c[i]),
                    bits(&fresh[j].c[i]),
                    "{model:?} {j} {i}"
                );
            }
        }
    }
}

//! Incremental Taylor-mode AD (`samara_system::taylor`) against the reference it replaces:
//! re-running the right-hand side on truncated series (`samara_num::Series`) once per
//! order, as the flows did before. On points (f64) the coefficients must agree to
//! rounding; on boxes (intervals) they must contain the f64 coefficients at random points
//! of the box (soundness), and an undecided branch must leave the series unusable.
//! Graphs: a file exercising every instruction with a recurrence, the shipped glider
//! files, and the built-in plant (`samara_plant::Plant::rhs`) recorded by
//! `taylor::record` for its three variants.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use samara_num::{Interval, Scalar, Series};
use samara_plant::{Model, Plant};
use samara_system::taylor::{record, solution_series};
use samara_system::{Graph, System};
use std::path::PathBuf;

pub(crate) const K: usize = 10;

/// Draws a start and the held inputs.
type Draw<'a> = &'a dyn Fn(&mut ChaCha8Rng) -> (Vec<f64>, Vec<f64>);
pub(crate) const UPTO: usize = 8;

/// The reference: the graph run on series once per order (`x_{i+1} = g_i / (i + 1)`).
pub(crate) fn series_loop<S: Scalar>(
    g: &Graph,
    x0: &[S],
    u: &[S],
    upto: usize,
) -> Vec<Series<S, K>> {
    let mut x: Vec<Series<S, K>> = x0.iter().map(|v| Series::var(v.clone())).collect();
    let us: Vec<Series<S, K>> = u.iter().map(|v| Series::constant(v.clone())).collect();
    let mut out = vec![Series::<S, K>::cst(0.0); x0.len()];
    for i in 0..upto {
        for xj in x.iter_mut() {
            xj.n = i + 1;
        }
        g.eval(&x, &us, &mut out);
        for j in 0..x0.len() {
            x[j].c[i + 1] = out[j].c[i].clone() / (i as f64 + 1.0);
            x[j].bad |= out[j].bad;
        }
    }
    x
}

/// Every instruction with a recurrence: add, sub, mul, div (by a state and by a
/// constant), neg, sqr, sqrt, exp, ln, sin, cos, atan, tanh, abs, an `if`, constants
/// on either side, and `^4` of the held input (an instruction taken on constants only).
const ALL_OPS: &str = "
state a, b, c
input u
a' = sqrt(b^2 + 1) * sin(c) - exp(-a / 4) + u^4 + 2 / (b^2 + 3)
b' = atan(a) * cos(c * u) + tanh(b - 1) - abs(c) * a + ln(a^2 + 2)
c' = (1 - a) / (b + 5) + (if a < 0 then a * b else -b) + 3 * c - u
period 1
horizon 1
observe a, b, c
actuate u = net[0]
init a in [0, 1]
init b in [0, 1]
init c in [0, 1]
";

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / (1.0 + a.abs().max(b.abs()))
}

fn shipped(name: &str) -> System {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples/archcomp")
        .join(name);
    System::from_file(&p).unwrap_or_else(|e| panic!("{e}"))
}

/// Points: both methods agree to 1e-12 (relative) at every order.
fn agree_on_points(g: &Graph, draw: Draw, n: usize) {
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    for _ in 0..n {
        let (x, u) = draw(&mut rng);
        let want = series_loop::<f64>(g, &x, &u, UPTO);
        let got = solution_series::<f64, K>(g, &x, &u, UPTO).expect("supported");
        for (j, (w, v)) in want.iter().zip(&got).enumerate() {
            assert_eq!(w.bad, v.bad);
            for i in 0..=UPTO {
                assert!(
                    rel(w.c[i], v.c[i]) < 1e-12,
                    "state {j} order {i} at {x:?}: {} vs {}",
                    w.c[i],
                    v.c[i]
                );
            }
        }
    }
}

/// Boxes: the interval coefficients contain those of 20 random points of the box,
/// unless the series is marked unusable; returns how many boxes were usable.
fn contain_on_boxes(g: &Graph, draw: Draw, radius: f64, n: usize) -> usize {
    let mut rng = ChaCha8Rng::seed_from_u64(11);
    let mut usable = 0;
    for _ in 0..n {
        let (x, u) = draw(&mut rng);
        let bx: Vec<Interval> = x
            .iter()
            .map(|&v| Interval {
                lo: v - radius * (1.0 + v.abs()),
                hi: v + radius * (1.0 + v.abs()),
            })
            .collect();
        let bu: Vec<Interval> = u.iter().map(|&v| Interval::point(v)).collect();
        let got = solution_series::<Interval, K>(g, &bx, &bu, UPTO).expect("supported");
        let reference = series_loop::<Interval>(g, &bx, &bu, UPTO);
        // Unusable exactly where the reference is.
        assert_eq!(
            got.iter().any(|s| s.bad),
            reference.iter().any(|s| s.bad),
            "at {x:?}"
        );
        if got.iter().any(|s| s.bad) {
            continue;
        }
        usable += 1;
        for _ in 0..20 {
            let p: Vec<f64> = bx.iter().map(|b| rng.gen_range(b.lo..=b.hi)).collect();
            let pt = series_loop::<f64>(g, &p, &u, UPTO);
            for (j, (s, q)) in got.iter().zip(&pt).enumerate() {
                for i in 0..=UPTO {
                    let tol = 1e-12 * (1.0 + q.c[i].abs());
                    assert!(
                        s.c[i].lo - tol <= q.c[i] && q.c[i] <= s.c[i].hi + tol,
                        "state {j} order {i}: {} outside [{}, {}]",
                        q.c[i],
                        s.c[i].lo,
                        s.c[i].hi
                    );
                }
            }
        }
    }
    usable
}

#[test]
fn every_instruction_agrees_with_the_series_and_boxes_contain_points() {
    let sys = System::parse(ALL_OPS, "all_ops.sys").unwrap();
    let g = sys.rhs_graph();
    let draw = |r: &mut ChaCha8Rng| {
        (
            vec![
                r.gen_range(-2.0..2.0),
                r.gen_range(-2.0..2.0),
                r.gen_range(-2.0..2.0),
            ],
            vec![r.gen_range(-1.0..1.0)],
        )
    };
    agree_on_points(g, &draw, 300);
    let usable = contain_on_boxes(g, &draw, 1e-3, 300);
    assert!(usable > 200, "{usable} of 300 boxes usable");
    // Boxes across the `abs` and the `if` are unusable, as on series.
    let wide = contain_on_boxes(g, &draw, 2.0, 50);
    assert!(wide < 50, "every wide box usable");
}

/// A glider state in the range the flights visit (`d` states, E = 0) and a held ex.
pub(crate) fn glider_state(r: &mut ChaCha8Rng, d: usize) -> (Vec<f64>, Vec<f64>) {
    let mut s = vec![
        r.gen_range(0.3..3.5),
        r.gen_range(-0.5..0.5),
        r.gen_range(-0.6..0.6),
        r.gen_range(-1.0..0.2),
        r.gen_range(0.0..40.0),
        r.gen_range(-40.0..4.0),
    ];
    s.resize(d, 0.0);
    (s, vec![r.gen_range(0.181..0.193)])
}

#[test]
fn the_shipped_glider_files_agree_with_the_series() {
    for name in [
        "alsomitra_reduced.sys",
        "alsomitra_plate6.sys",
        "alsomitra_full.sys",
    ] {
        let sys = shipped(name);
        let g = sys.rhs_graph();
        let d = sys.dim();
        let draw = move |r: &mut ChaCha8Rng| glider_state(r, d);
        agree_on_points(g, &draw, 100);
        let usable = contain_on_boxes(g, &draw, 1e-4, 100);
        assert!(usable > 50, "{name}: {usable} of 100 boxes usable");
    }
}

/// The built-in plant recorded at a point replays its own right-hand side bit for bit,
/// and its incremental series agree with the plant run on series; on boxes the recorded
/// series contain the points' (the zonotope flow's use).
#[test]
fn the_recorded_plant_replays_itself_and_agrees_with_its_series() {
    let mut rng = ChaCha8Rng::seed_from_u64(3);
    for model in [Model::Reduced, Model::Plate6, Model::Full] {
        let plant = Plant::new(model);
        let d = plant.dim();
        let mut refused = 0;
        for trial in 0..200 {
            let (s, u) = glider_state(&mut rng, d);
            let ex = u[0];
            let g = record(&s, &[ex], d, |x, u, out| plant.rhs(x, &u[0], out)).unwrap();
            let mut want = vec![0.0; d];
            plant.rhs(&s, &ex, &mut want);
            let mut got = vec![0.0; d];
            g.eval(&s, &[ex], &mut got);
            assert_eq!(want, got, "{model:?}");
            // Series of the plant itself (not the recording) as the reference.
            let mut x: Vec<Series<f64, K>> = s.iter().map(|&v| Series::var(v)).collect();
            let e = Series::<f64, K>::constant(ex);
            let mut out = vec![Series::<f64, K>::cst(0.0); d];
            for i in 0..UPTO {
                for xj in x.iter_mut() {
                    xj.n = i + 1;
                }
                plant.rhs(&x, &e, &mut out);
                for j in 0..d {
                    x[j].c[i + 1] = out[j].c[i] / (i as f64 + 1.0);
                }
            }
            let inc = solution_series::<f64, K>(&g, &s, &[ex], UPTO).unwrap();
            for j in 0..d {
                for i in 0..=UPTO {
                    assert!(rel(x[j].c[i], inc[j].c[i]) < 1e-12, "{model:?} {j} {i}");
                }
            }
            // A box: recorded on intervals (branches decided by the box), contains the
            // points' coefficients; refused where a branch is undecided.
            let r = if trial % 2 == 0 { 1e-4 } else { 0.3 };
            let bx: Vec<Interval> = s
                .iter()
                .map(|&v| Interval {
                    lo: v - r,
                    hi: v + r,
                })
                .collect();
            let be = [Interval::point(ex)];
            let Some(gi) = record(&bx, &be, d, |x, u, out| plant.rhs(x, &u[0], out)) else {
                refused += 1;
                continue;
            };
            let si = solution_series::<Interval, K>(&gi, &bx, &be, UPTO).unwrap();
            if si.iter().any(|v| v.bad) {
                continue;
            }
            for _ in 0..10 {
                let p: Vec<f64> = bx.iter().map(|b| rng.gen_range(b.lo..=b.hi)).collect();
                let gp = record(&p, &[ex], d, |x, u, out| plant.rhs(x, &u[0], out)).unwrap();
                let sp = solution_series::<f64, K>(&gp, &p, &[ex], UPTO).unwrap();
                for j in 0..d {
                    for i in 0..=UPTO {
                        let q = sp[j].c[i];
                        let tol = 1e-12 * (1.0 + q.abs());
                        assert!(
                            si[j].c[i].lo - tol <= q && q <= si[j].c[i].hi + tol,
                            "{model:?}: state {j} order {i}: {q} outside {:?}",
                            si[j].c[i]
                        );
                    }
                }
            }
        }
        if model == Model::Full {
            assert!(refused > 0, "wide boxes straddle the full model's branches");
        }
    }
}

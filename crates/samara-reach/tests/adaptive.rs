//! Adaptive splitting toward a width target (`samara_reach::adaptive`), on TORA
//! (ARCH-COMP's controller, tests/data/archcomp) with its x1 and x3 intervals widened
//! three times and a 6 s horizon, the target on x1 + x2 at the horizon:
//! - containment: 3,000 flights from random starts (samara_system::sim::fly, DOP853 at
//!   rtol 1e-10: an independent f64 integrator, no sets) lie inside the boxes of the
//!   cell their start belongs to at every control instant, and their x1 + x2 inside the
//!   cell's enclosure of it; the cells tile the initial set;
//! - the target is met, with fewer cells than the coarsest uniform grid (k pieces of
//!   every widened interval) that meets it;
//! - one and two threads give the same cells, sets and ratio;
//! - a budget too small for the target ends with the target unmet and says why.

use crate::common;

use rand::{Rng, SeedableRng};
use samara_reach::adaptive::{
    merge_adaptive, reach_adaptive, AdaptiveReach, AdaptiveSettings, FinishedRoot,
};
use samara_reach::grid;
use samara_reach::system::{Measure, NetworkError, SystemReachSettings};
use samara_system::sim::fly;
use samara_system::System;
use std::path::Path;
use std::sync::{Arc, Mutex};

fn tora() -> (System, samara_nn::Network) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(root.join("../../examples/archcomp/tora.sys")).unwrap();
    let text = text
        .replace("horizon 20", "horizon 6")
        .replace("init x1 in [0.6, 0.7]", "init x1 in [0.5, 0.8]")
        .replace("init x3 in [-0.4, -0.3]", "init x3 in [-0.5, -0.2]");
    let text: String = text
        .lines()
        .filter(|l| !l.starts_with("goal"))
        .map(|l| format!("{l}\n"))
        .collect();
    let sys = System::parse(&text, "tora, widened").unwrap();
    assert_eq!(sys.init[0], (0.5, 0.8));
    assert_eq!(sys.init[2], (-0.5, -0.2));
    let net = samara_nn::onnx::load(root.join("tests/data/archcomp/controller_tora.onnx")).unwrap();
    (sys, net)
}

fn settings() -> SystemReachSettings {
    SystemReachSettings {
        order: 3,
        network_error: Some(NetworkError::Symbolic { extra: 20 }),
        samples: 1000,
        max_boxes: 64,
        measures: vec![Measure {
            name: "x1 + x2".into(),
            coef: vec![1.0, 1.0, 0.0, 0.0],
            offset: 0.0,
        }],
        ..SystemReachSettings::default()
    }
}

fn run(threads: usize, s: &SystemReachSettings, ratio: f64) -> AdaptiveReach {
    let a = AdaptiveSettings {
        target_ratio: ratio,
        ..AdaptiveSettings::default()
    };
    run_with(threads, s, &a)
}

fn run_with(threads: usize, s: &SystemReachSettings, a: &AdaptiveSettings) -> AdaptiveReach {
    let (sys, net) = tora();
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(|| reach_adaptive(&sys, &net, s, a).unwrap())
}

fn close(v: f64, lo: f64, hi: f64) -> bool {
    let tol = 1e-7 * (1.0 + v.abs());
    v >= lo - tol && v <= hi + tol
}

#[test]
fn adaptive_cells_contain_3000_flights_and_meet_the_target_with_fewer_cells_than_a_grid() {
    let (sys, net) = tora();
    let s = settings();
    let target = 1.25;
    let r = run(2, &s, target);
    assert!(r.met, "target not met: {:?}", r.reason);
    let ratio = r.ratio.unwrap();
    assert!(ratio <= target, "ratio {ratio}");
    assert_eq!(r.reach.covered, 1.0);
    assert_eq!(r.cells.len(), r.reach.leaves.len());
    assert!(r.cells.iter().all(|c| c.accepted));
    assert!(r.cells.len() > 1, "the target should need cuts");
    common::assert_tiles_leaves(&sys.init, &r.reach.leaves);
    // Every cell's enclosure lies in the band, and the band is the flights' midpoint
    // plus or minus the target's share of their spread.
    let [lo, hi] = r.sampled;
    assert!((r.band[1] - r.band[0] - target * (hi - lo)).abs() < 1e-12);
    for l in &r.reach.leaves {
        let e = l.end_measures[0];
        assert!(
            r.band[0] <= e[0] && e[1] <= r.band[1],
            "{e:?} outside {:?}",
            r.band
        );
    }
    // 3,000 independent flights inside their cell's sets.
    let m = &s.measures[0];
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(39);
    let mut states = 0;
    for _ in 0..3000 {
        let x0: Vec<f64> = sys
            .init
            .iter()
            .map(|&(l, h)| if l < h { rng.gen_range(l..=h) } else { l })
            .collect();
        let f = fly(&sys, &|x: &[f64]| net.eval_f64(x), &x0, 1).unwrap();
        let cell = common::leaf_of(&r.reach.leaves, &x0);
        assert_eq!(f.states.len(), cell.instants.len());
        for (k, (x, b)) in f.states.iter().zip(&cell.instants).enumerate() {
            for (i, v) in x.iter().enumerate() {
                assert!(
                    close(*v, b[i][0], b[i][1]),
                    "flight from {x0:?}: state {i} = {v} at instant {k} outside {:?}",
                    b[i]
                );
                states += 1;
            }
        }
        let v = m.at(f.states.last().unwrap());
        let e = cell.end_measures[0];
        assert!(close(v, e[0], e[1]), "x1 + x2 = {v} outside {e:?}");
    }
    assert_eq!(states, 3000 * 7 * 4);
    // The coarsest uniform grid over the two widened intervals that meets the same
    // target (each cell its own run, cut no further) needs more cells.
    let mut grid_cells = None;
    for k in 1..=8usize {
        let mut gs = s.clone();
        gs.max_boxes = 1;
        let pieces = [k, 1, k, 1];
        let g = grid::reach_cells(&sys, &net, &gs, &pieces, 0..k * k).unwrap();
        let e = g.measures[0].enclosure;
        if let Some(e) = e {
            if (e[1] - e[0]) / (hi - lo) <= target {
                grid_cells = Some(k * k);
                break;
            }
        }
    }
    let grid_cells = grid_cells.expect("a uniform grid of at most 8 x 8 meets the target");
    eprintln!(
        "adaptive: {} cells ({} flown), ratio {ratio:.3}; uniform grid: {grid_cells} cells",
        r.cells.len(),
        r.flown
    );
    assert!(
        r.cells.len() < grid_cells,
        "adaptive {} cells, uniform grid {grid_cells}",
        r.cells.len()
    );
}

/// The result as JSON without the wall time.
fn strip(r: &AdaptiveReach) -> serde_json::Value {
    let mut v = serde_json::to_value(r).unwrap();
    v["reach"]["seconds"] = serde_json::Value::Null;
    v
}

#[test]
fn one_and_two_threads_give_the_same_cells_and_sets() {
    let s = settings();
    let a = run(1, &s, 1.3);
    let b = run(2, &s, 1.3);
    assert!(a.cells.len() > 1);
    assert_eq!(strip(&a), strip(&b));
}

/// Shards 0/2 and 1/2 of a run that starts from 2 x 2 cells (each shard the starting
/// cells of its residue), merged in either order, give the one-process result: the
/// same cells, sets, ratio and verdict.
#[test]
fn two_shards_merge_to_the_one_process_result() {
    let (sys, _) = tora();
    let s = settings();
    let a = AdaptiveSettings {
        target_ratio: 1.3,
        pieces: Some(vec![2, 1, 2, 1]),
        ..AdaptiveSettings::default()
    };
    let whole = run_with(2, &s, &a);
    assert!(whole.met);
    let part = |i: usize| {
        let sa = AdaptiveSettings {
            shard: Some((i, 2)),
            ..a.clone()
        };
        run_with(1, &s, &sa)
    };
    let (p0, p1) = (part(0), part(1));
    assert!(p0
        .cells
        .iter()
        .all(|c| c.id.starts_with('0') || c.id.starts_with('2')));
    assert!(
        !p0.met && p0.ratio.is_none(),
        "a shard covers part of the set only"
    );
    for parts in [vec![p0.clone(), p1.clone()], vec![p1, p0]] {
        let m = merge_adaptive(&sys, &s, &a, parts).unwrap();
        assert_eq!(strip(&m), strip(&whole));
    }
}

/// A checkpoint: every starting cell of a 2 x 2 start is reported once, when its cells
/// are final, and together they hold every cell of the run; a rerun given two of them
/// (as after a killed run) flies only the other two and gives the uninterrupted run's
/// cells, sets, ratio, rounds and count of cells flown. A checkpoint with a starting
/// cell the run does not fly is refused.
#[test]
fn a_run_resumed_from_its_finished_starting_cells_gives_the_same_result() {
    let s = settings();
    let log: Arc<Mutex<Vec<FinishedRoot>>> = Arc::default();
    let sink = log.clone();
    let a = AdaptiveSettings {
        target_ratio: 1.3,
        pieces: Some(vec![2, 1, 2, 1]),
        on_finished: Some(Arc::new(move |f: &FinishedRoot| {
            sink.lock().unwrap().push(f.clone())
        })),
        ..AdaptiveSettings::default()
    };
    let whole = run_with(2, &s, &a);
    assert!(whole.met);
    let mut fin = log.lock().unwrap().clone();
    fin.sort_by_key(|f| f.root);
    assert_eq!(fin.iter().map(|f| f.root).collect::<Vec<_>>(), [0, 1, 2, 3]);
    assert_eq!(
        fin.iter().map(|f| f.cells.len()).sum::<usize>(),
        whole.cells.len()
    );
    assert_eq!(fin.iter().map(|f| f.flown).sum::<usize>(), whole.flown);
    assert_eq!(fin.iter().map(|f| f.rounds).max(), Some(whole.rounds));
    let b = AdaptiveSettings {
        resume: vec![fin[0].clone(), fin[3].clone()],
        on_finished: None,
        ..a.clone()
    };
    let again = run_with(1, &s, &b);
    assert_eq!(strip(&again), strip(&whole));
    // Starting cell 1 belongs to shard 1/2, not 0/2.
    let c = AdaptiveSettings {
        resume: vec![fin[1].clone()],
        shard: Some((0, 2)),
        on_finished: None,
        ..a.clone()
    };
    let (sys, net) = tora();
    let e = reach_adaptive(&sys, &net, &s, &c).unwrap_err().to_string();
    assert!(e.contains("the checkpoint has starting cell 1"), "{e}");
}

/// Shards whose leaf budget ran out stopped where one process would not have: their
/// merge is refused, not passed off as the one-process result.
#[test]
fn a_merge_of_shards_stopped_by_their_budget_is_refused() {
    let (sys, _) = tora();
    let mut s = settings();
    s.max_boxes = 3;
    let a = AdaptiveSettings {
        target_ratio: 1.05,
        pieces: Some(vec![2, 1, 2, 1]),
        ..AdaptiveSettings::default()
    };
    let parts: Vec<AdaptiveReach> = (0..2)
        .map(|i| {
            run_with(
                1,
                &s,
                &AdaptiveSettings {
                    shard: Some((i, 2)),
                    ..a.clone()
                },
            )
        })
        .collect();
    assert!(parts[0].stopped.is_some());
    let e = merge_adaptive(&sys, &s, &a, parts).unwrap_err().to_string();
    assert!(e.contains("stopped splitting early"), "{e}");
}

#[test]
fn a_budget_too_small_for_the_target_says_so() {
    let (sys, _) = tora();
    let mut s = settings();
    s.max_boxes = 2;
    let r = run(2, &s, 1.05);
    assert!(!r.met);
    assert!(r.cells.len() <= 2);
    common::assert_tiles_leaves(&sys.init, &r.reach.leaves);
    let why = r.reason.unwrap();
    assert!(why.contains("budget of 2 leaves"), "{why}");
}

#[test]
fn settings_are_checked() {
    let (sys, net) = tora();
    let mut s = settings();
    for bad in [0.5, f64::NAN, f64::INFINITY] {
        let a = AdaptiveSettings {
            target_ratio: bad,
            ..AdaptiveSettings::default()
        };
        let e = reach_adaptive(&sys, &net, &s, &a).unwrap_err().to_string();
        assert!(e.contains("target ratio"), "{e}");
    }
    s.measures.clear();
    let e = reach_adaptive(&sys, &net, &s, &AdaptiveSettings::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("needs a measure"), "{e}");
    let mut s = settings();
    s.max_boxes = 3;
    let a = AdaptiveSettings {
        pieces: Some(vec![2, 1, 2, 1]),
        ..AdaptiveSettings::default()
    };
    let e = reach_adaptive(&sys, &net, &s, &a).unwrap_err().to_string();
    assert!(e.contains("starting grid has 4 cells"), "{e}");
}

/// ARCH-COMP's single pendulum with theta's initial interval [1, 1.175] widened to
/// [0.5, 2.5] and a 3 s horizon, order 2 with interval network errors, the target on
/// theta at the horizon: cells are lost there (the sets stop being enclosed), and
/// symbolic remainders (`retry_mode(Interval)` = `symbolic:20`) rescue some of them.
fn pendulum() -> (System, samara_nn::Network, SystemReachSettings) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let text =
        std::fs::read_to_string(root.join("../../examples/archcomp/single_pendulum.sys")).unwrap();
    let text = text
        .replace("init theta in [1, 1.175]", "init theta in [0.5, 2.5]")
        .replace("horizon 1", "horizon 3");
    let text: String = text
        .lines()
        .filter(|l| !l.starts_with("goal"))
        .map(|l| format!("{l}\n"))
        .collect();
    let sys = System::parse(&text, "single pendulum, widened").unwrap();
    assert_eq!(sys.init[0], (0.5, 2.5));
    let net =
        samara_nn::onnx::load(root.join("tests/data/archcomp/controller_single_pendulum.onnx"))
            .unwrap();
    let s = SystemReachSettings {
        order: 2,
        network_error: Some(NetworkError::Interval),
        samples: 200,
        max_boxes: 64,
        measures: vec![Measure {
            name: "theta".into(),
            coef: vec![1.0, 0.0],
            offset: 0.0,
        }],
        ..SystemReachSettings::default()
    };
    (sys, net, s)
}

/// A lost cell flown once more with `retry_mode`'s network error before it is cut
/// (`AdaptiveSettings::retry_from`, here from any instant): some cells are rescued
/// (`retried`, accepted, sets to the horizon), so the target is met with fewer cells
/// than when every lost cell is cut; 2,000 independent flights (DOP853 at rtol 1e-10)
/// lie inside their cell's boxes at every instant, the rescued cells' included; one and
/// two threads give the same result; shards of a 2 x 2 start merge to the one-process
/// result, and a run resumed from a finished starting cell (its `retried` marks kept)
/// gives it too.
#[test]
fn a_cell_lost_is_flown_again_with_more_symbolic_parameters_before_a_cut() {
    let (sys, net, s) = pendulum();
    let on = |threads: usize, a: &AdaptiveSettings| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| reach_adaptive(&sys, &net, &s, a).unwrap())
    };
    let a = AdaptiveSettings {
        target_ratio: 2.0,
        retry_from: Some(0.0),
        ..AdaptiveSettings::default()
    };
    let cut = on(
        2,
        &AdaptiveSettings {
            retry_from: None,
            ..a.clone()
        },
    );
    let r = on(2, &a);
    assert!(cut.met && r.met, "{:?} {:?}", cut.reason, r.reason);
    assert!(cut.cells.iter().all(|c| !c.retried));
    let rescued: Vec<usize> = (0..r.cells.len())
        .filter(|&i| r.cells[i].retried && r.cells[i].accepted)
        .collect();
    assert!(!rescued.is_empty(), "no lost cell was rescued");
    for &i in &rescued {
        let l = &r.reach.leaves[i];
        assert!(l.failure.is_none() && l.instants.len() == sys.steps() + 1);
    }
    assert!(
        r.cells.len() < cut.cells.len(),
        "{} cells with the second flights, {} without",
        r.cells.len(),
        cut.cells.len()
    );
    common::assert_tiles_leaves(&sys.init, &r.reach.leaves);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(51);
    let mut inside_rescued = 0;
    for _ in 0..2000 {
        let x0: Vec<f64> = sys
            .init
            .iter()
            .map(|&(l, h)| rng.gen_range(l..=h))
            .collect();
        let f = fly(&sys, &|x: &[f64]| net.eval_f64(x), &x0, 1).unwrap();
        let k = (0..r.reach.leaves.len())
            .find(|&k| {
                r.reach.leaves[k]
                    .init
                    .iter()
                    .zip(&x0)
                    .all(|(b, v)| b[0] <= *v && *v <= b[1])
            })
            .unwrap();
        let cell = &r.reach.leaves[k];
        assert_eq!(f.states.len(), cell.instants.len());
        for (t, (x, b)) in f.states.iter().zip(&cell.instants).enumerate() {
            for (i, v) in x.iter().enumerate() {
                assert!(
                    close(*v, b[i][0], b[i][1]),
                    "flight from {x0:?}: state {i} = {v} at instant {t} outside {:?} (cell {})",
                    b[i],
                    r.cells[k].id
                );
            }
        }
        inside_rescued += usize::from(rescued.contains(&k));
    }
    assert!(inside_rescued > 0, "no flight started in a rescued cell");
    assert_eq!(strip(&on(1, &a)), strip(&r));
    // Shards and a checkpoint, on a 2 x 2 start.
    let log: Arc<Mutex<Vec<FinishedRoot>>> = Arc::default();
    let sink = log.clone();
    let g = AdaptiveSettings {
        pieces: Some(vec![2, 2]),
        on_finished: Some(Arc::new(move |f: &FinishedRoot| {
            sink.lock().unwrap().push(f.clone())
        })),
        ..a.clone()
    };
    let whole = on(2, &g);
    assert!(whole.cells.iter().any(|c| c.retried && c.accepted));
    let g = AdaptiveSettings {
        on_finished: None,
        ..g
    };
    let parts: Vec<AdaptiveReach> = (0..2)
        .map(|i| {
            on(
                1,
                &AdaptiveSettings {
                    shard: Some((i, 2)),
                    ..g.clone()
                },
            )
        })
        .collect();
    let m = merge_adaptive(&sys, &s, &g, parts).unwrap();
    assert_eq!(strip(&m), strip(&whole));
    let mut fin = log.lock().unwrap().clone();
    fin.sort_by_key(|f| f.root);
    let with_retried = fin
        .iter()
        .find(|f| f.cells.iter().any(|(c, _)| c.retried))
        .expect("a starting cell with a rescued cell")
        .clone();
    let again = on(
        1,
        &AdaptiveSettings {
            resume: vec![with_retried],
            ..g.clone()
        },
    );
    assert_eq!(strip(&again), strip(&whole));
}

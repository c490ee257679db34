//! Closed-loop training with counterexample-guided rounds (issue 18 item 2) on the data
//! samara regenerates with its own simulator (the reproduction's data stage).

use samara_plant::{Model, Plant, EX_RANGE};
use samara_reach::GliderViolation;
use samara_reach::{Goal, Verdict};
use samara_sim::{
    fly, initial_state, published_starts, training_rows, LoopSettings, PidController,
};
use samara_train::cegis::{check_flights, counterexamples, train_closed_loop, CegisOptions};
use samara_train::Table;

/// The nine PID flights of the plate6 model (published protocol) as a data table.
fn pid_data() -> Table {
    let plant = Plant::new(Model::Plate6);
    let flights: Vec<_> = published_starts()
        .into_iter()
        .map(|y0| {
            fly(
                &plant,
                &mut PidController::default(),
                &initial_state(&plant, y0),
                &LoopSettings::default(),
            )
            .unwrap()
        })
        .collect();
    let rows = training_rows(&flights);
    let text: String = rows
        .iter()
        .map(|r| {
            r.iter()
                .map(|v| format!("{v:?}"))
                .collect::<Vec<_>>()
                .join(",")
                + "\n"
        })
        .collect();
    // One folder per call: the tests of this file run in parallel in one process.
    static CALLS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let k = CALLS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!("samara-cegis-{}-{k}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let p = dir.join("pid.csv");
    std::fs::write(&p, text).unwrap();
    let t = samara_train::read_table(&p).unwrap();
    let _ = std::fs::remove_dir_all(&dir);
    t
}

#[test]
fn closed_loop_training_proves_the_published_goal_and_plate6_flights_meet_it() {
    let data = pid_data();
    let o = CegisOptions::default();
    let out = train_closed_loop(&data, None, &o).unwrap();
    for r in &out.rounds {
        eprintln!("{r:?}");
    }
    eprintln!(
        "proved {} in {} rounds, {:.1} s; enclosure {:?}; R^2 {:.4}",
        out.proved,
        out.rounds.len(),
        out.seconds,
        out.reach.final_x_plus_y,
        out.r2
    );
    assert!(out.proved, "{:?}", out.reach.verdict);
    assert_eq!(out.reach.verdict, Verdict::Proved);
    let e = out.reach.final_x_plus_y;
    assert!(-2.0 <= e[0] && e[1] <= 2.0, "{e:?}");
    assert!(out.r2 >= 0.9, "R^2 {} against the PID data", out.r2);
    // The simulation model, not the reduced one reach proves it for.
    let c = check_flights(
        &out.network,
        Model::Plate6,
        o.y0,
        1000,
        7,
        Some(EX_RANGE),
        20.0,
        2.0,
    )
    .unwrap();
    eprintln!("{c:?}");
    assert_eq!((c.flights, c.violations), (1000, 0), "{c:?}");
    // Same seed, same network.
    let again = train_closed_loop(&data, None, &o).unwrap();
    assert_eq!(again.network, out.network);
}

#[test]
fn a_round_that_finds_a_counterexample_adds_it() {
    // No training steps: the data-only network, which simulation refutes at the low
    // end of the interval, is checked twice with a small reach budget.
    let data = pid_data();
    let o = CegisOptions {
        steps_per_round: 0,
        max_rounds: 2,
        round_reach: (4, 8),
        final_reach: (4, 8),
        max_added: 3,
        ..Default::default()
    };
    let out = train_closed_loop(&data, None, &o).unwrap();
    assert!(!out.proved);
    assert_eq!(out.rounds.len(), 2);
    let (r1, r2) = (&out.rounds[0], &out.rounds[1]);
    eprintln!("{r1:?}\n{r2:?}");
    assert_eq!(r1.starts, o.initial_set().len());
    assert_ne!(r1.verdict, "proved");
    assert!(
        !r1.added.is_empty() && r1.added.len() <= 3,
        "{:?}",
        r1.added
    );
    for y in &r1.added {
        assert!((o.y0.0..=o.y0.1).contains(y));
        assert!(o.initial_set().iter().all(|s| (s - y).abs() > 1e-9));
    }
    // The next round flies the grown set, and adds no start twice.
    assert_eq!(r2.starts, r1.starts + r1.added.len());
    for y in &r2.added {
        assert!(r1.added.iter().all(|s| (s - y).abs() > 1e-9));
    }
    // A violation found by reach's simulation is the first start added.
    if let Verdict::Violated(GliderViolation { initial, .. }) = &out.reach.verdict {
        let set: Vec<f64> = o.initial_set();
        let c = counterexamples(
            &out.reach,
            &Goal {
                ystar: 2.0,
                from: None,
            },
            20.0,
            &set,
            3,
        );
        if set.iter().all(|s| (s - initial[5]).abs() > 1e-9) {
            assert_eq!(c[0], initial[5]);
        }
    }
}

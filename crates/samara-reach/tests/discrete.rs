//! Discrete-time systems (`samara_reach::discrete`) on ARCH-COMP 2024's VerticalCAS
//! (`examples/archcomp/vcas.sys`, the nine networks in tests/data/archcomp/vcas).
//! Golden values come from `bench/archcomp/vcas_check.py`, an independent plain-Python
//! transcription of planeDynamics.m that reads the .nnet files itself, or are computed
//! by hand from the update h' = h - hdot0 - acc / 2.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use samara_reach::discrete::{
    reach_discrete, simulate, step_f64, Choice, Controllers, DiscreteResult, DiscreteSettings,
    DiscreteVerdict, DiscreteViolation,
};
use samara_system::System;
use std::path::Path;

fn vcas(hdot_norm: f64, h: (f64, f64), hdot0: f64) -> System {
    let p = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/archcomp/vcas.sys");
    let mut s = System::from_file(&p)
        .unwrap()
        .with_params(&[("hdot_norm", hdot_norm)])
        .unwrap();
    s.init[0] = h;
    s.init[1] = (hdot0, hdot0);
    s
}

fn ctrl(sys: &System) -> Controllers {
    let d = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/archcomp/vcas");
    let nets = (1..=9)
        .map(|i| {
            samara_nn::load(d.join(format!("VertCAS_noResp_pra0{i}_v9_20HU_200.nnet"))).unwrap()
        })
        .collect();
    Controllers::new(sys, nets).unwrap()
}

fn run(sys: &System, choice: Choice) -> DiscreteResult {
    let s = DiscreteSettings {
        choice,
        ..Default::default()
    };
    reach_discrete(sys, &ctrl(sys), &s).unwrap()
}

/// Every state of `n` random trajectories (random start, random table entries at every
/// step when `choice` is `All`, else the choice's entry) lies in a set of the same mode
/// at its instant.
fn assert_contains(sys: &System, r: &DiscreteResult, choice: Choice, n: usize) {
    let c = ctrl(sys);
    let mut rng = ChaCha8Rng::seed_from_u64(7);
    let mut points = 0;
    for _ in 0..n {
        let x0: Vec<f64> = sys
            .init
            .iter()
            .map(|(l, h)| if l < h { rng.gen_range(*l..=*h) } else { *l })
            .collect();
        let t = simulate(sys, &c, &x0, &mut |_, row| match choice {
            Choice::All => rng.gen_range(0..row.len()),
            c => c.indices(row)[0],
        });
        for (k, (x, m)) in t.states.iter().zip(&t.modes).enumerate() {
            assert!(
                r.sets[k].iter().any(|b| b.contains(x, *m)),
                "step {k}: state {x:?} (mode {m:?}) of a trajectory from {x0:?} is in no set"
            );
            points += 1;
        }
    }
    assert_eq!(points, n * (sys.steps() + 1));
}

#[test]
fn one_step_matches_the_independent_transcription() {
    // Competition normalisation (hdot0 / 5000): the COC network's scores at
    // (h, hdot0, tau) = (-131, -19.5, 25), vcas_check.py `point -131 -19.5 5000`.
    let sys = vcas(5000.0, (-131.0, -131.0), -19.5);
    let c = ctrl(&sys);
    let mut obs = [0.0; 3];
    sys.observe(&[-131.0, -19.5, 25.0], &mut obs);
    let scores = c.network(Some(0)).eval_f64(&obs);
    let python = [
        -0.09260441590278845,
        -0.3280239413495318,
        -0.2314069129987985,
        -0.2598949571798567,
        -0.013540924824113842,
        -1.5392280757330739,
        -1.4591434394788232,
        -1.7419053840935317,
        -1.3875093895280202,
    ];
    for (a, b) in scores.iter().zip(&python) {
        assert!((a - b).abs() < 1e-12, "{scores:?} vs {python:?}");
    }
    // argmax CL1500, middle acceleration 7 g / 24: h' = -131 + 19.5 - 7 * 32.2 / 48.
    let (x, m, u) = step_f64(&sys, &c, &[-131.0, -19.5, 25.0], Some(0), &mut |r| {
        Choice::Middle.indices(r)[0]
    });
    assert_eq!(m, Some(4));
    assert!((u[0] - 7.0 * 32.2 / 24.0).abs() < 1e-12);
    assert!((x[0] - (-111.5 - 7.0 * 32.2 / 48.0)).abs() < 1e-12, "{x:?}");
    assert!((x[1] - (-19.5 + 7.0 * 32.2 / 24.0)).abs() < 1e-12);
    assert_eq!(x[2], 24.0);
    // The networks' own normalisation (hdot0 / 200): COC, acceleration 0.
    let sys = vcas(200.0, (-131.0, -131.0), -19.5);
    let (x, m, _) = step_f64(&sys, &c, &[-131.0, -19.5, 25.0], Some(0), &mut |r| {
        Choice::Middle.indices(r)[0]
    });
    assert_eq!((m, x), (Some(0), vec![-111.5, -19.5, 24.0]));
}

#[test]
fn overlapping_scores_branch_into_both_advisories_and_contain_trajectories() {
    // With hdot0 / 200 the COC network's argmax changes from CL1500 to COC between h =
    // -271.5 and -271 (vcas_check.py scan): a box across it has both winners.
    let sys = vcas(200.0, (-275.0, -268.0), -19.5);
    let c = ctrl(&sys);
    let s = DiscreteSettings {
        choice: Choice::Middle,
        max_depth: 0,
        ..Default::default()
    };
    let r = reach_discrete(&sys, &c, &s).unwrap();
    let modes: Vec<Option<usize>> = r.sets[1].iter().map(|b| b.mode).collect();
    assert!(
        modes.contains(&Some(0)) && modes.contains(&Some(4)),
        "{modes:?}"
    );
    assert!(r.mode_branches >= 1);
    assert_contains(&sys, &r, Choice::Middle, 2000);
    // Halving separates the two sides: at step 1 the COC sets lie above the switch and
    // the CL1500 sets below it (h' = h + 19.5 under COC, up to the split width).
    let r = reach_discrete(
        &sys,
        &c,
        &DiscreteSettings {
            choice: Choice::Middle,
            ..Default::default()
        },
    )
    .unwrap();
    assert!(r.splits > 0);
    for b in &r.sets[1] {
        match b.mode {
            Some(0) => assert!(b.lo[0] >= -271.5 + 19.5 - 0.01, "{b:?}"),
            Some(4) => {}
            m => panic!("unexpected advisory {m:?}"),
        }
    }
    assert_contains(&sys, &r, Choice::Middle, 2000);
}

#[test]
fn all_choices_verified_case_contains_3000_random_pilots() {
    let sys = vcas(5000.0, (-133.0, -129.0), -19.5);
    let r = run(&sys, Choice::All);
    assert_eq!(r.verdict, DiscreteVerdict::Proved);
    assert_contains(&sys, &r, Choice::All, 3000);
}

#[test]
fn falsification_is_a_rechecked_trajectory() {
    // The networks' normalisation: COC throughout, so h(2) = h(0) + 2 * 19.5 from any
    // start; from -131 that is -92, inside the unsafe band (by hand).
    let sys = vcas(200.0, (-133.0, -129.0), -19.5);
    let r = run(&sys, Choice::Middle);
    let DiscreteVerdict::Violated(DiscreteViolation {
        trajectory, step, ..
    }) = &r.verdict
    else {
        panic!("{:?}", r.verdict)
    };
    let again = simulate(&sys, &ctrl(&sys), &trajectory.states[0], &mut |_, row| {
        Choice::Middle.indices(row)[0]
    });
    assert_eq!(&again, trajectory);
    assert!(trajectory.states[*step][0].abs() <= 100.0);
    assert_eq!(*step, 2);
    assert_eq!(trajectory.states[2][0], trajectory.states[0][0] + 39.0);
}

/// ARCH-COMP's published verdicts for the middle strategy (JuliaReach's VerticalCAS
/// script asserts them: -19.5 and -22.5 verified, -25.5 and -28.5 falsified), with the
/// competition's normalisation; and the sets contain the middle-strategy trajectories.
#[test]
fn middle_strategy_matches_the_published_verdicts() {
    for (hd, safe) in [(-19.5, true), (-22.5, true), (-25.5, false), (-28.5, false)] {
        let sys = vcas(5000.0, (-133.0, -129.0), hd);
        let r = run(&sys, Choice::Middle);
        match (&r.verdict, safe) {
            (DiscreteVerdict::Proved, true) => assert_contains(&sys, &r, Choice::Middle, 500),
            (DiscreteVerdict::Violated(_), false) => {}
            (v, _) => panic!("hdot0 {hd}: {v:?}"),
        }
    }
}

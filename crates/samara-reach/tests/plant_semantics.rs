//! One meaning of a plant (issue 35, item 1): `samara_system::sim::fly` (what `samara
//! simulate --system` runs) and `samara_reach::system::reach_system` (what `samara reach
//! --system` runs) fire the `reset` statements at the same instants: at t = 0, T, ...,
//! (N-1)T before the network reads the state, never at the horizon, so "at end" is the
//! last period's flow. Golden values are closed-form integrals of the plants below.

use samara_nn::{Activation, Affine, Layer, Network};
use samara_reach::system::SystemViolation;
use samara_reach::system::{reach_system, NetworkError, SystemReachSettings, SystemVerdict};
use samara_system::sim::{fly, goals_hold};
use samara_system::System;

/// A one-input, one-output network `u = 0.001 relu(x) + 0.1` (its values barely matter
/// to the plants here, which move `x` by 1e-6 u per unit time or not at all).
fn small_net() -> Network {
    Network {
        input_names: vec!["x".into()],
        output_names: vec!["u".into()],
        input_norm: None,
        layers: vec![
            Layer::Affine(Affine::new(1, 1, vec![1.0], vec![0.0])),
            Layer::Act(Activation::Relu),
            Layer::Affine(Affine::new(1, 1, vec![0.001], vec![0.1])),
        ],
        output_denorm: None,
    }
}

/// The plant of issue 35: `acc` integrates a spike 1e-4 wide around x = 0.3123 and is
/// reset at every control instant; the goal asks it to be near 0 at the horizon.
fn spike_plant(goal: &str, init: &str) -> System {
    let src = format!(
        "state x, acc\ninput u\nx' = 1e-6 * u\nacc' = max(0, 1 - 1e8 * (x - 0.3123)^2)\n\
         reset acc = 0\nperiod 0.5\nhorizon 2\nobserve x\nactuate u = net[0]\n\
         init x in {init}\ninit acc = 0\ngoal {goal}\n"
    );
    System::parse(&src, "spike.sys").unwrap()
}

/// The wrong `proved` of issue 35: the flight from x = 0.3123 ends with acc close to one
/// period (the spike's value 1 integrated over the last period: x moves by under 1e-6,
/// where the spike is still above 1 - 1e8 (1e-6)^2 = 0.9999), so the goal `acc <= 1e-6
/// at end` is violated; reach must say `violated` or `unknown`, never `proved`. One
/// falsification flight (the centre and the corners: all miss the spike), so the sets
/// decide; before the fix, reach fired the reset at the horizon and proved the goal on
/// `[-1, 1]`.
#[test]
fn reset_plant_is_never_proved_against_a_violating_flight() {
    for init in ["[-1, 1]", "[0.3118, 0.3124]"] {
        let sys = spike_plant("band acc <= 0.000001 at end", init);
        let net = small_net();
        let eval = |x: &[f64]| net.eval_f64(x);
        let f = fly(&sys, &eval, &[0.3123, 0.0], 10).unwrap();
        let end = f.states.last().unwrap();
        assert_eq!(*f.t.last().unwrap(), 2.0);
        assert!(
            (end[1] - 0.5).abs() < 1e-4,
            "acc at the horizon is the last period's integral, ~0.5: {}",
            end[1]
        );
        assert_eq!(goals_hold(&sys, &f), vec![false]);
        let s = SystemReachSettings {
            max_boxes: 2,
            samples: 1,
            network_error: Some(NetworkError::Interval),
            ..Default::default()
        };
        let r = reach_system(&sys, &net, &s).unwrap();
        eprintln!("{init}: {:?} in {:.1} s", r.verdict, r.seconds);
        assert!(
            matches!(
                r.verdict,
                SystemVerdict::Violated(SystemViolation { .. }) | SystemVerdict::Unknown { .. }
            ),
            "{:?}",
            r.verdict
        );
        // The sets at the horizon hold the flight's acc.
        if r.instants.len() == sys.steps() + 1 {
            let [lo, hi] = r.instants[sys.steps()][1];
            assert!(
                lo <= end[1] && end[1] <= hi,
                "[{lo}, {hi}] misses {}",
                end[1]
            );
        }
    }
}

/// Both commands give a reset state the same values: `acc' = 1` reset to 0 at every
/// instant is exactly T = 0.5 at every instant k >= 1 and at the horizon (the flow's end,
/// before the next reset), 0 at t = 0. The simulator records that, reach's sets at each
/// instant contain it, and reach proves `acc in [0.49, 0.51] at end` (the closed form
/// says 0.5) and `acc <= 0.51 always`, which every flight meets, while a goal asking
/// for the reset value at the end (`acc <= 0.1 at end`) is violated on both sides.
#[test]
fn reset_states_hold_the_last_period_at_instants_and_at_the_end() {
    let src = |goal: &str| {
        format!(
            "state x, acc\ninput u\nx' = 0 * u\nacc' = 1\nreset acc = 0\nperiod 0.5\n\
             horizon 2\nobserve x\nactuate u = net[0]\ninit x in [0, 1]\ninit acc = 3\n\
             goal {goal}\n"
        )
    };
    let net = small_net();
    let eval = |x: &[f64]| net.eval_f64(x);
    let s = SystemReachSettings {
        max_boxes: 4,
        samples: 10,
        ..Default::default()
    };
    for goal in ["band acc in [0.49, 0.51] at end", "band acc <= 0.51 always"] {
        let sys = System::parse(&src(goal), "t.sys").unwrap();
        let f = fly(&sys, &eval, &[0.5, 3.0], 10).unwrap();
        assert_eq!(f.states[0][1], 0.0, "the reset acts on the initial state");
        for (t, x) in f.t.iter().zip(&f.states) {
            let k = (t / sys.period).round();
            if *t > 0.0 && (t - k * sys.period).abs() < 1e-12 {
                assert!((x[1] - 0.5).abs() < 1e-9, "acc = {} at t = {t}", x[1]);
            }
        }
        assert_eq!(goals_hold(&sys, &f), vec![true], "{goal}");
        let r = reach_system(&sys, &net, &s).unwrap();
        assert_eq!(r.verdict, SystemVerdict::Proved, "{goal}");
        for (k, row) in r.instants.iter().enumerate() {
            let want = if k == 0 { 0.0 } else { 0.5 };
            let [lo, hi] = row[1];
            assert!(lo <= want && want <= hi, "instant {k}: [{lo}, {hi}]");
            assert!(hi - lo < 1e-6, "instant {k}: [{lo}, {hi}] not tight");
        }
    }
    let sys = System::parse(&src("band acc <= 0.1 at end"), "t.sys").unwrap();
    let f = fly(&sys, &eval, &[0.5, 3.0], 10).unwrap();
    assert_eq!(goals_hold(&sys, &f), vec![false]);
    let r = reach_system(&sys, &net, &s).unwrap();
    assert!(
        matches!(r.verdict, SystemVerdict::Violated(SystemViolation { .. })),
        "{:?}",
        r.verdict
    );
}

/// Time limits (issue 35, item 3): on a sliding-mode plant (`x' = if x < 0 then y + 0.5
/// else y - 0.5`, `|y| < 0.5`: the field points at the switch from both sides) every
/// falsification flight's step collapses and the flowpipe halves its steps to the
/// limit; a 2 s budget still ends the run within 2 s plus one period's work (1 s here),
/// `unknown` with a reason that says so and names the collapsed flight.
#[test]
fn sliding_mode_reach_ends_within_its_timeout() {
    let src = "state x, y\ninput u\nx' = if x < 0 then y + 0.5 else y - 0.5\n\
               y' = 0.01 * u\nperiod 0.5\nhorizon 5\nobserve x\nactuate u = net[0]\n\
               init x in [-0.1, 0.1]\ninit y in [-0.1, 0.1]\ngoal band x <= 1 always\n";
    let sys = System::parse(src, "slide.sys").unwrap();
    let net = small_net();
    let s = SystemReachSettings {
        timeout: samara_num::Timeout::from_secs_f64(2.0).unwrap(),
        ..Default::default()
    };
    let start = std::time::Instant::now();
    let r = reach_system(&sys, &net, &s).unwrap();
    let wall = start.elapsed().as_secs_f64();
    eprintln!("{:?} in {wall:.2} s", r.verdict);
    assert!(wall <= 3.0, "{wall:.2} s");
    match &r.verdict {
        SystemVerdict::Unknown { reason } => {
            assert!(reason.contains("collapsed"), "{reason}");
        }
        v => panic!("{v:?}"),
    }
}

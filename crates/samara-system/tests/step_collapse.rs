//! Discontinuous dynamics get a diagnosis (issue 35, item 4): a flight whose integrator
//! step collapses on a switch is reported as such, with the time, the state and the
//! `if` that flips there, not as a NaN.

use samara_system::sim::{fly, SimError};
use samara_system::System;

/// A sliding mode (issue 35, item 4): `x' = if x < 0 then y + 0.5 else y - 0.5` with
/// `|y| < 0.5`, so the field points at `x = 0` from both sides and the flight from
/// x = -0.1, y = 0 reaches it at t = 0.2 (x' = 0.5 until then). The simulator stops with
/// a step-collapse error naming that time, the state (x = 0) and the `if` with its
/// file:line:col, and suggests a smoothing or hysteresis, quickly (not after ten million
/// steps). The same plant with a transversal switch flies to the end.
#[test]
fn sliding_mode_gets_a_step_collapse_diagnosis() {
    let src = |right: &str| {
        format!(
            "state x, y\ninput u\nx' = if x < 0 then y + 0.5 else {right}\ny' = 0 * u\n\
             period 0.5\nhorizon 1\nactuate u = net[0]\ninit x in [-0.1, 0.1]\n\
             init y in [-0.1, 0.1]\n"
        )
    };
    let sys = System::parse(&src("y - 0.5"), "slide.sys").unwrap();
    let net = |_: &[f64]| vec![0.0];
    let start = std::time::Instant::now();
    let e = fly(&sys, &net, &[-0.1, 0.0], 10).unwrap_err();
    assert!(start.elapsed().as_secs_f64() < 1.0, "{:?}", start.elapsed());
    match &e {
        SimError::StepCollapse {
            t, state, switches, ..
        } => {
            assert!((t - 0.2).abs() < 1e-6, "{e}");
            assert!(state[0].abs() < 1e-6 && state[1] == 0.0, "{e}");
            assert_eq!(
                switches,
                &vec!["slide.sys:3:6: x' = if x < 0 then y + 0.5 else y - 0.5".to_string()]
            );
        }
        _ => panic!("{e}"),
    }
    let msg = e.to_string();
    for needle in [
        "collapsed at t = 0.2",
        "slide.sys:3:6",
        "tanh",
        "hysteresis",
    ] {
        assert!(msg.contains(needle), "{msg}");
    }
    let sys = System::parse(&src("y + 0.25"), "cross.sys").unwrap();
    let f = fly(&sys, &net, &[-0.1, 0.0], 10).unwrap();
    // x' = 0.5 until x = 0 at t = 0.2, then 0.25: x(1) = 0.25 * 0.8 = 0.2.
    assert!((f.states.last().unwrap()[0] - 0.2).abs() < 1e-9);
}

/// Every `if` is recorded for the diagnosis in one pass: a file with 20,000 of them
/// compiles in well under a second (no copy of the long line per `if`), and
/// `switches_at` finds the one that flips at a state (`x = 0.5` flips `if x < 0.5`,
/// the 5,001st) and only it.
#[test]
fn many_switches_compile_in_one_pass() {
    let terms: Vec<String> = (0..20_000)
        .map(|k| format!("(if x < {} then 1 else 0)", k as f64 * 1e-4))
        .collect();
    let src = format!(
        "state x\ninput u\nx' = u + {}\nperiod 1\nhorizon 1\nactuate u = net[0]\ninit x = 0\n",
        terms.join(" + ")
    );
    let start = std::time::Instant::now();
    let sys = System::parse(&src, "many.sys").unwrap();
    assert!(start.elapsed().as_secs_f64() < 1.0, "{:?}", start.elapsed());
    assert_eq!(sys.switches.len(), 20_000);
    let at = sys.switches_at(&[0.5], &[0.0], 1e-9);
    assert_eq!(at.len(), 1);
    assert_eq!(at[0].pos.line, 3);
    // A long line is quoted from the `if` on, not whole.
    assert!(
        at[0].text.starts_with("... if x < 0.5 then 1 else 0"),
        "{}",
        at[0].text
    );
    assert!(at[0].text.len() < 120);
}

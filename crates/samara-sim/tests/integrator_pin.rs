//! Regression pin for the integrator refactor (issue 12, item 4): the single adaptive
//! Runge-Kutta driver must give bit-identical results to the code it replaced.
//!
//! The numbers below are NOT a golden from an independent reference: they were recorded
//! from samara's own integrators *before* the refactor (commit f58c8e8, the separate
//! `dopri.rs`, `dop853.rs` and `ode45.rs` loops) by running this file with
//! `SAMARA_PIN_RECORD=1`, and they pin that the refactored code computes the very same
//! f64 bits (end states as exact bit patterns, every recorded number through an FNV-1a
//! hash of its bits, step statistics exactly).

use samara_plant::{Model, Plant};
use samara_sim::dopri::Tolerances;
use samara_sim::{
    fly, initial_state, ConstantController, Controller, Integrator, LoopSettings, PidController,
};

/// FNV-1a over the bit patterns of `values`.
fn fnv(values: &[f64]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for v in values {
        for b in v.to_bits().to_le_bytes() {
            h ^= b as u64;
            h = h.wrapping_mul(0x0100_0000_01b3);
        }
    }
    h
}

fn bits(values: &[f64]) -> Vec<u64> {
    values.iter().map(|v| v.to_bits()).collect()
}

fn recording() -> bool {
    std::env::var_os("SAMARA_PIN_RECORD").is_some()
}

/// One closed-loop flight: (final state bits, hash of every period-end state and of the
/// dense output, right-hand-side evaluations).
fn flight(model: Model, pid: bool, y0: f64, integrator: Integrator) -> (Vec<u64>, u64, usize) {
    let plant = Plant::new(model);
    let mut ctl: Box<dyn Controller> = if pid {
        Box::new(PidController::default())
    } else {
        Box::new(ConstantController(0.1))
    };
    let settings = LoopSettings {
        horizon: 3.0,
        integrator,
        output_step: Some(0.05),
        ..Default::default()
    };
    let f = fly(&plant, ctl.as_mut(), &initial_state(&plant, y0), &settings).unwrap();
    let mut all: Vec<f64> = f.steps.iter().flat_map(|s| s.state_end.clone()).collect();
    all.extend_from_slice(&f.dense.data);
    (bits(&f.steps.last().unwrap().state_end), fnv(&all), f.evals)
}

type FlightPin = (Model, bool, f64, &'static str, [u64; 7], u64, usize);

fn integrator(name: &str) -> Integrator {
    Integrator::from_name(name).unwrap()
}

const FLIGHTS: &[FlightPin] = &[
    // (model, pid?, y0, integrator, final state bits (padded with 0), hash, evals)
    (
        Model::Plate6,
        true,
        1.4285714285714286,
        "ode45",
        [
            0x4005329624c2855b,
            0xbfc1d4107642cffa,
            0xbfcb53aa8903043f,
            0xbfe92cb34ff2e2a1,
            0x40100eeb0a482b56,
            0xbff9f117fc9fc03e,
            0x3fb0ba463dde75de,
        ],
        0xf5813431a434ca2b,
        480,
    ),
    (
        Model::Plate6,
        true,
        1.4285714285714286,
        "tight",
        [
            0x400532962639d4bb,
            0xbfc1d4106cf0c6d1,
            0xbfcb53aa7fe6675a,
            0xbfe92cb34f7776c6,
            0x40100eeb0b2b57c6,
            0xbff9f1180284461d,
            0x3fb0ba463da3d930,
        ],
        0xf724d88ade766a08,
        716,
    ),
    (
        Model::Plate6,
        true,
        1.4285714285714286,
        "dp5",
        [
            0x40053296263b908f,
            0xbfc1d4106cf05f50,
            0xbfcb53aa7febf756,
            0xbfe92cb34f7f020e,
            0x40100eeb0b2abae7,
            0xbff9f1180289ddf7,
            0x3fb0ba463d9bfdfc,
        ],
        0x97f7995ba1d2f627,
        1176,
    ),
    (
        Model::Reduced,
        true,
        2.857142857142857,
        "ode45",
        [
            0x40049af4f8360b4e,
            0xbfc1d898a5be2240,
            0xbfc75b3f9af053a8,
            0xbfe7591e89b758b8,
            0x40101f0311e0e00b,
            0xbfb07ef757fcbe08,
            0x0,
        ],
        0x55bf86617c5be3f4,
        390,
    ),
    (
        Model::Reduced,
        true,
        2.857142857142857,
        "tight",
        [
            0x40049af4f9cf8468,
            0xbfc1d8989b5d0aec,
            0xbfc75b3f8f9a8380,
            0xbfe7591e8936a5e7,
            0x40101f0312d74d6d,
            0xbfb07ef7bb170f54,
            0x0,
        ],
        0x97ce01bc9055ef4c,
        705,
    ),
    (
        Model::Reduced,
        true,
        2.857142857142857,
        "dp5",
        [
            0x40049af4f9d188e2,
            0xbfc1d8989b5c8e56,
            0xbfc75b3f8fa2ec6f,
            0xbfe7591e893f7d12,
            0x40101f0312d6b20b,
            0xbfb07ef7bb7a8b3b,
            0x0,
        ],
        0x8657ae915b30f91a,
        1152,
    ),
    (
        Model::Full,
        false,
        2.857142857142857,
        "ode45",
        [
            0xbffa395b29932f06,
            0xbfe7dd5e98b9ecf5,
            0x3fef9b22d74f122a,
            0x3fe7e91bb534d931,
            0x3ff5f5b4621d27cc,
            0x3ff4bd0695a44da6,
            0x3fa2753beea077ee,
        ],
        0x49ca36c3a65e4c51,
        480,
    ),
    (
        Model::Full,
        false,
        2.857142857142857,
        "tight",
        [
            0xbffa38e329b6538e,
            0xbfe7dd5d751993ef,
            0x3fef9a0a6dc580fc,
            0x3fe7e87f7c6b8ba8,
            0x3ff5f5b16cd80d58,
            0x3ff4bd284f3eefe4,
            0x3fa2757db820eef3,
        ],
        0xbd07bbe38c0f923e,
        1069,
    ),
    (
        Model::Full,
        false,
        2.857142857142857,
        "dp5",
        [
            0xbffa38e3292b2fac,
            0xbfe7dd5d751571fe,
            0x3fef9a0a6c7b66e8,
            0x3fe7e87f7bba2a85,
            0x3ff5f5b16cde0f54,
            0x3ff4bd284f68a3d9,
            0x3fa2757db879431b,
        ],
        0xfb2a0ec4e12a59e7,
        1338,
    ),
];

#[test]
fn closed_loop_flights_are_bit_identical_to_the_pre_refactor_integrators() {
    let cases: Vec<(Model, bool, f64, &str)> = [Model::Plate6, Model::Reduced, Model::Full]
        .into_iter()
        .flat_map(|m| {
            ["ode45", "tight", "dp5"].into_iter().map(move |i| {
                (
                    m,
                    m != Model::Full,
                    if m == Model::Plate6 {
                        0.1 / 0.07
                    } else {
                        0.2 / 0.07
                    },
                    i,
                )
            })
        })
        .collect();
    if recording() {
        for (m, pid, y0, i) in &cases {
            let (b, h, e) = flight(*m, *pid, *y0, integrator(i));
            let mut p = [0u64; 7];
            p[..b.len()].copy_from_slice(&b);
            println!("    (Model::{m:?}, {pid}, {y0:?}, {i:?}, {p:#x?}, {h:#x}, {e}),");
        }
        return;
    }
    assert_eq!(FLIGHTS.len(), cases.len());
    for &(m, pid, y0, i, want_bits, want_hash, want_evals) in FLIGHTS {
        let (b, h, e) = flight(m, pid, y0, integrator(i));
        assert_eq!(b, want_bits[..b.len()], "{m:?} {i} final state");
        assert_eq!(h, want_hash, "{m:?} {i} trajectory hash");
        assert_eq!(e, want_evals, "{m:?} {i} evaluations");
    }
}

/// Direct calls of the public integrator functions (step statistics, continuation step,
/// dense output, a backward dp5 integration and a NaN right-hand side).
fn direct() -> Vec<(&'static str, usize, usize, usize, u64, u64)> {
    let plant = Plant::new(Model::Plate6);
    let rhs = |y: &[f64], d: &mut [f64]| plant.rhs(y, &0.05, d);
    let y0 = initial_state(&plant, 2.0);
    let times: Vec<f64> = (0..=20).map(|i| i as f64 * 0.05).collect();
    let tol = Tolerances::default();
    let mut rows = Vec::new();
    let mut push = |name, s: samara_sim::ode45::Stats, y: &[f64], out: &[f64]| {
        let mut all = y.to_vec();
        all.extend_from_slice(out);
        rows.push((
            name,
            s.accepted,
            s.rejected,
            s.evals,
            s.h_next.to_bits(),
            fnv(&all),
        ));
    };
    let (mut y, mut out) = (y0.clone(), Vec::new());
    let s = samara_sim::ode45::integrate(rhs, &mut y, &times, &Default::default(), Some(&mut out));
    push("ode45", s, &y, &out);
    let (mut y, mut out) = (y0.clone(), Vec::new());
    let s = samara_sim::dopri::integrate(rhs, &mut y, 0.0, 1.0, tol, &times, Some(&mut out));
    push("dp5", s, &y, &out);
    let (mut y, mut out) = (y0.clone(), Vec::new());
    let s = samara_sim::dopri::integrate(rhs, &mut y, 1.0, 0.0, tol, &[], Some(&mut out));
    push("dp5 backward", s, &y, &out);
    let (mut y, mut out) = (y0.clone(), Vec::new());
    let s = samara_sim::dop853::integrate(rhs, &mut y, 0.0, 1.0, tol, &times, Some(&mut out));
    push("dop853", s, &y, &out);
    let (mut y, mut out) = (y0.clone(), Vec::new());
    let s = samara_sim::dop853::integrate_from(
        rhs,
        &mut y,
        0.0,
        1.0,
        tol,
        Some(0.3),
        &times,
        Some(&mut out),
    );
    push("dop853 from 0.3", s, &y, &out);
    let loose = Tolerances {
        rtol: 1e-4,
        atol: 1e-6,
    };
    let (mut y, mut out) = (y0.clone(), Vec::new());
    let s = samara_sim::dop853::integrate(rhs, &mut y, 0.0, 1.0, loose, &times, Some(&mut out));
    push("dop853 loose", s, &y, &out);
    let (mut y, mut out) = (y0.clone(), Vec::new());
    let s = samara_sim::dopri::integrate(rhs, &mut y, 0.0, 1.0, loose, &times, Some(&mut out));
    push("dp5 loose", s, &y, &out);
    let nan_after = |y: &[f64], d: &mut [f64]| {
        for (di, yi) in d.iter_mut().zip(y) {
            *di = if *yi > 1.2 { f64::NAN } else { 1.0 };
        }
    };
    let nt = [0.0, 0.25, 0.5];
    let mut y = [1.0, 1.0];
    let s = samara_sim::dopri::integrate(nan_after, &mut y, 0.0, 0.5, tol, &nt, None);
    push("dp5 nan", s, &y, &[]);
    let mut y = [1.0, 1.0];
    let s = samara_sim::dop853::integrate(nan_after, &mut y, 0.0, 0.5, tol, &nt, None);
    push("dop853 nan", s, &y, &[]);
    let mut y = [1.0, 1.0];
    let s = samara_sim::ode45::integrate(nan_after, &mut y, &nt, &Default::default(), None);
    push("ode45 nan", s, &y, &[]);
    rows
}

const DIRECT: &[(&str, usize, usize, usize, u64, u64)] = &[
    // (call, accepted, rejected, evals, h_next bits, hash of end state and outputs)
    ("ode45", 14, 0, 85, 0x0, 0xa2f047133cf89481),
    ("dp5", 72, 0, 433, 0x0, 0x7d135b01733191b7),
    // Backward, the glider's flight ends NaN either way; since issue 35 the step
    // control stops it as collapsed after 1,000 steps in a row shorter than 1e-7 of
    // the span (explicit_rk::COLLAPSE_STEPS) instead of after 13,989 accepted steps
    // (same end state, fewer steps).
    ("dp5 backward", 1652, 51, 10219, 0x0, 0x57a42b45591720d0),
    ("dop853", 21, 5, 308, 0x3fb0c15b77b66700, 0x82abadf9f26e1986),
    (
        "dop853 from 0.3",
        18,
        7,
        294,
        0x3fb0d48d92e6b5dc,
        0x339d0cebe602df91,
    ),
    (
        "dop853 loose",
        7,
        0,
        85,
        0x3fdcb5e6fae84d93,
        0xab5e2fe37521d44f,
    ),
    ("dp5 loose", 8, 0, 49, 0x0, 0x3090d435bc9220b5),
    ("dp5 nan", 44, 44, 529, 0x0, 0x34dbfdf4b9875c55),
    (
        "dop853 nan",
        3,
        0,
        37,
        0x3fe1eb44bfda0441,
        0x34dbfdf4b9875c55,
    ),
    ("ode45 nan", 10, 0, 61, 0x0, 0x34dbfdf4b9875c55),
];

#[test]
fn direct_integrations_are_bit_identical_to_the_pre_refactor_integrators() {
    let got = direct();
    if recording() {
        for (n, a, r, e, h, x) in &got {
            println!("    ({n:?}, {a}, {r}, {e}, {h:#x}, {x:#x}),");
        }
        return;
    }
    assert_eq!(got.len(), DIRECT.len());
    for (g, w) in got.iter().zip(DIRECT) {
        // The one intended difference: the old DP5(4) loop reported no continuation step
        // (`h_next` 0, "not provided"); the shared standard control now proposes one
        // for both pairs. Everything else, states and outputs included, is unchanged.
        let h_next = if w.4 == 0 { 0 } else { g.4 };
        assert_eq!((g.0, g.1, g.2, g.3, h_next, g.5), *w, "{}", w.0);
    }
}

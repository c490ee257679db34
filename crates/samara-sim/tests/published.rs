//! The published training data are the independent reference here: they were produced
//! by the authors' MATLAB code (ode45), not by samara.

use samara_testkit as support;

use samara_plant::{Model, Plant};
use samara_sim::{
    fly, initial_state, published_starts, training_rows, Integrator, LoopSettings, PidController,
};

fn reference() -> Vec<[f64; 7]> {
    let text = std::fs::read_to_string(support::reference("Training_Data.csv")).unwrap();
    text.lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.trim().parse().unwrap()).collect();
            [v[0], v[1], v[2], v[3], v[4], v[5], v[6]]
        })
        .collect()
}

fn max_dev(integrator: Integrator) -> f64 {
    let plant = Plant::new(Model::Plate6);
    let settings = LoopSettings {
        integrator,
        output_step: None,
        ..Default::default()
    };
    let flights: Vec<_> = published_starts()
        .into_iter()
        .map(|y0| {
            fly(
                &plant,
                &mut PidController::default(),
                &initial_state(&plant, y0),
                &settings,
            )
            .unwrap()
        })
        .collect();
    let rows = training_rows(&flights);
    let refr = reference();
    assert_eq!(rows.len(), refr.len());
    let mut cols = [0.0f64; 7];
    for (a, b) in rows.iter().zip(&refr) {
        for j in 0..7 {
            cols[j] = cols[j].max((a[j] - b[j]).abs());
        }
    }
    eprintln!("per column {cols:?}");
    let mut dev = 0.0f64;
    for (a, b) in rows.iter().zip(&refr) {
        for j in 0..7 {
            dev = dev.max((a[j] - b[j]).abs());
        }
    }
    dev
}

#[test]
fn ode45_mode_reproduces_published_data_to_1e_12() {
    let d = max_dev(Integrator::Ode45);
    eprintln!("ode45 max abs deviation {d:e}");
    assert!(d <= 1e-12, "max deviation {d:e}");
}

#[test]
fn dp5_tight_mode_reproduces_published_data_to_1e_7() {
    let d = max_dev(Integrator::Dp5(Default::default()));
    assert!(d <= 1e-7, "max deviation {d:e}");
}

#[test]
fn dop853_mode_reproduces_published_data_to_1e_7() {
    let d = max_dev(Integrator::Dop853(Default::default()));
    eprintln!("dop853 (tight) max abs deviation {d:e}");
    assert!(d <= 1e-7, "max deviation {d:e}");
}

//! Training on the published data (../shared/reference/Training_Data.csv, produced by the
//! authors' MATLAB PID simulation): accuracy, determinism, the Lipschitz trade-off, and
//! the trained controller flown in samara's closed loop.

use samara_plant::{Model, Plant};
use samara_sim::{fly, initial_state, published_starts, LoopSettings, NetworkController};
use samara_train::{read_table, train, Method, MinMax, TrainOptions};

fn data() -> samara_train::Table {
    read_table(&samara_testkit::reference("Training_Data.csv")).unwrap()
}

#[test]
fn plain_training_reaches_r2_0_9_and_flies_along_the_line() {
    let d = data();
    let out = train(&d, None, &TrainOptions::default()).unwrap();
    eprintln!("plain: {:?}", out.metrics);
    assert!(out.metrics.r2 >= 0.9, "R^2 {}", out.metrics.r2);
    assert_eq!(out.metrics.n_test, 36);
    // Fly it (raw units, clipped as the published simulation).
    let plant = Plant::new(Model::Plate6);
    let mut ctl = NetworkController::new(out.network.clone(), Some((0.181, 0.193)), "plain");
    let settings = LoopSettings {
        output_step: None,
        ..Default::default()
    };
    let mut worst = 0.0f64;
    for y0 in published_starts() {
        let f = fly(&plant, &mut ctl, &initial_state(&plant, y0), &settings).unwrap();
        let s = &f.steps.last().unwrap().state_end;
        eprintln!("y0 {y0:.4}: x + y at t = 20 is {:.4}", s[4] + s[5]);
        worst = worst.max((s[4] + s[5]).abs());
    }
    // "Follows the line": over 20 time units the glider travels about 40 chords along
    // it. Holding any constant ex in [0.181, 0.193] drifts 15 to 27 chords off the line;
    // the PID that made the data ends within 0.6, the published networks within about
    // 2.1 (docs/model.md). The learned controller must stay within 4 chords and beat the
    // best constant input by a factor of 4.
    let best_constant = [0.181, 0.187, 0.193]
        .iter()
        .map(|&ex| {
            published_starts()
                .into_iter()
                .map(|y0| {
                    let f = fly(
                        &plant,
                        &mut samara_sim::ConstantController(ex),
                        &initial_state(&plant, y0),
                        &settings,
                    )
                    .unwrap();
                    let s = &f.steps.last().unwrap().state_end;
                    (s[4] + s[5]).abs()
                })
                .fold(0.0, f64::max)
        })
        .fold(f64::INFINITY, f64::min);
    eprintln!("worst final |x + y|: network {worst:.3}, best constant input {best_constant:.3}");
    assert!(
        worst < 4.0 && worst < 0.25 * best_constant,
        "worst final |x + y| = {worst}"
    );
}

#[test]
fn same_seed_same_data_gives_bit_identical_networks() {
    let d = data();
    let o = TrainOptions {
        epochs: 30,
        ..Default::default()
    };
    let a = train(&d, None, &o).unwrap();
    let b = train(&d, None, &o).unwrap();
    assert_eq!(a.network, b.network);
    let c = train(&d, None, &TrainOptions { seed: 1, ..o }).unwrap();
    assert_ne!(a.network, c.network);
}

#[test]
fn lipschitz_penalty_reduces_the_worst_attack_deviation() {
    let d = data();
    let mm = MinMax::of(&d);
    let plain = train(&d, Some(&mm), &TrainOptions::default()).unwrap();
    let lip = train(
        &d,
        Some(&mm),
        &TrainOptions {
            method: Method::Lipschitz {
                l: 0.5,
                weight: 10.0,
            },
            ..Default::default()
        },
    )
    .unwrap();
    eprintln!(
        "plain: R^2 {:.4} worst {:.3e}; lipschitz: R^2 {:.4} worst {:.3e}",
        plain.metrics.r2, plain.metrics.attack_worst, lip.metrics.r2, lip.metrics.attack_worst
    );
    assert!(lip.metrics.attack_worst < 0.5 * plain.metrics.attack_worst);
}

/// The case study's wide property-trained networks (6-64-32-1, linear output, Goedel
/// logic plus a Lipschitz penalty: `goedel_lipschitz_norm.onnx`): the added penalty is
/// really applied (a smaller worst attack deviation than the same Goedel training
/// without it), and the output layer has no ReLU.
#[test]
fn goedel_with_a_lipschitz_penalty_trains_a_smoother_linear_output_network() {
    let d = data();
    let mm = MinMax::of(&d);
    let spec = samara_train::case_study_spec();
    let mut b = samara_spec::Bindings::default();
    b.params.insert("ystar".into(), 2.0);
    let names: Vec<String> = ["p1", "p2", "p3", "p4"].map(String::from).to_vec();
    let props = samara_train::property::spec_properties(&spec, &names, &b, &mm, None).unwrap();
    let base = TrainOptions {
        arch: vec![6, 64, 32, 1],
        relu_output: false,
        epochs: 60,
        lr: 0.005,
        method: Method::Properties {
            logic: samara_train::Logic::Goedel,
            props,
            weight: 1.0,
        },
        ..Default::default()
    };
    let goedel = train(&d, Some(&mm), &base).unwrap();
    let lip = train(
        &d,
        Some(&mm),
        &TrainOptions {
            lipschitz: Some((0.5, 10.0)),
            ..base.clone()
        },
    )
    .unwrap();
    eprintln!(
        "goedel: R^2 {:.4} worst {:.3e}; goedel + lipschitz: R^2 {:.4} worst {:.3e}",
        goedel.metrics.r2, goedel.metrics.attack_worst, lip.metrics.r2, lip.metrics.attack_worst
    );
    assert!(lip.metrics.attack_worst < goedel.metrics.attack_worst);
    // Linear output: the last layer is affine, not followed by an activation.
    assert!(matches!(
        lip.network.layers.last(),
        Some(samara_nn::Layer::Affine(_))
    ));
    assert_eq!(lip.network.n_inputs(), 6);
}

#[test]
fn published_constants_file_is_understood() {
    let d = data();
    let mm = MinMax::read(&samara_testkit::reference("Normalisation_Constants.csv")).unwrap();
    assert_eq!(mm.min.len(), 7);
    assert_eq!((mm.min[6], mm.range[6]), (0.181, 0.012));
    let out = train(
        &d,
        Some(&mm),
        &TrainOptions {
            epochs: 50,
            ..Default::default()
        },
    )
    .unwrap();
    let den = out.network.output_denorm.as_ref().unwrap();
    assert_eq!((den.b[0], den.weight(0, 0)), (0.181, 0.012));
}

#[test]
fn wrong_shapes_and_settings_are_errors() {
    let d = data();
    let e = train(
        &d,
        None,
        &TrainOptions {
            arch: vec![5, 4, 1],
            ..Default::default()
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("needs 6"), "{e}");
    assert!(train(
        &d,
        None,
        &TrainOptions {
            epochs: 0,
            ..Default::default()
        }
    )
    .is_err());
    assert!(train(
        &d,
        None,
        &TrainOptions {
            lr: f64::NAN,
            ..Default::default()
        }
    )
    .is_err());
}

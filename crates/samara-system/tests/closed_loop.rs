//! The system-file closed loop against the built-in one (samara-sim's `fly` on
//! `samara_plant::Plant`, an independent code path for the equations and the loop): the
//! Alsomitra reduced model as a system file, flown under a published network, gives the
//! built-in model's states at every control instant.

use samara_sim::{fly, Integrator, LoopSettings, NetworkController, Tolerances};
use samara_system::sim;
use samara_system::System;
use std::path::Path;

use reference_files::reference;
use samara_testkit as reference_files;

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn alsomitra_system_file_flies_like_the_built_in_model() {
    let path = reference("base_model_denorm.onnx");
    let net = samara_nn::onnx::load(&path).unwrap();
    let sys =
        System::from_file(&root().join("../../examples/archcomp/alsomitra_reduced.sys")).unwrap();
    let plant = samara_plant::Plant::new(samara_plant::Model::Reduced);
    let settings = LoopSettings {
        integrator: Integrator::Dop853(Tolerances::default()),
        output_step: None,
        ..Default::default()
    };
    for y0 in [0.1 / 0.07, 0.2 / 0.07, 0.3 / 0.07] {
        let mut ctl = NetworkController::new(net.clone(), None, "base");
        let x0 = vec![1.0, 0.0, 0.0, 0.0, 0.0, y0];
        let built_in = fly(&plant, &mut ctl, &x0, &settings).unwrap();
        let f = sim::fly(&sys, &|o: &[f64]| net.eval_f64(o), &x0, 1).unwrap();
        assert_eq!(f.states.len(), built_in.steps.len() + 1);
        for (k, st) in built_in.steps.iter().enumerate() {
            assert!((f.t[k + 1] - st.t_end).abs() < 1e-12);
            for (a, b) in f.states[k + 1].iter().zip(&st.state_end) {
                assert!(
                    (a - b).abs() <= 1e-9 * (1.0 + b.abs()),
                    "y0 {y0} t {}: {a} vs {b}",
                    st.t_end
                );
            }
            // The input held over the period that ends at row k + 1.
            assert!((f.inputs[k + 1][0] - st.ex).abs() <= 1e-12 * (1.0 + st.ex.abs()));
        }
        // The file's goal |x + y| <= 2 at the end against the built-in final state.
        let end = &built_in.steps.last().unwrap().state_end;
        assert_eq!(
            sim::goals_hold(&sys, &f),
            vec![(end[4] + end[5]).abs() <= 2.0]
        );
    }
}

#[test]
fn wrong_network_width_and_state_count_are_errors() {
    let sys = System::from_file(&root().join("../../examples/archcomp/tora.sys")).unwrap();
    let e = sim::fly(&sys, &|_o: &[f64]| vec![], &[0.0; 4], 1).unwrap_err();
    assert!(e.to_string().contains("outputs"), "{e}");
    let e = sim::fly(&sys, &|_o: &[f64]| vec![0.0], &[0.0; 3], 1).unwrap_err();
    assert!(e.to_string().contains("4 states"), "{e}");
}

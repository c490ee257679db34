//! Closed-loop flights of all three variants against scipy (solve_ivp DOP853 at rtol
//! 1e-12, atol 1e-14) on an independent Python implementation of docs/model.md
//! (bench/model_reference/make_golden.py).

use samara_plant::{Model, Plant};
use samara_sim::{
    fly, initial_state, ConstantController, Controller, Integrator, LoopSettings, PidController,
};

#[test]
fn flights_match_scipy_on_the_python_model() {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/flight_reference.json"
    ))
    .unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let flights = v["flights"].as_array().unwrap();
    assert_eq!(flights.len(), 10);
    for f in flights {
        let model = Model::from_name(f["model"].as_str().unwrap()).unwrap();
        let plant = Plant::new(model);
        let y0 = f["y0"].as_f64().unwrap();
        let mut ctl: Box<dyn Controller> = match f["controller"].as_str() {
            Some("pid") => Box::new(PidController::default()),
            _ => Box::new(ConstantController(f["controller"].as_f64().unwrap())),
        };
        let settings = LoopSettings {
            integrator: Integrator::Dop853(Default::default()),
            output_step: None,
            ..Default::default()
        };
        let flight = fly(&plant, ctl.as_mut(), &initial_state(&plant, y0), &settings).unwrap();
        let want = f["states"].as_array().unwrap();
        let mut worst = 0.0f64;
        for (step, w) in flight.steps.iter().zip(want) {
            for (g, w) in step.state_end.iter().zip(w.as_array().unwrap()) {
                worst = worst.max((g - w.as_f64().unwrap()).abs());
            }
        }
        eprintln!(
            "{} {} y0 {y0:.4}: max |samara tight - scipy| = {worst:.2e}",
            model.name(),
            f["controller"]
        );
        // samara's tight mode (rtol 1e-10) against scipy at rtol 1e-12 over 40 periods.
        assert!(worst < 1e-6, "{model:?}: {worst:e}");
    }
}

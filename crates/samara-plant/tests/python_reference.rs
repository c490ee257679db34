//! The three variants against an independent implementation of docs/model.md in Python
//! (bench/model_reference/alsomitra.py; golden file written by make_golden.py).

use samara_plant::{Model, Plant};

#[test]
fn right_hand_sides_match_the_python_model() {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/rhs_reference.json"
    ))
    .unwrap();
    let v: serde_json::Value = serde_json::from_str(&text).unwrap();
    let mut n = 0;
    for model in Model::ALL {
        let plant = Plant::new(model);
        let cases = v["cases"][model.name()].as_array().unwrap();
        assert_eq!(cases.len(), 30);
        for c in cases {
            let s: Vec<f64> = c["state"]
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap())
                .collect();
            let ex = c["ex"].as_f64().unwrap();
            let want: Vec<f64> = c["rhs"]
                .as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap())
                .collect();
            let mut got = vec![0.0; plant.dim()];
            plant.rhs(&s, &ex, &mut got);
            for (i, (g, w)) in got.iter().zip(&want).enumerate() {
                assert!(
                    (g - w).abs() <= 1e-12 * (1.0 + w.abs()),
                    "{model:?} state {s:?} component {i}: {g} vs {w}"
                );
            }
            n += 1;
        }
    }
    assert_eq!(n, 90);
}

//! P1-P4 of models/alsomitra/alsomitra.spec as training properties: lowered in the
//! trainer's units, each is one property whose region and formula are those of the
//! published statement (checked against the thresholds written out by hand below, an
//! independent reading of the paper's P1-P4), and editing the spec moves them.

use samara_spec::{Bindings, Spec};
use samara_train::{case_study_spec, spec_properties, Formula, MinMax, CASE_STUDY_SPEC};

fn units() -> MinMax {
    // Arbitrary min-max units (not the spec's) to show the lowering uses the trainer's.
    MinMax {
        min: vec![1.0, -0.6, -0.4, -1.0, 0.0, -42.0, 0.18],
        range: vec![2.5, 0.6, 0.5, 1.0, 42.0, 46.0, 0.01],
    }
}

fn props(spec: &Spec) -> Vec<samara_train::Property> {
    spec_properties(
        spec,
        &["p1", "p2", "p3", "p4"].map(String::from),
        &Bindings::default(),
        &units(),
        None,
    )
    .unwrap()
}

/// Raw x + y of a normalised point.
fn xy(mm: &MinMax, z: &[f64]) -> f64 {
    mm.min[4] + mm.range[4] * z[4] + mm.min[5] + mm.range[5] * z[5]
}

#[test]
fn case_study_properties_state_the_published_thresholds() {
    let mm = units();
    let p = props(&case_study_spec());
    assert_eq!(
        p.iter().map(|p| p.name.as_str()).collect::<Vec<_>>(),
        ["p1", "p2", "p3", "p4"]
    );
    let out = |e: f64| (e - mm.min[6]) / mm.range[6];
    // Points inside the box, on either side of the bands' edges (ystar = 2).
    let mut z = vec![0.5; 6];
    z[3] = (-0.76 - mm.min[3]) / mm.range[3]; // theta in P3's range
    z[2] = (-0.2 - mm.min[2]) / mm.range[2]; // omega <= -0.12
    z[1] = (-0.4 - mm.min[1]) / mm.range[1]; // v_yp <= -0.3
    let at = |target: f64| {
        let mut z = z.clone();
        z[5] = (target - mm.min[4] - mm.range[4] * z[4] - mm.min[5]) / mm.range[5];
        z
    };
    for (name, x_plus_y, inside) in [
        ("p1", 2.5, true),
        ("p1", 1.5, false),
        ("p2", -2.5, true),
        ("p2", -1.5, false),
        ("p3", 1.9, true),
        ("p3", -1.9, true),
        ("p3", 2.1, false),
        ("p4", 1.9, true),
        ("p4", -0.1, false),
        ("p4", 2.1, false),
    ] {
        let q = p.iter().find(|p| p.name == name).unwrap();
        let zz = at(x_plus_y);
        assert!((xy(&mm, &zz) - x_plus_y).abs() < 1e-9);
        assert_eq!(
            q.region.contains(&zz, 0.0),
            inside,
            "{name} at x + y = {x_plus_y}"
        );
    }
    // The output thresholds, in raw ex.
    let holds = |name: &str, e: f64| {
        p.iter()
            .find(|p| p.name == name)
            .unwrap()
            .formula
            .holds(out(e))
    };
    assert!(holds("p1", 0.1871) && !holds("p1", 0.1869));
    assert!(holds("p2", 0.1869) && !holds("p2", 0.1871));
    assert!(holds("p3", 0.187) && !holds("p3", 0.1839) && !holds("p3", 0.1901));
    assert!(holds("p4", 0.1869) && !holds("p4", 0.1871));
    assert!(matches!(p[2].formula, Formula::And(_)));
}

#[test]
fn editing_the_spec_moves_the_training_properties() {
    let mm = units();
    let edited = CASE_STUDY_SPEC.replace("=> ex >= 0.187", "=> ex >= 0.2");
    assert_ne!(edited, CASE_STUDY_SPEC);
    let spec = Spec::parse(&edited, "edited.spec", std::path::Path::new(".")).unwrap();
    let p = props(&spec);
    let out = |e: f64| (e - mm.min[6]) / mm.range[6];
    assert!(!p[0].formula.holds(out(0.19)) && p[0].formula.holds(out(0.2001)));
    // ystar bound from outside moves the band.
    let mut b = Bindings::default();
    b.params.insert("ystar".into(), 5.0);
    let p5 = spec_properties(&case_study_spec(), &["p1".into()], &b, &mm, None).unwrap();
    let band = p5[0].region.band.clone().unwrap();
    let band2 = props(&case_study_spec())[0].region.band.clone().unwrap();
    assert!(
        (band.1 - band2.1 - 3.0).abs() < 1e-9,
        "{band:?} vs {band2:?}"
    );
}

/// Issue 12: the closed loop of the reachability stage comes from the spec too. The
/// shipped loop gives closed-loop training's published case (written out in
/// `CegisOptions::default`: y0 in [0.1/0.07, 0.3/0.07], goal 2 at t = 20, training
/// bound 1.25, period 0.5, clip [0.181, 0.193]) and the reach settings of the
/// published CORA setting (`ReachSettings::published`), bit for bit; a loop training
/// cannot fly is refused with its name.
#[test]
fn the_shipped_loop_is_the_published_closed_loop_case() {
    use samara_train::cegis::CegisOptions;
    let spec = case_study_spec();
    let lp = spec
        .closed_loop("published")
        .expect("the shipped spec states its loop");
    let o = CegisOptions::from_loop(lp).unwrap();
    let d = CegisOptions::default();
    assert_eq!(o.y0, d.y0);
    assert_eq!(o.goal, d.goal);
    assert_eq!(o.loss.bound, d.loss.bound);
    assert_eq!(o.loss.from, d.loss.from);
    assert_eq!(
        (o.loss.horizon, o.loss.period),
        (d.loss.horizon, d.loss.period)
    );
    assert_eq!(o.loss.clip, d.loss.clip);
    let r = samara_reach::ReachSettings::from_loop(lp);
    let p = samara_reach::ReachSettings::published(samara_plant::Model::Reduced);
    assert_eq!(r.model, p.model);
    assert_eq!(r.init, p.init);
    assert_eq!((r.period, r.horizon, r.clip), (p.period, p.horizon, p.clip));
    assert_eq!(
        r.goal,
        Some(samara_reach::Goal {
            ystar: 2.0,
            from: None
        })
    );
    let full = CASE_STUDY_SPEC.replace("model reduced, period 0.5", "model full, period 0.5");
    let spec = Spec::parse(&full, "full.spec", std::path::Path::new(".")).unwrap();
    let e = CegisOptions::from_loop(&spec.loops[0])
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("loop `published`") && e.contains("model reduced"),
        "{e}"
    );
}

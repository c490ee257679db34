//! The `loop`, `start` and `goal` statements (issue 12: the closed loop of the
//! reachability stage stated in the spec): the shipped spec's loop against the published
//! setting as the paper states it (reduced model, start (1, 0, 0, 0, 0, y0) with y0 in
//! [0.1/0.07, 0.3/0.07], period 0.5, horizon 20, clip [0.181, 0.193], goal |x + y| <= 2
//! at t = 20), and every mistake named with file:line:column and a fix.

use samara_spec::Spec;
use samara_system::plate::Variant;
use std::path::Path;

fn shipped() -> Spec {
    Spec::read(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models/alsomitra/alsomitra.spec"))
        .unwrap()
}

#[test]
fn the_shipped_loop_is_the_published_setting() {
    let spec = shipped();
    assert_eq!(spec.loops.len(), 1);
    let l = spec.closed_loop("published").unwrap();
    assert_eq!(l.net, "f");
    assert_eq!(l.model, Variant::Reduced);
    assert_eq!((l.period, l.horizon), (0.5, 20.0));
    assert_eq!(l.clip, Some((0.181, 0.193)));
    // Bit for bit: the spec's decimals are the shortest ones of these two quotients.
    let want = [
        (1.0, 1.0),
        (0.0, 0.0),
        (0.0, 0.0),
        (0.0, 0.0),
        (0.0, 0.0),
        (0.1 / 0.07, 0.3 / 0.07),
    ];
    assert_eq!(l.start, want);
    let g = l.goal.as_ref().unwrap();
    assert_eq!((g.bound, g.from), (2.0, None));
}

/// The loop lowers to a system file: the shipped `alsomitra_reduced.sys` (which states
/// the published setting itself, as the paper does) has the same states, period,
/// horizon and initial set, and the loop's clip and no goals of its own.
#[test]
fn the_shipped_loop_lowers_to_the_shipped_system_file() {
    let spec = shipped();
    let sys = spec.closed_loop("published").unwrap().system();
    let file = samara_system::System::from_file(
        &Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../examples/archcomp/alsomitra_reduced.sys"),
    )
    .unwrap();
    assert_eq!(sys.states, file.states);
    assert_eq!(sys.inputs, ["ex"]);
    assert_eq!((sys.period, sys.horizon), (file.period, file.horizon));
    assert_eq!(sys.init, file.init);
    assert_eq!(sys.clips, [Some((0.181, 0.193))]);
    assert!(sys.goals.is_empty());
    assert!(sys.fits_controller(6, 1));
    // A full-model loop: seven states, the filter state at rest.
    let s = parse(&format!("{LOOP}{START}")).unwrap();
    let sys = s.loops[0].system();
    assert_eq!(sys.states.len(), 7);
    assert_eq!(sys.init[6], (0.0, 0.0));
    assert_eq!(
        (sys.period, sys.horizon, sys.clips.clone()),
        (0.25, 1.0, vec![None])
    );
}

const HEAD: &str = "network f(v_xp, v_yp, omega, theta, x, y) -> (ex)\n";

fn parse(body: &str) -> Result<Spec, String> {
    Spec::parse(&format!("{HEAD}{body}"), "t.spec", Path::new(".")).map_err(|e| e.to_string())
}

fn err(body: &str) -> String {
    parse(body).unwrap_err()
}

const LOOP: &str = "loop l of f: model full, period 0.25, horizon 1\n";
const START: &str = "start l: v_xp = 1, v_yp = 0, omega = 0, theta = 0, x = 0, y in [2, 3]\n";

#[test]
fn a_loop_of_the_full_model_starts_its_filter_at_zero_and_takes_a_window_goal() {
    let s = parse(&format!("{LOOP}{START}goal l: |y + x| <= 1.5 from 0.5\n")).unwrap();
    let l = &s.loops[0];
    assert_eq!(l.model, Variant::Full);
    assert_eq!(l.start.len(), 7);
    assert_eq!(l.start[6], (0.0, 0.0));
    assert_eq!(l.start[5], (2.0, 3.0));
    assert_eq!(l.clip, None);
    let g = l.goal.as_ref().unwrap();
    assert_eq!((g.bound, g.from), (1.5, Some(0.5)));
    // A loop need not have a goal (reach then reports sets without a verdict).
    assert!(parse(&format!("{LOOP}{START}")).unwrap().loops[0]
        .goal
        .is_none());
}

#[test]
fn loop_mistakes_name_the_place_and_the_fix() {
    let cases: Vec<(String, &[&str])> = vec![
        (
            "loop l of f: model reducd, period 0.5, horizon 20\n".into(),
            &[
                "t.spec:2:14",
                "unknown model `reducd`",
                "plate6, reduced, full",
            ],
        ),
        (
            "loop l of g: model reduced, period 0.5, horizon 20\n".into(),
            &["t.spec:2:1", "unknown network `g`", "did you mean `f`?"],
        ),
        (
            "loop l of f: model reduced, period 0.5, horizon 20, step 0.1\n".into(),
            &[
                "t.spec:2:53",
                "unknown clause `step`",
                "model, period, horizon and clip",
            ],
        ),
        (
            "loop l of f: model reduced, period 0.3, horizon 1\n".into(),
            &[
                "t.spec:2:1",
                "horizon 1 is not a multiple of the period 0.3",
            ],
        ),
        (
            "loop l of f: model reduced, period 0.5\n".into(),
            &["t.spec:2:1", "loop `l` has no horizon"],
        ),
        (
            "loop l of f: model reduced, period -1, horizon 1\n".into(),
            &["t.spec:2:29", "period -1 must be a positive number"],
        ),
        (
            "loop l of f: model reduced, model full, period 1, horizon 1\n".into(),
            &["t.spec:2:29", "clause `model` is given twice"],
        ),
        (
            "loop l of f: model reduced, period 1, horizon 1, clip u in [0, 1]\n".into(),
            &[
                "t.spec:2:50",
                "`u` is not an output of network `f`",
                "outputs of `f`: ex",
            ],
        ),
        (
            "loop l of f: model reduced, period 1, horizon 1\n".into(),
            &["t.spec:2:1", "loop `l` has no initial set", "add `start l:"],
        ),
        (
            format!(
                "{LOOP}start l: v_xp = 1, v_yp = 0, omega = 0, theta = 0, x = 0, yy in [2, 3]\n"
            ),
            &[
                "t.spec:3:59",
                "`yy` is not a state of the full model",
                "did you mean `y`?",
            ],
        ),
        (
            format!("{LOOP}start l: v_xp = 1, y in [2, 3]\n"),
            &["t.spec:3:1", "leaves out v_yp, omega, theta, x"],
        ),
        (
            format!(
                "{LOOP}start l: v_xp = 1, v_yp = 0, omega = 0, theta = 0, x = 0, y in [3, 2]\n"
            ),
            &["t.spec:3:59", "initial interval [3, 2] of `y` is empty"],
        ),
        (
            format!("{LOOP}start m: v_xp = 1\n"),
            &["t.spec:3:1", "unknown loop `m`", "did you mean `l`?"],
        ),
        (
            format!("{LOOP}{START}goal l: |x - y| <= 2 at 1\n"),
            &[
                "t.spec:4:1",
                "bounds |x + y|",
                "goal NAME: |x + y| <= 2 at 20",
            ],
        ),
        (
            format!("{LOOP}{START}goal l: |x + y| <= 2 at 20\n"),
            &[
                "t.spec:4:1",
                "decided at the horizon 1, not at 20",
                "write `at 1`",
            ],
        ),
        (
            format!("{LOOP}{START}goal l: |x + y| <= 2 from 3\n"),
            &["t.spec:4:1", "window starts at 3, outside [0, 1]"],
        ),
        (
            format!("{LOOP}{START}goal l: |x + y| <= 2\n"),
            &["t.spec:4:21", "expected `at`"],
        ),
        (
            "network g(a, b) -> (u)\nloop l of g: model reduced, period 1, horizon 1\n".into(),
            &[
                "t.spec:3:1",
                "network `g` reads (a, b)",
                "network f(v_xp, v_yp, omega, theta, x, y) -> (ex)",
            ],
        ),
    ];
    for (body, want) in cases {
        let e = err(&body);
        for w in want {
            assert!(e.contains(w), "{body:?}: {w:?} not in\n{e}");
        }
    }
}

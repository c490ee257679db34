//! Relations between the variants stated in docs/model.md section 3, checked numerically:
//! - for alpha <= 0, `full` equals `reduced` except for the damping (omega|omega| vs
//!   omega sqrt(omega^2 + 1e-5)); at omega = 0 the damping vanishes in both, so the
//!   right-hand sides agree exactly;
//! - `plate6` and `reduced` differ only in the drag law: at v_yp = omega = 0 (alpha = 0,
//!   u_r = 0) the drag acts only along x_p, so v_yp', omega', theta', x', y' agree;
//! - E' is the low-pass filter of 0.07 (x + y + x' + y').

use samara_plant::{Model, Plant};

#[test]
fn full_equals_reduced_for_negative_alpha_without_rotation() {
    let full = Plant::new(Model::Full);
    let red = Plant::new(Model::Reduced);
    for &(vx, vy, th) in &[
        (1.0, -0.3, -0.2),
        (1.2, -0.05, 0.1),
        (0.9, -0.6, -1.0),
        (1.4, -1e-3, 0.0),
    ] {
        let s7 = [vx, vy, 0.0, th, 3.0, -2.0, 0.01];
        let mut df = [0.0; 7];
        let mut dr = [0.0; 6];
        full.rhs(&s7, &0.187, &mut df);
        red.rhs(&s7[..6], &0.187, &mut dr);
        for i in 0..6 {
            assert!(
                (df[i] - dr[i]).abs() <= 1e-15 * (1.0 + dr[i].abs()),
                "state {i}: {} vs {}",
                df[i],
                dr[i]
            );
        }
    }
}

#[test]
fn full_and_reduced_differ_for_positive_alpha() {
    let s = [1.0, 0.3, 0.0, 0.0, 0.0, 0.0, 0.0];
    let mut df = [0.0; 7];
    let mut dr = [0.0; 6];
    Plant::new(Model::Full).rhs(&s, &0.187, &mut df);
    Plant::new(Model::Reduced).rhs(&s[..6], &0.187, &mut dr);
    assert!(
        (df[1] - dr[1]).abs() > 1e-3,
        "the alpha > 0 branch must matter"
    );
}

#[test]
fn plate6_and_reduced_share_everything_but_drag() {
    let s = [1.1, 0.0, 0.0, -0.4, 5.0, -4.0, 0.0];
    let mut d6 = [0.0; 7];
    let mut dr = [0.0; 6];
    Plant::new(Model::Plate6).rhs(&s, &0.19, &mut d6);
    Plant::new(Model::Reduced).rhs(&s[..6], &0.19, &mut dr);
    for i in 1..6 {
        assert!((d6[i] - dr[i]).abs() <= 1e-15, "state {i}");
    }
    // Drag along x_p: plate6's fitted law at alpha = 0 is C_D0 (cos(pi) * 0.66 + 0.66 = 0),
    // reduced's is C_D0 too (sin(0) = 0): so even v_xp' agrees at alpha = 0.
    assert!((d6[0] - dr[0]).abs() <= 1e-15);
}

#[test]
fn filter_state_is_the_documented_low_pass() {
    let p = Plant::new(Model::Plate6);
    let s = [1.0, -0.2, 0.1, -0.3, 10.0, -9.0, 0.05];
    let mut d = [0.0; 7];
    p.rhs(&s, &0.185, &mut d);
    let expect = 0.07 * (s[4] + s[5] + d[4] + d[5]) - s[6];
    assert!((d[6] - expect).abs() < 1e-15);
    // Kinematics: x' and y' are the body velocity rotated by theta.
    let (st, ct) = s[3].sin_cos();
    assert!((d[4] - (s[0] * ct - s[1] * st)).abs() < 1e-15);
    assert!((d[5] - (s[0] * st + s[1] * ct)).abs() < 1e-15);
    assert_eq!(d[3], s[2]);
}

//! The forward-mode (Dual) Jacobian against central finite differences of the f64
//! right-hand side, for all three variants over the flight envelope.

use proptest::prelude::*;
use samara_plant::{Model, Plant};

fn fd_jacobian(p: &Plant, s: &[f64], ex: f64) -> (Vec<f64>, Vec<f64>) {
    let n = p.dim();
    let mut jac = vec![0.0; n * n];
    let mut jex = vec![0.0; n];
    let mut fp = vec![0.0; n];
    let mut fm = vec![0.0; n];
    for j in 0..=n {
        let h = 1e-6 * (1.0 + if j < n { s[j].abs() } else { ex });
        let (mut sp, mut sm) = (s.to_vec(), s.to_vec());
        let (mut ep, mut em) = (ex, ex);
        if j < n {
            sp[j] += h;
            sm[j] -= h;
        } else {
            ep += h;
            em -= h;
        }
        p.rhs(&sp, &ep, &mut fp);
        p.rhs(&sm, &em, &mut fm);
        for i in 0..n {
            let d = (fp[i] - fm[i]) / (2.0 * h);
            if j < n {
                jac[i * n + j] = d;
            } else {
                jex[i] = d;
            }
        }
    }
    (jac, jex)
}

fn check(model: Model, s: Vec<f64>, ex: f64) -> Result<(), TestCaseError> {
    let p = Plant::new(model);
    let n = p.dim();
    let (ja, ea) = p.jacobian(&s[..n], ex);
    let (jf, ef) = fd_jacobian(&p, &s[..n], ex);
    let scale = ja.iter().chain(&ea).fold(1.0f64, |m, v| m.max(v.abs()));
    for (a, f) in ja.iter().chain(&ea).zip(jf.iter().chain(&ef)) {
        // 1e-7 relative to the Jacobian's scale (central differences are O(h^2) ~ 1e-12
        // plus rounding ~ 1e-10 here).
        prop_assert!(
            (a - f).abs() <= 1e-7 * scale,
            "{model:?}: AD {a} vs FD {f} at {s:?}, ex {ex}"
        );
    }
    Ok(())
}

fn state() -> impl Strategy<Value = Vec<f64>> {
    (
        0.8f64..1.5,
        -0.6f64..0.3,
        -0.5f64..0.5,
        -1.2f64..0.3,
        0.0f64..40.0,
        -40.0f64..5.0,
        -0.2f64..0.2,
    )
        .prop_map(|(a, b, c, d, e, f, g)| vec![a, b, c, d, e, f, g])
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]
    #[test]
    fn plate6_jacobian(s in state(), ex in 0.181f64..0.193) { check(Model::Plate6, s, ex)?; }
    #[test]
    fn reduced_jacobian(s in state(), ex in 0.181f64..0.193) { check(Model::Reduced, s, ex)?; }
    #[test]
    fn full_jacobian(s in state(), ex in 0.181f64..0.193) {
        // |omega| is not differentiable at 0 and the masks switch at alpha = 0: stay away.
        prop_assume!(s[2].abs() > 1e-4 && s[1].abs() > 1e-4);
        check(Model::Full, s, ex)?;
    }
}

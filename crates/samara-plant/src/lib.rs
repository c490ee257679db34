//! The *Alsomitra macrocarpa* gliding-plate model (Li et al., JFM 2022, as coded in the
//! SAIV 2025 case study), in three variants, every equation written once over
//! [`Scalar`] so the same code simulates (`f64`), differentiates ([`samara_num::Dual`])
//! and encloses (intervals, Taylor models).
//!
//! The equations follow `docs/model.md` exactly (the MATLAB
//! code is the ground truth); evaluation order of the derived constants is kept so that
//! the published data are reproduced bit-faithfully.
#![warn(missing_docs)]

use samara_num::{Scalar, Sign};
use std::f64::consts::{FRAC_PI_2, PI};

/// Names of the state components, in order (`E` only for plate6 and full).
pub const STATE_NAMES: [&str; 7] = ["v_xp", "v_yp", "omega", "theta", "x", "y", "E"];

/// Allowed range of the control input `ex` (centre-of-mass offset / chord).
pub const EX_RANGE: (f64, f64) = (0.181, 0.193);

/// The three model variants of docs/model.md section 3.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Model {
    /// The simulation model (7 states, fitted drag law): produced `Training_Data.csv`.
    Plate6,
    /// The reachability model used with CORA (6 states, no filter state, `sin(alpha^2)` drag).
    Reduced,
    /// The four-quadrant model (7 states, unsmoothed damping, quadrant masks).
    Full,
}

impl Model {
    /// All variants.
    pub const ALL: [Model; 3] = [Model::Plate6, Model::Reduced, Model::Full];

    /// The CLI name.
    pub fn name(self) -> &'static str {
        match self {
            Model::Plate6 => "plate6",
            Model::Reduced => "reduced",
            Model::Full => "full",
        }
    }

    /// Parse a CLI name.
    pub fn from_name(s: &str) -> Option<Model> {
        Model::ALL.into_iter().find(|m| m.name() == s)
    }

    /// Number of states (7 with the filter state E, 6 without).
    pub fn dim(self) -> usize {
        match self {
            Model::Reduced => 6,
            _ => 7,
        }
    }

    /// Whether the model carries the filtered tracking error `E` (state 6).
    pub fn has_filter(self) -> bool {
        self.dim() == 7
    }
}

/// Physical and aerodynamic parameters, with the published defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct Params {
    /// Translational lift coefficient, attached flow.
    pub c_l1: f64,
    /// Translational lift coefficient, separated flow.
    pub c_l2: f64,
    /// Drag at zero incidence.
    pub c_d0: f64,
    /// Drag growth with incidence.
    pub c_d1: f64,
    /// Drag at 90 degrees.
    pub c_d_pi2: f64,
    /// Centre of pressure, constant term.
    pub c_cp0: f64,
    /// Centre of pressure, quadratic term.
    pub c_cp1: f64,
    /// Centre of pressure, separated flow.
    pub c_cp2: f64,
    /// Rotational lift coefficient.
    pub c_r: f64,
    /// Chord (m).
    pub l: f64,
    /// Mass (kg).
    pub m: f64,
    /// Fluid density (kg/m^3).
    pub rho_f: f64,
    /// Semi-axis a (m).
    pub a: f64,
    /// Semi-axis b (m).
    pub b: f64,
    /// Span (m).
    pub s: f64,
    /// Stall angle (rad).
    pub alpha0: f64,
    /// Stall transition width (rad).
    pub delta: f64,
    /// Smoothing of |omega| in plate6/reduced: `sqrt(omega^2 + omega_smooth)`.
    pub omega_smooth: f64,
    /// Gain of the error filter (m per chord): `E' = k (x + y + x' + y') - E`.
    pub filter_gain: f64,
}

impl Default for Params {
    fn default() -> Self {
        Params {
            c_l1: 5.18218452125279,
            c_l2: 0.807506506794260,
            c_d0: 0.105977518471870,
            c_d1: 4.93681162104530,
            c_d_pi2: 1.49958010664229,
            c_cp0: 0.238565281050545,
            c_cp1: 2.85289007725274,
            c_cp2: 0.368933365279324,
            c_r: 1.73001889433847,
            l: 0.07,
            m: 3.175e-4,
            rho_f: 1.225,
            a: 0.03375,
            b: 5.0e-4,
            s: 0.1745,
            alpha0: 14.0 * PI / 180.0,
            delta: 6.0 * PI / 180.0,
            omega_smooth: 1e-5,
            filter_gain: 0.07,
        }
    }
}

/// Nondimensional groups derived from [`Params`], in the documented evaluation order.
#[derive(Clone, Debug, PartialEq)]
pub struct Derived {
    /// Plate density.
    pub rho_s: f64,
    /// Nondimensional mass m'.
    pub m_prime: f64,
    /// Density ratio gamma.
    pub gamma: f64,
    /// Moment of inertia at e = 0.
    pub i0: f64,
}

impl Derived {
    /// Compute the groups (docs/model.md section 1).
    pub fn new(p: &Params) -> Self {
        let rho_s = p.m / (PI * p.a * p.b);
        let m_prime = 4.0 * p.m / (PI * p.rho_f * p.l * p.l * p.s);
        let gamma = p.rho_f / (rho_s - p.rho_f);
        let i0 = p.m * (p.a * p.a + p.b * p.b) / (p.rho_f * p.l.powi(4)) + 1.0 / 32.0;
        Derived {
            rho_s,
            m_prime,
            gamma,
            i0,
        }
    }
}

/// A plant: a model variant with its parameters.
#[derive(Clone, Debug, PartialEq)]
pub struct Plant {
    /// The variant.
    pub model: Model,
    /// The parameters.
    pub params: Params,
    /// Derived groups (kept in sync by [`Plant::new`]).
    pub derived: Derived,
}

/// Aerodynamic coefficients at one incidence.
struct Coefficients<S> {
    c_l: S,
    c_d: S,
    eps: S,
}

impl Plant {
    /// A plant with the published parameters.
    pub fn new(model: Model) -> Self {
        Self::with_params(model, Params::default())
    }

    /// A plant with given parameters.
    pub fn with_params(model: Model, params: Params) -> Self {
        let derived = Derived::new(&params);
        Plant {
            model,
            params,
            derived,
        }
    }

    /// Number of states.
    pub fn dim(&self) -> usize {
        self.model.dim()
    }

    /// F = [1 - tanh((g - alpha0)/delta)] / 2 (attachment function, g = -alpha), computed
    /// as the equal logistic form 1 / (1 + exp(2 (g - alpha0) / delta)): one `exp`
    /// instead of `tanh` (about 20% of the right-hand side's time).
    fn attach<S: Scalar>(&self, g: S) -> S {
        let p = &self.params;
        let e = ((g - p.alpha0) * (2.0 / p.delta)).exp();
        S::cst(1.0) / (e + 1.0)
    }

    fn coefficients<S: Scalar>(&self, alpha: &S) -> Coefficients<S> {
        let p = &self.params;
        match self.model {
            Model::Plate6 | Model::Reduced => {
                let f = self.attach(-alpha.clone());
                let one_minus_f = -f.clone() + 1.0;
                let sin_a = alpha.sin();
                let c_l = f.clone() * p.c_l1 * sin_a.clone()
                    + one_minus_f.clone() * p.c_l2 * (alpha.clone() * 2.0).sin();
                let c_d = if self.model == Model::Plate6 {
                    f.clone() * (sin_a.clone() * 0.683 * p.c_d1 * sin_a + p.c_d0)
                        + ((alpha.clone() * 2.143 + PI).cos() * 0.66 + 0.66)
                } else {
                    f.clone() * ((alpha.sqr()).sin() * p.c_d1 + p.c_d0)
                        + one_minus_f.clone() * p.c_d_pi2 * sin_a.sqr()
                };
                let eps = f * (-alpha.sqr() * p.c_cp1 + p.c_cp0)
                    + one_minus_f * p.c_cp2 * (alpha.clone() / FRAC_PI_2 + 1.0);
                Coefficients { c_l, c_d, eps }
            }
            Model::Full => self.full_coefficients(alpha),
        }
    }

    /// Per-quadrant coefficients of the full model at argument `g`.
    fn quadrant<S: Scalar>(&self, g: S) -> (S, S, S) {
        let p = &self.params;
        let f = -((g.clone() - p.alpha0) / p.delta).tanh() * 0.5 + 0.5;
        let one_minus_f = -f.clone() + 1.0;
        let sin_g = g.sin();
        let cl = f.clone() * p.c_l1 * sin_g.clone()
            + one_minus_f.clone() * p.c_l2 * (g.clone() * 2.0).sin();
        let cd = f.clone() * (g.sqr().sin() * p.c_d1 + p.c_d0)
            + one_minus_f.clone() * p.c_d_pi2 * sin_g.sqr();
        let cp =
            f * (-g.sqr() * p.c_cp1 + p.c_cp0) + one_minus_f * p.c_cp2 * (-(g / FRAC_PI_2) + 1.0);
        (cl, cd, cp)
    }

    /// The four-quadrant masks of docs/model.md section 3 (`full`). Since alpha = atan(.)
    /// lies in [-pi/2, pi/2], quadrants 1 and 4 are reached only at |alpha| = pi/2.
    /// For set-valued alpha whose position relative to a mask edge is undecided, the
    /// result is the hull of every combination that can occur.
    fn full_coefficients<S: Scalar>(&self, alpha: &S) -> Coefficients<S> {
        let zero = S::cst(0.0);
        // Position relative to -pi/2, 0, pi/2.
        let lo = alpha.sign_minus(-FRAC_PI_2);
        let mid = alpha.sign();
        let hi = alpha.sign_minus(FRAC_PI_2);
        let q1 = || self.quadrant(-alpha.abs() + PI);
        let q2 = || self.quadrant(alpha.abs());
        let q3 = || self.quadrant(alpha.clone());
        let q4 = || self.quadrant(-alpha.clone() + PI);

        // Membership tests: Some(true) certainly in, Some(false) certainly out, None undecided.
        let le = |s: Sign| match s {
            Sign::Negative | Sign::Zero | Sign::NonPositive => Some(true),
            Sign::Positive => Some(false),
            Sign::NonNegative | Sign::Mixed => None,
        };
        let lt = |s: Sign| match s {
            Sign::Negative => Some(true),
            Sign::Positive | Sign::Zero | Sign::NonNegative => Some(false),
            Sign::NonPositive | Sign::Mixed => None,
        };
        let not = |m: Option<bool>| m.map(|b| !b);
        let and = |a: Option<bool>, b: Option<bool>| match (a, b) {
            (Some(false), _) | (_, Some(false)) => Some(false),
            (Some(true), Some(true)) => Some(true),
            _ => None,
        };
        // Intervals of each mask (alpha >= -pi always holds here since alpha >= -pi/2 - tiny).
        let in_le_m = le(lo); // alpha <= -pi/2
        let in_lt_m = lt(lo); // alpha < -pi/2
        let in_le_0 = le(mid);
        let in_lt_0 = lt(mid);
        let in_le_p = le(hi);
        let in_lt_p = lt(hi);
        // C_L masks: [-pi,-pi/2], (-pi/2,0], (0,pi/2], (pi/2,pi]
        let cl_m = [
            in_le_m,
            and(not(in_le_m), in_le_0),
            and(not(in_le_0), in_le_p),
            not(in_le_p),
        ];
        // C_D masks: [-pi,-pi/2), [-pi/2,0), [0,pi/2), [pi/2,pi]
        let cd_m = [
            in_lt_m,
            and(not(in_lt_m), in_lt_0),
            and(not(in_lt_0), in_lt_p),
            not(in_lt_p),
        ];
        // eps masks (closed): [-pi,-pi/2], [-pi/2,0], [0,pi/2], [pi/2,pi]
        let cp_m = [
            in_le_m,
            and(not(in_lt_m), in_le_0),
            and(not(in_lt_0), in_le_p),
            not(in_lt_p),
        ];
        let quads: Vec<Option<(S, S, S)>> = (0..4)
            .map(|i| {
                if cl_m[i] == Some(false) && cd_m[i] == Some(false) && cp_m[i] == Some(false) {
                    None
                } else {
                    Some(match i {
                        0 => q1(),
                        1 => q2(),
                        2 => q3(),
                        _ => q4(),
                    })
                }
            })
            .collect();
        let signs_l = [1.0, -1.0, 1.0, -1.0];
        let signs_p = [-1.0, 1.0, 1.0, -1.0];
        let combine = |masks: &[Option<bool>; 4], pick: &dyn Fn(&(S, S, S)) -> S, sg: &[f64; 4]| {
            // Sum of the certainly-included terms; undecided terms contribute hull(0, term).
            let mut acc = zero.clone();
            for i in 0..4 {
                if let Some(q) = &quads[i] {
                    let term = pick(q) * sg[i];
                    match masks[i] {
                        Some(true) => acc += term,
                        Some(false) => {}
                        None => acc += term.hull(&zero),
                    }
                }
            }
            acc
        };
        let c_l = combine(&cl_m, &|q| q.0.clone(), &signs_l);
        let c_d = combine(&cd_m, &|q| q.1.clone(), &[1.0; 4]);
        let eps = combine(&cp_m, &|q| q.2.clone(), &signs_p);
        Coefficients { c_l, c_d, eps }
    }

    /// Damping factor P(e) of the rotational damping torque.
    fn damping_factor<S: Scalar>(&self, e: &S) -> S {
        let p4 = (e.clone() * 2.0 + 1.0).powi(4);
        let q4 = (e.clone() * 2.0 - 1.0).powi(4);
        let sum = p4.clone() + q4.clone();
        let diff = p4 - q4;
        match self.model {
            Model::Plate6 | Model::Reduced => sum + diff,
            Model::Full => match (e.clone() * 2.0).sign_minus(1.0) {
                Sign::Negative | Sign::Zero | Sign::NonPositive => sum + diff,
                Sign::Positive => sum - diff,
                _ => (sum.clone() + diff.clone()).hull(&(sum - diff)),
            },
        }
    }

    /// The right-hand side `ds/dt = f(s, ex)` of docs/model.md section 2. `state` and `out`
    /// have [`Plant::dim`] entries; `ex` is held constant by the caller.
    pub fn rhs<S: Scalar>(&self, state: &[S], ex: &S, out: &mut [S]) {
        let p = &self.params;
        let d = &self.derived;
        let vx = &state[0];
        let vy = &state[1];
        let w = &state[2];
        let th = &state[3];
        let e = ex;

        let alpha = (vy.clone() / vx.clone()).atan();
        let ur = vy.clone() - w.clone() * e.clone();
        let v = (vx.sqr() + ur.sqr()).sqrt();
        let co = self.coefficients(&alpha);

        let two_pi = 2.0 / PI;
        let lt = co.c_l * two_pi * v.clone(); // times (ur, -vx)
        let lr = w.clone() * (-two_pi * p.c_r); // times (ur, -vx)
        let dd = co.c_d * (-two_pi) * v; // times (vx, ur)
        let lt_x = lt.clone() * ur.clone();
        let lt_y = -(lt * vx.clone());
        let lr_x = lr.clone() * ur.clone();
        let lr_y = -(lr * vx.clone());
        let d_x = dd.clone() * vx.clone();
        let d_y = dd * ur;

        let omega_shape = match self.model {
            Model::Full => w.abs(),
            _ => (w.sqr() + p.omega_smooth).sqrt(),
        };
        let tau_d = w.clone() * (-(p.c_d_pi2) / (32.0 * PI)) * omega_shape * self.damping_factor(e);
        let (sin_t, cos_t) = th.sin_cos();
        let inertia = e.sqr() + d.i0;
        let dw = (tau_d + (lt_y.clone() + d_y.clone()) * (co.eps - e.clone())
            - e.clone() * d.gamma * cos_t.clone())
            / inertia;
        let mp = d.m_prime;
        let dvx =
            ((w.clone() * vy.clone()) * (mp + 1.0) - e.clone() * w.sqr() + (lt_x + lr_x) + d_x
                - sin_t.clone())
                / mp;
        let dvy = (-(w.clone() * vx.clone()) * mp + e.clone() * dw.clone() + (lt_y + lr_y) + d_y
            - cos_t.clone())
            / (mp + 1.0);
        let dx = vx.clone() * cos_t.clone() - vy.clone() * sin_t.clone();
        let dy = vx.clone() * sin_t + vy.clone() * cos_t;
        if self.model.has_filter() {
            let x = &state[4];
            let y = &state[5];
            let ee = &state[6];
            out[6] = (y.clone() + dy.clone()) * p.filter_gain
                + (x.clone() + dx.clone()) * p.filter_gain
                - ee.clone();
        }
        out[0] = dvx;
        out[1] = dvy;
        out[2] = dw;
        out[3] = w.clone();
        out[4] = dx;
        out[5] = dy;
    }

    /// Jacobian `d f / d state` (row-major `dim x dim`) and `d f / d ex` at a point,
    /// by forward-mode AD ([`samara_num::Dual`]) through the same equations.
    pub fn jacobian(&self, state: &[f64], ex: f64) -> (Vec<f64>, Vec<f64>) {
        use samara_num::Dual;
        let n = self.dim();
        let s: Vec<Dual<8>> = state
            .iter()
            .enumerate()
            .map(|(i, &v)| Dual::var(v, i))
            .collect();
        let e = Dual::<8>::var(ex, 7);
        let mut out = vec![Dual::<8>::constant(0.0); n];
        self.rhs(&s, &e, &mut out);
        let mut jac = vec![0.0; n * n];
        let mut jex = vec![0.0; n];
        for i in 0..n {
            for j in 0..n {
                jac[i * n + j] = out[i].d[j];
            }
            jex[i] = out[i].d[7];
        }
        (jac, jex)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn derived_constants_match_model_md() {
        let d = Derived::new(&Params::default());
        assert!((d.rho_s - 5.9889415622728).abs() < 1e-12);
        assert!((d.m_prime - 0.385945736987252).abs() < 1e-14);
        assert!((d.gamma - 0.257140013996219).abs() < 1e-14);
        assert!((d.i0 - 0.0435486755093541).abs() < 1e-15);
    }

    #[test]
    fn damping_factor_is_2_times_2e_plus_1_to_the_4() {
        let pl = Plant::new(Model::Plate6);
        let e = 0.187;
        let expect = 2.0 * (2.0 * e + 1.0_f64).powi(4);
        assert!((pl.damping_factor(&e) - expect).abs() < 1e-13);
    }
}

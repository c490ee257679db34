//! The closed-loop loss of issue 18 item 2 (used by [`crate::cegis`]):
//! flights of the reduced plant under the network controller, sample-and-hold as the
//! published loop (`ex = clip(net(state))` read at each control instant and held for one
//! period), from the initial states `(1, 0, 0, 0, 0, y0)`, and the penalty
//!
//! `L(theta) = sum over y0 of max(0, |x + y|(T) - Y)^2`,
//!
//! (with [`ClosedLoopLoss::from`], summed over every control instant of the window
//! `[from, T]` too),
//! with its gradient with respect to the network parameters `theta` by forward-mode
//! automatic differentiation: the plant ([`Plant::rhs`]), samara-sim's fixed-step RK4
//! ([`Rk4`]) in its sample-and-hold loop ([`sample_and_hold`]) and the network ([`Mlp::forward_with`]) run on [`Dual`] numbers that carry the derivatives
//! with respect to a chunk of [`CHUNK`] parameters at a time. The derivatives are those
//! of the discretised flight (exact up to rounding), with ReLU' (0) = 0, the clip's
//! derivative 0 where it is active and d|u|/du = 0 at u = 0.

use crate::data::MinMax;
use crate::mlp::Mlp;
use crate::train::TrainError;
use samara_num::{Dual, Scalar};
use samara_plant::{Model, Plant, EX_RANGE};
use samara_sim::{sample_and_hold, Rk4};
use std::convert::Infallible;

/// Parameters differentiated per forward pass.
pub const CHUNK: usize = 8;

/// The closed-loop penalty's settings.
#[derive(Clone, Debug)]
pub struct ClosedLoopLoss {
    /// The plant: the reduced model (6 states, no filter state).
    pub plant: Plant,
    /// Initial y (chords) of the flights; each starts at `(1, 0, 0, 0, 0, y0)`.
    pub y0: Vec<f64>,
    /// Horizon T; a positive multiple of `period`.
    pub horizon: f64,
    /// Control period (0.5).
    pub period: f64,
    /// RK4 step; each period takes `ceil(period / step)` equal steps.
    pub step: f64,
    /// The bound Y on |x + y| at T.
    pub bound: f64,
    /// Also penalise |x + y| > Y at every control instant t >= `from` (the goal over a
    /// window `[from, T]`); `None`: at T only.
    pub from: Option<f64>,
    /// Output clip of the controller (the published [`EX_RANGE`]); `None` for none.
    pub clip: Option<(f64, f64)>,
}

impl Default for ClosedLoopLoss {
    /// The reduced plant from the nine published starts y0 = (0.1 + 0.025 i) / 0.07,
    /// T = 20, period 0.5, RK4 step 0.01, Y = 2, clipped to [0.181, 0.193].
    fn default() -> Self {
        ClosedLoopLoss {
            plant: Plant::new(Model::Reduced),
            y0: (0..9).map(|i| (0.1 + i as f64 * 0.025) / 0.07).collect(),
            horizon: 20.0,
            period: 0.5,
            step: 0.01,
            bound: 2.0,
            from: None,
            clip: Some(EX_RANGE),
        }
    }
}

impl ClosedLoopLoss {
    /// Number of control periods; checks the settings.
    pub(crate) fn periods(&self, net: &Mlp, mm: &MinMax) -> Result<usize, TrainError> {
        let bad = |m: String| Err(TrainError::Settings(m));
        if !(self.period > 0.0 && self.period.is_finite()) {
            return bad(format!(
                "closed-loop period {} must be positive",
                self.period
            ));
        }
        let r = self.horizon / self.period;
        if !(self.horizon > 0.0 && self.horizon.is_finite()) || (r - r.round()).abs() > 1e-9 * r {
            return bad(format!(
                "closed-loop horizon {} must be a positive multiple of the period {}",
                self.horizon, self.period
            ));
        }
        if !(self.step > 0.0 && self.step.is_finite()) {
            return bad(format!(
                "closed-loop RK4 step {} must be positive",
                self.step
            ));
        }
        if !(self.bound.is_finite() && self.bound >= 0.0) {
            return bad(format!("closed-loop bound Y = {} must be >= 0", self.bound));
        }
        if let Some(f) = self.from {
            if !(f >= 0.0 && f <= self.horizon) {
                return bad(format!(
                    "closed-loop window start {f} must lie in [0, horizon = {}]",
                    self.horizon
                ));
            }
        }
        if self.y0.iter().any(|v| !v.is_finite()) {
            return bad("closed-loop initial y0 must be finite".into());
        }
        if self.plant.model != Model::Reduced {
            // The other variants carry the filter state E, which the published loop
            // resets every period; this loss does not model that.
            return bad(format!(
                "the closed-loop loss flies the reduced model, not `{}`",
                self.plant.model.name()
            ));
        }
        if net.sizes[0] != 6 || net.sizes.last() != Some(&1) {
            return bad(format!(
                "the closed-loop loss needs a 6-input, 1-output network (got {:?})",
                net.sizes
            ));
        }
        if mm.min.len() < 7 || mm.range.len() < 7 {
            return bad("the closed-loop loss needs 7 normalisation columns".into());
        }
        Ok(r.round() as usize)
    }

    /// The penalty of one flight from `y0`, on any [`Scalar`]: the network's parameters
    /// are `params`, its units those of `mm` (inputs `(s - min) / range`, output
    /// `min + range * y`).
    fn flight<S: Scalar>(&self, net: &Mlp, params: &[S], mm: &MinMax, n: usize, y0: f64) -> S {
        let dim = self.plant.dim();
        let mut s: Vec<S> = (0..dim)
            .map(|k| {
                S::cst(match k {
                    0 => 1.0,
                    5 => y0,
                    _ => 0.0,
                })
            })
            .collect();
        let mut rk = Rk4::new(dim);
        let mut penalty = S::cst(0.0);
        let ok: Result<(), Infallible> = sample_and_hold(
            &mut penalty,
            &mut s,
            n,
            |_, _, s| {
                let z: Vec<S> = (0..6)
                    .map(|j| (s[j].clone() - mm.min[j]) / mm.range[j])
                    .collect();
                let y = net.forward_with(params, &z)[0].clone();
                let raw = y * mm.range[6] + mm.min[6];
                Ok(vec![match self.clip {
                    Some((lo, hi)) => raw.clamp_to(lo, hi),
                    None => raw,
                }])
            },
            |_, s, u| {
                rk.integrate(
                    |x, out| self.plant.rhs(x, &u[0], out),
                    s,
                    0.0,
                    self.period,
                    self.step,
                );
            },
            |penalty, k, s, _, ()| {
                let t = (k + 1) as f64 * self.period;
                let in_window = self.from.is_some_and(|f| t >= f - 1e-9);
                if in_window || k + 1 == n {
                    *penalty += ((s[4].clone() + s[5].clone()).abs() - self.bound)
                        .relu()
                        .sqr();
                }
                Ok(())
            },
        );
        match ok {
            Ok(()) => {}
            Err(never) => match never {},
        }
        penalty
    }

    fn total<S: Scalar>(&self, net: &Mlp, params: &[S], mm: &MinMax, n: usize) -> S {
        let mut sum = S::cst(0.0);
        for &y0 in &self.y0 {
            sum += self.flight(net, params, mm, n, y0);
        }
        sum
    }

    /// The loss `sum over y0 of max(0, |x + y|(T) - Y)^2` of `net` (normalised units,
    /// constants `mm`: 6 state columns, then ex).
    pub fn loss(&self, net: &Mlp, mm: &MinMax) -> Result<f64, TrainError> {
        let n = self.periods(net, mm)?;
        Ok(self.total(net, &net.params, mm, n))
    }

    /// The loss and its gradient with respect to `net.params`, by forward-mode AD over
    /// [`CHUNK`] parameters per pass (`ceil(params / CHUNK)` passes of every flight).
    pub fn loss_and_gradient(&self, net: &Mlp, mm: &MinMax) -> Result<(f64, Vec<f64>), TrainError> {
        let n = self.periods(net, mm)?;
        let np = net.params.len();
        let mut grad = vec![0.0; np];
        let mut value = 0.0;
        for c0 in (0..np).step_by(CHUNK) {
            let params: Vec<Dual<CHUNK>> = net
                .params
                .iter()
                .enumerate()
                .map(|(k, &v)| {
                    if (c0..c0 + CHUNK).contains(&k) {
                        Dual::var(v, k - c0)
                    } else {
                        Dual::constant(v)
                    }
                })
                .collect();
            let l = self.total(net, &params, mm, n);
            value = l.v;
            let c1 = (c0 + CHUNK).min(np);
            grad[c0..c1].copy_from_slice(&l.d[..c1 - c0]);
        }
        Ok((value, grad))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;
    use samara_nn::{Affine, Network};
    use samara_sim::{fly, Integrator, LoopSettings, NetworkController};

    fn constants() -> MinMax {
        MinMax::read(&samara_testkit::reference("Normalisation_Constants.csv")).unwrap()
    }

    /// A 6-6-4-1 network (ReLU output, as published) trained for 300 epochs on the
    /// published data in the published units, so that its output moves inside the clip
    /// range during the flights.
    fn network() -> Mlp {
        let data = crate::read_table(&samara_testkit::reference("Training_Data.csv")).unwrap();
        let out = crate::train(
            &data,
            Some(&constants()),
            &crate::TrainOptions {
                epochs: 300,
                ..Default::default()
            },
        )
        .unwrap();
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(0);
        let mut net = Mlp::new(&[6, 6, 4, 1], true, &mut rng);
        net.params = out
            .network
            .layers
            .iter()
            .filter_map(|l| match l {
                samara_nn::Layer::Affine(a) => {
                    Some(a.to_dense().into_owned().into_iter().chain(a.b.clone()))
                }
                _ => None,
            })
            .flatten()
            .collect();
        assert_eq!(net.params.len(), 75);
        net
    }

    fn settings(horizon: f64, bound: f64) -> ClosedLoopLoss {
        ClosedLoopLoss {
            horizon,
            bound,
            ..Default::default()
        }
    }

    #[test]
    fn the_loss_is_the_penalty_of_samara_sims_closed_loop() {
        // Independent flights: samara-sim's sample-and-hold loop with its tight DOP853
        // integrator (so the comparison also bounds the RK4 error at step 0.01) and the
        // network exported with its normalisation layers.
        let (net, mm) = (network(), constants());
        let ir = Network {
            input_names: (0..6).map(|i| format!("s{i}")).collect(),
            output_names: vec!["ex".into()],
            input_norm: Some(Affine::normalise(&mm.min[..6], &mm.range[..6])),
            layers: net.to_layers(),
            output_denorm: Some(Affine::denormalise(&mm.min[6..7], &mm.range[6..7])),
        };
        let cl = settings(2.0, 3.0);
        let mut ctl = NetworkController::new(ir, cl.clip, "test");
        let loop_settings = LoopSettings {
            horizon: cl.horizon,
            period: cl.period,
            integrator: Integrator::Tight(Default::default()),
            output_step: None,
            ..Default::default()
        };
        let mut want = 0.0;
        let mut active = 0;
        for &y0 in &cl.y0 {
            let f = fly(
                &cl.plant,
                &mut ctl,
                &[1.0, 0.0, 0.0, 0.0, 0.0, y0],
                &loop_settings,
            )
            .unwrap();
            let s = &f.steps.last().unwrap().state_end;
            let e = (s[4] + s[5]).abs() - cl.bound;
            eprintln!("y0 {y0:.3}: |x + y|(2) = {:.6}", (s[4] + s[5]).abs());
            if e > 0.0 {
                want += e * e;
                active += 1;
            }
        }
        let got = cl.loss(&net, &mm).unwrap();
        eprintln!("loss {got} vs {want}, {active} of 9 flights penalised");
        assert!(active > 0 && active < 9, "both branches of max(0, .) occur");
        assert!((got - want).abs() <= 1e-6 * want, "{got} vs {want}");
        let (v, _) = cl.loss_and_gradient(&net, &mm).unwrap();
        assert!((v - got).abs() <= 1e-12 * got, "dual value {v} vs {got}");
    }

    #[test]
    fn the_gradient_matches_central_differences() {
        let (net, mm) = (network(), constants());
        let cl = settings(2.0, 3.0);
        let (_, g) = cl.loss_and_gradient(&net, &mm).unwrap();
        let mut nonzero = 0;
        let mut worst = 0.0f64;
        for k in 0..net.params.len() {
            let h = 1e-6 * net.params[k].abs().max(1.0);
            let mut p = net.clone();
            p.params[k] += h;
            let mut m = net.clone();
            m.params[k] -= h;
            let fd = (cl.loss(&p, &mm).unwrap() - cl.loss(&m, &mm).unwrap()) / (2.0 * h);
            let err = (fd - g[k]).abs() / (1.0 + fd.abs());
            worst = worst.max(err);
            assert!(
                err < 1e-6,
                "param {k}: AD {} vs central difference {fd}",
                g[k]
            );
            if g[k].abs() > 1e-8 {
                nonzero += 1;
            }
        }
        eprintln!(
            "{nonzero} of {} partials nonzero; worst relative error {worst:.2e}",
            g.len()
        );
        // Dead units give zero partials; most of the parameters must matter.
        assert!(nonzero > g.len() / 2, "{nonzero} nonzero partials");
    }

    #[test]
    fn a_window_adds_the_penalties_of_its_control_instants() {
        let (net, mm) = (network(), constants());
        let at_t = settings(2.0, 2.5);
        let window = ClosedLoopLoss {
            from: Some(1.0),
            ..at_t.clone()
        };
        let (a, b) = (
            at_t.loss(&net, &mm).unwrap(),
            window.loss(&net, &mm).unwrap(),
        );
        // The window [1, 2] holds the instants 1, 1.5 and 2 (the last is T, counted once).
        let sum: f64 = [1.0, 1.5]
            .iter()
            .map(|&t| settings(t, 2.5).loss(&net, &mm).unwrap())
            .sum();
        assert!(
            a > 0.0 && (b - (a + sum)).abs() <= 1e-12 * b,
            "{b} vs {a} + {sum}"
        );
        let (v, g) = window.loss_and_gradient(&net, &mm).unwrap();
        assert!((v - b).abs() <= 1e-12 * b && g.iter().any(|x| *x != 0.0));
    }

    #[test]
    fn bad_settings_are_errors() {
        let (net, mm) = (network(), constants());
        for cl in [
            settings(1.7, 2.0),
            settings(2.0, f64::NAN),
            ClosedLoopLoss {
                step: 0.0,
                ..settings(2.0, 2.0)
            },
            ClosedLoopLoss {
                plant: Plant::new(Model::Plate6),
                ..settings(2.0, 2.0)
            },
        ] {
            assert!(matches!(cl.loss(&net, &mm), Err(TrainError::Settings(_))));
        }
    }
}

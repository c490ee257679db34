//! The controller over Taylor-model sets: CROWN on the models' linear part with the
//! rest as a noise box, or the network evaluated on the models themselves.

use samara_num::tm_reduce::{fresh_param, linear_parts, mid_rad};

use samara_nn::{Affine, Layer, Network};
use samara_num::{Interval, Tm};

/// Most higher-order monomials of the inputs' Taylor models the network step keeps as
/// variables of their own (the heaviest; the others go into the noise box).
const MAX_TERM_VARS: usize = 160;

/// The inputs' Taylor models on one classic monomial table (`None` if they cannot
/// share one). Mixed-degree inputs (with lifted parameters, [`Tm::with_lifted_weight`])
/// never share the classic table, and building that table in all their parameters costs
/// seconds (every monomial of the order in the lifted parameters too: 249,900 at order
/// 4 in 47 parameters), so they go to the linear path at once.
fn common_basis(obs: &[Tm], order: u32) -> Option<(Tm, Vec<Tm>)> {
    if obs.iter().any(|v| v.full_params().is_some()) {
        return None;
    }
    let n = obs.iter().map(|v| v.n_vars()).max().unwrap_or(0);
    let base = Tm::constant(0.0, n, order);
    let obs: Vec<Tm> = obs.iter().map(|v| v.clone() + base.clone()).collect();
    obs.iter()
        .all(|v| v.same_basis(&base))
        .then_some((base, obs))
}

/// The network over a set of inputs given as Taylor models, by CROWN over a linear set
/// whose variables are the parameters *and* the inputs' heaviest higher-order monomials
/// (each monomial `m` a variable of its own over its range, `[-1, 1]`, or `[0, 1]` for
/// even ones): CROWN's affine bounds in those variables are then substituted back into
/// the monomials exactly, so the outputs keep the inputs' polynomial dependence instead
/// of bounding it into a box (the polynomial abstraction of the network's input set, as
/// POLAR and CORA's polynomial zonotopes keep it; Huang et al., ATVA 2022; Kochdumper et
/// al., "Open- and closed-loop neural network verification using polynomial
/// zonotopes", NFM 2023). The other monomials and the remainders form the noise box.
/// For networks without piecewise-linear layers the network evaluated on the Taylor
/// models is also computed, and the narrower result per output kept.
pub fn network_over(net: &Network, obs: &[Tm], order: u32) -> Vec<Tm> {
    let Some((base, obs)) = common_basis(obs, order) else {
        return network_over_linear(net, obs, order);
    };
    let n = base.n_vars();
    // Monomials of degree >= 2 by weight (sum of |coefficient| over the inputs).
    let mut weight: Vec<(usize, f64)> = (n + 1..base.n_terms())
        .filter_map(|m| {
            let w: f64 = obs.iter().map(|v| v.coef(m).abs()).sum();
            // Even monomials are shifted to [-1, 1] by halving: only where that is exact.
            let halves = !base.term_even(m)
                || obs.iter().all(|v| {
                    let h = v.coef(m);
                    (h * 0.5) * 2.0 == h
                });
            (w > 0.0 && halves).then_some((m, w))
        })
        .collect();
    if order < 2 || weight.is_empty() {
        return network_over_linear(net, &obs, order);
    }
    weight.sort_by(|a, b| b.1.total_cmp(&a.1));
    weight.truncate(MAX_TERM_VARS);
    let mons: Vec<usize> = weight.iter().map(|&(m, _)| m).collect();
    let mut kept = vec![false; base.n_terms()];
    for &m in &mons {
        kept[m] = true;
    }
    let mut c = Vec::with_capacity(obs.len());
    let mut noise = Vec::with_capacity(obs.len());
    let mut gens: Vec<Vec<f64>> = vec![Vec::with_capacity(obs.len()); n + mons.len()];
    for o in &obs {
        // The monomials not kept, plus the remainder: the noise box around its midpoint.
        let rest: Vec<(usize, f64)> = (n + 1..o.n_terms())
            .filter(|&m| !kept[m] && o.coef(m) != 0.0)
            .map(|m| (m, o.coef(m)))
            .collect();
        let r = o.from_terms(0.0, &rest).bound() + o.rem();
        let (mr, r0) = mid_rad(r);
        // Centre: constant + the noise box's midpoint + half of each kept even monomial
        // (`h m = h/2 + (h/2) nu` with `nu = 2 m - 1` in [-1, 1]), summed outward.
        let mut centre = Interval::point(o.coef(0)) + Interval::point(mr);
        for (k, g) in gens.iter_mut().enumerate() {
            if k < n {
                g.push(o.coef(k + 1));
            } else {
                let m = mons[k - n];
                let h = o.coef(m);
                if o.term_even(m) {
                    centre += Interval::point(h * 0.5);
                    g.push(h * 0.5);
                } else {
                    g.push(h);
                }
            }
        }
        let (cm, cr) = mid_rad(centre);
        c.push(cm);
        noise.push((r0 + cr).next_up());
    }
    let Ok(e) = samara_bounds::linset::bound_over_linear_set(net, &c, &gens, &noise) else {
        return network_over_linear(net, &obs, order);
    };
    let from_terms: Vec<Tm> = (0..net.n_outputs())
        .map(|j| {
            let a = &e.coef[j];
            let mut terms: Vec<(usize, f64)> = (0..n).map(|k| (k + 1, a[k])).collect();
            // `a nu = 2 a m - a` for an even monomial: the constant moves, outward.
            let mut cst = Interval::point(e.cst[j]);
            for (k, &m) in mons.iter().enumerate() {
                let ak = a[n + k];
                if base.term_even(m) {
                    terms.push((m, 2.0 * ak));
                    cst -= Interval::point(ak);
                } else {
                    terms.push((m, ak));
                }
            }
            let (cm, cr) = mid_rad(cst);
            let dev = (e.dev[j] + cr).next_up();
            base.from_terms(cm, &terms)
                .with_rem(Interval { lo: -dev, hi: dev })
        })
        .collect();
    let direct = smooth_direct(net, &obs);
    from_terms
        .into_iter()
        .enumerate()
        .map(|(j, a)| narrower(a, direct.as_ref().map(|d| d[j].clone())))
        .collect()
}

/// The network evaluated on the Taylor models, for networks without piecewise-linear
/// layers (where the smooth activations' Taylor models can beat CROWN's lines).
fn smooth_direct(net: &Network, obs: &[Tm]) -> Option<Vec<Tm>> {
    let smooth = !net
        .layers
        .iter()
        .any(|l| matches!(l, Layer::Act(a) if a.is_piecewise_linear()));
    smooth.then(|| eval_tm(net, obs))
}

/// The network evaluated on Taylor models: as `net.eval::<Tm>`, but each affine layer
/// over inputs on one monomial table is one dense product of coefficient vectors
/// ([`affine_tm`]) instead of a Taylor-model operation per weight (on docking's 256 x
/// 256 layer, 65,536 scalings and sums each allocating and re-checking a model of
/// thousands of terms: 87 % of a symbolic run's time, measured with perf).
fn eval_tm(net: &Network, x: &[Tm]) -> Vec<Tm> {
    let mut z = match &net.input_norm {
        Some(a) => affine_tm(a, x),
        None => x.to_vec(),
    };
    for l in &net.layers {
        z = match l {
            Layer::Affine(a) => affine_tm(a, &z),
            Layer::Act(act) => z.iter().map(|v| act.apply(v)).collect(),
        };
    }
    match &net.output_denorm {
        Some(a) => affine_tm(a, &z),
        None => z,
    }
}

/// `W x + b` over Taylor models `x` that share one monomial table (else
/// [`Affine::apply`]): per output and monomial the inner product of the weights with
/// the inputs' coefficients, summed in floating point, the rounding bounded as in
/// Higham, "Accuracy and Stability of Numerical Algorithms", (3.5): an inner product of
/// `n` terms (the bias one of them) computed in any order is within `gamma_n` times the
/// sum of the terms' magnitudes, `gamma_n = n u / (1 - n u)`; each monomial ranges over
/// `[-1, 1]` at most, so the sum over monomials of those bounds (doubled, for the
/// rounding of the bound's own sums) plus an underflow allowance bounds the whole
/// polynomial's error, added to the remainder with `sum_j W_ij rem_j` (outward).
fn affine_tm(a: &Affine, x: &[Tm]) -> Vec<Tm> {
    let shared = x.len() == a.inp
        && x.first()
            .is_some_and(|f| f.order() >= 1 && x.iter().all(|v| v.same_basis(f)));
    if !shared {
        return a.apply(x);
    }
    let base = &x[0];
    // Monomials some input uses (the constant always): the others stay zero.
    let used: Vec<usize> = (0..base.n_terms())
        .filter(|&m| m == 0 || x.iter().any(|v| v.coef(m) != 0.0))
        .collect();
    let cols: Vec<Vec<f64>> = x
        .iter()
        .map(|v| used.iter().map(|&m| v.coef(m)).collect())
        .collect();
    let k = used.len();
    let u = 0.5 * f64::EPSILON;
    let n = (a.inp + 1) as f64;
    let gamma = n * u / (1.0 - n * u);
    // A product below the normal range is off by at most half the smallest subnormal.
    let underflow = (a.inp * k) as f64 * f64::MIN_POSITIVE;
    let mut s = vec![0.0; k];
    let mut mag = vec![0.0; k];
    (0..a.out)
        .map(|i| {
            let row = a.dense_row(i);
            s.iter_mut().for_each(|v| *v = 0.0);
            mag.iter_mut().for_each(|v| *v = 0.0);
            s[0] = a.b[i];
            mag[0] = a.b[i].abs();
            let mut rem = Interval::point(0.0);
            for ((&w, col), v) in row.iter().zip(&cols).zip(x) {
                if w == 0.0 {
                    continue;
                }
                for ((sm, am), &c) in s.iter_mut().zip(mag.iter_mut()).zip(col) {
                    let p = w * c;
                    *sm += p;
                    *am += p.abs();
                }
                rem += v.rem() * w;
            }
            let total: f64 = mag.iter().sum();
            let err = (2.0 * gamma * total + underflow).next_up();
            let terms: Vec<(usize, f64)> = used[1..]
                .iter()
                .zip(&s[1..])
                .filter(|(_, &c)| c != 0.0)
                .map(|(&m, &c)| (m, c))
                .collect();
            base.from_terms(s[0], &terms)
                .with_rem(rem + Interval { lo: -err, hi: err })
        })
        .collect()
}

/// The narrower of two enclosures of one output (by the width of their bounds).
fn narrower(a: Tm, b: Option<Tm>) -> Tm {
    match b {
        Some(b) if b.bound().width() < a.bound().width() => b,
        _ => a,
    }
}

/// The network over Taylor-model inputs by CROWN on their linear parts, everything of
/// degree >= 2 and the remainders as a noise box (any network `samara_bounds::linset`
/// supports); for networks without piecewise-linear layers also the network evaluated
/// on the Taylor models, keeping the narrower result per output.
fn network_over_linear(net: &Network, obs: &[Tm], order: u32) -> Vec<Tm> {
    // Linear parts over every parameter any input depends on (after a
    // re-parameterisation there are more than the initial set's).
    let (c0s, g) = linear_parts(obs);
    let n_params = g.first().map_or(0, |r| r.len());
    let mut c = Vec::with_capacity(obs.len());
    let mut noise = Vec::with_capacity(obs.len());
    for (o, c0) in obs.iter().zip(c0s) {
        // Everything that is not linear (higher-order terms, remainder), as a box
        // centred on the linear part's constant shifted by the box's midpoint; the
        // rounding of that shift goes into the box's radius.
        let (mid, r0) = mid_rad(o.nonlinear_bound());
        let centre = c0 + mid;
        let shift_err = (centre - c0 - mid).abs() + f64::EPSILON * centre.abs();
        c.push(centre);
        noise.push((r0 + 2.0 * shift_err).next_up());
    }
    // linset takes the generators: one per parameter, each over the network's inputs.
    let gens: Vec<Vec<f64>> = (0..n_params)
        .map(|k| g.iter().map(|row: &Vec<f64>| row[k]).collect())
        .collect();
    let crown = samara_bounds::linset::bound_over_linear_set(net, &c, &gens, &noise).ok();
    let direct = smooth_direct(net, obs);
    let n_out = net.n_outputs();
    // The outputs on the inputs' table kind: a mixed-degree input's weights (a classic
    // table in all the lifted parameters would cost seconds to build,
    // [`Tm::affine_like`]).
    let kind = obs.iter().find(|v| v.full_params().is_some());
    let affine = |cst: f64, coef: &[f64]| match kind {
        Some(k) => k.affine_like(cst, coef, order),
        None => Tm::affine(cst, coef, order),
    };
    (0..n_out)
        .map(|j| {
            let from_crown = crown.as_ref().map(|e| {
                affine(e.cst[j], &e.coef[j]).with_rem(Interval {
                    lo: -e.dev[j],
                    hi: e.dev[j],
                })
            });
            let from_direct = direct.as_ref().map(|d| d[j].clone());
            match (from_crown, from_direct) {
                (Some(a), b) => narrower(a, b),
                (None, Some(b)) => b,
                (None, None) => {
                    // Not supported by CROWN: interval evaluation over the hull.
                    let bb: Vec<Interval> = obs.iter().map(|o| o.bound()).collect();
                    Tm::from_interval(net.eval::<Interval>(&bb)[j])
                }
            }
        })
        .collect()
}

/// The network's outputs with each remainder given a fresh parameter of its own
/// (`u_j = p_j + m_j + r_j xi_{n + j}` with `[m_j - r_j, m_j + r_j]` containing the
/// remainder): the error of the network step becomes a symbol the flow carries, so the
/// states it reaches stay correlated through it (symbolic remainders, as the generators
/// of a zonotope or the new variables of NNV's star sets) instead of independent
/// intervals. `n` is the number of parameters the states already use.
pub(crate) fn lift_remainders(y: Vec<Tm>, n: usize, order: u32) -> Vec<Tm> {
    // Rounding-size remainders stay intervals: a parameter would cost more than it
    // keeps.
    let lift: Vec<bool> = y
        .iter()
        .map(|v| {
            let b = v.bound();
            v.rem().width() > 1e-9 * (1.0 + b.lo.abs().max(b.hi.abs()))
        })
        .collect();
    let total = n + lift.iter().filter(|l| **l).count();
    let mut k = n;
    y.into_iter()
        .zip(lift)
        .map(|(v, l)| {
            let (p, r) = v.split_rem();
            if l {
                let (m, rad) = mid_rad(r);
                let xi = fresh_param(&p, k, total, order);
                let out = p + xi * rad + m;
                k += 1;
                out
            } else {
                p.with_rem(r)
            }
        })
        .collect()
}

/// Number of monomials of total degree at most `order` in `n` variables.
pub(crate) fn monomials(n: usize, order: usize) -> usize {
    // C(n + order, order), computed incrementally (exact: each prefix is a binomial).
    let mut c: usize = 1;
    for k in 1..=order {
        c = c.saturating_mul(n + k) / k;
    }
    c
}

/// The network as the closed loop reads it (f64).
pub(crate) fn controller(net: &Network) -> impl Fn(&[f64]) -> Vec<f64> + Sync + '_ {
    move |x: &[f64]| net.eval_f64(x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};
    use samara_num::Scalar;

    /// Issue 39's broken `--timeout`: over mixed-degree states (the flow's lifted
    /// parameters, weight 2), the network step and the lifting of its remainders stay on
    /// the states' table kind, so no classic table in all the parameters is built
    /// (order 4 in 47 parameters: 249,900 monomials and seconds, against 2,219). A tanh
    /// network (both paths: CROWN and the direct evaluation) and a ReLU one (CROWN
    /// only); the outputs hold the network's value at random parameter points.
    #[test]
    fn the_network_step_keeps_the_states_lifted_weights() {
        use samara_nn::{Activation, Affine, Layer};
        let (full, n, order) = (2, 47, 4);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let mut rnd = || rng.gen_range(-1.0..1.0);
        let x: Vec<Tm> = (0..full)
            .map(|k| {
                let v = (Tm::var(k, full, order) * 0.1 + rnd()).with_lifted_weight(2);
                // Lifted parameters full..n, each with a small weight.
                (full..n).fold(v, |acc, j| {
                    let p = acc.param(j, n);
                    acc + p * (1e-3 * rnd())
                })
            })
            .collect();
        for act in [Activation::Tanh, Activation::Relu] {
            let net = Network {
                input_names: vec!["a".into(), "b".into()],
                output_names: vec!["u".into()],
                input_norm: None,
                layers: vec![
                    Layer::Affine(Affine::new(
                        2,
                        3,
                        vec![0.5, -0.2, 0.3, 0.1, -0.4, 0.6],
                        vec![0.1, 0.0, -0.1],
                    )),
                    Layer::Act(act),
                    Layer::Affine(Affine::new(3, 1, vec![0.7, -0.3, 0.2], vec![0.05])),
                ],
                output_denorm: None,
            };
            let y = network_over(&net, &x, order);
            assert_eq!(y[0].full_params(), Some(full), "{act:?}: network step");
            let lifted = lift_remainders(y.clone(), n, order);
            assert_eq!(lifted[0].full_params(), Some(full), "{act:?}: lifted");
            for _ in 0..200 {
                let xi: Vec<f64> = (0..n).map(|_| rnd()).collect();
                let inp: Vec<f64> = x.iter().map(|v| v.eval_at(&xi).lo).collect();
                let want = net.eval_f64(&inp)[0];
                let got = y[0].eval_at(&xi);
                let tol = 1e-9 * (1.0 + want.abs());
                assert!(
                    got.lo - tol <= want && want <= got.hi + tol,
                    "{act:?}: {want} outside {got:?}"
                );
            }
        }
    }

    /// The dense affine layers of the direct evaluation ([`eval_tm`]) against the
    /// network in f64 at sampled points: a random 4-24-24-2 tanh network with an input
    /// normalisation and a denormalisation, over Taylor models in 6 parameters of
    /// order 3 with quadratic terms and remainders; at 2,000 random parameter points
    /// with random points of the input remainders, the network's value lies in the
    /// output models' enclosure at that point. The enclosures are also as narrow as the
    /// generic evaluation's (`net.eval::<Tm>`, one operation per weight) up to rounding,
    /// and inputs on different tables fall back to it.
    #[test]
    fn dense_affine_layers_hold_the_sampled_network() {
        use samara_nn::{Activation, Affine, Layer};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(23);
        let mut rnd = |s: f64| s * rng.gen_range(-1.0..1.0);
        let dense = |inp: usize, out: usize, rnd: &mut dyn FnMut(f64) -> f64| {
            let w = (0..inp * out).map(|_| rnd(0.8)).collect();
            let b = (0..out).map(|_| rnd(0.3)).collect();
            Affine::new(inp, out, w, b)
        };
        let net = Network {
            input_names: (0..4).map(|i| format!("x{i}")).collect(),
            output_names: vec!["u".into(), "v".into()],
            input_norm: Some(Affine::normalise(
                &[0.5, -1.0, 0.0, 2.0],
                &[2.0, 3.0, 0.5, 4.0],
            )),
            layers: vec![
                Layer::Affine(dense(4, 24, &mut rnd)),
                Layer::Act(Activation::Tanh),
                Layer::Affine(dense(24, 24, &mut rnd)),
                Layer::Act(Activation::Tanh),
                Layer::Affine(dense(24, 2, &mut rnd)),
            ],
            output_denorm: Some(Affine::denormalise(&[0.1, -0.2], &[3.0, 0.5])),
        };
        let (n, order) = (6, 3);
        let centre = [0.5, -1.0, 0.0, 2.0];
        let x: Vec<Tm> = (0..4)
            .map(|i| {
                let lin = (0..n).fold(Tm::constant(centre[i], n, order), |acc, k| {
                    acc + Tm::var(k, n, order) * rnd(0.3)
                });
                let q = Tm::var(i, n, order) * Tm::var((i + 1) % n, n, order) * rnd(0.1);
                let r = rnd(0.02).abs();
                (lin + q).with_rem(Interval {
                    lo: -r,
                    hi: 0.5 * r,
                })
            })
            .collect();
        let fast = eval_tm(&net, &x);
        let generic = net.eval::<Tm>(&x);
        for (f, g) in fast.iter().zip(&generic) {
            let (wf, wg) = (f.bound().width(), g.bound().width());
            assert!(
                wf <= wg * (1.0 + 1e-9) + 1e-12,
                "dense {wf} vs generic {wg}"
            );
        }
        for _ in 0..2000 {
            let xi: Vec<f64> = (0..n).map(|_| rnd(1.0)).collect();
            let inp: Vec<f64> = x
                .iter()
                .map(|v| {
                    let p = v.clone().split_rem().0.eval_at(&xi);
                    let r = v.rem();
                    let t = 0.5 + 0.5 * rnd(1.0);
                    0.5 * (p.lo + p.hi) + r.lo + t * (r.hi - r.lo)
                })
                .collect();
            let want = net.eval_f64(&inp);
            for (j, y) in fast.iter().enumerate() {
                let got = y.eval_at(&xi);
                let tol = 1e-9 * (1.0 + want[j].abs());
                assert!(
                    got.lo - tol <= want[j] && want[j] <= got.hi + tol,
                    "output {j}: {} outside {got:?}",
                    want[j]
                );
            }
        }
        // Inputs on different tables: the generic layer, the same models.
        let mixed = vec![x[0].clone(), Tm::var(0, 2, 2), x[2].clone(), x[3].clone()];
        let Layer::Affine(first) = &net.layers[0] else {
            unreachable!()
        };
        let a = affine_tm(first, &mixed);
        let b = first.apply(&mixed);
        for (p, q) in a.iter().zip(&b) {
            assert_eq!(p.bound(), q.bound());
        }
    }

    /// A lifted output (its remainder turned into a fresh parameter) still holds
    /// every value of the original model: at random parameter points, the original's
    /// enclosure `p(xi) + rem` (both ends) is reached by the lifted polynomial at the
    /// new parameter's ends, whose enclosures contain those values; the new parameters
    /// are numbered after the states' and the polynomial part is unchanged.
    #[test]
    fn lifted_remainders_keep_every_value() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        let mut rnd = || rng.gen_range(-1.0..1.0);
        for _ in 0..200 {
            let n = 3;
            let x: Vec<Tm> = (0..n)
                .map(|k| Tm::var(k, n, 3) * (0.5 + rnd().abs()) + rnd())
                .collect();
            let y0 = (x[0].clone() * x[1].clone() + x[2].clone().sqr()) * rnd();
            let r = Interval::new(-rnd().abs() - 1e-3, rnd().abs());
            let y = vec![y0.clone().with_rem(r), Tm::var(0, n, 3)];
            let lifted = lift_remainders(y, n, 3);
            assert_eq!(lifted[0].n_vars(), n + 1);
            assert!(
                lifted[1].rem().width() < 1e-300,
                "rounding-size remainders stay"
            );
            let xi: Vec<f64> = (0..n).map(|_| rnd()).collect();
            let v = y0.eval_at(&xi);
            for (end, target) in [(-1.0, v.lo + r.lo), (1.0, v.hi + r.hi)] {
                let mut p = xi.clone();
                p.push(end);
                let w = lifted[0].eval_at(&p);
                // The ends of the original enclosure are met at the new parameter's
                // ends, up to rounding.
                let tol = 1e-12 * (1.0 + target.abs());
                if end < 0.0 {
                    assert!(w.lo <= target + tol, "{w:?} vs {target}");
                } else {
                    assert!(w.hi >= target - tol, "{w:?} vs {target}");
                }
            }
        }
    }
}

//! The training loop: mini-batch Adam on MSE plus the method's term, and the metrics.

use crate::data::{split, MinMax, Table};
use crate::mlp::{Adam, Cache, Mlp};
use crate::property::{Logic, Property};
use crate::region::Region;
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use samara_nn::{Affine, Network};

/// Adversarial example generator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Attack {
    /// Fast gradient sign method (Goodfellow et al. 2015): one signed step of size eps,
    /// no projection (the published training).
    Fgsm,
    /// Projected gradient descent (Madry et al. 2018): random start in the eps-ball,
    /// `steps` signed steps of 2.5 eps / steps, projection onto the eps-ball intersected
    /// with the input domain [0, 1]^n.
    Pgd {
        /// Number of steps.
        steps: usize,
    },
}

/// What is trained for.
#[derive(Clone, Debug, PartialEq)]
pub enum Method {
    /// Mean squared error.
    Plain,
    /// MSE on clean and adversarial rows together.
    Adversarial(Attack),
    /// MSE + weight * mean(max(0, |f(x') - f(x)| - L ||x' - x||_inf)), x' from a PGD
    /// attack maximising the deviation; gradients through f(x) and f(x').
    Lipschitz {
        /// The Lipschitz constant L (normalised units).
        l: f64,
        /// Penalty weight.
        weight: f64,
    },
    /// MSE + weight * property loss at counterexamples found by PGD in each region.
    Properties {
        /// Logic.
        logic: Logic,
        /// Properties (normalised units).
        props: Vec<Property>,
        /// Penalty weight.
        weight: f64,
    },
}

impl Method {
    /// Short name for logs and reports.
    pub fn name(&self) -> &'static str {
        match self {
            Method::Plain => "plain",
            Method::Adversarial(_) => "adversarial",
            Method::Lipschitz { .. } => "lipschitz",
            Method::Properties {
                logic: Logic::Dl2, ..
            } => "dl2",
            Method::Properties {
                logic: Logic::Goedel,
                ..
            } => "goedel",
        }
    }
}

/// Training settings; defaults are the published setting (6-6-4-1, ReLU on every layer,
/// Adam lr 0.06, batch 50, 1000 epochs, 10% test split).
#[derive(Clone, Debug)]
pub struct TrainOptions {
    /// Layer widths (first = inputs, last = outputs).
    pub arch: Vec<usize>,
    /// Epochs.
    pub epochs: usize,
    /// Mini-batch size.
    pub batch: usize,
    /// Adam learning rate.
    pub lr: f64,
    /// Seed of initialisation, split, shuffles and attacks.
    pub seed: u64,
    /// Fraction of rows held out for testing.
    pub test_fraction: f64,
    /// ReLU on the output layer (the published networks have it).
    pub relu_output: bool,
    /// Attack radius (normalised input units) for adversarial training and metrics.
    pub eps: f64,
    /// PGD steps for metrics and the Lipschitz/property searches.
    pub attack_steps: usize,
    /// The method.
    pub method: Method,
    /// Show a progress bar on stderr.
    pub progress: bool,
}

impl Default for TrainOptions {
    fn default() -> Self {
        TrainOptions {
            arch: vec![6, 6, 4, 1],
            epochs: 1000,
            batch: 50,
            lr: 0.06,
            seed: 0,
            test_fraction: 0.1,
            relu_output: true,
            eps: 0.005,
            attack_steps: 10,
            method: Method::Plain,
            progress: false,
        }
    }
}

/// Invalid settings or data.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TrainError {
    /// Settings out of range.
    #[error("invalid training setting: {0}")]
    Settings(String),
    /// Data do not fit the architecture.
    #[error("the data have {cols} columns but the architecture {arch:?} needs {need} ({inputs} inputs + {outputs} outputs)")]
    Shape {
        /// Columns of the data.
        cols: usize,
        /// Architecture.
        arch: Vec<usize>,
        /// Needed columns.
        need: usize,
        /// Inputs.
        inputs: usize,
        /// Outputs.
        outputs: usize,
    },
}

impl TrainOptions {
    /// Check the settings.
    pub fn validate(&self) -> Result<(), TrainError> {
        let bad = |m: &str| Err(TrainError::Settings(m.into()));
        if self.arch.len() < 2 || self.arch.contains(&0) {
            return bad("--arch needs at least two positive widths, e.g. 6,6,4,1");
        }
        if self.epochs == 0 || self.batch == 0 {
            return bad("epochs and batch must be positive");
        }
        if !(self.lr > 0.0 && self.lr.is_finite()) {
            return bad("the learning rate must be positive");
        }
        if !(0.0..1.0).contains(&self.test_fraction) {
            return bad("the test fraction must be in [0, 1)");
        }
        if !(self.eps >= 0.0 && self.eps.is_finite()) {
            return bad("--eps must be a non-negative number");
        }
        if let Method::Lipschitz { l, .. } = self.method {
            if !(l >= 0.0 && l.is_finite()) {
                return bad("--lipschitz must be a non-negative number");
            }
        }
        Ok(())
    }
}

/// One row of the training log.
#[derive(Clone, Debug, PartialEq)]
pub struct LogRow {
    /// Epoch (1-based).
    pub epoch: usize,
    /// Mean training loss of the epoch (MSE + method term, normalised units).
    pub loss: f64,
    /// Test RMSE of ex (raw units).
    pub test_rmse: f64,
}

/// Metrics on the test split, in raw output units.
#[derive(Clone, Debug, PartialEq)]
pub struct Metrics {
    /// Root mean squared error.
    pub rmse: f64,
    /// Mean absolute error.
    pub mae: f64,
    /// Coefficient of determination.
    pub r2: f64,
    /// Worst output deviation |f(x') - f(x)| found by PGD within eps (raw output units),
    /// over the test points.
    pub attack_worst: f64,
    /// Mean of the per-point worst deviations.
    pub attack_mean: f64,
    /// Test rows.
    pub n_test: usize,
}

/// The result of training.
#[derive(Clone, Debug)]
pub struct TrainOutcome {
    /// The trained network in raw units (normalisation layers included).
    pub network: Network,
    /// Test metrics.
    pub metrics: Metrics,
    /// Per-epoch log.
    pub log: Vec<LogRow>,
}

/// Normalised rows: inputs z in [0,1]^n and outputs t.
struct Normalised {
    z: Vec<Vec<f64>>,
    t: Vec<Vec<f64>>,
}

fn normalise(data: &Table, mm: &MinMax, n_in: usize) -> Normalised {
    let mut z = Vec::with_capacity(data.rows());
    let mut t = Vec::with_capacity(data.rows());
    for i in 0..data.rows() {
        let r = data.row(i);
        z.push(
            (0..n_in)
                .map(|j| (r[j] - mm.min[j]) / mm.range[j])
                .collect(),
        );
        t.push(
            (n_in..data.cols)
                .map(|j| (r[j] - mm.min[j]) / mm.range[j])
                .collect(),
        );
    }
    Normalised { z, t }
}

/// Maximise `|f(x') - f(anchor)|` (first output) over `region` by signed-gradient ascent
/// from `start`, `steps` steps of size `step`; returns the best point and deviation.
#[allow(clippy::too_many_arguments)]
fn pgd_deviation(
    net: &Mlp,
    cache: &mut Cache,
    gx: &mut [f64],
    scratch: &mut [f64],
    anchor_out: f64,
    start: &[f64],
    region: &Region,
    steps: usize,
    step: f64,
) -> (Vec<f64>, f64) {
    let mut x = region.project(start).unwrap_or_else(|| start.to_vec());
    let mut best = (x.clone(), (net.forward(&x, cache)[0] - anchor_out).abs());
    for _ in 0..steps {
        let y = net.forward(&x, cache)[0];
        let sgn = if y >= anchor_out { 1.0 } else { -1.0 };
        net.backward(cache, &[sgn], 0.0, scratch, Some(gx));
        let moved: Vec<f64> = x
            .iter()
            .zip(gx.iter())
            .map(|(v, g)| v + step * g.signum())
            .collect();
        x = region.project(&moved).unwrap_or(moved);
        let dev = (net.forward(&x, cache)[0] - anchor_out).abs();
        if dev > best.1 {
            best = (x.clone(), dev);
        }
    }
    best
}

/// The eps-ball around `x` intersected with [0, 1]^n.
fn ball(x: &[f64], eps: f64) -> Region {
    Region::boxed(
        x.iter().map(|v| (v - eps).max(0.0)).collect(),
        x.iter().map(|v| (v + eps).min(1.0)).collect(),
    )
}

/// Train a network on `data` (columns: inputs then outputs, raw units) with min-max
/// constants `mm` (computed from the data when `None`).
pub fn train(
    data: &Table,
    mm: Option<&MinMax>,
    o: &TrainOptions,
) -> Result<TrainOutcome, TrainError> {
    o.validate()?;
    let n_in = o.arch[0];
    let n_out = *o.arch.last().expect("validated");
    if data.cols != n_in + n_out {
        return Err(TrainError::Shape {
            cols: data.cols,
            arch: o.arch.clone(),
            need: n_in + n_out,
            inputs: n_in,
            outputs: n_out,
        });
    }
    let computed;
    let mm = match mm {
        Some(m) => {
            if m.min.len() < data.cols {
                return Err(TrainError::Settings(format!(
                    "the normalisation constants have {} columns but the data have {}",
                    m.min.len(),
                    data.cols
                )));
            }
            m
        }
        None => {
            computed = MinMax::of(data);
            &computed
        }
    };
    let nd = normalise(data, mm, n_in);
    let (train_idx, test_idx) = split(data.rows(), o.test_fraction, o.seed);
    if train_idx.is_empty() {
        return Err(TrainError::Settings(
            "no training rows left after the test split".into(),
        ));
    }
    let mut rng = ChaCha8Rng::seed_from_u64(o.seed.wrapping_add(0x5a5a));
    let mut net = Mlp::new(&o.arch, o.relu_output, &mut rng);
    let mut adam = Adam::new(net.params.len(), o.lr);
    let mut grad = vec![0.0; net.params.len()];
    let mut scratch = vec![0.0; net.params.len()];
    let mut cache = net.cache();
    let mut cache2 = net.cache();
    let mut gx = vec![0.0; n_in];
    let mut order = train_idx.clone();
    let mut log = Vec::with_capacity(o.epochs);
    let pb = if o.progress {
        let pb = ProgressBar::with_draw_target(Some(o.epochs as u64), ProgressDrawTarget::stderr());
        pb.set_style(
            ProgressStyle::with_template("training {msg} [{bar:30}] {pos}/{len} epochs {elapsed}")
                .unwrap_or_else(|_| ProgressStyle::default_bar())
                .progress_chars("=> "),
        );
        pb.set_message(o.method.name().to_string());
        pb
    } else {
        ProgressBar::hidden()
    };
    for epoch in 1..=o.epochs {
        order.shuffle(&mut rng);
        let mut epoch_loss = 0.0;
        let mut seen = 0usize;
        for chunk in order.chunks(o.batch) {
            grad.iter_mut().for_each(|g| *g = 0.0);
            let mut rows: Vec<(Vec<f64>, &Vec<f64>)> =
                chunk.iter().map(|&i| (nd.z[i].clone(), &nd.t[i])).collect();
            if let Method::Adversarial(attack) = &o.method {
                let mut adv = Vec::with_capacity(rows.len());
                for (x, t) in &rows {
                    let xa = match attack {
                        Attack::Fgsm => {
                            let y = net.forward(x, &mut cache).to_vec();
                            let d: Vec<f64> =
                                y.iter().zip(t.iter()).map(|(a, b)| 2.0 * (a - b)).collect();
                            net.backward(&mut cache, &d, 0.0, &mut scratch, Some(&mut gx));
                            x.iter()
                                .zip(&gx)
                                .map(|(v, g)| v + o.eps * g.signum())
                                .collect()
                        }
                        Attack::Pgd { steps } => {
                            let r = ball(x, o.eps);
                            let start: Vec<f64> = x
                                .iter()
                                .map(|v| v + rng.gen_range(-o.eps..=o.eps))
                                .collect();
                            let mut xa = r.project(&start).unwrap_or_else(|| x.clone());
                            let step = 2.5 * o.eps / (*steps).max(1) as f64;
                            for _ in 0..*steps {
                                let y = net.forward(&xa, &mut cache).to_vec();
                                let d: Vec<f64> =
                                    y.iter().zip(t.iter()).map(|(a, b)| 2.0 * (a - b)).collect();
                                net.backward(&mut cache, &d, 0.0, &mut scratch, Some(&mut gx));
                                let moved: Vec<f64> = xa
                                    .iter()
                                    .zip(&gx)
                                    .map(|(v, g)| v + step * g.signum())
                                    .collect();
                                xa = r.project(&moved).unwrap_or(moved);
                            }
                            xa
                        }
                    };
                    adv.push((xa, *t));
                }
                rows.extend(adv);
            }
            let scale = 1.0 / rows.len() as f64;
            for (x, t) in &rows {
                let y = net.forward(x, &mut cache).to_vec();
                let d: Vec<f64> = y
                    .iter()
                    .zip(t.iter())
                    .map(|(a, b)| 2.0 * (a - b) / n_out as f64)
                    .collect();
                epoch_loss += y
                    .iter()
                    .zip(t.iter())
                    .map(|(a, b)| (a - b).powi(2))
                    .sum::<f64>()
                    / n_out as f64;
                seen += 1;
                net.backward(&mut cache, &d, scale, &mut grad, None);
            }
            match &o.method {
                Method::Lipschitz { l, weight } => {
                    let ws = weight / chunk.len() as f64;
                    for &i in chunk {
                        let x = &nd.z[i];
                        let fx = net.forward(x, &mut cache2)[0];
                        let r = ball(x, o.eps);
                        let start: Vec<f64> = x
                            .iter()
                            .map(|v| v + rng.gen_range(-o.eps..=o.eps))
                            .collect();
                        let step = 2.5 * o.eps / o.attack_steps.max(1) as f64;
                        let (xp, _) = pgd_deviation(
                            &net,
                            &mut cache,
                            &mut gx,
                            &mut scratch,
                            fx,
                            &start,
                            &r,
                            o.attack_steps,
                            step,
                        );
                        let fxp = net.forward(&xp, &mut cache)[0];
                        let dist = xp
                            .iter()
                            .zip(x)
                            .map(|(a, b)| (a - b).abs())
                            .fold(0.0, f64::max);
                        let hinge = (fxp - fx).abs() - l * dist;
                        if hinge > 0.0 {
                            epoch_loss += weight * hinge;
                            let s = (fxp - fx).signum();
                            // d/dθ |f(x') - f(x)| = s (∇f(x') - ∇f(x)).
                            net.backward(&mut cache, &[s], ws, &mut grad, None);
                            net.forward(x, &mut cache2);
                            net.backward(&mut cache2, &[-s], ws, &mut grad, None);
                        }
                    }
                }
                Method::Properties {
                    logic,
                    props,
                    weight,
                } => {
                    for p in props {
                        if !p.region.is_nonempty() {
                            continue;
                        }
                        // Counterexample search: maximise the property loss over the region.
                        let mut best: Option<(Vec<f64>, f64)> = None;
                        for _ in 0..4 {
                            let start: Vec<f64> = p
                                .region
                                .lo
                                .iter()
                                .zip(&p.region.hi)
                                .map(|(a, b)| rng.gen_range(*a..=*b))
                                .collect();
                            let mut x = p.region.project(&start).expect("non-empty");
                            let width = p
                                .region
                                .lo
                                .iter()
                                .zip(&p.region.hi)
                                .map(|(a, b)| b - a)
                                .fold(0.0, f64::max);
                            let step = 0.05 * width.max(1e-6);
                            for _ in 0..o.attack_steps {
                                let y = net.forward(&x, &mut cache)[0];
                                let (_, dl) = p.formula.loss(*logic, y);
                                if dl == 0.0 {
                                    // Flat here: push the output towards violation instead.
                                    net.backward(
                                        &mut cache,
                                        &[1.0],
                                        0.0,
                                        &mut scratch,
                                        Some(&mut gx),
                                    );
                                } else {
                                    net.backward(
                                        &mut cache,
                                        &[dl],
                                        0.0,
                                        &mut scratch,
                                        Some(&mut gx),
                                    );
                                }
                                let moved: Vec<f64> = x
                                    .iter()
                                    .zip(&gx)
                                    .map(|(v, g)| v + step * g.signum())
                                    .collect();
                                x = p.region.project(&moved).unwrap_or(moved);
                            }
                            let y = net.forward(&x, &mut cache)[0];
                            let (lv, _) = p.formula.loss(*logic, y);
                            if best.as_ref().is_none_or(|b| lv > b.1) {
                                best = Some((x, lv));
                            }
                        }
                        if let Some((x, lv)) = best {
                            if lv > 0.0 {
                                epoch_loss += weight * lv;
                                let y = net.forward(&x, &mut cache)[0];
                                let (_, dl) = p.formula.loss(*logic, y);
                                net.backward(&mut cache, &[dl], *weight, &mut grad, None);
                            }
                        }
                    }
                }
                _ => {}
            }
            adam.step(&mut net.params, &grad);
        }
        let test_rmse = metrics_basic(&net, &nd, &test_idx, mm, n_in).0;
        log.push(LogRow {
            epoch,
            loss: epoch_loss / seen.max(1) as f64,
            test_rmse,
        });
        pb.inc(1);
    }
    pb.finish_and_clear();
    let (rmse, mae, r2) = metrics_basic(&net, &nd, &test_idx, mm, n_in);
    let (attack_worst, attack_mean) = robustness(&net, &nd, &test_idx, o, mm.range[n_in]);
    let network = to_network(&net, mm, n_in, data);
    Ok(TrainOutcome {
        network,
        metrics: Metrics {
            rmse,
            mae,
            r2,
            attack_worst,
            attack_mean,
            n_test: test_idx.len(),
        },
        log,
    })
}

/// RMSE, MAE, R^2 of the first output in raw units over `idx`.
fn metrics_basic(
    net: &Mlp,
    nd: &Normalised,
    idx: &[usize],
    mm: &MinMax,
    n_in: usize,
) -> (f64, f64, f64) {
    if idx.is_empty() {
        return (f64::NAN, f64::NAN, f64::NAN);
    }
    let mut c = net.cache();
    let (s, m) = (mm.range[n_in], mm.min[n_in]);
    let pairs: Vec<(f64, f64)> = idx
        .iter()
        .map(|&i| (m + s * net.forward(&nd.z[i], &mut c)[0], m + s * nd.t[i][0]))
        .collect();
    let n = pairs.len() as f64;
    let mse = pairs.iter().map(|(p, t)| (p - t).powi(2)).sum::<f64>() / n;
    let mae = pairs.iter().map(|(p, t)| (p - t).abs()).sum::<f64>() / n;
    let mean = pairs.iter().map(|p| p.1).sum::<f64>() / n;
    let var = pairs.iter().map(|(_, t)| (t - mean).powi(2)).sum::<f64>() / n;
    let r2 = if var > 0.0 { 1.0 - mse / var } else { f64::NAN };
    (mse.sqrt(), mae, r2)
}

/// Worst and mean PGD deviation within eps over the test points (raw output units).
fn robustness(
    net: &Mlp,
    nd: &Normalised,
    idx: &[usize],
    o: &TrainOptions,
    out_scale: f64,
) -> (f64, f64) {
    if idx.is_empty() || o.eps == 0.0 {
        return (0.0, 0.0);
    }
    let mut rng = ChaCha8Rng::seed_from_u64(o.seed.wrapping_add(77));
    let (mut c, mut gx, mut scratch) = (
        net.cache(),
        vec![0.0; o.arch[0]],
        vec![0.0; net.params.len()],
    );
    let steps = o.attack_steps.max(20);
    let mut worst = 0.0f64;
    let mut sum = 0.0;
    for &i in idx {
        let x = &nd.z[i];
        let fx = net.forward(x, &mut c)[0];
        let r = ball(x, o.eps);
        let mut best = 0.0f64;
        for restart in 0..3 {
            let start: Vec<f64> = if restart == 0 {
                x.clone()
            } else {
                x.iter()
                    .map(|v| v + rng.gen_range(-o.eps..=o.eps))
                    .collect()
            };
            let (_, d) = pgd_deviation(
                net,
                &mut c,
                &mut gx,
                &mut scratch,
                fx,
                &start,
                &r,
                steps,
                2.5 * o.eps / steps as f64,
            );
            best = best.max(d);
        }
        worst = worst.max(best);
        sum += best;
    }
    (worst * out_scale, sum / idx.len() as f64 * out_scale)
}

fn to_network(net: &Mlp, mm: &MinMax, n_in: usize, data: &Table) -> Network {
    let n_out = net.sizes.last().copied().unwrap_or(1);
    let names = |r: std::ops::Range<usize>| -> Vec<String> {
        r.map(|j| {
            data.names
                .get(j)
                .cloned()
                .unwrap_or_else(|| format!("c{j}"))
        })
        .collect()
    };
    Network {
        input_names: names(0..n_in),
        output_names: names(n_in..n_in + n_out),
        input_norm: Some(Affine::normalise(&mm.min[..n_in], &mm.range[..n_in])),
        layers: net.to_layers(),
        output_denorm: Some(Affine::denormalise(
            &mm.min[n_in..n_in + n_out],
            &mm.range[n_in..n_in + n_out],
        )),
    }
}

//! The network IR: what every part of samara (simulation, training, verification,
//! reachability) reads.
//!
//! A [`Network`] is an optional input normalisation (an affine map, usually diagonal:
//! `(x - c) / s`), a body of layers, and an optional output denormalisation (an affine
//! map, e.g. `ex = 0.181 + 0.012 * out`). Keeping the two as distinguished layers lets
//! the same network be used in raw units ([`Network::eval`]) or in normalised units
//! ([`Network::eval_normalised`]).

use samara_num::Scalar;

/// A dense affine map `y = W x + b`, `W` stored row-major (`out x inp`).
#[derive(Clone, Debug, PartialEq)]
pub struct Affine {
    /// Number of inputs.
    pub inp: usize,
    /// Number of outputs.
    pub out: usize,
    /// Row-major weights, `out * inp` entries: `w[i * inp + j]` maps input j to output i.
    pub w: Vec<f64>,
    /// Biases, `out` entries.
    pub b: Vec<f64>,
}

impl Affine {
    /// A new affine map; `w.len() == out * inp` and `b.len() == out` are checked by
    /// [`Network::validate`].
    pub fn new(inp: usize, out: usize, w: Vec<f64>, b: Vec<f64>) -> Self {
        Affine { inp, out, w, b }
    }

    /// The diagonal map `y_i = (x_i - c_i) / s_i` (min-max normalisation).
    pub fn normalise(c: &[f64], s: &[f64]) -> Self {
        let n = c.len();
        let mut w = vec![0.0; n * n];
        let mut b = vec![0.0; n];
        for i in 0..n {
            w[i * n + i] = 1.0 / s[i];
            b[i] = -c[i] / s[i];
        }
        Affine::new(n, n, w, b)
    }

    /// The diagonal map `y_i = c_i + s_i * x_i` (denormalisation).
    pub fn denormalise(c: &[f64], s: &[f64]) -> Self {
        let n = c.len();
        let mut w = vec![0.0; n * n];
        for i in 0..n {
            w[i * n + i] = s[i];
        }
        Affine::new(n, n, w, c.to_vec())
    }

    /// Weight from input `j` to output `i`.
    #[inline]
    pub fn weight(&self, i: usize, j: usize) -> f64 {
        self.w[i * self.inp + j]
    }

    /// Apply to a vector of any scalar type. Zero weights are skipped, so a diagonal
    /// normalisation does not couple the dependencies of set-valued inputs.
    pub fn apply<S: Scalar>(&self, x: &[S]) -> Vec<S> {
        (0..self.out)
            .map(|i| {
                let row = &self.w[i * self.inp..(i + 1) * self.inp];
                let mut acc = S::cst(self.b[i]);
                for (wij, xj) in row.iter().zip(x) {
                    if *wij != 0.0 {
                        acc += xj.clone() * *wij;
                    }
                }
                acc
            })
            .collect()
    }

    /// Apply to an f64 vector, writing into `y` (no allocation). On long rows (a lowered
    /// convolution's: a kernel's patch of non-zeros among thousands of inputs) the zero
    /// weights are skipped: the same additions in the same order without those of exact
    /// zeros, so the same value for finite inputs, without a chain of dependent
    /// additions through every zero.
    #[inline]
    pub fn apply_f64(&self, x: &[f64], y: &mut [f64]) {
        let skip = self.inp >= 256;
        for ((yi, row), bi) in y.iter_mut().zip(self.w.chunks_exact(self.inp)).zip(&self.b) {
            let mut acc = *bi;
            if skip {
                for (wij, xj) in row.iter().zip(x) {
                    if *wij != 0.0 {
                        acc += wij * xj;
                    }
                }
            } else {
                for (wij, xj) in row.iter().zip(x) {
                    acc += wij * xj;
                }
            }
            *yi = acc;
        }
    }
}

/// An elementwise activation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Activation {
    /// `max(x, 0)`.
    Relu,
    /// `1 / (1 + exp(-x))`.
    Sigmoid,
    /// `tanh(x)`.
    Tanh,
    /// `min(max(x, lo), hi)`.
    Clamp {
        /// Lower bound (may be `-inf`).
        lo: f64,
        /// Upper bound (may be `+inf`).
        hi: f64,
    },
    /// ONNX `Sign`: `-1` for `x < 0`, `0` at `0`, `1` for `x > 0` (the binarised layers of
    /// BNNs). A step, so no chain of ReLUs computes it: engines that need a
    /// piecewise-linear network refuse it, and bounds come from its own rule.
    Sign,
}

impl Activation {
    /// Apply to one number of any scalar type.
    pub fn apply<S: Scalar>(&self, x: &S) -> S {
        match *self {
            Activation::Relu => x.relu(),
            Activation::Sigmoid => x.sigmoid(),
            Activation::Tanh => x.tanh(),
            Activation::Clamp { lo, hi } => x.clamp_to(lo, hi),
            // NaN stays NaN (a point type's `sgn` of NaN would be a number).
            Activation::Sign if x.value().is_nan() => x.clone(),
            Activation::Sign => x.sgn(),
        }
    }

    /// Apply to one f64. NaN propagates (`f64::max(NaN, 0)` is 0, which would turn a
    /// NaN input into a plausible number), as in [`Activation::apply`].
    #[inline]
    pub fn apply_f64(&self, x: f64) -> f64 {
        match *self {
            Activation::Relu => {
                if x <= 0.0 {
                    0.0
                } else {
                    x
                }
            }
            Activation::Sigmoid => 1.0 / (1.0 + (-x).exp()),
            Activation::Tanh => x.tanh(),
            Activation::Clamp { lo, hi } => {
                if x.is_nan() {
                    x
                } else {
                    x.max(lo).min(hi)
                }
            }
            Activation::Sign => {
                if x > 0.0 {
                    1.0
                } else if x < 0.0 {
                    -1.0
                } else {
                    // 0 stays 0 (of either sign), NaN stays NaN.
                    x
                }
            }
        }
    }

    /// Whether the activation is piecewise linear (exact MILP/LP encodings exist).
    pub fn is_piecewise_linear(&self) -> bool {
        matches!(self, Activation::Relu | Activation::Clamp { .. })
    }
}

/// One layer of the body.
#[derive(Clone, Debug, PartialEq)]
pub enum Layer {
    /// A dense affine map.
    Affine(Affine),
    /// An elementwise activation.
    Act(Activation),
}

/// A feed-forward network with named inputs and outputs and optional
/// normalisation/denormalisation affine layers around its body.
#[derive(Clone, Debug, PartialEq)]
pub struct Network {
    /// Names of the inputs, in order (e.g. `v_xp, v_yp, omega, theta, x, y`).
    pub input_names: Vec<String>,
    /// Names of the outputs, in order (e.g. `ex`).
    pub output_names: Vec<String>,
    /// Raw -> normalised input map, if the network carries one.
    pub input_norm: Option<Affine>,
    /// The body: normalised inputs -> normalised outputs.
    pub layers: Vec<Layer>,
    /// Normalised -> raw output map, if the network carries one.
    pub output_denorm: Option<Affine>,
}

impl Network {
    /// Number of inputs.
    pub fn n_inputs(&self) -> usize {
        self.input_names.len()
    }

    /// Number of outputs.
    pub fn n_outputs(&self) -> usize {
        self.output_names.len()
    }

    /// Evaluate in raw units: normalisation, body, denormalisation.
    pub fn eval<S: Scalar>(&self, x: &[S]) -> Vec<S> {
        let z = match &self.input_norm {
            Some(a) => a.apply(x),
            None => x.to_vec(),
        };
        let y = self.eval_normalised(&z);
        match &self.output_denorm {
            Some(a) => a.apply(&y),
            None => y,
        }
    }

    /// Evaluate the body only (normalised inputs to normalised outputs).
    pub fn eval_normalised<S: Scalar>(&self, x: &[S]) -> Vec<S> {
        let mut z = x.to_vec();
        for l in &self.layers {
            z = match l {
                Layer::Affine(a) => a.apply(&z),
                Layer::Act(act) => z.iter().map(|v| act.apply(v)).collect(),
            };
        }
        z
    }

    /// Evaluate in raw units in f64 (the reference evaluator verdicts are checked with).
    pub fn eval_f64(&self, x: &[f64]) -> Vec<f64> {
        let mut z = x.to_vec();
        let mut tmp = Vec::new();
        let mut affine = |a: &Affine, z: &mut Vec<f64>| {
            tmp.resize(a.out, 0.0);
            a.apply_f64(z, &mut tmp);
            std::mem::swap(z, &mut tmp);
        };
        if let Some(a) = &self.input_norm {
            affine(a, &mut z);
        }
        for l in &self.layers {
            match l {
                Layer::Affine(a) => affine(a, &mut z),
                Layer::Act(act) => z.iter_mut().for_each(|v| *v = act.apply_f64(*v)),
            }
        }
        if let Some(a) = &self.output_denorm {
            affine(a, &mut z);
        }
        z
    }

    /// Evaluate a batch in f64: `xs` holds `n` rows of [`Network::n_inputs`] values
    /// (row-major); returns `n` rows of outputs.
    pub fn eval_batch_f64(&self, xs: &[f64], n: usize) -> Vec<f64> {
        let d = self.n_inputs();
        (0..n)
            .flat_map(|r| self.eval_f64(&xs[r * d..(r + 1) * d]))
            .collect()
    }

    /// The same network with new input and output names (lengths must match).
    pub fn with_names(mut self, inputs: &[&str], outputs: &[&str]) -> Result<Self, IrError> {
        if inputs.len() != self.n_inputs() || outputs.len() != self.n_outputs() {
            return Err(IrError::Names {
                inputs: self.n_inputs(),
                outputs: self.n_outputs(),
                given_inputs: inputs.len(),
                given_outputs: outputs.len(),
            });
        }
        self.input_names = inputs.iter().map(|s| s.to_string()).collect();
        self.output_names = outputs.iter().map(|s| s.to_string()).collect();
        Ok(self)
    }

    /// All layers in raw units, normalisation folded in as ordinary affine layers:
    /// the body's layers borrowed, only the normalisation layers copied.
    pub fn raw_layer_refs(&self) -> Vec<std::borrow::Cow<'_, Layer>> {
        use std::borrow::Cow;
        let mut v = Vec::with_capacity(self.layers.len() + 2);
        if let Some(a) = &self.input_norm {
            v.push(Cow::Owned(Layer::Affine(a.clone())));
        }
        v.extend(self.layers.iter().map(Cow::Borrowed));
        if let Some(a) = &self.output_denorm {
            v.push(Cow::Owned(Layer::Affine(a.clone())));
        }
        v
    }

    /// [`Network::raw_layer_refs`] as owned layers (a copy of every weight: for a
    /// network with image-sized dense layers, gigabytes).
    pub fn raw_layers(&self) -> Vec<Layer> {
        let mut v = Vec::new();
        if let Some(a) = &self.input_norm {
            v.push(Layer::Affine(a.clone()));
        }
        v.extend(self.layers.iter().cloned());
        if let Some(a) = &self.output_denorm {
            v.push(Layer::Affine(a.clone()));
        }
        v
    }

    /// Check dimensions chain, weights are finite, names match the dimensions. Reads the
    /// layers in place (a lowered convolutional network's layers take gigabytes: a copy
    /// took seconds).
    pub fn validate(&self) -> Result<(), IrError> {
        let mut dim = self.n_inputs();
        let norm = self.input_norm.iter();
        let denorm = self.output_denorm.iter();
        let all: Vec<Option<&Affine>> = norm
            .map(Some)
            .chain(self.layers.iter().map(|l| match l {
                Layer::Affine(a) => Some(a),
                Layer::Act(_) => None,
            }))
            .chain(denorm.map(Some))
            .collect();
        for (k, l) in all.iter().enumerate() {
            if let Some(a) = l {
                if a.inp != dim {
                    return Err(IrError::Dimension {
                        layer: k,
                        expected: dim,
                        found: a.inp,
                    });
                }
                if a.w.len() != a.inp * a.out || a.b.len() != a.out {
                    return Err(IrError::Shape { layer: k });
                }
                if let Some(p) = a.w.iter().chain(&a.b).position(|v| !v.is_finite()) {
                    return Err(IrError::NonFinite { layer: k, index: p });
                }
                dim = a.out;
            }
        }
        if dim != self.n_outputs() {
            return Err(IrError::Dimension {
                layer: all.len(),
                expected: self.n_outputs(),
                found: dim,
            });
        }
        Ok(())
    }
}

/// Structural errors of a network.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum IrError {
    /// A layer's input size does not match the previous layer's output size.
    #[error("layer {layer}: expects {found} inputs but receives {expected}")]
    Dimension {
        /// Layer index (normalisation counted as layer 0 if present).
        layer: usize,
        /// The size flowing in.
        expected: usize,
        /// The size the layer declares.
        found: usize,
    },
    /// Weight or bias arrays of the wrong length.
    #[error("layer {layer}: weight/bias arrays do not match the declared shape")]
    Shape {
        /// Layer index.
        layer: usize,
    },
    /// Names given do not match the dimensions.
    #[error("the network has {inputs} inputs and {outputs} outputs, but {given_inputs} input names and {given_outputs} output names were given")]
    Names {
        /// Inputs of the network.
        inputs: usize,
        /// Outputs of the network.
        outputs: usize,
        /// Input names given.
        given_inputs: usize,
        /// Output names given.
        given_outputs: usize,
    },
    /// A NaN or infinite weight or bias.
    #[error("layer {layer}: parameter {index} is NaN or infinite; retrain or repair the network")]
    NonFinite {
        /// Layer index.
        layer: usize,
        /// Index into weights then biases.
        index: usize,
    },
}

impl Network {
    /// `k` copies of the network side by side (block-diagonal layers): inputs and outputs
    /// are concatenated copy by copy. This is the "doubled" network a single-call verifier
    /// needs for relational properties; samara's own verifier does not need it.
    pub fn stacked(&self, k: usize) -> Network {
        let block = |a: &Affine| {
            let (inp, out) = (a.inp * k, a.out * k);
            let mut w = vec![0.0; inp * out];
            let mut b = Vec::with_capacity(out);
            for c in 0..k {
                for i in 0..a.out {
                    for j in 0..a.inp {
                        w[(c * a.out + i) * inp + c * a.inp + j] = a.weight(i, j);
                    }
                }
                b.extend_from_slice(&a.b);
            }
            Affine::new(inp, out, w, b)
        };
        let names = |v: &[String]| {
            (0..k)
                .flat_map(|c| v.iter().map(move |n| format!("{n}#{c}")))
                .collect()
        };
        Network {
            input_names: names(&self.input_names),
            output_names: names(&self.output_names),
            input_norm: self.input_norm.as_ref().map(block),
            layers: self
                .layers
                .iter()
                .map(|l| match l {
                    Layer::Affine(a) => Layer::Affine(block(a)),
                    Layer::Act(x) => Layer::Act(*x),
                })
                .collect(),
            output_denorm: self.output_denorm.as_ref().map(block),
        }
    }
}

impl Network {
    /// A dense network with uniform random weights in `[-w, w]` and biases in
    /// `[-b, b]`, activation `act` between layers (none after the last): the random
    /// networks of samara's soundness tests and benchmarks.
    pub fn random_mlp(
        dims: &[usize],
        act: Activation,
        w: f64,
        b: f64,
        rng: &mut impl rand::Rng,
    ) -> Network {
        let mut layers = Vec::new();
        for (k, d) in dims.windows(2).enumerate() {
            layers.push(Layer::Affine(Affine::new(
                d[0],
                d[1],
                (0..d[0] * d[1]).map(|_| rng.gen_range(-w..=w)).collect(),
                (0..d[1]).map(|_| rng.gen_range(-b..=b)).collect(),
            )));
            if k + 2 < dims.len() {
                layers.push(Layer::Act(act));
            }
        }
        Network {
            input_names: (0..dims[0]).map(|i| format!("x{i}")).collect(),
            output_names: (0..dims[dims.len() - 1]).map(|i| format!("y{i}")).collect(),
            input_norm: None,
            layers,
            output_denorm: None,
        }
    }
}

#[cfg(test)]
mod stacked_tests {
    use super::*;

    #[test]
    fn stacked_network_evaluates_each_copy() {
        let net = Network {
            input_names: vec!["a".into(), "b".into()],
            output_names: vec!["y".into()],
            input_norm: Some(Affine::normalise(&[1.0, 2.0], &[2.0, 4.0])),
            layers: vec![
                Layer::Affine(Affine::new(2, 1, vec![0.5, -1.5], vec![0.25])),
                Layer::Act(Activation::Tanh),
            ],
            output_denorm: Some(Affine::denormalise(&[0.181], &[0.012])),
        };
        let s = net.stacked(2);
        let (x1, x2) = ([0.3, -0.7], [2.0, 5.0]);
        let y = s.eval_f64(&[x1[0], x1[1], x2[0], x2[1]]);
        assert_eq!(y, vec![net.eval_f64(&x1)[0], net.eval_f64(&x2)[0]]);
        assert_eq!(s.input_names[3], "b#1");
    }
}

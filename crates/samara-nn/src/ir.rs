//! The network IR: what every part of samara (simulation, training, verification,
//! reachability) reads.
//!
//! A [`Network`] is an optional input normalisation (an affine map, usually diagonal:
//! `(x - c) / s`), a body of layers, and an optional output denormalisation (an affine
//! map, e.g. `ex = 0.181 + 0.012 * out`). Keeping the two as distinguished layers lets
//! the same network be used in raw units ([`Network::eval`]) or in normalised units
//! ([`Network::eval_normalised`]).

use samara_num::Scalar;

/// An affine map `y = W x + b`, `W` (`out x inp`) stored dense (row-major) or sparse
/// (compressed sparse rows: for each output the (input, weight) pairs of its non-zeros).
///
/// The storage is private: every reader goes through a row accessor ([`Affine::row`],
/// which yields the non-zeros of either form, [`Affine::weight`], [`Affine::apply`]) or
/// asks for the dense matrix explicitly ([`Affine::to_dense`], [`Affine::to_dense_within`],
/// which charges an import [`Budget`](crate::limits::Budget)), so a sparse layer cannot
/// be misread as a dense one. The lowering of convolutions, pooling and ConvTranspose
/// ([`crate::graph::lower`]) emits sparse maps (a kernel's patch of non-zeros per row
/// among an image's inputs: dense, a 30x30 traffic-sign network's layer took 2.3 GB);
/// fully connected layers stay dense. Equality ([`PartialEq`]) compares the maps, not
/// their storage.
#[derive(Clone, Debug)]
pub struct Affine {
    /// Number of inputs.
    pub inp: usize,
    /// Number of outputs.
    pub out: usize,
    /// The weights (private: see the type's documentation).
    w: Weights,
    /// Biases, `out` entries.
    pub b: Vec<f64>,
}

/// The storage of an [`Affine`]'s weights.
#[derive(Clone, Debug)]
enum Weights {
    /// Row-major, `out * inp` entries: `w[i * inp + j]` maps input j to output i.
    Dense(Vec<f64>),
    /// Compressed sparse rows (boxed: an [`Affine`] stays the size of a dense one).
    Sparse(Box<Csr>),
}

/// Compressed sparse rows: row `i`'s entries are `col[start[i]..start[i + 1]]` (strictly
/// increasing columns) with weights `val[..]` (the same range), no stored zero.
#[derive(Clone, Debug)]
struct Csr {
    start: Vec<usize>,
    col: Vec<u32>,
    val: Vec<f64>,
}

/// One row of an [`Affine`]'s weights, in its storage: match on it, or read its non-zeros
/// with [`Row::nonzeros`] / [`Row::for_each_nonzero`] (the same entries, in increasing
/// column order, for either form).
#[derive(Clone, Copy, Debug)]
pub enum Row<'a> {
    /// The whole row, `inp` entries (zeros included).
    Dense(&'a [f64]),
    /// The non-zero entries: `cols[k]` has weight `vals[k]`, columns increasing.
    Sparse {
        /// Columns.
        cols: &'a [u32],
        /// Weights.
        vals: &'a [f64],
    },
}

impl<'a> Row<'a> {
    /// The non-zero entries `(j, w)`, in increasing `j`.
    #[inline]
    pub fn nonzeros(self) -> Nonzeros<'a> {
        Nonzeros(match self {
            Row::Dense(r) => NzInner::Dense(r.iter().enumerate()),
            Row::Sparse { cols, vals } => NzInner::Sparse(cols.iter().zip(vals.iter())),
        })
    }

    /// Call `f(j, w)` on each non-zero entry, in increasing `j` (a tight loop for
    /// either form: what the hot paths use).
    #[inline]
    pub fn for_each_nonzero(self, mut f: impl FnMut(usize, f64)) {
        match self {
            Row::Dense(r) => {
                for (j, &w) in r.iter().enumerate() {
                    if w != 0.0 {
                        f(j, w);
                    }
                }
            }
            Row::Sparse { cols, vals } => {
                for (&j, &w) in cols.iter().zip(vals) {
                    if w != 0.0 {
                        f(j as usize, w);
                    }
                }
            }
        }
    }

    /// The dense slice, when stored dense.
    #[inline]
    pub fn as_dense(self) -> Option<&'a [f64]> {
        match self {
            Row::Dense(r) => Some(r),
            Row::Sparse { .. } => None,
        }
    }

    /// The row as `n` dense entries (borrowed when stored dense; `n` is the map's
    /// [`Affine::inp`]).
    pub fn to_dense(self, n: usize) -> std::borrow::Cow<'a, [f64]> {
        match self {
            Row::Dense(r) => std::borrow::Cow::Borrowed(r),
            Row::Sparse { cols, vals } => {
                let mut v = vec![0.0; n];
                for (&j, &w) in cols.iter().zip(vals) {
                    v[j as usize] = w;
                }
                std::borrow::Cow::Owned(v)
            }
        }
    }

    /// `sum_j |w_j| * x_j` over the non-zeros.
    #[inline]
    pub fn abs_dot(self, x: &[f64]) -> f64 {
        match self {
            Row::Dense(r) => r.iter().zip(x).map(|(w, x)| w.abs() * x).sum(),
            Row::Sparse { cols, vals } => cols
                .iter()
                .zip(vals)
                .map(|(&j, w)| w.abs() * x[j as usize])
                .sum(),
        }
    }
}

/// The non-zero entries of a [`Row`] ([`Row::nonzeros`]).
#[derive(Clone, Debug)]
pub struct Nonzeros<'a>(NzInner<'a>);

#[derive(Clone, Debug)]
enum NzInner<'a> {
    Dense(std::iter::Enumerate<std::slice::Iter<'a, f64>>),
    Sparse(std::iter::Zip<std::slice::Iter<'a, u32>, std::slice::Iter<'a, f64>>),
}

impl Iterator for Nonzeros<'_> {
    type Item = (usize, f64);

    #[inline]
    fn next(&mut self) -> Option<(usize, f64)> {
        match &mut self.0 {
            NzInner::Dense(it) => it.find(|(_, w)| **w != 0.0).map(|(j, &w)| (j, w)),
            NzInner::Sparse(it) => it.find(|(_, w)| **w != 0.0).map(|(&j, &w)| (j as usize, w)),
        }
    }
}

/// Below this fraction of non-zeros the lowering stores a map sparse
/// ([`Affine::compact`]): a sparse entry takes 12 bytes (a u32 column and an f64) against
/// a dense one's 8, so past about half sparse storage would not save memory, and a
/// dense row's loop is faster; 10 % keeps the fully connected layers (ACAS Xu, MNIST
/// MLPs) dense.
pub const SPARSE_DENSITY: f64 = 0.1;

impl Affine {
    /// A new dense affine map; `w.len() == out * inp` and `b.len() == out` are checked by
    /// [`Network::validate`].
    pub fn new(inp: usize, out: usize, w: Vec<f64>, b: Vec<f64>) -> Self {
        Affine {
            inp,
            out,
            w: Weights::Dense(w),
            b,
        }
    }

    /// A new sparse affine map from its rows: `rows[i]` holds the `(j, w)` entries of
    /// output `i` in any order; entries of the same column add up, zero sums are dropped.
    /// `j < inp`, `rows.len() == out` and `b.len() == out` are checked by
    /// [`Network::validate`] (an entry past `inp` is kept there to be reported).
    pub fn from_rows(inp: usize, rows: Vec<Vec<(usize, f64)>>, b: Vec<f64>) -> Self {
        let out = rows.len();
        let mut start = Vec::with_capacity(out + 1);
        let nnz: usize = rows.iter().map(Vec::len).sum();
        let mut col = Vec::with_capacity(nnz);
        let mut val = Vec::with_capacity(nnz);
        start.push(0);
        for mut r in rows {
            r.sort_by_key(|e| e.0);
            let mut k = 0;
            while k < r.len() {
                let j = r[k].0;
                let mut v = 0.0;
                while k < r.len() && r[k].0 == j {
                    v += r[k].1;
                    k += 1;
                }
                if v != 0.0 {
                    col.push(u32::try_from(j).unwrap_or(u32::MAX));
                    val.push(v);
                }
            }
            start.push(col.len());
        }
        Affine {
            inp,
            out,
            w: Weights::Sparse(Box::new(Csr { start, col, val })),
            b,
        }
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

    /// Whether the weights are stored sparse.
    pub fn is_sparse(&self) -> bool {
        matches!(self.w, Weights::Sparse(_))
    }

    /// The number of weights stored: `out * inp` when dense, the non-zeros when sparse
    /// (what the map costs in memory, in f64s, and a pass over it in multiplications).
    pub fn stored(&self) -> usize {
        match &self.w {
            Weights::Dense(w) => w.len(),
            Weights::Sparse(c) => c.val.len(),
        }
    }

    /// The number of non-zero weights.
    pub fn nonzeros(&self) -> usize {
        match &self.w {
            Weights::Dense(w) => w.iter().filter(|w| **w != 0.0).count(),
            Weights::Sparse(c) => c.val.iter().filter(|w| **w != 0.0).count(),
        }
    }

    /// Row `i` (the weights into output `i`), in its storage.
    #[inline(always)]
    pub fn row(&self, i: usize) -> Row<'_> {
        match &self.w {
            Weights::Dense(w) => Row::Dense(&w[i * self.inp..(i + 1) * self.inp]),
            Weights::Sparse(c) => {
                let r = c.start[i]..c.start[i + 1];
                Row::Sparse {
                    cols: &c.col[r.clone()],
                    vals: &c.val[r],
                }
            }
        }
    }

    /// Row `i` as `inp` dense entries: borrowed when stored dense, a new vector of `inp`
    /// entries when sparse (for readers whose loops need a slice).
    #[inline]
    pub fn dense_row(&self, i: usize) -> std::borrow::Cow<'_, [f64]> {
        self.row(i).to_dense(self.inp)
    }

    /// The stored weights of row `i`, to change in place (all `inp` when dense, the
    /// non-zeros when sparse): scaling them or setting them to zero is the same map
    /// change for either form.
    pub fn row_values_mut(&mut self, i: usize) -> &mut [f64] {
        match &mut self.w {
            Weights::Dense(w) => &mut w[i * self.inp..(i + 1) * self.inp],
            Weights::Sparse(c) => &mut c.val[c.start[i]..c.start[i + 1]],
        }
    }

    /// Every stored weight, to change in place by a map with `f(0) = 0` (e.g. a scaling;
    /// a sparse map's absent zeros are not visited).
    pub fn map_weights(&mut self, f: impl FnMut(&mut f64)) {
        match &mut self.w {
            Weights::Dense(w) => w.iter_mut().for_each(f),
            Weights::Sparse(c) => c.val.iter_mut().for_each(f),
        }
    }

    /// The stored weights, in row order (all `out * inp` when dense, the non-zeros when
    /// sparse): for checks over every weight (finiteness, magnitude).
    pub fn stored_weights(&self) -> &[f64] {
        match &self.w {
            Weights::Dense(w) => w,
            Weights::Sparse(c) => &c.val,
        }
    }

    /// The row-major dense weights, when stored dense.
    pub fn as_dense(&self) -> Option<&[f64]> {
        match &self.w {
            Weights::Dense(w) => Some(w),
            Weights::Sparse(_) => None,
        }
    }

    /// The row-major dense weights (`out * inp` entries): borrowed when stored dense,
    /// allocated when sparse (for a lowered convolution, gigabytes: charge a budget
    /// first with [`Affine::to_dense_within`]).
    pub fn to_dense(&self) -> std::borrow::Cow<'_, [f64]> {
        match &self.w {
            Weights::Dense(w) => std::borrow::Cow::Borrowed(w),
            Weights::Sparse(c) => {
                let mut w = vec![0.0; self.out * self.inp];
                for i in 0..self.out {
                    for k in c.start[i]..c.start[i + 1] {
                        w[i * self.inp + c.col[k] as usize] = c.val[k];
                    }
                }
                std::borrow::Cow::Owned(w)
            }
        }
    }

    /// [`Affine::to_dense`], charging a sparse map's `out * inp` dense entries to
    /// `budget` first (`Err`: the budget's message, nothing allocated).
    pub fn to_dense_within(
        &self,
        budget: &crate::limits::Budget,
    ) -> Result<std::borrow::Cow<'_, [f64]>, String> {
        if self.is_sparse() {
            let (o, i) = (self.out, self.inp);
            budget.charge(o.saturating_mul(i), &|| {
                format!("the dense form of a sparse {i} -> {o} map")
            })?;
        }
        Ok(self.to_dense())
    }

    /// The same map stored dense.
    pub fn densified(&self) -> Affine {
        Affine::new(
            self.inp,
            self.out,
            self.to_dense().into_owned(),
            self.b.clone(),
        )
    }

    /// The same map stored sparse (its non-zeros).
    pub fn sparsified(&self) -> Affine {
        let rows = (0..self.out)
            .map(|i| self.row(i).nonzeros().collect())
            .collect();
        Affine::from_rows(self.inp, rows, self.b.clone())
    }

    /// The same map in the storage its density calls for: sparse below
    /// [`SPARSE_DENSITY`] non-zeros (and at least 64 inputs), dense otherwise.
    pub fn compact(self) -> Affine {
        let dense_size = self.out.saturating_mul(self.inp);
        let want_sparse = self.inp >= 64
            && self.inp <= u32::MAX as usize
            && (self.nonzeros() as f64) < SPARSE_DENSITY * dense_size as f64;
        match (want_sparse, self.is_sparse()) {
            (true, false) => self.sparsified(),
            (false, true) => self.densified(),
            _ => self,
        }
    }

    /// Weight from input `j` to output `i` (a binary search in the row when sparse).
    #[inline]
    pub fn weight(&self, i: usize, j: usize) -> f64 {
        match &self.w {
            Weights::Dense(w) => w[i * self.inp + j],
            Weights::Sparse(c) => {
                let r = c.start[i]..c.start[i + 1];
                match c.col[r.clone()].binary_search(&(j as u32)) {
                    Ok(k) => c.val[r.start + k],
                    Err(_) => 0.0,
                }
            }
        }
    }

    /// Apply to a vector of any scalar type. Zero weights are skipped, so a diagonal
    /// normalisation does not couple the dependencies of set-valued inputs.
    pub fn apply<S: Scalar>(&self, x: &[S]) -> Vec<S> {
        (0..self.out)
            .map(|i| {
                let mut acc = S::cst(self.b[i]);
                self.row(i)
                    .for_each_nonzero(|j, wij| acc += x[j].clone() * wij);
                acc
            })
            .collect()
    }

    /// Apply to an f64 vector, writing into `y` (no allocation). On long rows (a lowered
    /// convolution's: a kernel's patch of non-zeros among thousands of inputs) the zero
    /// weights are skipped: the same additions in the same order without those of exact
    /// zeros, so the same value for finite inputs, without a chain of dependent
    /// additions through every zero. A sparse map adds its non-zeros in the same order:
    /// the same bits as the dense form on rows of 256 inputs or more.
    #[inline(always)]
    pub fn apply_f64(&self, x: &[f64], y: &mut [f64]) {
        let c = match &self.w {
            Weights::Dense(w) => return self.apply_dense_f64(w, x, y),
            Weights::Sparse(c) => c,
        };
        for (i, (yi, bi)) in y.iter_mut().zip(&self.b).enumerate() {
            let r = c.start[i]..c.start[i + 1];
            let mut acc = *bi;
            for (&j, &w) in c.col[r.clone()].iter().zip(&c.val[r]) {
                acc += w * x[j as usize];
            }
            *yi = acc;
        }
    }

    #[inline]
    fn apply_dense_f64(&self, w: &[f64], x: &[f64], y: &mut [f64]) {
        let skip = self.inp >= 256;
        for ((yi, row), bi) in y.iter_mut().zip(w.chunks_exact(self.inp)).zip(&self.b) {
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

    /// Structural check: `Err(index)` of the first non-finite weight or bias (index into
    /// the stored weights then the biases), `Err(usize::MAX)` on a shape mismatch.
    fn check(&self) -> Result<(), Option<usize>> {
        if self.b.len() != self.out {
            return Err(None);
        }
        match &self.w {
            Weights::Dense(w) => {
                if w.len() != self.inp.checked_mul(self.out).ok_or(None)? {
                    return Err(None);
                }
            }
            Weights::Sparse(c) => {
                let ok = c.start.len() == self.out + 1
                    && c.start[0] == 0
                    && c.start.windows(2).all(|p| p[0] <= p[1])
                    && c.start[self.out] == c.col.len()
                    && c.col.len() == c.val.len()
                    && c.start.windows(2).all(|p| {
                        let r = &c.col[p[0]..p[1]];
                        r.windows(2).all(|q| q[0] < q[1])
                            && r.last().is_none_or(|&j| (j as usize) < self.inp)
                    });
                if !ok {
                    return Err(None);
                }
            }
        }
        match self
            .stored_weights()
            .iter()
            .chain(&self.b)
            .position(|v| !v.is_finite())
        {
            Some(p) => Err(Some(p)),
            None => Ok(()),
        }
    }
}

impl PartialEq for Affine {
    /// The same map: dimensions, biases and every row's non-zeros (whatever the storage).
    fn eq(&self, o: &Affine) -> bool {
        self.inp == o.inp
            && self.out == o.out
            && self.b == o.b
            && match (&self.w, &o.w) {
                (Weights::Dense(a), Weights::Dense(b)) => a == b,
                _ => (0..self.out).all(|i| self.row(i).nonzeros().eq(o.row(i).nonzeros())),
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
                match a.check() {
                    Ok(()) => {}
                    Err(None) => return Err(IrError::Shape { layer: k }),
                    Err(Some(p)) => return Err(IrError::NonFinite { layer: k, index: p }),
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
            let mut b = Vec::with_capacity(out);
            for _ in 0..k {
                b.extend_from_slice(&a.b);
            }
            if a.is_sparse() {
                let rows = (0..k)
                    .flat_map(|c| {
                        (0..a.out).map(move |i| {
                            a.row(i)
                                .nonzeros()
                                .map(|(j, w)| (c * a.inp + j, w))
                                .collect()
                        })
                    })
                    .collect();
                return Affine::from_rows(inp, rows, b);
            }
            let mut w = vec![0.0; inp * out];
            for c in 0..k {
                for i in 0..a.out {
                    a.row(i)
                        .for_each_nonzero(|j, v| w[(c * a.out + i) * inp + c * a.inp + j] = v);
                }
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

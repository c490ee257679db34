//! Lowering a piecewise-linear [`Graph`] to the chain [`Network`] the verifier reads:
//! affine maps (dense or sparse) each followed by ReLU.
//!
//! The lowering walks the nodes in order keeping every live tensor as an affine
//! function `A z + c` of the current chain state `z` (the network's input, then the
//! outputs of the last ReLU layer emitted). Affine operators (Conv, ConvTranspose,
//! BatchNormalization, AveragePool, GlobalAveragePool, Pad, Upsample, Add/Sub of any operands,
//! Mul/Div/MatMul/Gemm by a constant, Concat, Slice, Split, Gather, Reshape, Flatten,
//! Transpose, Squeeze, Unsqueeze) are applied to `c` and to each column of `A` (their
//! linear part is `f(a) - f(0)`), so every operator needs only its evaluation. A
//! piecewise-linear operator emits one ReLU layer (several for MaxPool) whose neurons
//! are its own and the other live tensors, carried through the ReLU either as
//! themselves when they are known non-negative (ReLU outputs and what moves or averages
//! them) or as `relu(x) - relu(-x)`:
//! - `Relu`: `relu(x)`;
//! - `LeakyRelu`/`PRelu` with slope `a`: `relu(x) - a relu(-x)`;
//! - `Clip(lo, hi)`: `lo + relu(x - lo) - relu(x - hi)`;
//! - `MaxPool`: a tree of `max(a, b) = a + relu(b - a)`, one layer per level;
//! - `Sigmoid`/`Tanh`/`Sign`: a layer of that activation, only when no other tensor is
//!   live (`Sign`, a step, has its own bound rule in `samara-bounds`).
//!
//! While lowering, the maps are kept by sparse columns; a layer emitted (the chain IR's
//! [`Affine`]) is stored by sparse rows when fewer than [`SPARSE_DENSITY`] of its
//! entries are non-zero (a convolution's neuron reads a kernel's patch of the image:
//! 12 bytes per non-zero), dense otherwise (a layer of `m` neurons over a state of `n`
//! takes `m n` f64; fully connected layers). Every layer emitted is charged to the
//! import's memory [`Budget`] before it is allocated (its non-zeros when sparse), and
//! the live tensors' sparse maps must fit in what is left of it; past it, lowering
//! refuses naming the node, the bytes needed and allowed and the environment variable
//! that raises the limit.

use super::Graph;
use crate::ir::{Activation, Affine, Layer, Network, SPARSE_DENSITY};
use crate::limits::{show_bytes, Budget};
use crate::ops::elementwise::{BinOp, UnOp};
use crate::ops::{pool, Op, Tensor};
use std::collections::HashMap;

/// A sparse column: (row, value) pairs, a row possibly repeated (values add up).
type Col = Vec<(u32, f64)>;

/// A sparse column as a dense vector of `n` entries.
fn dense(col: &Col, n: usize) -> Vec<f64> {
    let mut v = vec![0.0; n];
    for &(i, x) in col {
        v[i as usize] += x;
    }
    v
}

/// An affine function `A z + c` of the chain state, `A` by sparse columns (`None`: a
/// zero column).
#[derive(Clone, Debug)]
struct Lin {
    cols: Vec<Option<Col>>,
    c: Vec<f64>,
    /// Known to be non-negative for every input.
    nonneg: bool,
}

impl Lin {
    fn rows(&self) -> usize {
        self.c.len()
    }

    /// Rows as sparse combinations of rows of `srcs`: row `i` is
    /// `sum coef * srcs[s].row(r)` over `spec[i]`.
    /// `Err` ([`crate::limits::TIMED_OUT`]) once `budget`'s deadline has passed (checked
    /// every [`CHECK_WORK`] multiply-adds: a column of a wide convolution's combination
    /// can take a million).
    fn combine(
        srcs: &[&Lin],
        spec: &[Vec<(usize, usize, f64)>],
        nonneg: bool,
        budget: &Budget,
    ) -> Result<Lin, String> {
        let zdim = srcs.first().map_or(0, |s| s.cols.len());
        let n = spec.len();
        let c = spec
            .iter()
            .map(|row| row.iter().map(|&(s, r, k)| k * srcs[s].c[r]).sum())
            .collect();
        let mut clock = Clock::new(budget);
        // Per source row, the new rows it enters and with which coefficient (tens of
        // millions of entries for a wide convolution: counted too).
        let mut inv: Vec<Vec<Vec<(u32, f64)>>> =
            srcs.iter().map(|l| vec![Vec::new(); l.rows()]).collect();
        for (i, row) in spec.iter().enumerate() {
            clock.work(row.len().max(1))?;
            for &(s, r, k) in row {
                inv[s][r].push((i as u32, k));
            }
        }
        let mut acc = vec![0.0; n];
        let mut touched: Vec<u32> = Vec::new();
        let cols = (0..zdim)
            .map(|j| {
                for (s, l) in srcs.iter().enumerate() {
                    for &(r, v) in l.cols[j].iter().flatten() {
                        let fan = &inv[s][r as usize];
                        clock.work(fan.len())?;
                        for &(i, k) in fan {
                            if acc[i as usize] == 0.0 {
                                touched.push(i);
                            }
                            acc[i as usize] += k * v;
                        }
                    }
                }
                if touched.is_empty() {
                    return Ok(None);
                }
                touched.sort_unstable();
                touched.dedup();
                let col: Col = touched
                    .iter()
                    .filter(|&&i| acc[i as usize] != 0.0)
                    .map(|&i| (i, acc[i as usize]))
                    .collect();
                for &i in &touched {
                    acc[i as usize] = 0.0;
                }
                touched.clear();
                Ok((!col.is_empty()).then_some(col))
            })
            .collect::<Result<_, String>>()?;
        Ok(Lin { cols, c, nonneg })
    }

    /// Rows as sparse combinations of the new state's coordinates plus constants.
    fn from_state(zdim: usize, rows: &[Vec<(usize, f64)>], c: Vec<f64>, nonneg: bool) -> Lin {
        let mut cols: Vec<Option<Col>> = vec![None; zdim];
        for (i, row) in rows.iter().enumerate() {
            for &(k, coef) in row {
                cols[k].get_or_insert_with(Vec::new).push((i as u32, coef));
            }
        }
        Lin { cols, c, nonneg }
    }

    /// Stored entries.
    fn stored(&self) -> usize {
        self.cols.iter().flatten().map(Vec::len).sum()
    }

    /// The dense row-major matrix `out x zdim` of `A`; `Err` ([`crate::limits::TIMED_OUT`])
    /// once `budget`'s deadline has passed (filling gigabytes takes seconds: checked
    /// every [`CHECK_WORK`] entries).
    fn matrix(&self, budget: &Budget) -> Result<Vec<f64>, String> {
        let (m, zd) = (self.rows(), self.cols.len());
        let mut w = vec![0.0; m * zd];
        let mut clock = Clock::new(budget);
        for (j, col) in self.cols.iter().enumerate() {
            clock.work(col.as_ref().map_or(1, Vec::len))?;
            for &(i, v) in col.iter().flatten() {
                w[i as usize * zd + j] += v;
            }
        }
        Ok(w)
    }
}

impl Lin {
    /// Whether the layer of `A` is stored sparse: fewer than [`SPARSE_DENSITY`] of its
    /// entries stored (duplicates counted: an upper bound on the non-zeros), and at
    /// least 64 columns ([`Affine::compact`]'s rule).
    fn sparse(&self) -> bool {
        let (m, zd) = (self.rows(), self.cols.len());
        zd >= 64
            && zd <= u32::MAX as usize
            && (self.stored() as f64) < SPARSE_DENSITY * m as f64 * zd as f64
    }

    /// The f64s the layer of `A` takes: `rows x zdim` dense; sparse, 12 bytes (a u32
    /// column and an f64) per stored entry and a row start per row.
    fn layer_values(&self) -> usize {
        if self.sparse() {
            let s = self.stored();
            s.saturating_add(s / 2).saturating_add(self.rows() + 1)
        } else {
            self.rows().saturating_mul(self.cols.len())
        }
    }

    /// The layer `A z + c` ([`Lin::sparse`] decides the storage), to be charged first
    /// ([`Lin::layer_values`]); `Err` ([`crate::limits::TIMED_OUT`]) once `budget`'s
    /// deadline has passed.
    fn layer(&self, budget: &Budget) -> Result<Affine, String> {
        let zd = self.cols.len();
        if !self.sparse() {
            return Ok(Affine::new(
                zd,
                self.rows(),
                self.matrix(budget)?,
                self.c.clone(),
            ));
        }
        let mut rows: Vec<Vec<(usize, f64)>> = vec![Vec::new(); self.rows()];
        let mut clock = Clock::new(budget);
        for (j, col) in self.cols.iter().enumerate() {
            clock.work(col.as_ref().map_or(1, Vec::len))?;
            for &(i, v) in col.iter().flatten() {
                rows[i as usize].push((j, v));
            }
        }
        Ok(Affine::from_rows(zd, rows, self.c.clone()))
    }
}

/// How many multiply-adds (or stored entries) a loop of the lowering does between two
/// looks at the clock ([`Clock`]): about a millisecond. Counting columns instead let
/// one check cover seconds on a wide convolution (1024 columns of a 128-channel layer's
/// combination, about 350 million multiply-adds: 7 s past a 6 s limit on a loaded
/// machine).
const CHECK_WORK: usize = 1 << 20;

/// A deadline check by work done: [`Clock::work`] counts, and looks at the clock
/// ([`Budget::check_time`]) once [`CHECK_WORK`] units have passed since the last look.
struct Clock<'b> {
    budget: &'b Budget,
    done: usize,
}

impl<'b> Clock<'b> {
    fn new(budget: &'b Budget) -> Self {
        Clock { budget, done: 0 }
    }

    /// Count `units` of work; `Err` ([`crate::limits::TIMED_OUT`]) once the deadline
    /// has passed.
    #[inline]
    fn work(&mut self, units: usize) -> Result<(), String> {
        self.done += units;
        if self.done >= CHECK_WORK {
            self.done = 0;
            self.budget.check_time()?;
        }
        Ok(())
    }
}

/// A pre-activation row: `sum coef * block[s].row(r)`.
type Row = Vec<(usize, usize, f64)>;

struct Lower<'g> {
    g: &'g Graph,
    zdim: usize,
    reps: HashMap<usize, Lin>,
    layers: Vec<Layer>,
    last_use: Vec<usize>,
    budget: &'g Budget,
}

/// Why a graph cannot be lowered: the node, its operator and the reason.
#[derive(Clone, Debug, PartialEq)]
pub struct LowerError {
    /// Node name.
    pub node: String,
    /// Operator.
    pub op: String,
    /// What is wrong.
    pub message: String,
}

impl std::fmt::Display for LowerError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "node `{}` ({}): {}", self.node, self.op, self.message)
    }
}

impl std::error::Error for LowerError {}

fn err(g: &Graph, node: usize, message: String) -> LowerError {
    let n = &g.nodes[node];
    LowerError {
        node: n.name.clone(),
        op: n.op_type.clone(),
        message,
    }
}

fn graph_err(message: String) -> LowerError {
    LowerError {
        node: "graph".into(),
        op: "-".into(),
        message,
    }
}

impl Lower<'_> {
    /// Charge the layer `l` the node emits to the budget ([`Lin::layer_values`]), then
    /// build it.
    fn emit(&self, node: usize, l: &Lin) -> Result<Affine, LowerError> {
        let (rows, cols) = (l.rows(), l.cols.len());
        self.budget
            .charge(l.layer_values(), &|| match l.sparse() {
                true => format!(
                    "lowering to sparse layers: its {rows} x {cols} map ({} non-zeros)",
                    l.stored()
                ),
                false => format!("lowering to dense layers: its {rows} x {cols} map"),
            })
            .map_err(|m| err(self.g, node, m))?;
        l.layer(self.budget).map_err(|m| err(self.g, node, m))
    }

    /// Whether a live tensor's map of `stored` entries fits in what is left of the
    /// budget (it is not charged: it is dropped once no node reads it).
    /// A stored entry is a (row, value) pair: 16 bytes, two f64's worth.
    fn fits(&self, node: usize, stored: usize) -> Result<(), LowerError> {
        if self.budget.fits(stored.saturating_mul(2)) {
            return Ok(());
        }
        Err(err(
            self.g,
            node,
            format!(
                "lowering: the maps of the live tensors store {stored} entries ({}), more than is left of the import's {} (used: {}); raise the limit with {}=<size> if the machine has the memory",
                show_bytes(stored as u64 * 16),
                show_bytes(self.budget.allowed()),
                show_bytes(self.budget.used()),
                crate::limits::IMPORT_MEMORY_ENV
            ),
        ))
    }

    /// Apply an operator affine in its dynamic inputs.
    fn affine(&self, ni: usize, nonneg: bool) -> Result<Vec<Lin>, LowerError> {
        let node = &self.g.nodes[ni];
        let g = self.g;
        let dyn_in: Vec<Option<&Lin>> = node
            .inputs
            .iter()
            .map(|i| i.and_then(|i| self.reps.get(&i)))
            .collect();
        let run = |fill: &dyn Fn(&Lin) -> Option<Vec<f64>>| -> Result<Vec<Tensor>, LowerError> {
            let ts: Vec<Option<Tensor>> = node
                .inputs
                .iter()
                .zip(&dyn_in)
                .map(|(i, d)| {
                    i.map(|i| match d {
                        Some(l) => {
                            let shape = g.values[i].shape.clone();
                            let data = fill(l).unwrap_or_else(|| vec![0.0; l.rows()]);
                            Tensor::new(shape, data)
                        }
                        None => g.values[i].konst.clone().expect("a constant input"),
                    })
                })
                .collect();
            let refs: Vec<Option<&Tensor>> = ts.iter().map(|t| t.as_ref()).collect();
            node.op.eval(&refs).map_err(|m| err(g, ni, m))
        };
        let outc = run(&|l| Some(l.c.clone()))?;
        if let Some(specs) = self.sparse_rows(ni, &dyn_in)? {
            let srcs: Vec<&Lin> = dyn_in.iter().flatten().copied().collect();
            return specs
                .into_iter()
                .zip(outc)
                .map(|(spec, c)| {
                    let mut l = Lin::combine(&srcs, &spec, nonneg, self.budget)
                        .map_err(|m| err(g, ni, m))?;
                    l.c = c.data;
                    self.fits(ni, l.stored())?;
                    Ok(l)
                })
                .collect();
        }
        if let Some(wd) = self.matrix_of(ni) {
            // A product with a constant matrix: column j of the result is the sum of
            // the matrix's columns weighted by column j's entries.
            let l = dyn_in.iter().flatten().next().expect("one dynamic input");
            let m = outc[0].numel();
            let mut clock = Clock::new(self.budget);
            let cols: Vec<Option<Col>> = l
                .cols
                .iter()
                .map(|col| {
                    let Some(col) = col.as_ref() else {
                        return Ok(None);
                    };
                    clock
                        .work(col.len().saturating_mul(m).max(1))
                        .map_err(|m| err(g, ni, m))?;
                    let mut acc = vec![0.0; m];
                    for &(r, v) in col {
                        for (a, w) in acc.iter_mut().zip(&wd[r as usize]) {
                            *a += v * w;
                        }
                    }
                    let s: Col = acc
                        .iter()
                        .enumerate()
                        .filter(|(_, a)| **a != 0.0)
                        .map(|(i, a)| (i as u32, *a))
                        .collect();
                    Ok((!s.is_empty()).then_some(s))
                })
                .collect::<Result<_, LowerError>>()?;
            let out = Lin {
                cols,
                c: outc.into_iter().next().expect("one output").data,
                nonneg,
            };
            self.fits(ni, out.stored())?;
            return Ok(vec![out]);
        }
        let f0 = run(&|_| None)?;
        let mut cols: Vec<Vec<Option<Col>>> = vec![Vec::with_capacity(self.zdim); outc.len()];
        for j in 0..self.zdim {
            // One evaluation of the operator per column: look at the clock every 64.
            if j % 64 == 0 {
                self.budget.check_time().map_err(|m| err(g, ni, m))?;
            }
            let any = dyn_in.iter().flatten().any(|l| l.cols[j].is_some());
            if !any {
                cols.iter_mut().for_each(|c| c.push(None));
                continue;
            }
            let outs = run(&|l| l.cols[j].as_ref().map(|c| dense(c, l.rows())))?;
            for ((o, base), cs) in outs.into_iter().zip(&f0).zip(cols.iter_mut()) {
                let v: Col = o
                    .data
                    .iter()
                    .zip(&base.data)
                    .enumerate()
                    .filter(|(_, (a, b))| a != b)
                    .map(|(i, (a, b))| (i as u32, a - b))
                    .collect();
                cs.push((!v.is_empty()).then_some(v));
            }
        }
        let out: Vec<Lin> = outc
            .into_iter()
            .zip(cols)
            .map(|(c, cols)| Lin {
                cols,
                c: c.data,
                nonneg,
            })
            .collect();
        for l in &out {
            self.fits(ni, l.stored())?;
        }
        Ok(out)
    }

    /// The operator's linear part as sparse rows over its dynamic inputs (numbered in
    /// order, as `Lin::combine` reads them), one spec per output, for the operators
    /// whose rows are short: moves of entries (read off one evaluation on the entries'
    /// indices), pooling, normalisation, convolution, elementwise arithmetic with
    /// constants. `None`: use the evaluation per column.
    #[allow(clippy::type_complexity)]
    fn sparse_rows(
        &self,
        ni: usize,
        dyn_in: &[Option<&Lin>],
    ) -> Result<Option<Vec<Vec<Row>>>, LowerError> {
        let g = self.g;
        let node = &g.nodes[ni];
        let shape_of = |k: usize| node.inputs[k].map(|i| g.values[i].shape.clone());
        let konst = |k: usize| self.konst(ni, k);
        let e = |m: String| err(g, ni, m);
        let one = |rows: Vec<Row>| Ok(Some(vec![rows]));
        match &node.op {
            Op::Reshape { .. }
            | Op::Flatten { .. }
            | Op::Squeeze { .. }
            | Op::Unsqueeze { .. }
            | Op::Identity
            | Op::Cast { to_int: false } => {
                let n = dyn_in[0].map_or(0, |l| l.rows());
                one((0..n).map(|r| vec![(0, r, 1.0)]).collect())
            }
            Op::Transpose { .. }
            | Op::Slice { .. }
            | Op::Gather { .. }
            | Op::Upsample { .. }
            | Op::Pad { .. }
            | Op::Split { .. }
            | Op::Concat { .. } => {
                // Evaluate on the indices: dynamic data input k's entry r is encoded as
                // base_k + r + 1, constant data and padding as 0.
                let data = |k: usize| matches!(node.op, Op::Concat { .. }) || k == 0;
                let mut bases = Vec::new();
                let mut next = 0usize;
                let ts: Vec<Option<Tensor>> = node
                    .inputs
                    .iter()
                    .enumerate()
                    .map(|(k, i)| {
                        let i = (*i)?;
                        if matches!(node.op, Op::Pad { .. }) && k == 2 {
                            return None;
                        }
                        let v = &g.values[i];
                        if !data(k) {
                            return v.konst.clone();
                        }
                        let n: usize = v.shape.iter().product();
                        Some(match dyn_in[k] {
                            Some(_) => {
                                bases.push(next);
                                let t = Tensor::new(
                                    v.shape.clone(),
                                    (0..n).map(|r| (next + r + 1) as f64).collect(),
                                );
                                next += n;
                                t
                            }
                            None => Tensor::zeros(&v.shape),
                        })
                    })
                    .collect();
                let op = match &node.op {
                    Op::Pad { pads, .. } => Op::Pad {
                        pads: pads.clone(),
                        value: 0.0,
                    },
                    o => o.clone(),
                };
                let refs: Vec<Option<&Tensor>> = ts.iter().map(|t| t.as_ref()).collect();
                let outs = op.eval(&refs).map_err(e)?;
                let specs = outs
                    .iter()
                    .map(|t| {
                        t.data
                            .iter()
                            .map(|&v| {
                                if v == 0.0 {
                                    return vec![];
                                }
                                let gidx = v as usize - 1;
                                let s = bases.partition_point(|&b| b <= gidx) - 1;
                                vec![(s, gidx - bases[s], 1.0)]
                            })
                            .collect()
                    })
                    .collect();
                Ok(Some(specs))
            }
            Op::AveragePool(a) => {
                let sh = shape_of(0).unwrap_or_default();
                let (_, wins, counts) = pool::windows(&sh, a).map_err(e)?;
                one(wins
                    .iter()
                    .zip(&counts)
                    .map(|(w, &cnt)| {
                        let d = if a.count_include_pad { cnt } else { w.len() } as f64;
                        w.iter().map(|&r| (0, r, 1.0 / d)).collect()
                    })
                    .collect())
            }
            Op::GlobalAveragePool => {
                let sh = shape_of(0).unwrap_or_default();
                let sp: usize = sh[2..].iter().product();
                let nc = sh[0] * sh[1];
                one((0..nc)
                    .map(|k| (0..sp).map(|r| (0, k * sp + r, 1.0 / sp as f64)).collect())
                    .collect())
            }
            Op::BatchNorm { epsilon } => {
                let (Some(sc), Some(b), Some(m), Some(v)) =
                    (konst(1), konst(2), konst(3), konst(4))
                else {
                    return Ok(None);
                };
                let (mul, _) = crate::ops::norm::channel_affine(sc, b, m, v, *epsilon);
                let sh = shape_of(0).unwrap_or_default();
                let c = sh[1];
                let sp: usize = sh[2..].iter().product();
                let n: usize = sh.iter().product();
                one((0..n).map(|r| vec![(0, r, mul[(r / sp) % c])]).collect())
            }
            Op::Conv(a) => {
                let Some(w) = konst(1) else { return Ok(None) };
                let sh = shape_of(0).unwrap_or_default();
                let rows = crate::ops::conv::conv_rows(&sh, w, a, &|| self.budget.check_time())
                    .map_err(e)?;
                one(rows
                    .into_iter()
                    .map(|r| r.into_iter().map(|(i, v)| (0, i, v)).collect())
                    .collect())
            }
            Op::ConvTranspose(a) => {
                let Some(w) = konst(1) else { return Ok(None) };
                let sh = shape_of(0).unwrap_or_default();
                let (_, rows) =
                    crate::ops::conv::conv_transpose_rows(&sh, w, a, &|| self.budget.check_time())
                        .map_err(e)?;
                one(rows
                    .into_iter()
                    .map(|r| r.into_iter().map(|(i, v)| (0, i, v)).collect())
                    .collect())
            }
            Op::Unary(UnOp::Neg) => {
                let n = dyn_in[0].map_or(0, |l| l.rows());
                one((0..n).map(|r| vec![(0, r, -1.0)]).collect())
            }
            Op::Binary(op @ (BinOp::Add | BinOp::Sub | BinOp::Mul | BinOp::Div)) => {
                let (Some(sa), Some(sb)) = (shape_of(0), shape_of(1)) else {
                    return Ok(None);
                };
                let out = crate::ops::elementwise::broadcast_shapes(&sa, &sb).map_err(e)?;
                let ia = crate::ops::elementwise::broadcast_index(&out, &sa);
                let ib = crate::ops::elementwise::broadcast_index(&out, &sb);
                let (da, db) = (dyn_in[0].is_some(), dyn_in[1].is_some());
                let rows = (0..ia.len())
                    .map(|o| {
                        let mut row = Vec::new();
                        match op {
                            BinOp::Add | BinOp::Sub => {
                                let sgn = if *op == BinOp::Sub { -1.0 } else { 1.0 };
                                if da {
                                    row.push((0, ia[o], 1.0));
                                }
                                if db {
                                    row.push((usize::from(da), ib[o], sgn));
                                }
                            }
                            BinOp::Mul if da => {
                                row.push((0, ia[o], konst(1).map_or(0.0, |t| t.data[ib[o]])))
                            }
                            BinOp::Mul => {
                                row.push((0, ib[o], konst(0).map_or(0.0, |t| t.data[ia[o]])))
                            }
                            _ => {
                                row.push((0, ia[o], 1.0 / konst(1).map_or(1.0, |t| t.data[ib[o]])))
                            }
                        }
                        row
                    })
                    .collect();
                one(rows)
            }
            _ => Ok(None),
        }
    }

    /// For a `MatMul`/`Gemm` of one vector computed from the input (all dimensions but
    /// one of size 1) by a constant matrix, the matrix of the product by its columns:
    /// `wd[r]` is the output's dependence on the input's entry `r`. `None` otherwise.
    fn matrix_of(&self, ni: usize) -> Option<Vec<Vec<f64>>> {
        let node = &self.g.nodes[ni];
        let (alpha, ta, tb) = match node.op {
            Op::MatMul => (1.0, false, false),
            Op::Gemm {
                alpha,
                trans_a,
                trans_b,
                ..
            } => (alpha, trans_a, trans_b),
            _ => return None,
        };
        let a = node.inputs.first().copied().flatten()?;
        let b = node.inputs.get(1).copied().flatten()?;
        let vector = |v: usize| {
            let s = &self.g.values[v].shape;
            s.iter().filter(|&&d| d != 1).count() <= 1
        };
        let mat = |t: &Tensor, tr: bool| -> Option<(usize, usize, Vec<f64>)> {
            if t.shape.len() != 2 {
                return None;
            }
            let (r, c) = (t.shape[0], t.shape[1]);
            if !tr {
                return Some((r, c, t.data.clone()));
            }
            let mut d = vec![0.0; r * c];
            for i in 0..r {
                for j in 0..c {
                    d[j * r + i] = t.data[i * c + j];
                }
            }
            Some((c, r, d))
        };
        let (ka, kb) = (
            self.g.values[a].konst.as_ref(),
            self.g.values[b].konst.as_ref(),
        );
        match (ka, kb) {
            // x [1, k] (or [k]) times B [k, m]: output i depends on x_r through B[r, i].
            (None, Some(bm)) if vector(a) && !ta => {
                let (k, m, d) = mat(bm, tb)?;
                (self.g.values[a].shape.iter().product::<usize>() == k).then(|| {
                    (0..k)
                        .map(|r| (0..m).map(|i| alpha * d[r * m + i]).collect())
                        .collect()
                })
            }
            // A [n, k] times x [k, 1] (or [k]): output i depends on x_r through A[i, r].
            (Some(am), None) if vector(b) && !tb => {
                let (n, k, d) = mat(am, ta)?;
                (self.g.values[b].shape.iter().product::<usize>() == k).then(|| {
                    (0..k)
                        .map(|r| (0..n).map(|i| alpha * d[i * k + r]).collect())
                        .collect()
                })
            }
            _ => None,
        }
    }

    /// Emit a ReLU layer: `blocks` are the pre-activation sources, `rows` the neurons
    /// (combinations of block rows). Every live tensor not consumed by node `ni` is
    /// carried. Returns the offset of the carried tensors' neurons; the node's own
    /// neurons are `0..rows.len()`.
    fn relu_layer(&mut self, ni: usize, blocks: &[&Lin], rows: Vec<Row>) -> Result<(), LowerError> {
        let own = rows.len();
        let mut srcs: Vec<Lin> = blocks.iter().map(|l| (*l).clone()).collect();
        let mut all_rows = rows;
        let carried: Vec<usize> = {
            let mut v: Vec<usize> = self
                .reps
                .keys()
                .copied()
                .filter(|&k| self.last_use[k] > ni)
                .collect();
            v.sort_unstable();
            v
        };
        let mut plan = Vec::new();
        for &k in &carried {
            let l = &self.reps[&k];
            let s = srcs.len();
            let off = all_rows.len();
            let n = l.rows();
            for r in 0..n {
                all_rows.push(vec![(s, r, 1.0)]);
            }
            if !l.nonneg {
                for r in 0..n {
                    all_rows.push(vec![(s, r, -1.0)]);
                }
            }
            plan.push((k, off, n, l.nonneg));
            srcs.push(l.clone());
        }
        let m = all_rows.len();
        let refs: Vec<&Lin> = srcs.iter().collect();
        let pre =
            Lin::combine(&refs, &all_rows, false, self.budget).map_err(|m| err(self.g, ni, m))?;
        let layer = self.emit(ni, &pre)?;
        self.layers.push(Layer::Affine(layer));
        self.layers.push(Layer::Act(Activation::Relu));
        self.zdim = m;
        let _ = own;
        for (k, off, n, nonneg) in plan {
            let rows: Vec<Vec<(usize, f64)>> = (0..n)
                .map(|i| {
                    if nonneg {
                        vec![(off + i, 1.0)]
                    } else {
                        vec![(off + i, 1.0), (off + n + i, -1.0)]
                    }
                })
                .collect();
            self.reps
                .insert(k, Lin::from_state(m, &rows, vec![0.0; n], nonneg));
        }
        Ok(())
    }

    fn input_rep(&self, ni: usize, k: usize) -> Result<Lin, LowerError> {
        let node = &self.g.nodes[ni];
        node.inputs
            .get(k)
            .copied()
            .flatten()
            .and_then(|i| self.reps.get(&i))
            .cloned()
            .ok_or_else(|| {
                err(
                    self.g,
                    ni,
                    format!("input {k} must be computed from the network's input"),
                )
            })
    }

    fn konst(&self, ni: usize, k: usize) -> Option<&Tensor> {
        self.g.nodes[ni]
            .inputs
            .get(k)
            .copied()
            .flatten()
            .and_then(|i| self.g.values[i].konst.as_ref())
    }

    fn node(&mut self, ni: usize) -> Result<(), LowerError> {
        let g = self.g;
        let node = &g.nodes[ni];
        let dyn_count = node
            .inputs
            .iter()
            .flatten()
            .filter(|i| self.reps.contains_key(i))
            .count();
        // Non-negative data in, non-negative data out for the operators that move or
        // average entries; a constant data operand (Concat) must be non-negative too.
        let all_nonneg = node
            .inputs
            .iter()
            .flatten()
            .all(|i| match self.reps.get(i) {
                Some(l) => l.nonneg,
                None => {
                    !matches!(node.op, Op::Concat { .. })
                        || g.values[*i]
                            .konst
                            .as_ref()
                            .is_some_and(|t| t.data.iter().all(|&v| v >= 0.0))
                }
            });
        let out0 = node.outputs[0];
        let refuse = |why: &str| {
            Err(err(
                g,
                ni,
                format!("cannot be lowered to the chain of affine maps and ReLUs the verifier reads ({why}); the graph evaluation supports it"),
            ))
        };
        match &node.op {
            Op::Conv(_)
            | Op::ConvTranspose(_)
            | Op::BatchNorm { .. }
            | Op::Binary(BinOp::Add)
            | Op::Binary(BinOp::Sub)
            | Op::Unary(UnOp::Neg) => {
                let outs = self.affine(ni, false)?;
                self.set(ni, outs);
            }
            Op::Binary(BinOp::Mul) | Op::MatMul | Op::Gemm { .. } => {
                if dyn_count != 1 {
                    return refuse("a product of two tensors computed from the input");
                }
                let outs = self.affine(ni, false)?;
                self.set(ni, outs);
            }
            Op::Binary(BinOp::Div) => {
                if dyn_count != 1 || self.konst(ni, 1).is_none() {
                    return refuse("a division by a tensor computed from the input");
                }
                let outs = self.affine(ni, false)?;
                self.set(ni, outs);
            }
            Op::AveragePool(_)
            | Op::GlobalAveragePool
            | Op::Concat { .. }
            | Op::Slice { .. }
            | Op::Split { .. }
            | Op::Gather { .. }
            | Op::Upsample { .. }
            | Op::Reshape { .. }
            | Op::Flatten { .. }
            | Op::Transpose { .. }
            | Op::Squeeze { .. }
            | Op::Unsqueeze { .. }
            | Op::Identity
            | Op::Cast { to_int: false } => {
                let outs = self.affine(ni, all_nonneg)?;
                self.set(ni, outs);
            }
            Op::Pad { value, .. } => {
                let v = self
                    .konst(ni, 2)
                    .and_then(|t| t.data.first().copied())
                    .unwrap_or(*value);
                let outs = self.affine(ni, all_nonneg && v >= 0.0)?;
                self.set(ni, outs);
            }
            Op::Unary(UnOp::Relu) => {
                let x = self.input_rep(ni, 0)?;
                let n = x.rows();
                if x.nonneg {
                    self.reps.insert(out0, x);
                    return Ok(());
                }
                let rows = (0..n).map(|r| vec![(0, r, 1.0)]).collect();
                self.relu_layer(ni, &[&x], rows)?;
                let out = (0..n).map(|r| vec![(r, 1.0)]).collect::<Vec<_>>();
                let l = Lin::from_state(self.zdim, &out, vec![0.0; n], true);
                self.reps.insert(out0, l);
            }
            Op::LeakyRelu { .. } | Op::PRelu => {
                let x = self.input_rep(ni, 0)?;
                let n = x.rows();
                let shape = &g.values[node.inputs[0].expect("input")].shape;
                let slope: Vec<f64> = match &node.op {
                    Op::LeakyRelu { alpha } => vec![*alpha; n],
                    _ => {
                        let s = self
                            .konst(ni, 1)
                            .ok_or_else(|| err(g, ni, "the slope must be a constant".into()))?;
                        let idx = crate::ops::elementwise::broadcast_index(shape, &s.shape);
                        if crate::ops::elementwise::broadcast_shapes(shape, &s.shape).as_deref()
                            != Ok(shape.as_slice())
                        {
                            return refuse("a slope that enlarges the input");
                        }
                        idx.iter().map(|&i| s.data[i]).collect()
                    }
                };
                let mut rows: Vec<Row> = (0..n).map(|r| vec![(0, r, 1.0)]).collect();
                rows.extend((0..n).map(|r| vec![(0, r, -1.0)]));
                self.relu_layer(ni, &[&x], rows)?;
                let out: Vec<Vec<(usize, f64)>> =
                    (0..n).map(|r| vec![(r, 1.0), (n + r, -slope[r])]).collect();
                let nonneg = slope.iter().all(|&a| a == 0.0);
                let l = Lin::from_state(self.zdim, &out, vec![0.0; n], nonneg);
                self.reps.insert(out0, l);
            }
            Op::Clip { lo, hi } => {
                let x = self.input_rep(ni, 0)?;
                let n = x.rows();
                let lo = self
                    .konst(ni, 1)
                    .and_then(|t| t.data.first().copied())
                    .unwrap_or(*lo);
                let hi = self
                    .konst(ni, 2)
                    .and_then(|t| t.data.first().copied())
                    .unwrap_or(*hi);
                // Shift rows: x - lo and x - hi through a unit constant column is not
                // available, so the shifts go into a copy of x with its constants moved.
                let mut rows: Vec<Row> = Vec::new();
                let mut shifted = Vec::new();
                if lo.is_finite() {
                    let mut xl = x.clone();
                    xl.c.iter_mut().for_each(|v| *v -= lo);
                    shifted.push(xl);
                }
                if hi.is_finite() {
                    let mut xh = x.clone();
                    xh.c.iter_mut().for_each(|v| *v -= hi);
                    shifted.push(xh);
                }
                if shifted.is_empty() {
                    self.reps.insert(out0, x);
                    return Ok(());
                }
                if lo > hi {
                    // Clip with min > max is the constant max (as evaluated).
                    let l = Lin {
                        cols: vec![None; self.zdim],
                        c: vec![hi; n],
                        nonneg: hi >= 0.0,
                    };
                    self.reps.insert(out0, l);
                    return Ok(());
                }
                for (s, _) in shifted.iter().enumerate() {
                    // lo only: relu(x - lo); hi only: relu(-(x - hi)); both: both rows.
                    let sign = if !lo.is_finite() { -1.0 } else { 1.0 };
                    rows.extend((0..n).map(|r| vec![(s, r, sign)]));
                }
                let refs: Vec<&Lin> = shifted.iter().collect();
                self.relu_layer(ni, &refs, rows)?;
                let (out, c): (Vec<Vec<(usize, f64)>>, Vec<f64>) =
                    if lo.is_finite() && hi.is_finite() {
                        (
                            (0..n).map(|r| vec![(r, 1.0), (n + r, -1.0)]).collect(),
                            vec![lo; n],
                        )
                    } else if lo.is_finite() {
                        ((0..n).map(|r| vec![(r, 1.0)]).collect(), vec![lo; n])
                    } else {
                        ((0..n).map(|r| vec![(r, -1.0)]).collect(), vec![hi; n])
                    };
                let l = Lin::from_state(self.zdim, &out, c, lo.is_finite() && lo >= 0.0);
                self.reps.insert(out0, l);
            }
            Op::MaxPool(a) => {
                let x = self.input_rep(ni, 0)?;
                let shape = &g.values[node.inputs[0].expect("input")].shape;
                let (_, wins, _) = pool::windows(shape, a).map_err(|m| err(g, ni, m))?;
                // Candidates: one Lin whose rows are grouped per output.
                let mut groups: Vec<Vec<usize>> = Vec::with_capacity(wins.len());
                let mut spec: Vec<Row> = Vec::new();
                for w in &wins {
                    let mut gi = Vec::with_capacity(w.len());
                    for &r in w {
                        gi.push(spec.len());
                        spec.push(vec![(0, r, 1.0)]);
                    }
                    groups.push(gi);
                }
                let nonneg = x.nonneg;
                let mut cand =
                    Lin::combine(&[&x], &spec, nonneg, self.budget).map_err(|m| err(g, ni, m))?;
                while groups.iter().any(|g| g.len() > 1) {
                    let mut rows: Vec<Row> = Vec::new();
                    // Per group, the new candidates as state combinations (filled after
                    // the layer: neuron indices are known now).
                    let mut next: Vec<Vec<Vec<(usize, f64)>>> = Vec::with_capacity(groups.len());
                    for gr in &groups {
                        let mut ng = Vec::new();
                        let push_carry = |rows: &mut Vec<Row>, r: usize| -> Vec<(usize, f64)> {
                            let k = rows.len();
                            rows.push(vec![(0, r, 1.0)]);
                            if nonneg {
                                vec![(k, 1.0)]
                            } else {
                                rows.push(vec![(0, r, -1.0)]);
                                vec![(k, 1.0), (k + 1, -1.0)]
                            }
                        };
                        for pair in gr.chunks(2) {
                            if pair.len() == 2 {
                                let mut comb = push_carry(&mut rows, pair[0]);
                                let d = rows.len();
                                rows.push(vec![(0, pair[1], 1.0), (0, pair[0], -1.0)]);
                                comb.push((d, 1.0));
                                ng.push(comb);
                            } else {
                                ng.push(push_carry(&mut rows, pair[0]));
                            }
                        }
                        next.push(ng);
                    }
                    self.relu_layer(ni, &[&cand], rows)?;
                    let mut flat: Vec<Vec<(usize, f64)>> = Vec::new();
                    groups = next
                        .into_iter()
                        .map(|ng| {
                            ng.into_iter()
                                .map(|comb| {
                                    flat.push(comb);
                                    flat.len() - 1
                                })
                                .collect()
                        })
                        .collect();
                    let n = flat.len();
                    cand = Lin::from_state(self.zdim, &flat, vec![0.0; n], nonneg);
                }
                let order: Vec<Row> = groups.iter().map(|g| vec![(0, g[0], 1.0)]).collect();
                let l = Lin::combine(&[&cand], &order, nonneg, self.budget)
                    .map_err(|m| err(g, ni, m))?;
                self.reps.insert(out0, l);
            }
            Op::Unary(u @ (UnOp::Sigmoid | UnOp::Tanh | UnOp::Sign)) => {
                let x = self.input_rep(ni, 0)?;
                let live = self.reps.keys().filter(|&&k| self.last_use[k] > ni).count();
                if live > 0 {
                    return refuse("a smooth or step activation while another branch is live");
                }
                let n = x.rows();
                let layer = self.emit(ni, &x)?;
                self.layers.push(Layer::Affine(layer));
                self.layers.push(Layer::Act(match u {
                    UnOp::Sigmoid => Activation::Sigmoid,
                    UnOp::Sign => Activation::Sign,
                    _ => Activation::Tanh,
                }));
                self.zdim = n;
                let out = (0..n).map(|r| vec![(r, 1.0)]).collect::<Vec<_>>();
                let l = Lin::from_state(n, &out, vec![0.0; n], *u == UnOp::Sigmoid);
                self.reps.clear();
                self.reps.insert(out0, l);
            }
            _ => return refuse("not piecewise linear"),
        }
        Ok(())
    }

    fn set(&mut self, ni: usize, outs: Vec<Lin>) {
        for (o, l) in self.g.nodes[ni].outputs.iter().zip(outs) {
            self.reps.insert(*o, l);
        }
    }
}

/// Lower a graph to the chain form (see the module documentation) within the import
/// budget of [`crate::limits::import_memory`]; `Err` names the node that cannot be
/// lowered and why.
pub fn lower(g: &Graph) -> Result<Network, LowerError> {
    let budget = Budget::from_env().map_err(graph_err)?;
    lower_within(g, &budget)
}

/// [`lower`], charging every layer to `budget` before it is allocated.
pub fn lower_within(g: &Graph, budget: &Budget) -> Result<Network, LowerError> {
    let n_in = g.n_inputs();
    let mut last_use = vec![0usize; g.values.len()];
    for (k, n) in g.nodes.iter().enumerate() {
        for i in n.inputs.iter().flatten() {
            last_use[*i] = last_use[*i].max(k);
        }
    }
    last_use[g.output] = usize::MAX;
    let mut lw = Lower {
        g,
        zdim: n_in,
        reps: HashMap::new(),
        layers: Vec::new(),
        last_use,
        budget,
    };
    let ident = (0..n_in).map(|r| vec![(r, 1.0)]).collect::<Vec<_>>();
    lw.reps.insert(
        g.input,
        Lin::from_state(n_in, &ident, vec![0.0; n_in], false),
    );
    for ni in 0..g.nodes.len() {
        budget.check_time().map_err(|m| err(g, ni, m))?;
        lw.node(ni)?;
        // Drop tensors no later node reads.
        let lu = &lw.last_use;
        lw.reps.retain(|&k, _| lu[k] > ni);
        let stored: usize = lw.reps.values().map(Lin::stored).sum();
        lw.fits(ni, stored)?;
    }
    let out = lw
        .reps
        .get(&g.output)
        .ok_or_else(|| graph_err("the output was not computed".into()))?
        .clone();
    let m = out.rows();
    let zd = lw.zdim;
    budget
        .charge(out.layer_values(), &|| {
            let form = if out.sparse() { "sparse" } else { "dense" };
            format!("lowering to {form} layers: the output's {m} x {zd} map")
        })
        .map_err(graph_err)?;
    lw.layers
        .push(Layer::Affine(out.layer(budget).map_err(graph_err)?));
    let iname = &g.values[g.input].name;
    let oname = &g.values[g.output].name;
    let net = Network {
        input_names: (0..n_in).map(|i| format!("{iname}[{i}]")).collect(),
        output_names: (0..m).map(|i| format!("{oname}[{i}]")).collect(),
        input_norm: None,
        layers: lw.layers,
        output_denorm: None,
    };
    net.validate().map_err(|e| graph_err(e.to_string()))?;
    Ok(net)
}

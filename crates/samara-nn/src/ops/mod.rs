//! The operators of the graph IR ([`crate::graph`]): a dense f64 [`Tensor`] and, per
//! operator, its evaluation. One file per operator family with logic of its own
//! (convolutions, pooling, normalisation, shape manipulation, matrix products,
//! elementwise maps); this module holds the tensor type and the dispatch.
//!
//! Every evaluation is total on well-shaped inputs and returns `Err(message)` on
//! shapes it cannot combine; the graph importer runs each node once on zeros at import
//! time, so a network that imports evaluates without shape errors.

pub mod conv;
pub mod elementwise;
pub mod matmul;
pub mod norm;
pub mod pool;
pub mod shape;

pub use conv::{ConvAttrs, ConvTransposeAttrs};
pub use pool::PoolAttrs;

/// A dense row-major tensor of f64 values.
#[derive(Clone, Debug, PartialEq)]
pub struct Tensor {
    /// Dimensions (empty for a scalar).
    pub shape: Vec<usize>,
    /// Row-major values, `shape.iter().product()` of them.
    pub data: Vec<f64>,
}

impl Tensor {
    /// A tensor from its shape and values (lengths must agree).
    pub fn new(shape: Vec<usize>, data: Vec<f64>) -> Self {
        debug_assert_eq!(numel(&shape), Some(data.len()));
        Tensor { shape, data }
    }

    /// A tensor of zeros.
    pub fn zeros(shape: &[usize]) -> Self {
        let n = numel(shape).unwrap_or(0);
        Tensor {
            shape: shape.to_vec(),
            data: vec![0.0; n],
        }
    }

    /// Number of values.
    pub fn numel(&self) -> usize {
        self.data.len()
    }

    /// The values as integers (shapes, axes, indices); `Err` if one is not integral.
    pub fn ints(&self) -> Result<Vec<i64>, String> {
        self.data
            .iter()
            .map(|&v| {
                // Integers past 2^53 are not exact as f64 but stay integers: INT64_MAX
                // (PyTorch's "to the end" in a Slice) saturates to i64::MAX.
                (v.is_finite() && v.fract() == 0.0)
                    .then_some(v as i64)
                    .ok_or_else(|| format!("{v} is not an integer"))
            })
            .collect()
    }
}

/// Number of entries of a tensor of this shape (`None` on overflow).
pub fn numel(shape: &[usize]) -> Option<usize> {
    shape.iter().try_fold(1usize, |a, &d| a.checked_mul(d))
}

/// Row-major strides of a shape.
pub fn strides(shape: &[usize]) -> Vec<usize> {
    let mut s = vec![1usize; shape.len()];
    for k in (0..shape.len().saturating_sub(1)).rev() {
        s[k] = s[k + 1] * shape[k + 1];
    }
    s
}

/// An axis in `[-r, r)` as an index.
pub fn norm_axis(a: i64, r: usize) -> Result<usize, String> {
    let ri = r as i64;
    let k = if a < 0 { a + ri } else { a };
    if (0..ri).contains(&k) {
        Ok(k as usize)
    } else {
        Err(format!("axis {a} is out of range for rank {r}"))
    }
}

/// Check a result's size before allocating it: at most the import memory budget
/// ([`crate::limits::max_tensor_values`]).
pub fn check_size(shape: &[usize]) -> Result<usize, String> {
    let max = crate::limits::max_tensor_values();
    numel(shape).filter(|&n| n <= max).ok_or_else(|| {
        format!(
            "gives shape {shape:?}, more than the {max} values (8 bytes each) of the import memory budget; raise it with {}=<size> if the machine has the memory",
            crate::limits::IMPORT_MEMORY_ENV
        )
    })
}

/// `Slice`'s attribute form (opsets before 10): starts, ends, optional axes.
pub type SliceAttrs = (Vec<i64>, Vec<i64>, Option<Vec<i64>>);

/// One operator with its attributes (constant operands are node inputs).
#[derive(Clone, Debug, PartialEq)]
pub enum Op {
    /// Convolution (inputs X, W, optional B).
    Conv(ConvAttrs),
    /// Transposed convolution (inputs X, W, optional B).
    ConvTranspose(ConvTransposeAttrs),
    /// Batch normalisation in inference mode (X, scale, B, mean, var).
    BatchNorm {
        /// Added to the variance.
        epsilon: f64,
    },
    /// Max pooling.
    MaxPool(PoolAttrs),
    /// Average pooling.
    AveragePool(PoolAttrs),
    /// Mean over all spatial positions, per channel.
    GlobalAveragePool,
    /// Constant padding: (begin..., end...) per axis, may be negative (cropping); the
    /// pads and value come from attributes (opsets before 11) or inputs.
    Pad {
        /// Pads from the attribute, if given there.
        pads: Option<Vec<i64>>,
        /// Fill value from the attribute, if given there.
        value: f64,
    },
    /// Nearest-neighbour upsampling (opsets 7 to 9): output index `o` of an axis reads
    /// input index `floor(o / scale)`; scales from the attribute (opset 7) or the
    /// second input, each at least 1.
    Upsample {
        /// Scales from the attribute, if given there.
        scales: Option<Vec<f64>>,
    },
    /// Numpy-broadcast binary operator.
    Binary(elementwise::BinOp),
    /// Elementwise unary map.
    Unary(elementwise::UnOp),
    /// `max(x, alpha x)` for `alpha < 1`: `x` if positive, `alpha x` otherwise.
    LeakyRelu {
        /// Slope for negative inputs.
        alpha: f64,
    },
    /// Leaky ReLU with a slope tensor (second input, broadcast).
    PRelu,
    /// `min(max(x, lo), hi)` (attributes before opset 11, else optional inputs).
    Clip {
        /// Lower bound from the attribute (or -inf).
        lo: f64,
        /// Upper bound from the attribute (or +inf).
        hi: f64,
    },
    /// Softmax along an axis.
    Softmax {
        /// Axis.
        axis: i64,
    },
    /// Numpy matrix product.
    MatMul,
    /// `alpha op(A) op(B) + beta C`.
    Gemm {
        /// Scale of the product.
        alpha: f64,
        /// Scale of C.
        beta: f64,
        /// Transpose A.
        trans_a: bool,
        /// Transpose B.
        trans_b: bool,
    },
    /// Concatenation along an axis.
    Concat {
        /// Axis.
        axis: i64,
    },
    /// Slice (starts, ends, axes, steps from attributes before opset 10, else inputs).
    Slice {
        /// Attribute form `(starts, ends, axes)`, if given there.
        attrs: Option<SliceAttrs>,
    },
    /// Split along an axis into parts (sizes from the attribute or the second input).
    Split {
        /// Axis.
        axis: i64,
        /// Sizes from the attribute, if given there.
        sizes: Option<Vec<i64>>,
        /// Number of outputs (equal parts when no sizes are given).
        outputs: usize,
    },
    /// Gather along an axis with constant indices (second input).
    Gather {
        /// Axis.
        axis: i64,
    },
    /// Reshape to the second input's shape (or the attribute's, opsets before 5).
    Reshape {
        /// Attribute shape, if given there.
        shape: Option<Vec<i64>>,
        /// `allowzero`: a 0 in the shape is a zero dimension, not a copy.
        allowzero: bool,
    },
    /// Flatten to 2-D at an axis.
    Flatten {
        /// Axis.
        axis: i64,
    },
    /// Permute axes.
    Transpose {
        /// Permutation (reversal when absent).
        perm: Option<Vec<i64>>,
    },
    /// Remove size-1 axes (attribute before opset 13, else optional input).
    Squeeze {
        /// Axes from the attribute.
        axes: Option<Vec<i64>>,
    },
    /// Insert size-1 axes (attribute before opset 13, else input).
    Unsqueeze {
        /// Axes from the attribute.
        axes: Option<Vec<i64>>,
    },
    /// The input unchanged (Identity, Dropout in inference).
    Identity,
    /// The input's shape as an int tensor, `start..end`.
    Shape {
        /// First axis.
        start: i64,
        /// One past the last axis (None: rank).
        end: Option<i64>,
    },
    /// Conversion; to an integer type the values are truncated.
    Cast {
        /// Whether the target type is an integer type.
        to_int: bool,
    },
    /// A tensor of the first input's shape filled with a value.
    ConstantOfShape {
        /// Fill value.
        value: f64,
    },
}

impl Op {
    /// Evaluate on the node's inputs (absent optional inputs are `None`).
    pub fn eval(&self, inp: &[Option<&Tensor>]) -> Result<Vec<Tensor>, String> {
        let x = |k: usize| -> Result<&Tensor, String> {
            inp.get(k)
                .copied()
                .flatten()
                .ok_or_else(|| format!("missing input {k}"))
        };
        let opt = |k: usize| inp.get(k).copied().flatten();
        let one = |t: Tensor| Ok(vec![t]);
        match self {
            Op::Conv(a) => one(conv::conv(x(0)?, x(1)?, opt(2), a)?),
            Op::ConvTranspose(a) => one(conv::conv_transpose(x(0)?, x(1)?, opt(2), a)?),
            Op::BatchNorm { epsilon } => one(norm::batch_norm(
                x(0)?,
                x(1)?,
                x(2)?,
                x(3)?,
                x(4)?,
                *epsilon,
            )?),
            Op::MaxPool(a) => one(pool::max_pool(x(0)?, a)?),
            Op::AveragePool(a) => one(pool::average_pool(x(0)?, a)?),
            Op::GlobalAveragePool => one(pool::global_average_pool(x(0)?)?),
            Op::Pad { pads, value } => {
                let pads = match pads {
                    Some(p) => p.clone(),
                    None => x(1)?.ints()?,
                };
                let value = opt(2)
                    .and_then(|t| t.data.first().copied())
                    .unwrap_or(*value);
                let axes = opt(3).map(|t| t.ints()).transpose()?;
                one(shape::pad(x(0)?, &pads, axes.as_deref(), value)?)
            }
            Op::Upsample { scales } => {
                let scales = match scales {
                    Some(s) => s.clone(),
                    None => x(1)?.data.clone(),
                };
                one(shape::upsample_nearest(x(0)?, &scales)?)
            }
            Op::Binary(b) => one(elementwise::binary(*b, x(0)?, x(1)?)?),
            Op::Unary(u) => one(elementwise::unary(*u, x(0)?)),
            Op::LeakyRelu { alpha } => {
                let t = x(0)?;
                one(Tensor::new(
                    t.shape.clone(),
                    t.data
                        .iter()
                        .map(|&v| if v < 0.0 { alpha * v } else { v })
                        .collect(),
                ))
            }
            Op::PRelu => one(elementwise::binary(
                elementwise::BinOp::PRelu,
                x(0)?,
                x(1)?,
            )?),
            Op::Clip { lo, hi } => {
                let lo = opt(1).and_then(|t| t.data.first().copied()).unwrap_or(*lo);
                let hi = opt(2).and_then(|t| t.data.first().copied()).unwrap_or(*hi);
                let t = x(0)?;
                one(Tensor::new(
                    t.shape.clone(),
                    t.data
                        .iter()
                        .map(|&v| if v.is_nan() { v } else { v.max(lo).min(hi) })
                        .collect(),
                ))
            }
            Op::Softmax { axis } => one(elementwise::softmax(x(0)?, *axis)?),
            Op::MatMul => one(matmul::matmul(x(0)?, x(1)?)?),
            Op::Gemm {
                alpha,
                beta,
                trans_a,
                trans_b,
            } => one(matmul::gemm(
                x(0)?,
                x(1)?,
                opt(2),
                *alpha,
                *beta,
                *trans_a,
                *trans_b,
            )?),
            Op::Concat { axis } => {
                let ts: Vec<&Tensor> = inp.iter().flatten().copied().collect();
                one(shape::concat(&ts, *axis)?)
            }
            Op::Slice { attrs } => {
                let t = x(0)?;
                let (starts, ends, axes, steps) = match attrs {
                    Some((s, e, a)) => (s.clone(), e.clone(), a.clone(), None),
                    None => (
                        x(1)?.ints()?,
                        x(2)?.ints()?,
                        opt(3).map(|t| t.ints()).transpose()?,
                        opt(4).map(|t| t.ints()).transpose()?,
                    ),
                };
                one(shape::slice(
                    t,
                    &starts,
                    &ends,
                    axes.as_deref(),
                    steps.as_deref(),
                )?)
            }
            Op::Split {
                axis,
                sizes,
                outputs,
            } => {
                let sizes = match sizes {
                    Some(s) => Some(s.clone()),
                    None => opt(1).map(|t| t.ints()).transpose()?,
                };
                shape::split(x(0)?, *axis, sizes.as_deref(), *outputs)
            }
            Op::Gather { axis } => one(shape::gather(x(0)?, &x(1)?.ints()?, &x(1)?.shape, *axis)?),
            Op::Reshape { shape, allowzero } => {
                let target = match shape {
                    Some(s) => s.clone(),
                    None => x(1)?.ints()?,
                };
                let t = x(0)?;
                let s = shape::reshape_shape(&t.shape, &target, *allowzero)?;
                one(Tensor::new(s, t.data.clone()))
            }
            Op::Flatten { axis } => {
                let t = x(0)?;
                let r = t.shape.len() as i64;
                let a = if *axis < 0 { axis + r } else { *axis };
                if !(0..=r).contains(&a) {
                    return Err(format!("axis {axis} is out of range for rank {r}"));
                }
                let a = a as usize;
                let rows = t.shape[..a].iter().product();
                let cols = t.shape[a..].iter().product();
                one(Tensor::new(vec![rows, cols], t.data.clone()))
            }
            Op::Transpose { perm } => one(shape::transpose(x(0)?, perm.as_deref())?),
            Op::Squeeze { axes } => {
                let axes = match axes {
                    Some(a) => Some(a.clone()),
                    None => opt(1).map(|t| t.ints()).transpose()?,
                };
                let t = x(0)?;
                one(Tensor::new(
                    shape::squeeze_shape(&t.shape, axes.as_deref())?,
                    t.data.clone(),
                ))
            }
            Op::Unsqueeze { axes } => {
                let axes = match axes {
                    Some(a) => a.clone(),
                    None => x(1)?.ints()?,
                };
                let t = x(0)?;
                one(Tensor::new(
                    shape::unsqueeze_shape(&t.shape, &axes)?,
                    t.data.clone(),
                ))
            }
            Op::Identity => one(x(0)?.clone()),
            Op::Shape { start, end } => {
                let s = &x(0)?.shape;
                let r = s.len() as i64;
                let clampi = |v: i64| (if v < 0 { v + r } else { v }).clamp(0, r) as usize;
                let (a, b) = (clampi(*start), clampi(end.unwrap_or(r)));
                let v: Vec<f64> = s[a..b.max(a)].iter().map(|&d| d as f64).collect();
                one(Tensor::new(vec![v.len()], v))
            }
            Op::Cast { to_int } => {
                let t = x(0)?;
                if *to_int {
                    one(Tensor::new(
                        t.shape.clone(),
                        t.data.iter().map(|v| v.trunc()).collect(),
                    ))
                } else {
                    one(t.clone())
                }
            }
            Op::ConstantOfShape { value } => {
                let dims = x(0)?.ints()?;
                let s: Vec<usize> = dims
                    .iter()
                    .map(|&d| usize::try_from(d).map_err(|_| format!("negative dimension {d}")))
                    .collect::<Result<_, _>>()?;
                let n = check_size(&s)?;
                one(Tensor::new(s, vec![*value; n]))
            }
        }
    }
}

//! Elementwise operators: numpy-broadcast binary operators (`Add`, `Sub`, `Mul`, `Div`,
//! `Pow`, `PRelu`'s slope), unary maps (`Relu`, `Sigmoid`, `Tanh`, `Neg`, `Sign`, `Sin`,
//! `Cos`, `Exp`, `Sqrt`, `Abs`) and `Softmax`.

use super::{check_size, norm_axis, Tensor};

/// A broadcast binary operator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BinOp {
    /// `a + b`.
    Add,
    /// `a - b`.
    Sub,
    /// `a * b`.
    Mul,
    /// `a / b`.
    Div,
    /// `a ^ b`.
    Pow,
    /// `a` if positive, else `b a` (PRelu with slope `b`).
    PRelu,
}

/// An elementwise unary map.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum UnOp {
    /// `max(x, 0)`.
    Relu,
    /// `1 / (1 + exp(-x))`.
    Sigmoid,
    /// `tanh(x)`.
    Tanh,
    /// `-x`.
    Neg,
    /// `-1`, `0` or `1`.
    Sign,
    /// `sin(x)`.
    Sin,
    /// `cos(x)`.
    Cos,
    /// `exp(x)`.
    Exp,
    /// `sqrt(x)`.
    Sqrt,
    /// `|x|`.
    Abs,
}

impl UnOp {
    /// Apply to one value (NaN propagates through Relu, unlike `f64::max`).
    pub fn apply(self, v: f64) -> f64 {
        match self {
            UnOp::Relu => {
                if v <= 0.0 {
                    0.0
                } else {
                    v
                }
            }
            UnOp::Sigmoid => 1.0 / (1.0 + (-v).exp()),
            UnOp::Tanh => v.tanh(),
            UnOp::Neg => -v,
            UnOp::Sign => crate::ir::Activation::Sign.apply_f64(v),
            UnOp::Sin => v.sin(),
            UnOp::Cos => v.cos(),
            UnOp::Exp => v.exp(),
            UnOp::Sqrt => v.sqrt(),
            UnOp::Abs => v.abs(),
        }
    }
}

impl BinOp {
    /// Apply to one pair.
    pub fn apply(self, a: f64, b: f64) -> f64 {
        match self {
            BinOp::Add => a + b,
            BinOp::Sub => a - b,
            BinOp::Mul => a * b,
            BinOp::Div => a / b,
            BinOp::Pow => a.powf(b),
            BinOp::PRelu => {
                if a < 0.0 {
                    a * b
                } else {
                    a
                }
            }
        }
    }
}

/// Multidirectional (numpy) broadcast of two shapes.
pub fn broadcast_shapes(a: &[usize], b: &[usize]) -> Result<Vec<usize>, String> {
    let r = a.len().max(b.len());
    let at = |s: &[usize], k: usize| {
        if k + s.len() >= r {
            s[k + s.len() - r]
        } else {
            1
        }
    };
    (0..r)
        .map(|k| match (at(a, k), at(b, k)) {
            (x, y) if x == y => Ok(x),
            (1, y) => Ok(y),
            (x, 1) => Ok(x),
            _ => Err(format!("shapes {a:?} and {b:?} do not broadcast")),
        })
        .collect()
}

/// For each entry of a tensor of shape `out`, the entry of a tensor of shape `src`
/// (which broadcasts to `out`) numpy reads there.
pub fn broadcast_index(out: &[usize], src: &[usize]) -> Vec<usize> {
    let r = out.len();
    let off = r - src.len();
    let mut st = vec![0usize; src.len()];
    let mut s = 1usize;
    for k in (0..src.len()).rev() {
        st[k] = if src[k] == 1 { 0 } else { s };
        s *= src[k];
    }
    let n: usize = out.iter().product();
    (0..n)
        .map(|flat| {
            let (mut rem, mut idx) = (flat, 0);
            for k in (0..r).rev() {
                let i = rem % out[k];
                rem /= out[k];
                if k >= off {
                    idx += i * st[k - off];
                }
            }
            idx
        })
        .collect()
}

/// Evaluate a broadcast binary operator.
pub fn binary(op: BinOp, a: &Tensor, b: &Tensor) -> Result<Tensor, String> {
    let s = broadcast_shapes(&a.shape, &b.shape)?;
    check_size(&s)?;
    let data = if a.shape == s && b.shape == s {
        a.data
            .iter()
            .zip(&b.data)
            .map(|(&x, &y)| op.apply(x, y))
            .collect()
    } else {
        let ia = broadcast_index(&s, &a.shape);
        let ib = broadcast_index(&s, &b.shape);
        ia.iter()
            .zip(&ib)
            .map(|(&i, &j)| op.apply(a.data[i], b.data[j]))
            .collect()
    };
    Ok(Tensor::new(s, data))
}

/// Evaluate a unary map.
pub fn unary(op: UnOp, x: &Tensor) -> Tensor {
    Tensor::new(
        x.shape.clone(),
        x.data.iter().map(|&v| op.apply(v)).collect(),
    )
}

/// `Softmax` along `axis`: `exp(x - max) / sum exp(x - max)`.
pub fn softmax(x: &Tensor, axis: i64) -> Result<Tensor, String> {
    let r = x.shape.len().max(1);
    let ax = norm_axis(axis, r)?;
    let shape = if x.shape.is_empty() {
        vec![1]
    } else {
        x.shape.clone()
    };
    let len = shape[ax];
    let inner: usize = shape[ax + 1..].iter().product();
    let outer: usize = shape[..ax].iter().product();
    let mut y = x.data.clone();
    for o in 0..outer {
        for i in 0..inner {
            let idx = |k: usize| (o * len + k) * inner + i;
            let m = (0..len)
                .map(|k| x.data[idx(k)])
                .fold(f64::NEG_INFINITY, f64::max);
            let s: f64 = (0..len).map(|k| (x.data[idx(k)] - m).exp()).sum();
            for k in 0..len {
                y[idx(k)] = (x.data[idx(k)] - m).exp() / s;
            }
        }
    }
    Ok(Tensor::new(x.shape.clone(), y))
}

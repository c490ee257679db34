//! `MaxPool`, `AveragePool`, `GlobalAveragePool` over one or two spatial dimensions.
//! [`windows`] lists, for every output entry, the input entries its window covers (the
//! padding excluded): the evaluation and the lowering of `MaxPool` to ReLUs
//! ([`crate::graph::lower`]) both read it.

use super::conv::{geometry, out_shape, AutoPad};
use super::{check_size, Tensor};

/// Attributes of a pooling operator.
#[derive(Clone, Debug, PartialEq)]
pub struct PoolAttrs {
    /// Window size per spatial axis.
    pub kernel: Vec<usize>,
    /// Strides (default 1).
    pub strides: Vec<usize>,
    /// Pads: begins then ends (default 0).
    pub pads: Vec<usize>,
    /// Dilations (default 1; MaxPool only).
    pub dilations: Vec<usize>,
    /// Round the output size up.
    pub ceil_mode: bool,
    /// AveragePool: divide by the window size including the padding.
    pub count_include_pad: bool,
    /// Automatic padding.
    pub auto_pad: AutoPad,
}

/// Output shape, per output entry its window's input entries, per output entry the
/// number of positions inside the padded input.
pub type Windows = (Vec<usize>, Vec<Vec<usize>>, Vec<usize>);

/// The windows of a pooling operator on an input of shape `shape`: the output shape,
/// per output entry (row-major) the flat input indices inside its window, and per
/// output entry the number of positions inside the padded input (the divisor of
/// `count_include_pad`).
pub fn windows(shape: &[usize], a: &PoolAttrs) -> Result<Windows, String> {
    let (g, peh, pew) = geometry(
        shape,
        &a.kernel,
        &a.strides,
        &a.dilations,
        &a.pads,
        a.auto_pad,
        a.ceil_mode,
    )?;
    let (pbh, pbw) = (g.ph, g.pw);
    let (n, c) = (shape[0], shape[1]);
    let oshape = out_shape(shape, c, &g);
    check_size(&oshape)?;
    let mut wins = Vec::with_capacity(n * c * g.oh * g.ow);
    let mut counts = Vec::with_capacity(n * c * g.oh * g.ow);
    for nc in 0..n * c {
        for oi in 0..g.oh {
            for oj in 0..g.ow {
                let mut win = Vec::with_capacity(g.kh * g.kw);
                let mut inside_padded = 0;
                for ki in 0..g.kh {
                    let ii = (oi * g.sh + ki * g.dh) as isize - pbh as isize;
                    for kj in 0..g.kw {
                        let jj = (oj * g.sw + kj * g.dw) as isize - pbw as isize;
                        if ii < (g.h + peh) as isize && jj < (g.w + pew) as isize {
                            inside_padded += 1;
                        }
                        if ii >= 0 && (ii as usize) < g.h && jj >= 0 && (jj as usize) < g.w {
                            win.push((nc * g.h + ii as usize) * g.w + jj as usize);
                        }
                    }
                }
                if win.is_empty() {
                    return Err(format!(
                        "output ({oi}, {oj}) of the pooling window covers padding only"
                    ));
                }
                wins.push(win);
                counts.push(inside_padded);
            }
        }
    }
    Ok((oshape, wins, counts))
}

/// `MaxPool`: the largest input in each window (NaN propagates).
pub fn max_pool(x: &Tensor, a: &PoolAttrs) -> Result<Tensor, String> {
    let (s, wins, _) = windows(&x.shape, a)?;
    let data = wins
        .iter()
        .map(|w| {
            w.iter().fold(f64::NEG_INFINITY, |m, &i| {
                let v = x.data[i];
                if v.is_nan() || m.is_nan() {
                    f64::NAN
                } else {
                    m.max(v)
                }
            })
        })
        .collect();
    Ok(Tensor::new(s, data))
}

/// `AveragePool`: the mean of each window, over its inputs only or (with
/// `count_include_pad`) over its positions inside the padded input.
pub fn average_pool(x: &Tensor, a: &PoolAttrs) -> Result<Tensor, String> {
    let (s, wins, counts) = windows(&x.shape, a)?;
    let data = wins
        .iter()
        .zip(&counts)
        .map(|(w, &cnt)| {
            let sum: f64 = w.iter().map(|&i| x.data[i]).sum();
            let d = if a.count_include_pad { cnt } else { w.len() };
            sum / d as f64
        })
        .collect();
    Ok(Tensor::new(s, data))
}

/// `GlobalAveragePool`: `[N, C, ...] -> [N, C, 1, ...]`, the mean over all spatial
/// positions of each channel.
pub fn global_average_pool(x: &Tensor) -> Result<Tensor, String> {
    if x.shape.len() < 3 {
        return Err(format!(
            "input of shape {:?}; GlobalAveragePool needs [N, C, spatial...]",
            x.shape
        ));
    }
    let (n, c) = (x.shape[0], x.shape[1]);
    let sp: usize = x.shape[2..].iter().product();
    let mut shape = vec![n, c];
    shape.extend(std::iter::repeat_n(1, x.shape.len() - 2));
    let data = (0..n * c)
        .map(|k| x.data[k * sp..(k + 1) * sp].iter().sum::<f64>() / sp as f64)
        .collect();
    Ok(Tensor::new(shape, data))
}

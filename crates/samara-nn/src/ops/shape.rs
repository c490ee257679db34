//! Operators that move entries without arithmetic: `Pad` (constant), `Concat`, `Slice`,
//! `Split`, `Gather`, `Reshape`, `Transpose`, `Squeeze`, `Unsqueeze` (Flatten and
//! Identity need no logic of their own).

use super::{check_size, norm_axis, strides, Tensor};

/// Map a function over every multi-index of `shape` (row-major), passing the flat index
/// and the multi-index.
fn for_each_index(shape: &[usize], mut f: impl FnMut(usize, &[usize])) {
    let n: usize = shape.iter().product();
    let mut idx = vec![0usize; shape.len()];
    for flat in 0..n {
        f(flat, &idx);
        for k in (0..shape.len()).rev() {
            idx[k] += 1;
            if idx[k] < shape[k] {
                break;
            }
            idx[k] = 0;
        }
    }
}

/// Constant `Pad`: `pads` holds the begins then the ends of the padded axes (all axes,
/// or `axes`); negative pads crop.
pub fn pad(x: &Tensor, pads: &[i64], axes: Option<&[i64]>, value: f64) -> Result<Tensor, String> {
    let r = x.shape.len();
    let axes: Vec<usize> = match axes {
        Some(a) => a
            .iter()
            .map(|&a| norm_axis(a, r))
            .collect::<Result<_, _>>()?,
        None => (0..r).collect(),
    };
    if pads.len() != 2 * axes.len() {
        return Err(format!(
            "pads {pads:?} must hold {} values (a begin and an end per axis)",
            2 * axes.len()
        ));
    }
    let mut begin = vec![0i64; r];
    let mut end = vec![0i64; r];
    for (k, &a) in axes.iter().enumerate() {
        begin[a] = pads[k];
        end[a] = pads[axes.len() + k];
    }
    let out: Vec<usize> = (0..r)
        .map(|k| {
            let s = x.shape[k] as i64 + begin[k] + end[k];
            usize::try_from(s).map_err(|_| format!("pads {pads:?} crop axis {k} below zero"))
        })
        .collect::<Result<_, _>>()?;
    check_size(&out)?;
    let xs = strides(&x.shape);
    let mut y = vec![value; out.iter().product()];
    for_each_index(&out, |flat, idx| {
        let mut src = 0usize;
        for k in 0..r {
            let i = idx[k] as i64 - begin[k];
            if i < 0 || i >= x.shape[k] as i64 {
                return;
            }
            src += i as usize * xs[k];
        }
        y[flat] = x.data[src];
    });
    Ok(Tensor::new(out, y))
}

/// `Concat` along `axis`.
pub fn concat(ts: &[&Tensor], axis: i64) -> Result<Tensor, String> {
    let first = ts.first().ok_or("Concat of nothing")?;
    let r = first.shape.len();
    let ax = norm_axis(axis, r)?;
    for t in ts {
        if t.shape.len() != r || (0..r).any(|k| k != ax && t.shape[k] != first.shape[k]) {
            return Err(format!(
                "operands of shapes {:?} and {:?} do not concatenate along axis {ax}",
                first.shape, t.shape
            ));
        }
    }
    let mut out = first.shape.clone();
    out[ax] = ts.iter().map(|t| t.shape[ax]).sum();
    check_size(&out)?;
    let outer: usize = out[..ax].iter().product();
    let mut y = Vec::with_capacity(out.iter().product());
    for o in 0..outer {
        for t in ts {
            let block: usize = t.shape[ax..].iter().product();
            y.extend_from_slice(&t.data[o * block..(o + 1) * block]);
        }
    }
    Ok(Tensor::new(out, y))
}

/// `Slice` with numpy semantics (negative indices from the end, clamped; negative
/// steps walk backwards).
pub fn slice(
    x: &Tensor,
    starts: &[i64],
    ends: &[i64],
    axes: Option<&[i64]>,
    steps: Option<&[i64]>,
) -> Result<Tensor, String> {
    let r = x.shape.len();
    let axes: Vec<usize> = match axes {
        Some(a) => a
            .iter()
            .map(|&a| norm_axis(a, r))
            .collect::<Result<_, _>>()?,
        None => (0..starts.len()).collect(),
    };
    if starts.len() != axes.len() || ends.len() != axes.len() {
        return Err(format!(
            "starts {starts:?}, ends {ends:?} and axes {axes:?} differ in length"
        ));
    }
    // Per axis: first index, step, count.
    let mut sel: Vec<(i64, i64, usize)> = x.shape.iter().map(|&d| (0, 1, d)).collect();
    for (k, &a) in axes.iter().enumerate() {
        let d = x.shape[a] as i64;
        let step = steps.map_or(1, |s| s.get(k).copied().unwrap_or(1));
        if step == 0 {
            return Err("a step of 0".into());
        }
        let fix = |v: i64, lo: i64, hi: i64| {
            let v = if v < 0 { v.saturating_add(d) } else { v };
            v.clamp(lo, hi)
        };
        let (s, e) = if step > 0 {
            (fix(starts[k], 0, d), fix(ends[k], 0, d))
        } else {
            (fix(starts[k], -1, d - 1), fix(ends[k], -1, d - 1))
        };
        let count = if step > 0 {
            if e > s {
                (e - s + step - 1) / step
            } else {
                0
            }
        } else if s > e {
            (s - e + (-step) - 1) / (-step)
        } else {
            0
        };
        sel[a] = (s, step, count as usize);
    }
    let out: Vec<usize> = sel.iter().map(|s| s.2).collect();
    check_size(&out)?;
    let xs = strides(&x.shape);
    let mut y = vec![0.0; out.iter().product()];
    for_each_index(&out, |flat, idx| {
        let src: usize = (0..r)
            .map(|k| (sel[k].0 + idx[k] as i64 * sel[k].1) as usize * xs[k])
            .sum();
        y[flat] = x.data[src];
    });
    Ok(Tensor::new(out, y))
}

/// `Split` along `axis` into `sizes` (or `outputs` equal parts, the last one smaller
/// if the axis does not divide).
pub fn split(
    x: &Tensor,
    axis: i64,
    sizes: Option<&[i64]>,
    outputs: usize,
) -> Result<Vec<Tensor>, String> {
    let r = x.shape.len();
    let ax = norm_axis(axis, r)?;
    let d = x.shape[ax];
    let sizes: Vec<usize> = match sizes {
        Some(s) => s
            .iter()
            .map(|&v| usize::try_from(v).map_err(|_| format!("negative split size {v}")))
            .collect::<Result<_, _>>()?,
        None => {
            let k = outputs.max(1);
            let part = d.div_ceil(k);
            (0..k)
                .map(|i| part.min(d.saturating_sub(i * part)))
                .collect()
        }
    };
    if sizes.iter().sum::<usize>() != d {
        return Err(format!(
            "split sizes {sizes:?} do not add up to the axis size {d}"
        ));
    }
    let mut start = 0i64;
    sizes
        .iter()
        .map(|&s| {
            let t = slice(x, &[start], &[start + s as i64], Some(&[ax as i64]), None);
            start += s as i64;
            t
        })
        .collect()
}

/// `Gather` along `axis` with integer `indices` of shape `ishape` (negative from the
/// end).
pub fn gather(x: &Tensor, indices: &[i64], ishape: &[usize], axis: i64) -> Result<Tensor, String> {
    let r = x.shape.len();
    let ax = norm_axis(axis, r)?;
    let d = x.shape[ax] as i64;
    let idx: Vec<usize> = indices
        .iter()
        .map(|&i| {
            let j = if i < 0 { i + d } else { i };
            if (0..d).contains(&j) {
                Ok(j as usize)
            } else {
                Err(format!("index {i} is out of range for an axis of size {d}"))
            }
        })
        .collect::<Result<_, _>>()?;
    let mut out: Vec<usize> = x.shape[..ax].to_vec();
    out.extend_from_slice(ishape);
    out.extend_from_slice(&x.shape[ax + 1..]);
    check_size(&out)?;
    let outer: usize = x.shape[..ax].iter().product();
    let inner: usize = x.shape[ax + 1..].iter().product();
    let mut y = Vec::with_capacity(out.iter().product());
    for o in 0..outer {
        for &j in &idx {
            let base = (o * x.shape[ax] + j) * inner;
            y.extend_from_slice(&x.data[base..base + inner]);
        }
    }
    Ok(Tensor::new(out, y))
}

/// Nearest-neighbour upsampling (ONNX `Upsample`, mode `nearest`, as onnxruntime
/// computes it): each axis of size `d` becomes `floor(d * scale)`, and output index `o`
/// reads input index `floor(o / scale)`. Scales below 1 (downsampling) are refused.
pub fn upsample_nearest(x: &Tensor, scales: &[f64]) -> Result<Tensor, String> {
    let r = x.shape.len();
    if scales.len() != r {
        return Err(format!(
            "has {} scales for an input of rank {r}; give one per axis",
            scales.len()
        ));
    }
    if let Some(s) = scales.iter().find(|s| !(s.is_finite() && **s >= 1.0)) {
        return Err(format!(
            "scale {s} is not supported (nearest upsampling by scales of at least 1)"
        ));
    }
    let out: Vec<usize> = x
        .shape
        .iter()
        .zip(scales)
        .map(|(&d, &s)| (d as f64 * s).floor() as usize)
        .collect();
    let n = check_size(&out)?;
    // Per axis, the input index each output index reads.
    let src: Vec<Vec<usize>> = out
        .iter()
        .zip(scales)
        .zip(&x.shape)
        .map(|((&o, &s), &d)| {
            (0..o)
                .map(|k| ((k as f64 / s).floor() as usize).min(d.saturating_sub(1)))
                .collect()
        })
        .collect();
    let (ist, ost) = (strides(&x.shape), strides(&out));
    let data = (0..n)
        .map(|flat| {
            let mut at = 0;
            for a in 0..r {
                at += src[a][(flat / ost[a]) % out[a]] * ist[a];
            }
            x.data[at]
        })
        .collect();
    Ok(Tensor::new(out, data))
}

/// The shape `Reshape` gives a tensor of `shape`: `0` copies the input's dimension
/// (unless `allowzero`), `-1` is inferred.
pub fn reshape_shape(
    shape: &[usize],
    target: &[i64],
    allowzero: bool,
) -> Result<Vec<usize>, String> {
    let d: usize = shape.iter().product();
    let bad = || format!("shape {target:?} is not a valid reshape of shape {shape:?}");
    let mut out = Vec::with_capacity(target.len());
    let mut infer = None;
    for (k, &t) in target.iter().enumerate() {
        match t {
            -1 if infer.is_none() => {
                infer = Some(k);
                out.push(1);
            }
            0 if !allowzero => out.push(*shape.get(k).ok_or_else(bad)?),
            t if t >= 0 && (t as usize) <= crate::limits::max_tensor_values() => {
                out.push(t as usize)
            }
            _ => return Err(bad()),
        }
    }
    let known: usize = out
        .iter()
        .try_fold(1usize, |a, &b| a.checked_mul(b))
        .ok_or_else(bad)?;
    if let Some(k) = infer {
        if known == 0 || !d.is_multiple_of(known) {
            return Err(bad());
        }
        out[k] = d / known;
    }
    if out.iter().product::<usize>() != d {
        return Err(bad());
    }
    Ok(out)
}

/// `Transpose` by `perm` (reversal when absent).
pub fn transpose(x: &Tensor, perm: Option<&[i64]>) -> Result<Tensor, String> {
    let r = x.shape.len();
    let perm: Vec<usize> = match perm {
        None => (0..r).rev().collect(),
        Some(p) => {
            let v: Vec<usize> = p
                .iter()
                .map(|&a| usize::try_from(a).ok().filter(|&a| a < r))
                .collect::<Option<_>>()
                .ok_or_else(|| format!("perm {p:?} is not a permutation of {r} axes"))?;
            if v.len() != r || (0..r).any(|k| !v.contains(&k)) {
                return Err(format!("perm {p:?} is not a permutation of {r} axes"));
            }
            v
        }
    };
    let out: Vec<usize> = perm.iter().map(|&p| x.shape[p]).collect();
    let xs = strides(&x.shape);
    let mut y = vec![0.0; x.numel()];
    for_each_index(&out, |flat, idx| {
        let src: usize = (0..r).map(|k| idx[k] * xs[perm[k]]).sum();
        y[flat] = x.data[src];
    });
    Ok(Tensor::new(out, y))
}

/// The shape after `Squeeze` (all size-1 axes when `axes` is absent).
pub fn squeeze_shape(shape: &[usize], axes: Option<&[i64]>) -> Result<Vec<usize>, String> {
    match axes {
        None => Ok(shape.iter().copied().filter(|&s| s != 1).collect()),
        Some(a) => {
            let ks: Vec<usize> = a
                .iter()
                .map(|&a| norm_axis(a, shape.len()))
                .collect::<Result<_, _>>()?;
            if let Some(&k) = ks.iter().find(|&&k| shape[k] != 1) {
                return Err(format!(
                    "axis {k} of shape {shape:?} is not 1 and cannot be squeezed"
                ));
            }
            Ok((0..shape.len())
                .filter(|k| !ks.contains(k))
                .map(|k| shape[k])
                .collect())
        }
    }
}

/// The shape after `Unsqueeze` at `axes` (of the output).
pub fn unsqueeze_shape(shape: &[usize], axes: &[i64]) -> Result<Vec<usize>, String> {
    let r = shape.len() + axes.len();
    let ks: Vec<usize> = axes
        .iter()
        .map(|&a| norm_axis(a, r))
        .collect::<Result<_, _>>()?;
    let mut rest = shape.iter().copied();
    Ok((0..r)
        .map(|k| {
            if ks.contains(&k) {
                1
            } else {
                rest.next().unwrap_or(1)
            }
        })
        .collect())
}

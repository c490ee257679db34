//! `Conv` and `ConvTranspose` over one or two spatial dimensions (a 1-D convolution is
//! evaluated as a 2-D one of height 1), with strides, pads, dilations and groups.

use super::{check_size, Tensor};

/// How `auto_pad` chooses the pads.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum AutoPad {
    /// The explicit `pads` attribute.
    NotSet,
    /// No padding.
    Valid,
    /// Output size `ceil(in / stride)`, the odd pad at the end.
    SameUpper,
    /// Output size `ceil(in / stride)`, the odd pad at the beginning.
    SameLower,
}

/// Attributes of a `Conv` (per spatial axis; empty vectors take the defaults).
#[derive(Clone, Debug, PartialEq)]
pub struct ConvAttrs {
    /// Strides (default 1).
    pub strides: Vec<usize>,
    /// Pads: begins then ends (default 0).
    pub pads: Vec<usize>,
    /// Dilations (default 1).
    pub dilations: Vec<usize>,
    /// Groups.
    pub group: usize,
    /// Automatic padding.
    pub auto_pad: AutoPad,
    /// The kernel's spatial shape if the attribute gives it (checked against W).
    pub kernel_shape: Option<Vec<usize>>,
}

/// Attributes of a `ConvTranspose`.
#[derive(Clone, Debug, PartialEq)]
pub struct ConvTransposeAttrs {
    /// The convolution's attributes.
    pub conv: ConvAttrs,
    /// Extra size added at the end of each spatial axis.
    pub output_padding: Vec<usize>,
}

/// Geometry of a 2-D window operation (1-D as height 1).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Geo {
    pub h: usize,
    pub w: usize,
    pub kh: usize,
    pub kw: usize,
    pub sh: usize,
    pub sw: usize,
    pub dh: usize,
    pub dw: usize,
    pub ph: usize,
    pub pw: usize,
    pub oh: usize,
    pub ow: usize,
}

/// The spatial dims of `[N, C, spatial...]` as (h, w), or an error for rank other than
/// 3 or 4.
pub(crate) fn spatial2(shape: &[usize]) -> Result<(usize, usize), String> {
    match shape.len() {
        3 => Ok((1, shape[2])),
        4 => Ok((shape[2], shape[3])),
        _ => Err(format!(
            "input of shape {shape:?}: samara evaluates windows over 1 or 2 spatial dimensions ([N, C, W] or [N, C, H, W])"
        )),
    }
}

/// Per-axis value `k` of an attribute vector for the (h, w) axes of a rank-`sr` window,
/// default `def`.
fn pick(v: &[usize], sr: usize, def: usize) -> (usize, usize) {
    let g = |k: usize| v.get(k).copied().unwrap_or(def);
    if sr == 1 {
        (def, g(0))
    } else {
        (g(0), g(1))
    }
}

/// The window geometry: output size per axis from input, kernel, stride, dilation and
/// pads (`ceil` rounds the output size up, as pooling's `ceil_mode`).
#[allow(clippy::too_many_arguments)]
pub(crate) fn geometry(
    in_shape: &[usize],
    kernel: &[usize],
    strides: &[usize],
    dilations: &[usize],
    pads: &[usize],
    auto_pad: AutoPad,
    ceil: bool,
) -> Result<(Geo, usize, usize), String> {
    let (h, w) = spatial2(in_shape)?;
    let sr = in_shape.len() - 2;
    if kernel.len() != sr {
        return Err(format!(
            "kernel of {} dimensions over an input of shape {in_shape:?}",
            kernel.len()
        ));
    }
    let (kh, kw) = pick(kernel, sr, 1);
    let (sh, sw) = pick(strides, sr, 1);
    let (dh, dw) = pick(dilations, sr, 1);
    if sh == 0 || sw == 0 || dh == 0 || dw == 0 || kh == 0 || kw == 0 {
        return Err("strides, dilations and kernel sizes must be positive".into());
    }
    let begins: Vec<usize> = pads.iter().take(sr).copied().collect();
    let ends: Vec<usize> = pads.iter().skip(sr).take(sr).copied().collect();
    let (mut pbh, mut pbw) = pick(&begins, sr, 0);
    let (mut peh, mut pew) = pick(&ends, sr, 0);
    let same = |n: usize, k: usize, s: usize, d: usize, upper: bool| {
        let out = n.div_ceil(s);
        let need = ((out - 1) * s + (k - 1) * d + 1).saturating_sub(n);
        if upper {
            (need / 2, need - need / 2)
        } else {
            (need - need / 2, need / 2)
        }
    };
    match auto_pad {
        AutoPad::NotSet => {}
        AutoPad::Valid => (pbh, pbw, peh, pew) = (0, 0, 0, 0),
        AutoPad::SameUpper | AutoPad::SameLower => {
            let up = auto_pad == AutoPad::SameUpper;
            (pbh, peh) = if sr == 1 {
                (0, 0)
            } else {
                same(h, kh, sh, dh, up)
            };
            (pbw, pew) = same(w, kw, sw, dw, up);
        }
    }
    let out = |n: usize, pb: usize, pe: usize, k: usize, s: usize, d: usize| {
        let span = (k - 1) * d + 1;
        let full = n + pb + pe;
        if full < span {
            return Err(format!(
                "a window of extent {span} does not fit the padded input of size {full}"
            ));
        }
        let o = if ceil {
            let mut o = (full - span).div_ceil(s) + 1;
            // The last window must start inside the input or its begin padding.
            if (o - 1) * s >= n + pb {
                o -= 1;
            }
            o
        } else {
            (full - span) / s + 1
        };
        Ok(o)
    };
    let oh = out(h, pbh, peh, kh, sh, dh)?;
    let ow = out(w, pbw, pew, kw, sw, dw)?;
    Ok((
        Geo {
            h,
            w,
            kh,
            kw,
            sh,
            sw,
            dh,
            dw,
            ph: pbh,
            pw: pbw,
            oh,
            ow,
        },
        peh,
        pew,
    ))
}

/// The output shape `[N, C, oh, ow]` (or `[N, C, ow]` for 1-D inputs).
pub(crate) fn out_shape(in_shape: &[usize], c: usize, g: &Geo) -> Vec<usize> {
    if in_shape.len() == 3 {
        vec![in_shape[0], c, g.ow]
    } else {
        vec![in_shape[0], c, g.oh, g.ow]
    }
}

/// `Conv`: `y[n, m, o] = B[m] + sum_{c, k} W[m, c, k] x[n, g(m) C/G + c, o s - p + k d]`.
pub fn conv(x: &Tensor, w: &Tensor, b: Option<&Tensor>, a: &ConvAttrs) -> Result<Tensor, String> {
    let xs = &x.shape;
    if w.shape.len() != xs.len() {
        return Err(format!(
            "the kernel W of shape {:?} does not match the input of shape {xs:?}",
            w.shape
        ));
    }
    let (n, c) = (xs[0], xs[1]);
    let (m, cg) = (w.shape[0], w.shape[1]);
    let group = a.group.max(1);
    if let Some(k) = &a.kernel_shape {
        if k.as_slice() != &w.shape[2..] {
            return Err(format!(
                "kernel_shape {k:?} disagrees with the kernel W of shape {:?}",
                w.shape
            ));
        }
    }
    if cg * group != c || m % group != 0 {
        return Err(format!(
            "the kernel W of shape {:?} with group {group} does not match {c} input channels",
            w.shape
        ));
    }
    let (g, _, _) = geometry(
        xs,
        &w.shape[2..],
        &a.strides,
        &a.dilations,
        &a.pads,
        a.auto_pad,
        false,
    )?;
    if let Some(b) = b {
        if b.numel() != m {
            return Err(format!(
                "the bias B has shape {:?}, expected [{m}]",
                b.shape
            ));
        }
    }
    let oshape = out_shape(xs, m, &g);
    check_size(&oshape)?;
    let mg = m / group;
    let (hw, ohw, khw) = (g.h * g.w, g.oh * g.ow, g.kh * g.kw);
    let mut y = vec![0.0; n * m * ohw];
    for ni in 0..n {
        for mi in 0..m {
            let gi = mi / mg;
            let bias = b.map_or(0.0, |b| b.data[mi]);
            let yo = &mut y[(ni * m + mi) * ohw..(ni * m + mi + 1) * ohw];
            yo.iter_mut().for_each(|v| *v = bias);
            for ci in 0..cg {
                let xc = &x.data[(ni * c + gi * cg + ci) * hw..][..hw];
                let wk = &w.data[(mi * cg + ci) * khw..][..khw];
                for ki in 0..g.kh {
                    for kj in 0..g.kw {
                        let wv = wk[ki * g.kw + kj];
                        if wv == 0.0 {
                            continue;
                        }
                        for oi in 0..g.oh {
                            let ii = (oi * g.sh + ki * g.dh) as isize - g.ph as isize;
                            if ii < 0 || ii as usize >= g.h {
                                continue;
                            }
                            let row = &xc[ii as usize * g.w..][..g.w];
                            let yr = &mut yo[oi * g.ow..][..g.ow];
                            for (oj, yv) in yr.iter_mut().enumerate() {
                                let jj = (oj * g.sw + kj * g.dw) as isize - g.pw as isize;
                                if jj >= 0 && (jj as usize) < g.w {
                                    *yv += wv * row[jj as usize];
                                }
                            }
                        }
                    }
                }
            }
        }
    }
    Ok(Tensor::new(oshape, y))
}

/// `ConvTranspose`: every input position scatters its kernel-weighted value to
/// `o = i s + k d - p`; W has shape `[C, M / G, k...]`. Evaluated through
/// `conv_transpose_visit`, the geometry [`conv_transpose_rows`] lowers with: each
/// output adds its bias, then its (input, weight) pairs in the rows' order, so the two
/// give the same bits.
pub fn conv_transpose(
    x: &Tensor,
    w: &Tensor,
    b: Option<&Tensor>,
    a: &ConvTransposeAttrs,
) -> Result<Tensor, String> {
    let oshape = conv_transpose_shape(&x.shape, w, a)?;
    let m = oshape[1];
    if let Some(b) = b {
        if b.numel() != m {
            return Err(format!(
                "the bias B has shape {:?}, expected [{m}]",
                b.shape
            ));
        }
    }
    let per_channel: usize = oshape[2..].iter().product();
    let n_out: usize = oshape.iter().product();
    let mut y: Vec<f64> = (0..n_out)
        .map(|o| b.map_or(0.0, |b| b.data[(o / per_channel) % m]))
        .collect();
    conv_transpose_visit(&x.shape, w, a, &|| Ok(()), |o, i, wv| {
        let xv = x.data[i];
        if xv != 0.0 {
            y[o] += xv * wv;
        }
    })?;
    Ok(Tensor::new(oshape, y))
}

/// The output shape of a `ConvTranspose` on an input of shape `xs`.
fn conv_transpose_shape(
    xs: &[usize],
    w: &Tensor,
    a: &ConvTransposeAttrs,
) -> Result<Vec<usize>, String> {
    conv_transpose_geo(xs, w, a).map(|g| g.oshape)
}

/// The geometry of a `ConvTranspose` (see [`conv_transpose_visit`]).
struct TransposeGeo {
    oshape: Vec<usize>,
    n: usize,
    c: usize,
    cg: usize,
    mg: usize,
    m: usize,
    h: usize,
    wd: usize,
    kh: usize,
    kw: usize,
    sh: usize,
    sw: usize,
    dh: usize,
    dw: usize,
    pbh: usize,
    pbw: usize,
    oh: usize,
    ow: usize,
}

fn conv_transpose_geo(
    xs: &[usize],
    w: &Tensor,
    a: &ConvTransposeAttrs,
) -> Result<TransposeGeo, String> {
    let (h, wd) = spatial2(xs)?;
    if w.shape.len() != xs.len() {
        return Err(format!(
            "the kernel W of shape {:?} does not match the input of shape {xs:?}",
            w.shape
        ));
    }
    let sr = xs.len() - 2;
    let (n, c) = (xs[0], xs[1]);
    let group = a.conv.group.max(1);
    if w.shape[0] != c || c % group != 0 {
        return Err(format!(
            "the kernel W of shape {:?} with group {group} does not match {c} input channels",
            w.shape
        ));
    }
    let mg = w.shape[1];
    let m = mg * group;
    let cg = c / group;
    let (kh, kw) = pick(&w.shape[2..], sr, 1);
    let (sh, sw) = pick(&a.conv.strides, sr, 1);
    let (dh, dw) = pick(&a.conv.dilations, sr, 1);
    let begins: Vec<usize> = a.conv.pads.iter().take(sr).copied().collect();
    let ends: Vec<usize> = a.conv.pads.iter().skip(sr).take(sr).copied().collect();
    let (pbh, pbw) = pick(&begins, sr, 0);
    let (peh, pew) = pick(&ends, sr, 0);
    let (oph, opw) = pick(&a.output_padding, sr, 0);
    if a.conv.auto_pad != AutoPad::NotSet && a.conv.auto_pad != AutoPad::Valid {
        return Err(
            "auto_pad SAME_* is not supported for ConvTranspose; give explicit pads".into(),
        );
    }
    let full =
        |n: usize, s: usize, k: usize, d: usize, op: usize| s * (n - 1) + op + (k - 1) * d + 1;
    let (fh, fw) = (full(h, sh, kh, dh, oph), full(wd, sw, kw, dw, opw));
    if fh < pbh + peh || fw < pbw + pew {
        return Err("the pads remove the whole output".into());
    }
    let (oh, ow) = (fh - pbh - peh, fw - pbw - pew);
    let oshape = if sr == 1 {
        vec![n, m, ow]
    } else {
        vec![n, m, oh, ow]
    };
    check_size(&oshape)?;
    check_size(&[n, c, h, wd, mg, kh, kw])?;
    Ok(TransposeGeo {
        oshape,
        n,
        c,
        cg,
        mg,
        m,
        h,
        wd,
        kh,
        kw,
        sh,
        sw,
        dh,
        dw,
        pbh,
        pbw,
        oh,
        ow,
    })
}

/// Every (output entry, input entry, weight) term of a `ConvTranspose` on an input of
/// shape `xs` (row-major indices), in the order the direct scatter adds them: by input
/// entry, then kernel tap. `check` is called once per input channel (a deadline: an
/// `Err` stops the walk and is returned). Returns the output shape.
pub(crate) fn conv_transpose_visit(
    xs: &[usize],
    w: &Tensor,
    a: &ConvTransposeAttrs,
    check: &dyn Fn() -> Result<(), String>,
    mut f: impl FnMut(usize, usize, f64),
) -> Result<Vec<usize>, String> {
    let g = conv_transpose_geo(xs, w, a)?;
    let (kh, kw, oh, ow) = (g.kh, g.kw, g.oh, g.ow);
    for ni in 0..g.n {
        for ci in 0..g.c {
            check()?;
            let gi = ci / g.cg;
            for mj in 0..g.mg {
                let mi = gi * g.mg + mj;
                let wk = &w.data[(ci * g.mg + mj) * kh * kw..][..kh * kw];
                for ii in 0..g.h {
                    for jj in 0..g.wd {
                        let xi = ((ni * g.c + ci) * g.h + ii) * g.wd + jj;
                        for ki in 0..kh {
                            let o = (ii * g.sh + ki * g.dh) as isize - g.pbh as isize;
                            if o < 0 || o as usize >= oh {
                                continue;
                            }
                            for kj in 0..kw {
                                let q = (jj * g.sw + kj * g.dw) as isize - g.pbw as isize;
                                if q < 0 || q as usize >= ow {
                                    continue;
                                }
                                f(
                                    ((ni * g.m + mi) * oh + o as usize) * ow + q as usize,
                                    xi,
                                    wk[ki * kw + kj],
                                );
                            }
                        }
                    }
                }
            }
        }
    }
    Ok(g.oshape)
}

/// The output shape of a `ConvTranspose` on an input of shape `xs` and its rows as a
/// sparse linear map (the bias left out): per output entry (row-major), the input
/// entries it reads and their weights, in the order the direct scatter adds them.
/// `check` is called once per input channel (`conv_transpose_visit`).
#[allow(clippy::type_complexity)]
pub fn conv_transpose_rows(
    xs: &[usize],
    w: &Tensor,
    a: &ConvTransposeAttrs,
    check: &dyn Fn() -> Result<(), String>,
) -> Result<(Vec<usize>, Vec<Vec<(usize, f64)>>), String> {
    let oshape = conv_transpose_shape(xs, w, a)?;
    let mut rows: Vec<Vec<(usize, f64)>> = vec![Vec::new(); oshape.iter().product()];
    conv_transpose_visit(xs, w, a, check, |o, i, wv| rows[o].push((i, wv)))?;
    Ok((oshape, rows))
}

/// The rows of a `Conv` as a sparse linear map (the bias left out): per output entry
/// (row-major), the input entries it reads and their weights. The lowering to the
/// chain form composes these with sparse columns instead of evaluating the convolution
/// once per column.
/// `check` is called once per output channel (a deadline: an `Err` stops and is
/// returned).
pub fn conv_rows(
    xs: &[usize],
    w: &Tensor,
    a: &ConvAttrs,
    check: &dyn Fn() -> Result<(), String>,
) -> Result<Vec<Vec<(usize, f64)>>, String> {
    let (n, c) = (xs[0], xs[1]);
    let (m, cg) = (w.shape[0], w.shape[1]);
    let group = a.group.max(1);
    let (g, _, _) = geometry(
        xs,
        &w.shape[2..],
        &a.strides,
        &a.dilations,
        &a.pads,
        a.auto_pad,
        false,
    )?;
    let mg = m / group;
    let khw = g.kh * g.kw;
    let mut rows = Vec::with_capacity(n * m * g.oh * g.ow);
    for ni in 0..n {
        for mi in 0..m {
            check()?;
            let gi = mi / mg;
            for oi in 0..g.oh {
                for oj in 0..g.ow {
                    let mut row = Vec::with_capacity(cg * khw);
                    for ci in 0..cg {
                        let ch = ni * c + gi * cg + ci;
                        for ki in 0..g.kh {
                            let ii = (oi * g.sh + ki * g.dh) as isize - g.ph as isize;
                            if ii < 0 || ii as usize >= g.h {
                                continue;
                            }
                            for kj in 0..g.kw {
                                let jj = (oj * g.sw + kj * g.dw) as isize - g.pw as isize;
                                if jj < 0 || jj as usize >= g.w {
                                    continue;
                                }
                                let wv = w.data[(mi * cg + ci) * khw + ki * g.kw + kj];
                                if wv != 0.0 {
                                    row.push(((ch * g.h + ii as usize) * g.w + jj as usize, wv));
                                }
                            }
                        }
                    }
                    rows.push(row);
                }
            }
        }
    }
    Ok(rows)
}

//! `MatMul` (numpy semantics: vectors promoted, batch dimensions broadcast) and `Gemm`,
//! with the weight on either side.

use super::elementwise::{broadcast_index, broadcast_shapes};
use super::{check_size, Tensor};

/// Numpy matrix product.
pub fn matmul(a: &Tensor, b: &Tensor) -> Result<Tensor, String> {
    if a.shape.is_empty() || b.shape.is_empty() {
        return Err("MatMul of a scalar".into());
    }
    let av = a.shape.len() == 1;
    let bv = b.shape.len() == 1;
    let sa = if av {
        vec![1, a.shape[0]]
    } else {
        a.shape.clone()
    };
    let sb = if bv {
        vec![b.shape[0], 1]
    } else {
        b.shape.clone()
    };
    let (n, k) = (sa[sa.len() - 2], sa[sa.len() - 1]);
    let (k2, m) = (sb[sb.len() - 2], sb[sb.len() - 1]);
    if k != k2 {
        return Err(format!(
            "operands of shapes {:?} and {:?}: inner dimensions {k} and {k2} differ",
            a.shape, b.shape
        ));
    }
    let ba = &sa[..sa.len() - 2];
    let bb = &sb[..sb.len() - 2];
    let batch = broadcast_shapes(ba, bb)?;
    let mut out = batch.clone();
    out.extend([n, m]);
    check_size(&out)?;
    let ia = broadcast_index(&batch, ba);
    let ib = broadcast_index(&batch, bb);
    let mut y = vec![0.0; out.iter().product()];
    for (bi, (&pa, &pb)) in ia.iter().zip(&ib).enumerate() {
        let am = &a.data[pa * n * k..][..n * k];
        let bm = &b.data[pb * k * m..][..k * m];
        let ym = &mut y[bi * n * m..][..n * m];
        for i in 0..n {
            for l in 0..k {
                let av = am[i * k + l];
                if av == 0.0 {
                    continue;
                }
                let brow = &bm[l * m..][..m];
                for (yv, bv) in ym[i * m..][..m].iter_mut().zip(brow) {
                    *yv += av * bv;
                }
            }
        }
    }
    let mut shape = batch;
    if !av {
        shape.push(n);
    }
    if !bv {
        shape.push(m);
    }
    Ok(Tensor::new(shape, y))
}

/// `Gemm`: `alpha op(A) op(B) + beta C`, A and B matrices, C broadcast to the result.
pub fn gemm(
    a: &Tensor,
    b: &Tensor,
    c: Option<&Tensor>,
    alpha: f64,
    beta: f64,
    trans_a: bool,
    trans_b: bool,
) -> Result<Tensor, String> {
    let mat = |t: &Tensor, tr: bool, what: &str| -> Result<Tensor, String> {
        // A vector is read as one row, as onnxruntime does for A.
        let t2 = match t.shape.len() {
            1 => Tensor::new(vec![1, t.shape[0]], t.data.clone()),
            2 => t.clone(),
            _ => return Err(format!("{what} must be a matrix, has shape {:?}", t.shape)),
        };
        Ok(if tr { transpose2(&t2) } else { t2 })
    };
    let am = mat(a, trans_a, "A")?;
    let bm = mat(b, trans_b, "B")?;
    let mut y = matmul(&am, &bm)?;
    y.data.iter_mut().for_each(|v| *v *= alpha);
    if let Some(c) = c {
        let s = broadcast_shapes(&y.shape, &c.shape)?;
        if s != y.shape {
            return Err(format!(
                "C of shape {:?} does not broadcast to the result {:?}",
                c.shape, y.shape
            ));
        }
        let ic = broadcast_index(&y.shape, &c.shape);
        for (v, i) in y.data.iter_mut().zip(ic) {
            *v += beta * c.data[i];
        }
    }
    Ok(y)
}

fn transpose2(t: &Tensor) -> Tensor {
    let (r, c) = (t.shape[0], t.shape[1]);
    let mut d = vec![0.0; r * c];
    for i in 0..r {
        for j in 0..c {
            d[j * r + i] = t.data[i * c + j];
        }
    }
    Tensor::new(vec![c, r], d)
}

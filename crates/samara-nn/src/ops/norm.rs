//! `BatchNormalization` in inference mode: per channel (axis 1) the affine map
//! `y = scale (x - mean) / sqrt(var + epsilon) + B`.

use super::Tensor;

/// Evaluate batch normalisation with the running statistics.
pub fn batch_norm(
    x: &Tensor,
    scale: &Tensor,
    b: &Tensor,
    mean: &Tensor,
    var: &Tensor,
    epsilon: f64,
) -> Result<Tensor, String> {
    if x.shape.len() < 2 {
        return Err(format!(
            "input of shape {:?}; BatchNormalization needs [N, C, ...]",
            x.shape
        ));
    }
    let c = x.shape[1];
    for (name, t) in [("scale", scale), ("B", b), ("mean", mean), ("var", var)] {
        if t.numel() != c {
            return Err(format!(
                "{name} has shape {:?}, expected [{c}] (one value per channel)",
                t.shape
            ));
        }
    }
    let (mul, add) = channel_affine(scale, b, mean, var, epsilon);
    let sp: usize = x.shape[2..].iter().product();
    let data = x
        .data
        .iter()
        .enumerate()
        .map(|(i, &v)| {
            let ch = (i / sp) % c;
            v * mul[ch] + add[ch]
        })
        .collect();
    Ok(Tensor::new(x.shape.clone(), data))
}

/// The per-channel multiplier and offset of the normalisation.
pub fn channel_affine(
    scale: &Tensor,
    b: &Tensor,
    mean: &Tensor,
    var: &Tensor,
    epsilon: f64,
) -> (Vec<f64>, Vec<f64>) {
    let mul: Vec<f64> = scale
        .data
        .iter()
        .zip(&var.data)
        .map(|(s, v)| s / (v + epsilon).sqrt())
        .collect();
    let add = b
        .data
        .iter()
        .zip(&mean.data)
        .zip(&mul)
        .map(|((b, m), k)| b - m * k)
        .collect();
    (mul, add)
}

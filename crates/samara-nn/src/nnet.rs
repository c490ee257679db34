//! The NNet text format (K. Julian and M. Kochenderfer, Stanford 2016; the format of the
//! ACAS Xu networks of Katz et al., "Reluplex", CAV 2017, and of several ARCH-COMP AINNCS
//! benchmarks; reference reader: <https://github.com/sisl/NNet>).
//!
//! Layout of a file (values comma-separated, a trailing comma is normal):
//!
//! ```text
//! // any number of leading comment lines
//! numLayers, inputSize, outputSize, maxLayerSize
//! size_0, size_1, ..., size_numLayers          (size_0 = inputSize, last = outputSize)
//! flag                                         (unused)
//! min_0, ..., min_{inputSize-1}                (input minimums)
//! max_0, ..., max_{inputSize-1}                (input maximums)
//! mean_0, ..., mean_{inputSize-1}, mean_out    (normalisation means)
//! range_0, ..., range_{inputSize-1}, range_out (normalisation ranges)
//! then for each layer k: size_{k+1} weight rows of size_k values, then size_{k+1}
//! biases, one per line
//! ```
//!
//! Semantics: every input is clipped to `[min_i, max_i]`, normalised to
//! `(x_i - mean_i) / range_i`, passed through the layers (ReLU after every layer but the
//! last, which is linear), and every output is denormalised to `y * range_out + mean_out`.
//!
//! In the [`Network`] IR the clipping is represented exactly, with the break points at
//! the stored f64 bounds: `clip(x, lo, hi) = lo + relu(x - lo) - relu(x - hi)` (one
//! affine map with weights `+-1` and biases `-lo`, `-hi`, then a ReLU); a one-sided or
//! absent bound uses `lo + relu(x - lo)`, `hi - relu(hi - x)` or `relu(x) - relu(-x)`.
//! The recombination, the normalisation `(. - mean_i) / range_i` and the first layer of
//! the file are composed into one affine map (rounded once in f64, like any reader that
//! normalises in f64). The output map goes in [`Network::output_denorm`];
//! [`Network::input_norm`] stays empty (the normalisation is inside the body, after the
//! clipping). For inputs inside `[min, max]` the clipping ReLUs are all stable, so bound
//! propagation through them is exact. (The f64 evaluation of `relu(x - lo) - relu(x - hi)`
//! cancels for inputs far outside the bounds: at `|x| = 1e6` times the bounds' scale the
//! clipped value is off by about `1e-10` relative; at `1e16` times it is meaningless.
//! Exact-arithmetic tools are unaffected.)

use crate::ir::{Activation, Affine, Layer, Network};
use std::path::Path;

/// Largest layer size accepted (the format has no limit; this guards allocations).
pub const MAX_LAYER_SIZE: usize = 1 << 16;
/// Largest number of layers accepted.
pub const MAX_LAYERS: usize = 4096;
/// Largest total number of weights and biases accepted.
pub const MAX_PARAMETERS: usize = 50_000_000;

/// An error reading an NNet file: the file, the 1-based line, what was expected and
/// how to fix it.
#[derive(Debug, thiserror::Error)]
pub enum NnetError {
    /// The file could not be read.
    // The OS error is part of the message and deliberately not a `source()` (as in the
    // ONNX reader): shown once.
    #[error("{file}: cannot read: {cause}")]
    Io {
        /// The file.
        file: String,
        /// The OS error.
        cause: std::io::Error,
    },
    /// The text does not follow the format.
    #[error("{file}:{line}: {message}")]
    Format {
        /// The file (or the name given to [`parse`]).
        file: String,
        /// 1-based line number (the line after the last one at end of file).
        line: usize,
        /// What was expected, what was found, and the fix.
        message: String,
    },
}

/// Read and convert an NNet file.
pub fn load(path: &Path) -> Result<Network, NnetError> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|cause| NnetError::Io {
        file: file.clone(),
        cause,
    })?;
    let text = String::from_utf8(bytes).map_err(|e| {
        // Line of the first invalid byte.
        let upto = e.utf8_error().valid_up_to();
        let line = 1 + e.as_bytes()[..upto].iter().filter(|&&b| b == b'\n').count();
        NnetError::Format {
            file: file.clone(),
            line,
            message: "the text is not valid UTF-8; an NNet file is plain ASCII text (is this \
                      a binary file such as .onnx or .h5?)"
                .into(),
        }
    })?;
    parse(&text, &file)
}

/// The lines of the text after the leading comments, with their 1-based numbers; blank
/// lines are skipped.
struct Lines<'a> {
    name: &'a str,
    lines: Vec<(usize, &'a str)>,
    pos: usize,
    last: usize,
}

impl<'a> Lines<'a> {
    fn err(&self, line: usize, message: String) -> NnetError {
        NnetError::Format {
            file: self.name.to_string(),
            line,
            message,
        }
    }

    /// The next non-blank line, or an error saying what was expected there.
    fn next(&mut self, what: &str) -> Result<(usize, &'a str), NnetError> {
        match self.lines.get(self.pos) {
            Some(&l) => {
                self.pos += 1;
                Ok(l)
            }
            None => Err(self.err(
                self.last + 1,
                format!(
                    "unexpected end of file: expected {what}; the file is truncated or its \
                     header declares more layers or neurons than it contains"
                ),
            )),
        }
    }

    /// The next line's fields, which must be exactly `n` (else the error `wrong_count`
    /// of the number found).
    fn fields_n(
        &mut self,
        n: usize,
        what: &str,
        wrong_count: impl FnOnce(usize) -> String,
    ) -> Result<(usize, Vec<&'a str>), NnetError> {
        let (line, text) = self.next(what)?;
        let fields = fields(text);
        if fields.len() != n {
            return Err(self.err(line, wrong_count(fields.len())));
        }
        Ok((line, fields))
    }

    /// The next line as exactly `n` finite numbers.
    fn numbers(&mut self, n: usize, what: &str) -> Result<(usize, Vec<f64>), NnetError> {
        self.numbers_inf(n, what, false)
    }

    /// [`Lines::numbers`], accepting infinities when `allow_inf` (input bounds).
    fn numbers_inf(
        &mut self,
        n: usize,
        what: &str,
        allow_inf: bool,
    ) -> Result<(usize, Vec<f64>), NnetError> {
        let (line, fields) = self.fields_n(n, what, |found| {
            format!(
                "expected {what}: {n} comma-separated value{}, found {found}; fix the line or \
                 the sizes declared in the header",
                if n == 1 { "" } else { "s" },
            )
        })?;
        let mut out = Vec::with_capacity(n);
        for (k, f) in fields.iter().enumerate() {
            match f.parse::<f64>() {
                Ok(v) if v.is_finite() || (allow_inf && v.is_infinite()) => out.push(v),
                Ok(_) => {
                    return Err(self.err(
                        line,
                        format!(
                            "{what}: value {} is `{f}`, which is not finite; NaN and infinite \
                             values are not allowed (only input bounds may be `inf`/`-inf`); repair the network",
                            k + 1
                        ),
                    ))
                }
                Err(_) => {
                    return Err(self.err(
                        line,
                        format!(
                            "{what}: value {} is `{}`, expected a decimal number such as \
                             `-1.5e-3`",
                            k + 1,
                            truncate(f)
                        ),
                    ))
                }
            }
        }
        Ok((line, out))
    }

    /// The next line as exactly `n` non-negative integers.
    fn integers(&mut self, n: usize, what: &str) -> Result<(usize, Vec<usize>), NnetError> {
        let (line, fields) = self.fields_n(n, what, |found| {
            format!(
                "expected {what}: {n} comma-separated integers, found {found} values; fix the \
                 line (or the number of layers in the header)"
            )
        })?;
        let mut out = Vec::with_capacity(n);
        for (k, f) in fields.iter().enumerate() {
            match f.parse::<usize>() {
                Ok(v) => out.push(v),
                Err(_) => {
                    return Err(self.err(
                        line,
                        format!(
                            "{what}: value {} is `{}`, expected a non-negative integer",
                            k + 1,
                            truncate(f)
                        ),
                    ))
                }
            }
        }
        Ok((line, out))
    }
}

/// The comma-separated fields of a line, trimmed; a trailing empty field (trailing comma)
/// is dropped.
fn fields(line: &str) -> Vec<&str> {
    let mut v: Vec<&str> = line.split(',').map(str::trim).collect();
    if v.len() > 1 && v.last() == Some(&"") {
        v.pop();
    }
    if v.len() == 1 && v[0].is_empty() {
        v.clear();
    }
    v
}

/// At most 40 characters of a field, for messages.
fn truncate(s: &str) -> String {
    if s.chars().count() <= 40 {
        s.to_string()
    } else {
        format!("{}...", s.chars().take(40).collect::<String>())
    }
}

/// Parse and convert NNet text; `name` names it in errors (usually the file path).
pub fn parse(text: &str, name: &str) -> Result<Network, NnetError> {
    let mut all = text.lines().enumerate().map(|(i, l)| (i + 1, l)).peekable();
    // Leading comments (blank lines among them are skipped too).
    while let Some(&(_, l)) = all.peek() {
        let t = l.trim();
        if t.starts_with("//") || t.is_empty() {
            all.next();
        } else {
            break;
        }
    }
    let lines: Vec<(usize, &str)> = all.filter(|(_, l)| !l.trim().is_empty()).collect();
    let last = text.lines().count();
    let mut r = Lines {
        name,
        lines,
        pos: 0,
        last,
    };

    let (hline, header) = r.integers(
        4,
        "the header `numLayers, inputSize, outputSize, maxLayerSize`",
    )?;
    let (nl, n_in, n_out) = (header[0], header[1], header[2]);
    if nl == 0 || nl > MAX_LAYERS {
        return Err(r.err(
            hline,
            format!("numLayers is {nl}; expected between 1 and {MAX_LAYERS}"),
        ));
    }
    for (v, what) in [(n_in, "inputSize"), (n_out, "outputSize")] {
        if v == 0 || v > MAX_LAYER_SIZE {
            return Err(r.err(
                hline,
                format!("{what} is {v}; expected between 1 and {MAX_LAYER_SIZE}"),
            ));
        }
    }
    let (sline, sizes) = r.integers(nl + 1, "the layer sizes (numLayers + 1 values)")?;
    if let Some(&s) = sizes.iter().find(|&&s| s == 0 || s > MAX_LAYER_SIZE) {
        return Err(r.err(
            sline,
            format!("a layer size is {s}; expected between 1 and {MAX_LAYER_SIZE}"),
        ));
    }
    if sizes[0] != n_in || sizes[nl] != n_out {
        return Err(r.err(
            sline,
            format!(
                "the layer sizes start with {} and end with {}, but the header declares \
                 inputSize {n_in} and outputSize {n_out}; make them agree",
                sizes[0], sizes[nl]
            ),
        ));
    }
    let params: usize = sizes
        .windows(2)
        .map(|d| d[0].saturating_mul(d[1]).saturating_add(d[1]))
        .fold(0usize, usize::saturating_add);
    if params > MAX_PARAMETERS {
        return Err(r.err(
            sline,
            format!(
                "the layer sizes declare {params} parameters, more than the {MAX_PARAMETERS} \
                 this reader accepts; is the sizes line corrupted?"
            ),
        ));
    }
    r.next("the (unused) flag line")?;
    let (nline, mins) = r.numbers_inf(n_in, "the input minimums (inputSize values)", true)?;
    if let Some(i) = mins.iter().position(|&v| v == f64::INFINITY) {
        return Err(r.err(
            nline,
            format!("input {i}: the minimum is +inf; use a finite minimum or -inf for none"),
        ));
    }
    let (mline, maxs) = r.numbers_inf(n_in, "the input maximums (inputSize values)", true)?;
    if let Some(i) = (0..n_in)
        .find(|&i| mins[i] > maxs[i] || mins[i] == f64::INFINITY || maxs[i] == f64::NEG_INFINITY)
    {
        return Err(r.err(
            mline,
            format!(
                "input {i}: maximum {} is below minimum {}; swap or fix the bounds",
                maxs[i], mins[i]
            ),
        ));
    }
    let (_, means) = r.numbers(n_in + 1, "the means (inputSize + 1 values, last = output)")?;
    let (rline, ranges) =
        r.numbers(n_in + 1, "the ranges (inputSize + 1 values, last = output)")?;
    if let Some(i) = ranges.iter().position(|&v| v == 0.0) {
        return Err(r.err(
            rline,
            format!(
                "range {} is 0; normalisation divides by it, use a non-zero range (1 for none)",
                i + 1
            ),
        ));
    }

    // Layers of the file.
    let mut file_layers: Vec<(Affine, usize)> = Vec::with_capacity(nl);
    for k in 0..nl {
        let (inp, out) = (sizes[k], sizes[k + 1]);
        // Grown as lines arrive: a corrupted header cannot make a large allocation.
        let mut w = Vec::with_capacity((inp * out).min(1 << 16));
        let mut first = 0;
        for i in 0..out {
            let (line, row) = r.numbers(
                inp,
                &format!(
                    "layer {} weight row {} of {out} ({inp} values)",
                    k + 1,
                    i + 1
                ),
            )?;
            if i == 0 {
                first = line;
            }
            w.extend_from_slice(&row);
        }
        let mut b = Vec::with_capacity(out.min(1 << 16));
        for i in 0..out {
            let (_, v) = r.numbers(
                1,
                &format!("layer {} bias {} of {out} (1 value)", k + 1, i + 1),
            )?;
            b.push(v[0]);
        }
        file_layers.push((Affine::new(inp, out, w, b), first));
    }
    if let Some(&(line, text)) = r.lines.get(r.pos) {
        return Err(r.err(
            line,
            format!(
                "unexpected data after the last layer (`{}`); the header declares fewer layers \
                 or neurons than the file contains",
                truncate(text.trim())
            ),
        ));
    }

    // Clipping: rows of the first map, and how to recombine them into clip(x_i).
    // clip_i = base_i + sum_r sign_r * relu(row_r).
    let mut cw: Vec<f64> = Vec::new();
    let mut cb: Vec<f64> = Vec::new();
    let mut recomb: Vec<(usize, f64)> = Vec::new(); // (input, sign) per row
    let mut base = vec![0.0; n_in];
    for i in 0..n_in {
        let (lo, hi) = (mins[i], maxs[i]);
        let mut row = |coef: f64, bias: f64, sign: f64| {
            let mut v = vec![0.0; n_in];
            v[i] = coef;
            cw.extend_from_slice(&v);
            cb.push(bias);
            recomb.push((i, sign));
        };
        // `-inf` minimums and `+inf` maximums (written `-inf`, `inf`) mean no clipping.
        match (lo.is_finite(), hi.is_finite()) {
            (true, true) => {
                base[i] = lo;
                row(1.0, -lo, 1.0);
                row(1.0, -hi, -1.0);
            }
            (true, false) => {
                base[i] = lo;
                row(1.0, -lo, 1.0);
            }
            (false, true) => {
                base[i] = hi;
                row(-1.0, hi, -1.0);
            }
            (false, false) => {
                row(1.0, 0.0, 1.0);
                row(-1.0, 0.0, -1.0);
            }
        }
    }
    let nc = cb.len();
    let clip = Affine::new(n_in, nc, cw, cb);

    // First file layer composed with recombination and normalisation:
    // W1 ((base + R r - mean) / range) + b1.
    let (w1, line1) = &file_layers[0];
    let h = w1.out;
    let mut w = vec![0.0; h * nc];
    let mut b = w1.b.clone();
    for j in 0..h {
        for (rr, &(i, sign)) in recomb.iter().enumerate() {
            w[j * nc + rr] = sign * w1.weight(j, i) / ranges[i];
        }
        for i in 0..n_in {
            b[j] += w1.weight(j, i) * ((base[i] - means[i]) / ranges[i]);
        }
    }
    if w.iter().chain(&b).any(|v| !v.is_finite()) {
        return Err(r.err(
            *line1,
            "layer 1 composed with the input normalisation overflows (a range is too small \
             or a weight or mean too large); check the means and ranges"
                .into(),
        ));
    }
    let mut layers = vec![
        Layer::Affine(clip),
        Layer::Act(Activation::Relu),
        Layer::Affine(Affine::new(nc, h, w, b)),
    ];
    for (a, _) in file_layers.into_iter().skip(1) {
        layers.push(Layer::Act(Activation::Relu));
        layers.push(Layer::Affine(a));
    }
    let net = Network {
        input_names: (0..n_in).map(|i| format!("x{i}")).collect(),
        output_names: (0..n_out).map(|i| format!("y{i}")).collect(),
        input_norm: None,
        layers,
        output_denorm: Some(Affine::denormalise(
            &vec![means[n_in]; n_out],
            &vec![ranges[n_in]; n_out],
        )),
    };
    net.validate()
        .map_err(|e| r.err(hline, format!("inconsistent network: {e}")))?;
    Ok(net)
}

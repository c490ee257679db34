//! Data sets: CSV (with or without a header) and IDX (the dataset format of the Vehicle
//! specification language), min-max normalisation, seeded train/test splits.

use rand::seq::SliceRandom;
use rand::SeedableRng;
use std::path::Path;

/// Errors reading data.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    /// I/O.
    // The OS error is part of the message and deliberately not a `source()`: shown both
    // ways it would be printed twice by `{:#}` (issue 17).
    #[error("{file}: cannot read: {cause}")]
    Io {
        /// File.
        file: String,
        /// Cause.
        cause: std::io::Error,
    },
    /// Malformed content.
    #[error("{}{}: {message}", .file, at_line(*.line))]
    Format {
        /// File.
        file: String,
        /// 1-based line (0 for binary formats).
        line: usize,
        /// What is wrong and how to fix it.
        message: String,
    },
}

/// `:LINE` for a 1-based line, nothing for 0 (a binary format or the file as a whole),
/// so a message never shows the meaningless place `file:0`.
fn at_line(line: usize) -> String {
    if line == 0 {
        String::new()
    } else {
        format!(":{line}")
    }
}

/// A table of numbers (rows of equal length).
#[derive(Clone, Debug, PartialEq)]
pub struct Table {
    /// Column names (from a header, or `c0, c1, ...`).
    pub names: Vec<String>,
    /// Number of columns.
    pub cols: usize,
    /// Row-major values.
    pub values: Vec<f64>,
}

impl Table {
    /// Number of rows.
    pub fn rows(&self) -> usize {
        self.values.len().checked_div(self.cols).unwrap_or(0)
    }

    /// Row `i`.
    pub fn row(&self, i: usize) -> &[f64] {
        &self.values[i * self.cols..(i + 1) * self.cols]
    }
}

/// Read a CSV of numbers. A first line that does not parse as numbers is a header.
/// Empty files, ragged rows and non-numbers are errors naming file and line.
pub fn read_csv(path: &Path) -> Result<Table, DataError> {
    let file = path.display().to_string();
    let text = std::fs::read_to_string(path).map_err(|cause| DataError::Io {
        file: file.clone(),
        cause,
    })?;
    parse_csv(&text, &file)
}

/// Parse CSV text (see [`read_csv`]).
pub fn parse_csv(text: &str, file: &str) -> Result<Table, DataError> {
    let fmt = |line: usize, message: String| DataError::Format {
        file: file.into(),
        line,
        message,
    };
    let mut names: Option<Vec<String>> = None;
    let mut cols = 0usize;
    let mut values = Vec::new();
    let mut data_rows = 0usize;
    for (i, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        let parsed: Result<Vec<f64>, _> = fields.iter().map(|f| f.parse::<f64>()).collect();
        match parsed {
            Err(_) if names.is_none() && data_rows == 0 => {
                names = Some(fields.iter().map(|s| s.to_string()).collect());
                cols = fields.len();
            }
            Err(_) => {
                let bad = fields
                    .iter()
                    .find(|f| f.parse::<f64>().is_err())
                    .unwrap_or(&"");
                return Err(fmt(i + 1, format!("`{bad}` is not a number")));
            }
            Ok(v) => {
                if cols == 0 {
                    cols = v.len();
                }
                if v.len() != cols {
                    return Err(fmt(
                        i + 1,
                        format!(
                            "row has {} values but the file has {cols} columns (ragged CSV)",
                            v.len()
                        ),
                    ));
                }
                if let Some(j) = v.iter().position(|x| !x.is_finite()) {
                    return Err(fmt(
                        i + 1,
                        format!("column {} is {} (NaN or infinite)", j + 1, v[j]),
                    ));
                }
                values.extend(v);
                data_rows += 1;
            }
        }
    }
    if data_rows == 0 {
        return Err(fmt(
            0,
            "no data rows (the file is empty or has only a header)".into(),
        ));
    }
    let names = names.unwrap_or_else(|| (0..cols).map(|j| format!("c{j}")).collect());
    Ok(Table {
        names,
        cols,
        values,
    })
}

/// Read an IDX file (big-endian: two zero bytes, a type byte 0x08 u8, 0x09 i8, 0x0B i16,
/// 0x0C i32, 0x0D f32, 0x0E f64, a rank byte, the dimensions as u32, then the data).
/// The first dimension is rows; the rest are flattened into columns.
pub fn read_idx(path: &Path) -> Result<Table, DataError> {
    let file = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|cause| DataError::Io {
        file: file.clone(),
        cause,
    })?;
    parse_idx(&bytes, &file)
}

/// Parse IDX bytes (see [`read_idx`]).
pub fn parse_idx(bytes: &[u8], file: &str) -> Result<Table, DataError> {
    let fmt = |message: String| DataError::Format {
        file: file.into(),
        line: 0,
        message,
    };
    if bytes.len() < 4 || bytes[0] != 0 || bytes[1] != 0 {
        return Err(fmt(
            "not an IDX file (the magic number must start with two zero bytes)".into(),
        ));
    }
    let (ty, rank) = (bytes[2], bytes[3] as usize);
    let size = match ty {
        0x08 | 0x09 => 1,
        0x0B => 2,
        0x0C | 0x0D => 4,
        0x0E => 8,
        t => return Err(fmt(format!("unknown IDX element type 0x{t:02x}"))),
    };
    if rank == 0 || bytes.len() < 4 + 4 * rank {
        return Err(fmt("truncated IDX header".into()));
    }
    let dims: Vec<usize> = (0..rank)
        .map(|k| {
            u32::from_be_bytes(bytes[4 + 4 * k..8 + 4 * k].try_into().expect("4 bytes")) as usize
        })
        .collect();
    let n: usize = dims
        .iter()
        .try_fold(1usize, |a, &d| a.checked_mul(d))
        .ok_or_else(|| fmt("dimensions overflow".into()))?;
    let body = &bytes[4 + 4 * rank..];
    if n == 0 {
        return Err(fmt(format!(
            "the IDX header announces dimensions {dims:?}, i.e. no values"
        )));
    }
    if n.checked_mul(size) != Some(body.len()) {
        return Err(fmt(format!(
            "IDX header announces {n} values of {size} byte(s) (dimensions {dims:?}) but the file holds {} bytes after the header; is it truncated?",
            body.len()
        )));
    }
    let values: Vec<f64> = body
        .chunks_exact(size)
        .map(|c| match ty {
            0x08 => c[0] as f64,
            0x09 => c[0] as i8 as f64,
            0x0B => i16::from_be_bytes([c[0], c[1]]) as f64,
            0x0C => i32::from_be_bytes([c[0], c[1], c[2], c[3]]) as f64,
            0x0D => f32::from_be_bytes([c[0], c[1], c[2], c[3]]) as f64,
            _ => f64::from_be_bytes(c.try_into().expect("8 bytes")),
        })
        .collect();
    let cols = n.checked_div(dims[0]).unwrap_or(0);
    Ok(Table {
        names: (0..cols).map(|j| format!("c{j}")).collect(),
        cols,
        values,
    })
}

/// Read CSV or IDX by extension.
pub fn read_table(path: &Path) -> Result<Table, DataError> {
    match path.extension().and_then(|e| e.to_str()) {
        Some("idx") => read_idx(path),
        _ => read_csv(path),
    }
}

/// Min-max constants per column: `normalised = (raw - min) / range`.
#[derive(Clone, Debug, PartialEq)]
pub struct MinMax {
    /// Minimum C per column.
    pub min: Vec<f64>,
    /// Range S per column (a zero range is replaced by 1 so constant columns map to 0).
    pub range: Vec<f64>,
}

impl MinMax {
    /// Constants of a table's columns.
    pub fn of(t: &Table) -> Self {
        let mut min = vec![f64::INFINITY; t.cols];
        let mut max = vec![f64::NEG_INFINITY; t.cols];
        for i in 0..t.rows() {
            for (j, v) in t.row(i).iter().enumerate() {
                min[j] = min[j].min(*v);
                max[j] = max[j].max(*v);
            }
        }
        let range = min
            .iter()
            .zip(&max)
            .map(|(a, b)| if b > a { b - a } else { 1.0 })
            .collect();
        MinMax { min, range }
    }

    /// Read a constants file: two numeric rows (minimum, range), optional header, like
    /// the published `Normalisation_Constants.csv`.
    pub fn read(path: &Path) -> Result<Self, DataError> {
        let t = read_csv(path)?;
        if t.rows() != 2 {
            return Err(DataError::Format {
                file: path.display().to_string(),
                line: 0,
                message: format!("expected 2 rows (minimum, range), found {}", t.rows()),
            });
        }
        if let Some(j) = t.row(1).iter().position(|v| *v == 0.0) {
            return Err(DataError::Format {
                file: path.display().to_string(),
                line: 0,
                message: format!("range of column {} is zero", j + 1),
            });
        }
        Ok(MinMax {
            min: t.row(0).to_vec(),
            range: t.row(1).to_vec(),
        })
    }
}

/// Split row indices into (train, test) with a seeded shuffle; `test_fraction` of the
/// rows (rounded) go to the test set.
pub fn split(n: usize, test_fraction: f64, seed: u64) -> (Vec<usize>, Vec<usize>) {
    let mut idx: Vec<usize> = (0..n).collect();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
    idx.shuffle(&mut rng);
    let n_test = ((n as f64) * test_fraction).round() as usize;
    let test = idx[..n_test].to_vec();
    let train = idx[n_test..].to_vec();
    (train, test)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_header_ragged_empty() {
        let t = parse_csv("a,b\n1,2\n3,4\n", "f.csv").unwrap();
        assert_eq!(
            (t.names.clone(), t.rows(), t.row(1).to_vec()),
            (vec!["a".into(), "b".into()], 2, vec![3.0, 4.0])
        );
        let e = parse_csv("1,2\n3\n", "f.csv").unwrap_err().to_string();
        assert!(e.contains("f.csv:2") && e.contains("ragged"), "{e}");
        assert!(parse_csv("", "e.csv")
            .unwrap_err()
            .to_string()
            .contains("no data rows"));
        assert!(parse_csv("a,b\n", "h.csv")
            .unwrap_err()
            .to_string()
            .contains("no data rows"));
        // A non-numeric first line is a header: with nothing after it there is no data.
        assert!(parse_csv("1,x\n", "n.csv")
            .unwrap_err()
            .to_string()
            .contains("no data rows"));
        assert!(parse_csv("1,2\n1,x\n", "n.csv")
            .unwrap_err()
            .to_string()
            .contains("`x`"));
    }

    #[test]
    fn idx_round_numbers_and_errors() {
        let mut b = vec![0, 0, 0x0D, 2, 0, 0, 0, 2, 0, 0, 0, 3];
        for v in [1.0f32, 2.0, 3.0, 4.0, 5.0, 6.5] {
            b.extend(v.to_be_bytes());
        }
        let t = parse_idx(&b, "t.idx").unwrap();
        assert_eq!((t.rows(), t.cols, t.row(1)[2]), (2, 3, 6.5));
        assert!(parse_idx(&b[..b.len() - 1], "t.idx").is_err());
        assert!(parse_idx(b"PK\x03\x04", "t.idx").is_err());
        // A huge announced size never overflows or allocates; the message has no `:0`.
        let e = parse_idx(
            &[
                0, 0, 0x0E, 3, 255, 255, 255, 255, 255, 255, 255, 255, 255, 255, 255, 255, 1,
            ],
            "h.idx",
        )
        .unwrap_err()
        .to_string();
        assert!(e.starts_with("h.idx: ") && !e.contains(":0"), "{e}");
        assert!(parse_idx(&[0, 0, 0x08, 1, 0, 0, 0, 0], "z.idx").is_err());
    }

    #[test]
    fn split_is_seeded_and_complete() {
        let (a, b) = split(360, 0.1, 7);
        assert_eq!((a.len(), b.len()), (324, 36));
        assert_eq!(split(360, 0.1, 7), (a.clone(), b.clone()));
        let mut all: Vec<usize> = a.into_iter().chain(b).collect();
        all.sort();
        assert_eq!(all, (0..360).collect::<Vec<_>>());
    }
}

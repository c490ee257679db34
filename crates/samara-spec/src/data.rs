//! Data sets for quantifiers and domains: CSV (with or without a header line) and IDX
//! (the format of the Vehicle language's data sets: big-endian magic, dimensions, values).

use std::path::Path;

/// A table of numbers, row-major.
#[derive(Clone, Debug, PartialEq)]
pub struct Table {
    /// Number of rows.
    pub rows: usize,
    /// Number of columns.
    pub cols: usize,
    /// Values, `rows * cols`.
    pub values: Vec<f64>,
}

impl Table {
    /// Row `r`.
    pub fn row(&self, r: usize) -> &[f64] {
        &self.values[r * self.cols..(r + 1) * self.cols]
    }
}

/// Read a CSV file of numbers; a first line that does not parse is taken as a header.
pub fn read_csv(path: &Path) -> Result<Table, String> {
    let text = std::fs::read_to_string(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    parse_csv(&text).map_err(|e| format!("{}: {e}", path.display()))
}

/// Parse CSV text (see [`read_csv`]).
pub fn parse_csv(text: &str) -> Result<Table, String> {
    let mut values = Vec::new();
    let mut cols = 0;
    let mut rows = 0;
    for (i, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() {
            continue;
        }
        let parsed: Result<Vec<f64>, _> = line.split(',').map(|f| f.trim().parse::<f64>()).collect();
        match parsed {
            Ok(v) => {
                if rows == 0 {
                    cols = v.len();
                } else if v.len() != cols {
                    return Err(format!("line {}: {} fields, expected {cols}", i + 1, v.len()));
                }
                values.extend(v);
                rows += 1;
            }
            Err(_) if rows == 0 && i == 0 => continue,
            Err(e) => return Err(format!("line {}: {e}", i + 1)),
        }
    }
    if rows == 0 {
        return Err("no data rows".into());
    }
    Ok(Table { rows, cols, values })
}

/// Read an IDX file (1-D: one column; 2-D: rows x columns; higher: rows x product).
pub fn read_idx(path: &Path) -> Result<Table, String> {
    let b = std::fs::read(path).map_err(|e| format!("cannot read {}: {e}", path.display()))?;
    parse_idx(&b).map_err(|e| format!("{}: {e}", path.display()))
}

/// Parse IDX bytes (see [`read_idx`]).
pub fn parse_idx(b: &[u8]) -> Result<Table, String> {
    if b.len() < 4 || b[0] != 0 || b[1] != 0 {
        return Err("not an IDX file (bad magic)".into());
    }
    let (size, kind) = match b[2] {
        0x08 => (1, 0),
        0x09 => (1, 1),
        0x0B => (2, 2),
        0x0C => (4, 3),
        0x0D => (4, 4),
        0x0E => (8, 5),
        t => return Err(format!("unknown IDX element type 0x{t:02x}")),
    };
    let nd = b[3] as usize;
    if nd == 0 || b.len() < 4 + 4 * nd {
        return Err("truncated IDX header".into());
    }
    let dims: Vec<usize> = (0..nd)
        .map(|i| u32::from_be_bytes(b[4 + 4 * i..8 + 4 * i].try_into().unwrap()) as usize)
        .collect();
    let n = dims.iter().try_fold(1usize, |a, d| a.checked_mul(*d)).ok_or("IDX dimensions overflow")?;
    let off = 4 + 4 * nd;
    if n.checked_mul(size).map(|s| b.len() < off + s).unwrap_or(true) {
        return Err(format!("IDX data truncated: {n} values of {size} bytes expected"));
    }
    let mut values = Vec::with_capacity(n);
    for i in 0..n {
        let c = &b[off + i * size..off + (i + 1) * size];
        values.push(match kind {
            0 => c[0] as f64,
            1 => c[0] as i8 as f64,
            2 => i16::from_be_bytes([c[0], c[1]]) as f64,
            3 => i32::from_be_bytes(c.try_into().unwrap()) as f64,
            4 => f32::from_be_bytes(c.try_into().unwrap()) as f64,
            _ => f64::from_be_bytes(c.try_into().unwrap()),
        });
    }
    let rows = dims[0];
    let cols = if rows == 0 { 0 } else { n / rows.max(1) };
    if nd == 1 {
        return Ok(Table { rows, cols: 1, values });
    }
    Ok(Table { rows, cols, values })
}

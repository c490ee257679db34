//! The training data set as text: the published row layout with a header, and its
//! min-max constants (row 1 minimum C, row 2 range S; normalised = (raw - C) / S).
//! Numbers are written in Rust's shortest round-trip form, so reading them back gives
//! the same f64 bits.

use std::fmt::Write as _;

/// Header of the data set and of the constants file.
pub const HEADER: &str = "v_xp,v_yp,omega,theta,x,y,ex";

fn line(values: &[f64]) -> String {
    values
        .iter()
        .map(|v| format!("{v:?}"))
        .collect::<Vec<_>>()
        .join(",")
}

/// The data set CSV (header, one row per control step).
pub fn training_csv(rows: &[[f64; 7]]) -> String {
    let mut s = format!("{HEADER}\n");
    for r in rows {
        let _ = writeln!(s, "{}", line(r));
    }
    s
}

/// The constants CSV (header, minimum row, range row).
pub fn normalisation_csv(min: &[f64; 7], range: &[f64; 7]) -> String {
    format!("{HEADER}\n{}\n{}\n", line(min), line(range))
}

#[cfg(test)]
mod tests {
    #[test]
    fn round_trips_bits() {
        let r = [
            0.1 + 0.2,
            -1e-300,
            3.0,
            f64::MIN_POSITIVE,
            1.0 / 3.0,
            -0.0,
            0.19,
        ];
        let text = super::training_csv(&[r]);
        let back: Vec<f64> = text
            .lines()
            .nth(1)
            .unwrap()
            .split(',')
            .map(|v| v.parse().unwrap())
            .collect();
        for (a, b) in r.iter().zip(&back) {
            assert_eq!(a.to_bits(), b.to_bits());
        }
    }
}

//! The robustness table of a sweep (`samara robustness`, `samara.robustness`), and the
//! sweep's shard files with their merge (`samara merge robustness`).

use crate::shard::Exact;
use crate::{input, AppError};
use samara_verify::robustness::{lipschitz_cell, published_cell, PointBall};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// The form of the robustness property.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Form {
    /// `|f(x') - ref| <= L / eps` (the published P5).
    Published,
    /// `|f(x') - f(x)| <= L ||x' - x||`.
    Lipschitz,
}

impl Form {
    /// The form named `s` (`published`, `lipschitz`).
    pub fn parse(s: &str) -> Option<Form> {
        match s {
            "published" => Some(Form::Published),
            "lipschitz" => Some(Form::Lipschitz),
            _ => None,
        }
    }

    /// Its name.
    pub fn text(self) -> &'static str {
        match self {
            Form::Published => "published",
            Form::Lipschitz => "lipschitz",
        }
    }
}

/// One cell of the table: the data points at radius `eps` and bound `L`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Cell {
    /// The radius.
    pub eps: f64,
    /// The bound.
    #[serde(rename = "L")]
    pub l: f64,
    /// Points proved robust.
    pub proved: usize,
    /// Points with a concrete violation.
    pub violated: usize,
    /// Points neither (their search was cut short).
    pub unknown: usize,
    /// `proved` over the number of data points.
    pub success_rate: f64,
}

/// The table: one row per radius, one cell per bound.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Table {
    /// The form.
    pub form: Form,
    /// How many data points.
    pub points: usize,
    /// Wall time of the sweep.
    pub seconds: f64,
    /// Rows by radius, cells by bound.
    pub table: Vec<Vec<Cell>>,
}

impl Table {
    /// The table of a sweep's `points` over `n_rows` data points.
    pub fn of(
        form: Form,
        eps: &[f64],
        ls: &[f64],
        n_rows: usize,
        seconds: f64,
        points: &[PointBall],
    ) -> Table {
        let table = eps
            .iter()
            .map(|e| {
                ls.iter()
                    .map(|l| {
                        let c = match form {
                            Form::Published => published_cell(points, *e, *l),
                            Form::Lipschitz => lipschitz_cell(points, *e, *l),
                        };
                        Cell {
                            eps: *e,
                            l: *l,
                            proved: c.proved,
                            violated: c.violated,
                            unknown: c.unknown,
                            success_rate: c.proved as f64 / n_rows.max(1) as f64,
                        }
                    })
                    .collect()
            })
            .collect();
        Table {
            form,
            points: n_rows,
            seconds,
            table,
        }
    }

    /// Some cell has unknown points.
    pub fn any_unknown(&self) -> bool {
        self.table.iter().flatten().any(|c| c.unknown > 0)
    }
}

/// `run` of a robustness shard: the inputs' digests and the settings every shard of one
/// sweep shares, numbers as exact text.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SweepRun {
    /// Content digests of `--network` and `--data`.
    pub inputs: BTreeMap<String, String>,
    /// Rows of the data set.
    pub points: usize,
    /// The radii.
    pub eps: Vec<Exact>,
    /// The bounds.
    pub lipschitz: Vec<Exact>,
    /// `--reference`.
    pub reference: String,
    /// `--form`.
    pub form: String,
    /// `--timeout` per query.
    pub timeout: Exact,
    /// `--max-nodes`.
    pub max_nodes: usize,
}

/// One data point at one radius in a shard (a [`PointBall`] as exact text).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PointText {
    /// The row.
    pub index: usize,
    /// The radius.
    pub eps: Exact,
    /// Lower bound of the output over the ball.
    pub f_min: Exact,
    /// Upper bound.
    pub f_max: Exact,
    /// The reference output.
    pub reference: Exact,
    /// Bound on the deviation from the reference.
    pub max_deviation: Exact,
    /// Deviation a concrete point reaches.
    pub witnessed_deviation: Exact,
    /// Lipschitz lower bound.
    pub lipschitz_lower: Exact,
    /// Lipschitz upper bound.
    pub lipschitz_upper: Exact,
    /// Why the search was cut short, if it was (its kind).
    pub unknown: Option<String>,
}

impl From<&PointBall> for PointText {
    fn from(p: &PointBall) -> Self {
        PointText {
            index: p.index,
            eps: Exact(p.eps),
            f_min: Exact(p.f_min),
            f_max: Exact(p.f_max),
            reference: Exact(p.reference),
            max_deviation: Exact(p.max_deviation),
            witnessed_deviation: Exact(p.witnessed_deviation),
            lipschitz_lower: Exact(p.lipschitz_lower),
            lipschitz_upper: Exact(p.lipschitz_upper),
            unknown: p.unknown.as_ref().map(|r| r.kind().to_string()),
        }
    }
}

impl PointText {
    fn point(&self) -> PointBall {
        PointBall {
            index: self.index,
            eps: self.eps.0,
            f_min: self.f_min.0,
            f_max: self.f_max.0,
            reference: self.reference.0,
            max_deviation: self.max_deviation.0,
            witnessed_deviation: self.witnessed_deviation.0,
            unknown: None,
            lipschitz_upper: self.lipschitz_upper.0,
            lipschitz_lower: self.lipschitz_lower.0,
        }
    }
}

/// `result` of a robustness shard.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SweepShard {
    /// The shard's rows.
    pub rows: (usize, usize),
    /// Wall time.
    pub seconds: f64,
    /// Its points.
    pub points: Vec<PointText>,
}

/// The `--json` line of a robustness shard.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SweepShardLine {
    /// `[I, N]`.
    pub shard: (usize, usize),
    /// The shard's rows.
    pub rows: (usize, usize),
    /// The shard file.
    pub out: std::path::PathBuf,
}

/// A sweep put back together from its shards.
#[derive(Clone, Debug)]
pub struct MergedSweep {
    /// The form.
    pub form: String,
    /// The radii.
    pub eps: Vec<f64>,
    /// The bounds.
    pub ls: Vec<f64>,
    /// Rows of the data set.
    pub n_rows: usize,
    /// The sum of the shards' wall times.
    pub seconds: f64,
    /// Every (row, radius) in order.
    pub points: Vec<PointBall>,
}

/// `samara merge robustness`: the shards' points in order, each (row, radius) of the
/// data set exactly once, every point's bounds consistent.
pub fn merge_sweep(
    run: &SweepRun,
    shards: &[(std::path::PathBuf, SweepShard)],
) -> Result<MergedSweep, AppError> {
    let eps: Vec<f64> = run.eps.iter().map(|e| e.0).collect();
    let ls: Vec<f64> = run.lipschitz.iter().map(|e| e.0).collect();
    let n_rows = run.points;
    let mut points: Vec<PointBall> = Vec::new();
    let mut secs = 0.0;
    let mut next = 0usize;
    for (file, r) in shards {
        let (start, end) = r.rows;
        if start != next {
            return input(format!(
                "{}: rows {start}..{end}, expected to start at {next} (the shards do not tile the data set)",
                file.display()
            ));
        }
        if end < next || end > n_rows {
            return input(format!(
                "{}: rows {start}..{end} of a {n_rows}-row data set",
                file.display()
            ));
        }
        let range = next..end;
        next = end;
        secs += r.seconds;
        // Every (row, radius) of the shard's rows exactly once.
        let mut seen = std::collections::HashSet::new();
        for p in &r.points {
            let q = p.point();
            if !range.contains(&q.index) || !eps.contains(&q.eps) {
                return input(format!(
                    "{}: a point of row {} radius {} is not of this shard's rows {}..{} and the run's radii",
                    file.display(),
                    q.index,
                    q.eps,
                    range.start,
                    range.end
                ));
            }
            if !seen.insert((q.index, q.eps.to_bits())) {
                return input(format!(
                    "{}: row {} radius {} appears more than once (the shard is damaged or tampered with); run it again",
                    file.display(),
                    q.index,
                    q.eps
                ));
            }
            // Sound bounds and witnesses cannot cross (NaN fails too).
            if !(q.f_min <= q.f_max
                && q.witnessed_deviation <= q.max_deviation
                && q.lipschitz_lower <= q.lipschitz_upper)
            {
                return input(format!(
                    "{}: row {} radius {}: its bounds contradict each other (f_min {} > f_max {}, a witnessed deviation above the bound, or a Lipschitz lower bound above the upper); the shard is damaged or tampered with, run it again",
                    file.display(),
                    q.index,
                    q.eps,
                    q.f_min,
                    q.f_max
                ));
            }
            points.push(q);
        }
        if r.points.len() != range.len() * eps.len() {
            return input(format!(
                "{}: {} points for rows {}..{} and {} radii (expected {}): the shard was cut short or damaged; run it again",
                file.display(),
                r.points.len(),
                range.start,
                range.end,
                eps.len(),
                range.len() * eps.len()
            ));
        }
    }
    if next != n_rows {
        return input(format!("the shards cover rows 0..{next} of {n_rows}"));
    }
    Ok(MergedSweep {
        form: run.form.clone(),
        eps,
        ls,
        n_rows,
        seconds: secs,
        points,
    })
}

/// The per-point CSV of a robustness sweep (`samara robustness --out`): one line per
/// point and radius, every number as Rust's `{:?}` writes it (exact, round-trips).
pub fn points_csv(points: &[samara_verify::robustness::PointBall]) -> String {
    let mut csv = String::from(
        "index,eps,f_min,f_max,reference,max_deviation,lipschitz_lower,lipschitz_upper\n",
    );
    for p in points {
        csv.push_str(&format!(
            "{},{:?},{:?},{:?},{:?},{:?},{:?},{:?}\n",
            p.index,
            p.eps,
            p.f_min,
            p.f_max,
            p.reference,
            p.max_deviation,
            p.lipschitz_lower,
            p.lipschitz_upper
        ));
    }
    csv
}

//! The robustness table of a sweep (`samara robustness`, `samara.robustness`), and the
//! sweep's shard files with their merge (`samara merge robustness`).

pub use crate::robustness_form::{
    bound_ok, parse_form, parse_reference, radius_ok, Form, BOUND_ALLOWED, RADIUS_ALLOWED,
};
use crate::shard::Exact;
use crate::{input, AppError};
use samara_verify::robustness::{lipschitz_cell, published_cell, PointBall};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

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

/// A finished robustness sweep (one process, or merged shards), to be reported.
#[derive(Clone, Copy, Debug)]
pub struct Sweep<'a> {
    /// `--form`.
    pub form: &'a str,
    /// The radii.
    pub eps: &'a [f64],
    /// The bounds L.
    pub ls: &'a [f64],
    /// Rows of the data set.
    pub n_rows: usize,
    /// Wall time.
    pub secs: f64,
    /// Every (row, radius).
    pub points: &'a [PointBall],
    /// The per-point CSV to write, if any.
    pub out: Option<&'a std::path::Path>,
}

/// The robustness table (`--json`) and its human form.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepReport {
    /// The table.
    pub table: Table,
    /// The table as text: the success rate per radius (rows) and bound (columns).
    pub human: String,
}

/// Tabulate a finished sweep and write its per-point CSV (`w.out`).
pub fn report(w: &Sweep) -> anyhow::Result<SweepReport> {
    use std::fmt::Write as _;
    let form = Form::parse(w.form).ok_or_else(|| {
        anyhow::anyhow!(
            "form {:?}: not a robustness form (published or lipschitz)",
            w.form
        )
    })?;
    let t = Table::of(form, w.eps, w.ls, w.n_rows, w.secs, w.points);
    if let Some(p) = w.out {
        samara_report::write_atomic(p, points_csv(w.points).as_bytes())
            .map_err(|e| anyhow::anyhow!("--out {}: {e}", p.display()))?;
    }
    let mut h = format!(
        "{} form, {} points, {:.3} s; success rate (rows eps, columns L):\n{:>10}",
        w.form, w.n_rows, w.secs, "eps \\ L"
    );
    for l in w.ls {
        let _ = write!(h, "{l:>10.0e}");
    }
    h.push('\n');
    for (e, row) in w.eps.iter().zip(&t.table) {
        let _ = write!(h, "{e:>10.0e}");
        for c in row {
            let _ = write!(h, "{:>9.1}%", 100.0 * c.success_rate);
        }
        h.push('\n');
    }
    if t.any_unknown() {
        h.push_str("(some points are unknown, neither proved nor violated: see --json)\n");
    }
    Ok(SweepReport { table: t, human: h })
}

/// What `samara robustness` gives back.
#[derive(Clone, Debug)]
pub enum SweepDone {
    /// `--shard I/N`: the shard file was written; its `--json` line and human line.
    Shard {
        /// The `--json` line.
        line: SweepShardLine,
        /// The human line.
        human: String,
    },
    /// The whole sweep, tabulated (its per-point CSV written with `--out`).
    Table(SweepReport),
}

/// Run `samara robustness` with the verifier's `settings` until `deadline`: check the
/// flags (each note to `on_note`), load the network and the data, sweep this shard's
/// rows (all without `--shard`), then write the shard file or tabulate.
pub fn run(
    a: &crate::args::RobustnessArgs,
    settings: &samara_verify::Settings,
    deadline: Option<std::time::Instant>,
    mut on_note: impl FnMut(&str),
) -> anyhow::Result<SweepDone> {
    if a.shard.is_some() && a.out.is_none() {
        anyhow::bail!(
            "--shard needs --out FILE (the shard's partial result, for `samara merge robustness`)"
        );
    }
    if let Some(o) = &a.out {
        samara_report::guard::check_output_file(
            "--out",
            o,
            &[("--data", &a.data), ("--network", &a.network)],
        )?;
    }
    let checked = a.validate()?;
    for n in &checked.notes {
        on_note(n);
    }
    let (eps, ls, reference) = (checked.eps, checked.lipschitz, checked.reference);
    let net = crate::bind::load_network(&a.network, "--network")?;
    let t = crate::bind::read_data(&a.data, "--data")?;
    let rows = a.data_rows(net.n_inputs(), &t, reference)?;
    let t0 = std::time::Instant::now();
    let range = a.shard.map_or(0..rows.len(), |s| s.range(rows.len()));
    let mut points = samara_verify::robustness::sweep_until(
        &net,
        &rows[range.clone()],
        &eps,
        reference,
        None,
        settings,
        deadline,
    )
    .map_err(|e| anyhow::anyhow!("{e}"))?;
    for p in &mut points {
        p.index += range.start;
    }
    let secs = t0.elapsed().as_secs_f64();
    let (Some(s), Some(out)) = (a.shard, &a.out) else {
        return Ok(SweepDone::Table(report(&Sweep {
            form: &a.form,
            eps: &eps,
            ls: &ls,
            n_rows: rows.len(),
            secs,
            points: &points,
            out: a.out.as_deref(),
        })?));
    };
    let run = SweepRun {
        inputs: crate::shard::digest_inputs([
            (
                "--network".to_string(),
                a.network.as_path(),
                "--network".to_string(),
            ),
            ("--data".to_string(), a.data.as_path(), "--data".to_string()),
        ])?,
        points: rows.len(),
        eps: eps.iter().map(|e| Exact(*e)).collect(),
        lipschitz: ls.iter().map(|l| Exact(*l)).collect(),
        reference: a.reference.clone(),
        form: a.form.clone(),
        timeout: Exact(a.timeout),
        max_nodes: a.max_nodes,
    };
    let result = SweepShard {
        rows: (range.start, range.end),
        seconds: secs,
        points: points.iter().map(PointText::from).collect(),
    };
    crate::shard::write(out, "robustness", s, &run, &result)?;
    Ok(SweepDone::Shard {
        line: SweepShardLine {
            shard: (s.i, s.n),
            rows: (range.start, range.end),
            out: out.clone(),
        },
        human: format!(
            "shard {}/{}: rows {}..{} of {} ({} points x {} radii), {secs:.3} s; partial result in {} (merge with `samara merge robustness`)",
            s.i,
            s.n,
            range.start,
            range.end,
            rows.len(),
            range.len(),
            eps.len(),
            out.display()
        ),
    })
}

/// `samara merge robustness`: the shards' points in order ([`merge_sweep`]), reported as
/// one process reports them (the per-point CSV written to `out`).
pub fn merge(
    shards: &crate::shard::Shards,
    out: Option<&std::path::Path>,
) -> anyhow::Result<SweepReport> {
    let run: SweepRun = shards.run_as()?;
    let m = merge_sweep(&run, &shards.results_as::<SweepShard>()?)?;
    report(&Sweep {
        form: &m.form,
        eps: &m.eps,
        ls: &m.ls,
        n_rows: m.n_rows,
        secs: m.seconds,
        points: &m.points,
        out,
    })
}

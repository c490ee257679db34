//! What the `samara` Python package runs, as library calls: the checks of its
//! arguments and the typed results it hands over, so that `python/src/lib.rs` only
//! converts Python values and calls these (no logic of its own, none copied).
//!
//! - [`ReachRequest`]: the arguments of `samara.reach`, checked into the library's
//!   `ReachSettings`;
//! - [`train_method`] and [`TrainReport`]: `samara.train`'s method (P1-P4 of the case
//!   study for dl2/goedel) and its report (the fields of `samara train --json` without
//!   the file paths, plus the training R^2 and the loss log);
//! - [`robustness`] and [`RobustnessReport`]: the robustness table with its per-point
//!   rows (the columns of `samara robustness --out`'s CSV);
//! - [`GridPart`] and [`merge_grid_parts`]: a Taylor-model grid run over a range of
//!   cells and the exact merge of consecutive ranges.
//!
//! Messages name arguments through [`Front`], so the same checks read `--goal-ystar` on
//! the command line and `goal_ystar` in Python.

use crate::bind::Front;
use crate::robustness::Table;
use crate::{input, AppError};
use samara_reach::system::SystemReach;
use samara_train::{Method, MinMax};
use samara_verify::robustness::{sweep_with, PointBall, Reference};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::time::Instant;

type Result<T> = std::result::Result<T, AppError>;

pub use crate::reach::args::{
    check_budget, ReachRequest, REACH_MAX_COUNT, REACH_MAX_PERIOD, REACH_MAX_PERIODS,
};
pub use crate::simulate::{
    check_glider_network as glider_controller, ControllerRequest, SimulatePlan,
};
pub use crate::train::{default_min_r2, TrainReport};

/// The verifier's settings of a `verify`, `critical` or `robustness` call: `timeout`
/// seconds per query (infinite: none; NaN or negative refused) and `max_nodes`.
pub fn verify_settings(
    front: Front,
    timeout: f64,
    max_nodes: usize,
) -> Result<samara_verify::Settings> {
    let Ok(timeout) = samara_verify::Timeout::from_secs_f64(timeout) else {
        let none = match front {
            Front::Cli => "inf",
            Front::Python => "float('inf')",
        };
        return input(format!(
            "{} {timeout}: must be a number of seconds >= 0 (e.g. {}; {none} for no limit)",
            front.arg("timeout"),
            front.eg("timeout", "60")
        ));
    };
    Ok(samara_verify::Settings {
        timeout,
        max_nodes,
        ..Default::default()
    })
}

/// A worker-thread count: 1 to 1024 (`None`: all cores).
pub fn check_threads(front: Front, threads: Option<usize>) -> Result<()> {
    match threads {
        Some(t) if !(1..=1024).contains(&t) => input(format!(
            "{} {t}: give 1 to 1024 worker threads (default: all cores)",
            front.arg("threads")
        )),
        _ => Ok(()),
    }
}

/// The training method `method` (plain, adversarial, lipschitz, dl2, goedel) with its
/// options: [`crate::train::method`], the check `samara train` makes. dl2 and goedel
/// train for P1-P4 as `models/alsomitra/alsomitra.spec` states them (compiled into
/// samara-train), lowered in the units of the network being trained (`mm`) over the box
/// of `data`, with `ystar` bound: what `samara train` does without `--spec`.
#[allow(clippy::too_many_arguments)]
pub fn train_method(
    front: Front,
    method: &str,
    attack: &str,
    lipschitz: f64,
    weight: Option<f64>,
    ystar: f64,
    data: &samara_train::Table,
    mm: &MinMax,
    arch: &[usize],
) -> Result<Method> {
    let arch_text = format!("{arch:?}");
    let r = crate::train::MethodRequest {
        method,
        attack,
        lipschitz,
        weight,
        ystar,
        arch_text: &arch_text,
        ..Default::default()
    };
    crate::train::method(front, &r, data, mm, arch)
}

/// One data point at one radius: a row of `samara robustness --out`'s CSV.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PointRow {
    /// The data row, counted from 0.
    pub index: usize,
    /// The radius.
    pub eps: f64,
    /// Lower bound of the output over the ball.
    pub f_min: f64,
    /// Upper bound of the output over the ball.
    pub f_max: f64,
    /// The reference output.
    pub reference: f64,
    /// Bound on the deviation from the reference.
    pub max_deviation: f64,
    /// Lipschitz lower bound.
    pub lipschitz_lower: f64,
    /// Lipschitz upper bound.
    pub lipschitz_upper: f64,
}

impl From<&PointBall> for PointRow {
    fn from(p: &PointBall) -> Self {
        PointRow {
            index: p.index,
            eps: p.eps,
            f_min: p.f_min,
            f_max: p.f_max,
            reference: p.reference,
            max_deviation: p.max_deviation,
            lipschitz_lower: p.lipschitz_lower,
            lipschitz_upper: p.lipschitz_upper,
        }
    }
}

/// The robustness table (the fields of `samara robustness --json`) and its per-point
/// rows.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct RobustnessReport {
    /// The table.
    #[serde(flatten)]
    pub table: Table,
    /// One row per data point and radius.
    pub per_point: Vec<PointRow>,
}

/// The robustness sweep of `net` over `data` (`n` rows of `cols`: the network's inputs,
/// then the label unless `reference` is `network`) at the radii `eps`, tabulated
/// against the bounds `lipschitz` in `form`; every argument checked, the data's bad
/// entries named by row and column (counted from 0).
#[allow(clippy::too_many_arguments)]
pub fn robustness(
    front: Front,
    net: &samara_nn::Network,
    data: &[f64],
    n: usize,
    cols: usize,
    eps: &[f64],
    lipschitz: &[f64],
    reference: &str,
    form: &str,
    settings: &samara_verify::Settings,
) -> Result<RobustnessReport> {
    let d = front.arg("data");
    if data.len() != n * cols {
        return input(format!("{d}: {} values for {n} rows of {cols}", data.len()));
    }
    let mut es: Vec<f64> = Vec::new();
    use crate::robustness::{bound_ok, radius_ok, BOUND_ALLOWED, RADIUS_ALLOWED};
    for &e in eps {
        if !radius_ok(e) {
            return input(format!(
                "{} {e}: out of range; each value must be {RADIUS_ALLOWED}",
                front.arg("eps")
            ));
        }
        if !es.contains(&e) {
            es.push(e);
        }
    }
    let mut ls: Vec<f64> = Vec::new();
    for &l in lipschitz {
        if !bound_ok(l) {
            return input(format!(
                "{} {l}: out of range; each value must be {BOUND_ALLOWED}",
                front.arg("lipschitz")
            ));
        }
        if !ls.contains(&l) {
            ls.push(l);
        }
    }
    let reference = crate::robustness::parse_reference(front, reference)?;
    let form = crate::robustness::parse_form(front, form)?;
    let ni = net.n_inputs();
    let used = if reference == Reference::Label {
        ni + 1
    } else {
        ni
    };
    if cols < used {
        return input(format!(
            "{d}: {cols} columns but the network has {ni} inputs{}",
            if reference == Reference::Label {
                format!(
                    " and the label column is needed (or pass {})",
                    front.eg("reference", "network")
                )
            } else {
                String::new()
            }
        ));
    }
    let rows: Vec<Vec<f64>> = (0..n)
        .map(|i| data[i * cols..(i + 1) * cols].to_vec())
        .collect();
    for (i, r) in rows.iter().enumerate() {
        if let Some(j) = r.iter().take(used).position(|v| !v.is_finite()) {
            return input(format!(
                "{d}: row {i} column {j} is {}, not a finite number",
                r[j]
            ));
        }
    }
    let t0 = Instant::now();
    let points = sweep_with(net, &rows, &es, reference, None, settings).map_err(AppError::Input)?;
    let secs = t0.elapsed().as_secs_f64();
    Ok(RobustnessReport {
        table: Table::of(form, &es, &ls, rows.len(), secs, &points),
        per_point: points.iter().map(PointRow::from).collect(),
    })
}

/// A Taylor-model grid run over the cells `[start, end)` (`None` without a grid), the
/// grid's cell count and the cells' merged result.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct GridPart {
    /// `(start, end)` of the cells flown.
    pub cells: Option<(usize, usize)>,
    /// The grid's cells in all.
    pub total_cells: Option<usize>,
    /// The cells' result.
    pub reach: SystemReach,
}

/// The results of consecutive cell ranges of one grid, given in cell order from cell 0,
/// merged into the result of their union (`samara_reach::grid::merge_parts`); `label`
/// names the list in messages (`parts`: `parts[2]: ...`).
pub fn merge_grid_parts(parts: Vec<GridPart>, label: &str) -> Result<GridPart> {
    if parts.is_empty() {
        return input(format!("{label}: give at least one result"));
    }
    let mut out: Vec<(usize, SystemReach)> = Vec::new();
    let (mut next, mut total) = (None::<usize>, None);
    for (i, v) in parts.into_iter().enumerate() {
        let at = format!("{label}[{i}]");
        let Some((a, b)) = v.cells else {
            return input(format!("{at}: not a grid result (no cells)"));
        };
        if next.is_some_and(|n| n != a)
            || (next.is_none() && a != 0)
            || total.is_some_and(|t| t != v.total_cells)
        {
            return input(format!(
                "{at}: cells {a}..{b} do not continue the parts before it; give the ranges of one grid in order from cell 0"
            ));
        }
        next = Some(b);
        total = Some(v.total_cells);
        out.push((b - a, v.reach));
    }
    Ok(GridPart {
        cells: next.map(|n| (0, n)),
        total_cells: total.flatten(),
        reach: samara_reach::grid::merge_parts(out),
    })
}

/// The arguments of a Taylor-model reach run of a system file (`samara.reach_system`).
#[derive(Clone, Debug, Default)]
pub struct SystemRequest {
    /// Pieces per state of the grid the initial set is cut into (empty: no grid).
    pub grid: BTreeMap<String, usize>,
    /// Only the cells `[start, end)` of the grid.
    pub cells: Option<(usize, usize)>,
    /// Taylor-model order.
    pub order: usize,
    /// `auto`, `interval`, `symbolic` or `symbolic:N`.
    pub network_error: String,
    /// Order of the lifted parameters' terms.
    pub lifted_weight: u32,
    /// Share of the width at which a parameter is lifted.
    pub lift_at: f64,
    /// Sub-box budget.
    pub max_leaves: usize,
    /// Sampled flights.
    pub samples: usize,
    /// Sampling seed.
    pub seed: u64,
    /// Time limit in seconds.
    pub timeout: Option<f64>,
    /// The flow's order in time, 1 to 8 (`--time-order`; `None`: the flow's default).
    pub time_order: Option<i64>,
    /// The flow's step tolerance as a share of the set's width, in (0, 0.01]
    /// (`--step-tol`; `None`: the flow's default).
    pub step_tol: Option<f64>,
}

/// A checked [`SystemRequest`]: the settings, the grid's pieces per state, and the
/// cells to fly with the grid's cell count (both `None` without a grid).
#[derive(Clone, Debug)]
pub struct SystemPlan {
    /// The run's settings.
    pub settings: samara_reach::system::SystemReachSettings,
    /// Pieces per state.
    pub pieces: Vec<usize>,
    /// The cells flown.
    pub range: Option<std::ops::Range<usize>>,
    /// The grid's cells in all.
    pub total: Option<usize>,
}

impl SystemRequest {
    /// Check the arguments for system `sys` (named `file`) and controller `net`.
    pub fn plan(
        &self,
        front: Front,
        sys: &samara_system::System,
        file: &str,
        net: &samara_nn::Network,
    ) -> Result<SystemPlan> {
        use samara_reach::system::{end_band_measures, NetworkError, SystemReachSettings};
        let a = |n: &str| front.arg(n);
        crate::reach::args::check_fits(&a("network"), net, sys, file)?;
        let order = self.order;
        crate::reach::args::check_order(front, order)?;
        let lw = self.lifted_weight;
        crate::reach::args::check_lifted_weight(front, lw as i64, order)?;
        let lift_at = self.lift_at;
        crate::reach::args::check_lift_at(front, lift_at)?;
        check_budget(
            front,
            Some(self.max_leaves),
            Some(self.samples),
            SystemReachSettings::default().max_boxes,
        )?;
        let timeout = match self.timeout {
            Some(t) => crate::reach::args::check_reach_timeout(front, t)?,
            None => samara_num::Timeout::default(),
        };
        let network_error = NetworkError::parse(&self.network_error).map_err(|e| {
            AppError::Input(format!(
                "{} {:?}: {e}",
                a("network_error"),
                self.network_error
            ))
        })?;
        let mut s = SystemReachSettings {
            order,
            max_boxes: self.max_leaves,
            samples: self.samples,
            seed: self.seed,
            timeout,
            network_error,
            measures: end_band_measures(sys),
            ..SystemReachSettings::default()
        };
        s.flow.lift_at = lift_at;
        s.flow.lifted_weight = lw;
        if let Some(v) = self.time_order {
            s.flow.time_order = crate::reach::args::check_time_order(front, v)?;
        }
        if let Some(v) = self.step_tol {
            crate::reach::args::check_step_tol(front, v)?;
            crate::reach::args::set_step_tol(&mut s.flow, v);
        }
        let mut pieces = vec![1usize; sys.dim()];
        for (k, &n) in &self.grid {
            let Some(i) = sys.states.iter().position(|x| x == k) else {
                return input(format!(
                    "{}[{k:?}]: no such state; the states are {}",
                    a("grid"),
                    sys.states.join(", ")
                ));
            };
            pieces[i] = n;
        }
        let gridded = !self.grid.is_empty() || self.cells.is_some();
        let total = if gridded {
            Some(
                samara_reach::grid::cell_count(sys, &pieces)
                    .map_err(|e| AppError::Input(format!("{}: {e}", a("grid"))))?,
            )
        } else {
            None
        };
        let range = match (total, self.cells) {
            (Some(c), Some((x, y))) if x < y && y <= c => Some(x..y),
            (Some(c), Some((x, y))) => {
                return input(format!(
                    "{} ({x}, {y}): give start < end <= {c}, the grid's cells",
                    a("cells")
                ))
            }
            (Some(c), None) => Some(0..c),
            _ => None,
        };
        Ok(SystemPlan {
            settings: s,
            pieces,
            range,
            total,
        })
    }
}

impl SystemPlan {
    /// Fly the plan: the whole initial set, or the grid's cells `range`. The error is
    /// the computation's message.
    pub fn run(
        &self,
        sys: &samara_system::System,
        net: &samara_nn::Network,
    ) -> std::result::Result<GridPart, String> {
        let r = match &self.range {
            None => samara_reach::system::reach_system(sys, net, &self.settings),
            Some(r) => {
                samara_reach::grid::reach_cells(sys, net, &self.settings, &self.pieces, r.clone())
            }
        }
        .map_err(|e| e.to_string())?;
        Ok(GridPart {
            cells: self.range.as_ref().map(|r| (r.start, r.end)),
            total_cells: self.total,
            reach: r,
        })
    }
}

/// The arguments of closed-loop flights of the glider (`samara.simulate`).
#[derive(Clone, Debug)]
pub struct SimulateRequest {
    /// `plate6`, `reduced` or `full`.
    pub model: String,
    /// The controller.
    pub controller: ControllerRequest,
    /// The initial heights (`None`: the nine published starts).
    pub y0: Option<Vec<f64>>,
    /// `ode45`, `tight`, `dp5` or `rk4`.
    pub integrator: String,
    /// Horizon.
    pub horizon: f64,
    /// Control period.
    pub period: f64,
}

impl SimulateRequest {
    /// Check the arguments (most periods: `max_periods`).
    pub fn plan(self, front: Front, max_periods: f64) -> Result<SimulatePlan> {
        use samara_plant::Plant;
        let (model, settings) = crate::simulate::glider_loop(
            front,
            &self.model,
            &self.integrator,
            self.horizon,
            self.period,
            max_periods,
        )?;
        let controller = match &self.controller {
            ControllerRequest::Pid | ControllerRequest::Network { .. } => front.arg("controller"),
            ControllerRequest::Constant(_) => format!("{} constant", front.arg("controller")),
        };
        let controller = crate::simulate::glider_controller(
            front,
            self.controller,
            model,
            &controller,
            "network",
        )?;
        let starts = match self.y0 {
            Some(v) => {
                if v.is_empty() || v.len() > 100_000 {
                    return input(format!(
                        "{}: {} starts; give 1 to 100000",
                        front.arg("y0"),
                        v.len()
                    ));
                }
                if let Some(y) = v.iter().find(|y| !(y.is_finite() && y.abs() <= 1000.0)) {
                    return input(format!(
                        "{}: the height {y} is outside [-1000, 1000], the range in which the nondimensional model means anything (published starts: 1.43 to 4.29)",
                        front.arg("y0")
                    ));
                }
                v
            }
            None => samara_sim::published_starts(),
        };
        Ok(SimulatePlan {
            plant: Plant::new(model),
            controller,
            settings,
            starts,
        })
    }
}

/// The messages inside a result in `front`'s words ([`Front::words`]): the library
/// writes its reasons naming the CLI's flags ("time limit reached (raise --timeout)"),
/// which Python users know as keyword arguments ("raise timeout").
pub trait InWords {
    /// The result with every message in `front`'s words.
    fn in_words(self, front: Front) -> Self;
}

fn words_opt(front: Front, m: &mut Option<String>) {
    if let Some(t) = m {
        *t = front.words(t);
    }
}

impl InWords for crate::Reason {
    fn in_words(mut self, front: Front) -> Self {
        self.message = front.words(&self.message);
        self
    }
}

impl InWords for crate::VerdictRow {
    fn in_words(mut self, front: Front) -> Self {
        use crate::verify::RowCounterexample;
        self.unknown_reason = self.unknown_reason.map(|r| r.in_words(front));
        if let Some(RowCounterexample::Reason { reason }) = &mut self.counterexample {
            *reason = front.words(reason);
        }
        words_opt(front, &mut self.vacuity);
        self
    }
}

impl InWords for crate::CriticalValue {
    fn in_words(mut self, front: Front) -> Self {
        self.unknown_reason = self.unknown_reason.map(|r| r.in_words(front));
        self
    }
}

impl InWords for crate::reach::ReachReport {
    fn in_words(mut self, front: Front) -> Self {
        use crate::reach::VerdictReport;
        match &mut self.verdict {
            VerdictReport::Unknown { reason } | VerdictReport::Violated { reason, .. } => {
                *reason = front.words(reason)
            }
            VerdictReport::Proved | VerdictReport::NoGoal => {}
        }
        words_opt(front, &mut self.enclosure_lost);
        for w in &mut self.warnings {
            *w = front.words(w);
        }
        for l in &mut self.leaves {
            words_opt(front, &mut l.failure);
        }
        self
    }
}

impl InWords for GridPart {
    fn in_words(mut self, front: Front) -> Self {
        use samara_reach::system::SystemVerdict;
        if let SystemVerdict::Unknown { reason } = &mut self.reach.verdict {
            *reason = front.words(reason);
        }
        for l in &mut self.reach.leaves {
            words_opt(front, &mut l.failure);
        }
        self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn request() -> ReachRequest {
        ReachRequest {
            model: "reduced".into(),
            horizon: 2.0,
            period: 0.5,
            clip: true,
            ..ReachRequest::default()
        }
    }

    #[test]
    fn reach_request_checks_name_the_argument_in_each_front() {
        let r = ReachRequest {
            goal_from: Some(1.0),
            ..request()
        };
        let py = r.settings(Front::Python).unwrap_err().to_string();
        let cli = r.settings(Front::Cli).unwrap_err().to_string();
        assert_eq!(
            py,
            "goal_from 1: needs a goal; add goal_ystar=Y (e.g. goal_ystar=2)"
        );
        assert_eq!(
            cli,
            "--goal-from 1: needs a goal; add --goal-ystar Y (e.g. --goal-ystar 2)"
        );
        let r = ReachRequest {
            horizon: 1.2,
            ..request()
        };
        let m = r.settings(Front::Python).unwrap_err().to_string();
        assert!(
            m.contains("horizon 1.2 is not a positive multiple of period 0.5"),
            "{m}"
        );
        let r = ReachRequest {
            max_leaves: Some(0),
            ..request()
        };
        let m = r.settings(Front::Python).unwrap_err().to_string();
        assert!(
            m.starts_with("max_leaves 0: give at least 1 (default 64)"),
            "{m}"
        );
    }

    #[test]
    fn reach_request_gives_the_published_settings_with_its_changes() {
        let mut init = BTreeMap::new();
        init.insert("theta".to_string(), (-0.01, 0.01));
        let s = ReachRequest {
            init,
            goal_ystar: Some(2.0),
            samples: Some(7),
            ..request()
        }
        .settings(Front::Python)
        .unwrap();
        let published = samara_reach::ReachSettings::published(samara_plant::Model::Reduced);
        assert_eq!(s.init[3], (-0.01, 0.01));
        assert_eq!(s.init[5], (0.1 / 0.07, 0.3 / 0.07));
        assert_eq!((s.horizon, s.period, s.samples), (2.0, 0.5, 7));
        assert_eq!(s.max_leaves, published.max_leaves);
        assert_eq!(s.clip, published.clip);
        assert_eq!(
            s.goal.as_ref().map(|g| (g.ystar, g.from)),
            Some((2.0, None))
        );
    }

    #[test]
    fn reasons_in_results_name_python_arguments() {
        let r = crate::Reason {
            kind: "timeout".into(),
            message: "time limit reached after 31 nodes (raise --timeout)".into(),
        };
        assert_eq!(
            r.clone().in_words(Front::Python).message,
            "time limit reached after 31 nodes (raise timeout)"
        );
        assert_eq!(r.clone().in_words(Front::Cli), r);
    }

    #[test]
    fn a_bad_timeout_is_named_in_each_front() {
        let py = verify_settings(Front::Python, -1.0, 10).unwrap_err();
        assert_eq!(
            py.to_string(),
            "timeout -1: must be a number of seconds >= 0 (e.g. timeout=60; float('inf') for no limit)"
        );
        let cli = verify_settings(Front::Cli, f64::NAN, 10).unwrap_err();
        assert_eq!(
            cli.to_string(),
            "--timeout NaN: must be a number of seconds >= 0 (e.g. --timeout 60; inf for no limit)"
        );
        let s = verify_settings(Front::Python, f64::INFINITY, 10).unwrap();
        assert_eq!(
            (s.timeout, s.max_nodes),
            (samara_verify::Timeout::none(), 10)
        );
    }

    #[test]
    fn grid_parts_merge_only_in_cell_order() {
        let part = |a, b| GridPart {
            cells: Some((a, b)),
            total_cells: Some(4),
            reach: SystemReach {
                system: "s".into(),
                verdict: samara_reach::system::SystemVerdict::NoGoal,
                instants: vec![],
                periods: vec![],
                boxes: 1,
                covered: 1.0,
                order: 3,
                network_error: samara_reach::system::NetworkError::Interval,
                seconds: 1.0,
                leaves: vec![],
                measures: vec![],
                flights: vec![],
            },
        };
        let m = merge_grid_parts(vec![part(0, 1), part(1, 4)], "parts").unwrap();
        assert_eq!((m.cells, m.total_cells), (Some((0, 4)), Some(4)));
        let e = merge_grid_parts(vec![part(1, 4), part(0, 1)], "parts").unwrap_err();
        assert!(
            e.to_string()
                .starts_with("parts[0]: cells 1..4 do not continue"),
            "{e}"
        );
        let e = merge_grid_parts(vec![], "parts").unwrap_err();
        assert_eq!(e.to_string(), "parts: give at least one result");
    }
}

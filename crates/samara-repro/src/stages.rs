//! The stages of the reproduction and the report built from their typed results (so a
//! cached run renders the same report).

pub use crate::common::flights_figure;
use crate::common::{read_plain_csv, stage_err};
use crate::doc::{Block, Document};
use crate::results::{reals, DataResult, FinalPoint, Real, Results, Stages};
use crate::{new_report, table, Ctx, ReproError, ReproduceOptions, StageFn};
use samara_plant::{Model, Plant};
use samara_report::write_atomic;
use samara_sim::dataset::{normalisation_csv, training_csv};
use samara_sim::{
    fly, initial_state, minmax, published_starts, training_rows, LoopSettings, PidController,
};

/// Every stage, in order.
pub fn all() -> Vec<(&'static str, StageFn)> {
    vec![
        ("data", data as StageFn),
        ("train", crate::train_stage::train as StageFn),
        ("verify", crate::verify_stage::verify as StageFn),
        ("closed_loop", crate::flights_stage::closed_loop as StageFn),
        ("reach", crate::reach_stage::reach as StageFn),
    ]
}

/// Stage 1: the PID data set (published protocol), its constants and the figure.
fn data(ctx: &Ctx, st: &mut Stages) -> Result<Vec<String>, ReproError> {
    let plant = Plant::new(Model::Plate6);
    let settings = LoopSettings::default();
    let starts = published_starts();
    let pb = ctx.bar(starts.len() as u64, "PID flights (ode45)");
    let mut flights = Vec::new();
    for &y0 in &starts {
        let f = fly(
            &plant,
            &mut PidController::default(),
            &initial_state(&plant, y0),
            &settings,
        )
        .map_err(|e| stage_err("data", e))?;
        flights.push(f);
        pb.inc(1);
    }
    pb.finish_and_clear();
    let rows = training_rows(&flights);
    let (lo, range) = minmax(&rows);
    write_atomic(
        &ctx.path("data/training_data.csv"),
        training_csv(&rows).as_bytes(),
    )
    .map_err(|e| stage_err("data", e))?;
    write_atomic(
        &ctx.path("data/normalisation.csv"),
        normalisation_csv(&lo, &range).as_bytes(),
    )
    .map_err(|e| stage_err("data", e))?;
    flights_figure(
        "PID flights (plate6 model, published protocol)",
        &flights,
        None,
    )
    .render(
        &ctx.path("figures/pid_trajectories.png"),
        &ctx.path("figures/pid_trajectories.svg"),
    )
    .map_err(|e| stage_err("data", e))?;
    let finals = flights
        .iter()
        .map(|f| {
            let s = &f
                .steps
                .last()
                .map(|r| r.state_end.clone())
                .unwrap_or_default();
            FinalPoint {
                x_plus_y: Real(s[4] + s[5]),
                y0: Real(f.initial[5]),
            }
        })
        .collect();
    let mut result = DataResult {
        finals,
        normalisation_min: reals(&lo),
        normalisation_range: reals(&range),
        published_constants: None,
        published_constants_vs_data_max_abs: None,
        published_max_abs_deviation: None,
        published_rows: None,
        rows: rows.len(),
    };
    if let Some(p) = &ctx.opts.published {
        let refr =
            read_plain_csv(&p.join("Training_Data.csv")).map_err(|e| stage_err("data", e))?;
        let dev = rows
            .iter()
            .zip(&refr)
            .flat_map(|(a, b)| a.iter().zip(b).map(|(x, y)| (x - y).abs()))
            .fold(0.0f64, f64::max);
        result.published_max_abs_deviation = Some(Real(dev));
        result.published_rows = Some(refr.len());
        if let Ok(nc) = read_plain_csv(&p.join("Normalisation_Constants.csv")) {
            if nc.len() >= 2 && nc[0].len() >= 7 {
                // Does the published constants file describe the published data set?
                let mut worst = 0.0f64;
                for j in 0..6 {
                    worst = worst.max((nc[0][j] - lo[j]).abs().max((nc[1][j] - range[j]).abs()));
                }
                result.published_constants_vs_data_max_abs = Some(Real(worst));
                result.published_constants = Some(nc[..2].iter().map(|r| reals(r)).collect());
            }
        }
    }
    st.data = Some(result);
    Ok(vec![
        "data/training_data.csv".into(),
        "data/normalisation.csv".into(),
        "figures/pid_trajectories.png".into(),
        "figures/pid_trajectories.svg".into(),
    ])
}

/// Build the report from the run's results.
pub fn report(full: &Results, _opts: &ReproduceOptions) -> Document {
    let mut d = new_report(full);
    let st = &full.stages;
    let mut findings: Vec<String> = Vec::new();

    if let Some(data) = &st.data {
        d.push(Block::Heading(
            1,
            "1. Data generation (PID, published protocol)".into(),
        ));
        d.push(Block::Para(format!(
            "Nine PID flights of the plate6 model (y0 = n/0.07, n = 0.1:0.025:0.3; 40 control steps of 0.5; MATLAB-ode45-compatible integration) give {} training rows (`data/training_data.csv`) and their min-max constants (`data/normalisation.csv`).",
            data.rows
        )));
        d.push(Block::Image {
            path: "figures/pid_trajectories.png".into(),
            caption: "PID flights and the target line y = -x (equal axes)".into(),
        });
        let rows = data
            .finals
            .iter()
            .map(|f| vec![f.y0.f4(), f.x_plus_y.f4()])
            .collect();
        d.push(table(&["y0", "x + y at t = 20"], rows));
        if let Some(dev) = data.published_max_abs_deviation.and_then(Real::get) {
            findings.push(format!(
                "samara's simulator regenerates the published `Training_Data.csv` to a maximum absolute deviation of {dev:.2e} over all {} numbers, so the published data come from the plate6 model with the filter state reset every control step.",
                data.rows * 7
            ));
        }
        if let Some(w) = data.published_constants_vs_data_max_abs.and_then(Real::get) {
            findings.push(format!(
                "The published `Normalisation_Constants.csv` does not describe the published `Training_Data.csv`: its minima/ranges differ from the data's by up to {w:.3} (raw units). The networks were trained on an older data set, so their normalisation does not match the data the paper publishes."
            ));
        }
    }

    crate::sections::report(st, &mut d, &mut findings);
    d.push(Block::Heading(1, "Findings".into()));
    if findings.is_empty() {
        d.push(Block::Para(
            "Run with `--published DIR` to compare with the published files.".into(),
        ));
    } else {
        d.push(Block::List(findings));
    }
    d
}

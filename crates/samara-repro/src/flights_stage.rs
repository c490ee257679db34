//! Stage 5 of the reproduction: every raw-unit controller flown from the published
//! starts (plate6 model, sample and hold).

use crate::common::{flights_figure, stage_err};
use crate::results::{reals, FlightsResult, FlownController, Real, Stages};
use crate::verify_stage::subjects;
use crate::{Ctx, ReproError};
use samara_plant::{Model, Plant};
use samara_sim::{
    fly, initial_state, published_starts, LoopSettings, NetworkController, PidController,
};

/// Stage 5: every controller flown in the closed loop (plate6, ode45, clipped).
pub fn closed_loop(ctx: &Ctx, st: &mut Stages) -> Result<Vec<String>, ReproError> {
    let subs = subjects(ctx, st)?;
    let plant = Plant::new(Model::Plate6);
    let settings = LoopSettings::default();
    let mut out = Vec::new();
    let mut figure_flights = Vec::new();
    let mid = published_starts()[4];
    let mut pid = PidController::default();
    figure_flights.push(
        fly(&plant, &mut pid, &initial_state(&plant, mid), &settings)
            .map_err(|e| stage_err("closed_loop", e))?,
    );
    let mut labels = vec!["PID".to_string()];
    for s in subs.iter().filter(|s| s.raw_controller.is_some()) {
        let mut c = NetworkController::new(
            s.raw_controller.clone().expect("filtered"),
            Some((0.181, 0.193)),
            s.label.clone(),
        );
        let mut finals = Vec::new();
        for y0 in published_starts() {
            let f = fly(&plant, &mut c, &initial_state(&plant, y0), &settings)
                .map_err(|e| stage_err("closed_loop", e))?;
            let st = &f.steps.last().expect("steps").state_end;
            finals.push(st[4] + st[5]);
            if y0 == mid {
                figure_flights.push(f);
                labels.push(s.label.clone());
            }
        }
        out.push(FlownController {
            controller: s.label.clone(),
            worst: Real(finals.iter().map(|v| v.abs()).fold(0.0, f64::max)),
            final_x_plus_y: reals(&finals),
        });
    }
    let mut fig = flights_figure(
        &format!("Closed loop from y0 = {mid:.4} (plate6, clipped controllers)"),
        &figure_flights,
        Some(2.0),
    );
    for (c, l) in fig.curves.iter_mut().zip(&labels) {
        c.label = l.clone();
    }
    fig.render(
        &ctx.path("figures/closed_loop.png"),
        &ctx.path("figures/closed_loop.svg"),
    )
    .map_err(|e| stage_err("closed_loop", e))?;
    st.closed_loop = Some(FlightsResult {
        controllers: out,
        starts: reals(&published_starts()),
    });
    Ok(vec![
        "figures/closed_loop.png".into(),
        "figures/closed_loop.svg".into(),
    ])
}

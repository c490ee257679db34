//! `samara simulate`: the checks, the flights and the data files are
//! `samara_app::simulate`'s (the controller and loop checks shared with Python's
//! `samara.simulate`); this draws the figure and prints the summary.

use anyhow::{anyhow, Result};
pub use samara_app::args::SimulateArgs;
use samara_app::simulate::{write_data, SimulateSummary};
use std::process::ExitCode;
use std::time::Instant;

/// Run `samara simulate`.
pub fn run(a: &SimulateArgs) -> Result<ExitCode> {
    if let Some(sys) = &a.system {
        let done = samara_app::simulate::run_system(a, sys)?;
        if a.json {
            println!("{}", crate::json_text(&done.summary, false)?);
        } else {
            for l in &done.human {
                println!("{l}");
            }
        }
        return Ok(if done.summary.violations.is_empty() {
            ExitCode::SUCCESS
        } else {
            ExitCode::from(1)
        });
    }
    let (plan, warnings) = a.prepare()?;
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    // Output directory: create and probe before simulating, so a bad path fails fast;
    // a failed run removes the folders it created.
    let out = samara_report::guard::OutDir::prepare(&a.out)?;
    let (model, settings) = (plan.plant.model, plan.settings.clone());
    let cname = plan.controller.name();
    let t0 = Instant::now();
    let flights = plan.fly().map_err(|e| anyhow!("{e}"))?;
    let wall = t0.elapsed().as_secs_f64();
    write_data(&a.out, model.dim(), &flights)?;
    if !a.no_plot {
        let title = format!(
            "Alsomitra glider, {} model, {cname} controller",
            model.name()
        );
        let mut fig = samara_repro::stages::flights_figure(&title, &flights, None);
        fig.legend = flights.len() <= 12;
        fig.render(
            &a.out.join("trajectories.png"),
            &a.out.join("trajectories.svg"),
        )?;
    }
    if a.json {
        let s = SimulateSummary::of(a, model, &settings, &flights, wall, warnings);
        println!("{}", crate::json_text(&s, true)?);
    } else {
        eprintln!(
            "simulated {} flight(s) of model {} in {:.3} s; wrote {}",
            flights.len(),
            model.name(),
            wall,
            a.out.display()
        );
    }
    out.keep();
    Ok(ExitCode::SUCCESS)
}

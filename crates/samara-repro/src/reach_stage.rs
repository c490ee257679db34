//! Stage 6 of the reproduction: sound reachable sets of every raw-unit controller on
//! the spec's closed loop.

use crate::common::stage_err;
use crate::spec_check::published_loop;
use crate::verify_stage::{subjects, Subject};
use crate::{Ctx, ReproError, StageOutput};
use samara_report::reach::{Trajectory, XyBox};
use serde_json::{json, Value};

/// Stage 6: sound reachable sets of every raw-unit controller on the spec's closed loop
/// (the shipped spec's `published`: reduced model, the published interval of y0, clipped
/// as in simulation, goal |x + y| <= 2 at t = 20): verdict, width against the sampled
/// range, figure.
pub fn reach(ctx: &Ctx, up: &Value) -> Result<StageOutput, ReproError> {
    let lp = published_loop(ctx.spec()).map_err(|e| stage_err("reach", e))?;
    let goal = lp.goal.as_ref().map_or(f64::NAN, |g| g.bound);
    let subs = subjects(ctx, up)?;
    let subs: Vec<&Subject> = subs.iter().filter(|s| s.raw_controller.is_some()).collect();
    let pb = ctx.bar(subs.len() as u64, "reachability");
    let mut out = Vec::new();
    let mut files = Vec::new();
    for (i, s) in subs.iter().enumerate() {
        let net = s.raw_controller.as_ref().expect("filtered");
        let mut rs = samara_reach::ReachSettings::from_loop(lp);
        if ctx.opts.quick {
            rs.max_leaves = 16;
            rs.samples = 50;
        }
        let r = samara_reach::reach(net, &rs).map_err(|e| stage_err("reach", e))?;
        let png = format!("figures/reach_{i}.png");
        let svg = format!("figures/reach_{i}.svg");
        let sets: Vec<Vec<XyBox>> = r
            .leaves
            .iter()
            .map(|l| l.steps.iter().map(|st| [st.bbox[4], st.bbox[5]]).collect())
            .collect();
        let samples: Vec<Trajectory> = r
            .samples
            .iter()
            .map(|smp| Trajectory {
                y0: smp.initial[5],
                xy: &smp.xy,
            })
            .collect();
        samara_report::reach::figure(
            &format!("{}, {} model", s.label, lp.model.name()),
            r.verdict.name(),
            &sets,
            &samples,
            Some(goal),
        )
        .render(&ctx.path(&png), &ctx.path(&svg))
        .map_err(|e| stage_err("reach", e))?;
        let reason = r.verdict.reason();
        let stopped: Vec<f64> = r
            .leaves
            .iter()
            .filter(|l| l.failure.is_some())
            .filter_map(|l| l.steps.last().map(|st| st.t))
            .collect();
        out.push(json!({
            "controller": s.label,
            "stopped": stopped.len(),
            "stopped_at": stopped.iter().cloned().fold(f64::INFINITY, f64::min),
            "verdict": r.verdict.name(),
            "reason": reason,
            "final_x_plus_y": r.final_x_plus_y,
            "sampled_x_plus_y": r.sampled_x_plus_y,
            "ratio": r.width_ratio(),
            "subproblems": r.subproblems(),
            "seconds": r.seconds,
            "figure": png,
        }));
        files.push(png);
        files.push(svg);
        pb.inc(1);
    }
    pb.finish_and_clear();
    Ok(StageOutput {
        result: json!({"networks": out, "model": lp.model.name(), "y0": lp.start[5],
            "horizon": lp.horizon, "period": lp.period, "goal_ystar": goal,
            "goal_from": lp.goal.as_ref().and_then(|g| g.from), "clip": lp.clip, "loop": lp.name}),
        files,
    })
}

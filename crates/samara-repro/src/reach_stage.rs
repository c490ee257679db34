//! Stage 6 of the reproduction: sound reachable sets of every raw-unit controller on
//! the spec's closed loop.

use crate::common::stage_err;
use crate::results::{pair, ReachStageResult, ReachedNetwork, Real, Stages};
use crate::spec_check::published_loop;
use crate::verify_stage::{subjects, Subject};
use crate::{Ctx, ReproError};
use samara_report::reach::{Trajectory, XyBox};

/// Stage 6: sound reachable sets of every raw-unit controller on the spec's closed loop
/// (the shipped spec's `published`: reduced model, the published interval of y0, clipped
/// as in simulation, goal |x + y| <= 2 at t = 20): verdict, width against the sampled
/// range, figure.
pub fn reach(ctx: &Ctx, st: &mut Stages) -> Result<Vec<String>, ReproError> {
    let lp = published_loop(ctx.spec()).map_err(|e| stage_err("reach", e))?;
    let goal = lp.goal.as_ref().map_or(f64::NAN, |g| g.bound);
    let subs = subjects(ctx, st)?;
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
        out.push(ReachedNetwork {
            controller: s.label.clone(),
            figure: png.clone(),
            final_x_plus_y: pair(r.final_x_plus_y),
            ratio: Real(r.width_ratio()),
            reason,
            sampled_x_plus_y: pair(r.sampled_x_plus_y),
            seconds: Real(r.seconds),
            stopped: stopped.len(),
            stopped_at: Real(stopped.iter().cloned().fold(f64::INFINITY, f64::min)),
            subproblems: r.subproblems(),
            verdict: r.verdict.name().to_string(),
        });
        files.push(png);
        files.push(svg);
        pb.inc(1);
    }
    pb.finish_and_clear();
    st.reach = Some(ReachStageResult {
        clip: lp.clip.map(|(a, b)| [Real(a), Real(b)]),
        goal_from: Real::of(lp.goal.as_ref().and_then(|g| g.from)),
        goal_ystar: Real(goal),
        horizon: Real(lp.horizon),
        loop_name: lp.name.clone(),
        model: lp.model.name().to_string(),
        networks: out,
        period: Real(lp.period),
        y0: [Real(lp.start[5].0), Real(lp.start[5].1)],
    });
    Ok(files)
}

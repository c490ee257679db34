//! What the stages take from the run's spec, checked before any stage runs: P1-P4 as
//! critical-value queries and training properties, and the closed loop of the
//! reachability stage and closed-loop training.

use crate::common::P1_TO_P4;
use crate::verify_stage::critical_query;
use samara_spec::{Bindings, LoopDecl, Spec};
use samara_train::{from_query, CegisOptions};

/// Whether `spec` states what the stages lower: a first network with the six state
/// inputs and one output, and `p1`-`p4` both as critical-value queries over `ystar` (the
/// verify stage) and as training properties with `ystar` at its default (the train
/// stage). The message names the spec, and the place where the spec has one.
pub(crate) fn check_spec(spec: &Spec) -> Result<(), String> {
    let file = &spec.file;
    let Some(net) = spec.networks.first() else {
        return Err(format!(
            "{file}: declares no network; the reproduction needs `network f(v_xp, v_yp, omega, theta, x, y) -> (ex)`"
        ));
    };
    if net.inputs.len() != samara_nn::STATE_INPUTS.len() || net.outputs.len() != 1 {
        return Err(format!(
            "{file}: network `{}` takes {} inputs and gives {} outputs; the reproduction's controllers take the six states (v_xp, v_yp, omega, theta, x, y) and give one output (ex)",
            net.name,
            net.inputs.len(),
            net.outputs.len()
        ));
    }
    const TRAIN: &str =
        "the reproduction's DL2/Goedel training lowers p1-p4 with `ystar` at its default";
    let note = |e: &str, why: &str| format!("{}\n  = note: {why}", e.trim_end());
    for name in P1_TO_P4 {
        critical_query(spec, name, "ystar").map_err(|e| {
            note(
                &e,
                "the reproduction computes the critical value of `ystar` for each of p1-p4",
            )
        })?;
        let insts = spec
            .lower_prove(name, &Bindings::default())
            .map_err(|e| note(&e.to_string(), TRAIN))?;
        for inst in insts {
            from_query(&inst.query).map_err(|e| note(&format!("{file}: {e}"), TRAIN))?;
        }
    }
    published_loop(spec)?;
    Ok(())
}

/// The closed loop the reachability stage and closed-loop training fly: the spec's first
/// `loop`, flown by its first network, with a goal, in the shape closed-loop training
/// takes (reduced model, start `(1, 0, 0, 0, 0, y0)`). The message names the spec.
pub(crate) fn published_loop(spec: &Spec) -> Result<&LoopDecl, String> {
    let file = &spec.file;
    let Some(lp) = spec.loops.first() else {
        return Err(format!(
            "{file}: states no closed loop; the reproduction's reachability stage and closed-loop training fly the spec's first `loop` (see models/alsomitra/alsomitra.spec: `loop published of f: ...`, `start published: ...`, `goal published: ...`)"
        ));
    };
    let at = |m: String| format!("{file}:{}:{}: {m}", lp.pos.line, lp.pos.col);
    if lp.net != spec.networks[0].name {
        return Err(at(format!(
            "loop `{}` is flown by `{}`; the reproduction's controllers are the first network, `{}`",
            lp.name, lp.net, spec.networks[0].name
        )));
    }
    if lp.goal.is_none() {
        return Err(at(format!(
            "loop `{}` has no goal; the reproduction decides it: add `goal {}: |x + y| <= 2 at {}`",
            lp.name, lp.name, lp.horizon
        )));
    }
    CegisOptions::from_loop(lp).map_err(|e| at(e.to_string()))?;
    Ok(lp)
}

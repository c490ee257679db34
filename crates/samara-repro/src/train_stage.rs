//! Stage 2 of the reproduction: the six controllers trained on the regenerated data
//! (plain, adversarial, Lipschitz, DL2 and Goedel on the spec's P1-P4, and closed-loop
//! training on the spec's loop).

use crate::common::{stage_err, METHODS, P1_TO_P4};
use crate::results::{
    pair, reals, ClosedLoopResult, Real, RoundRow, Stages, TrainResult, TrainedNetwork,
};
use crate::spec_check::published_loop;
use crate::{Ctx, ReproError};
use samara_nn::Network;
use samara_spec::{Bindings, Spec};
use samara_train::{
    read_table, spec_properties, train as train_net, train_closed_loop, Attack, CegisOptions,
    Logic, Method, MinMax, Property, TrainOptions,
};

/// R^2 of a raw-unit network against every row of `data` (raw units).
pub(crate) fn r2_all(net: &Network, data: &samara_train::Table) -> f64 {
    r2_rows(net, data, &(0..data.rows()).collect::<Vec<_>>()).0
}

/// R^2 and RMSE of a raw-unit network against the rows `idx` of `data` (raw units).
pub(crate) fn r2_rows(net: &Network, data: &samara_train::Table, idx: &[usize]) -> (f64, f64) {
    let n = idx.len() as f64;
    let mean = idx.iter().map(|&i| data.row(i)[6]).sum::<f64>() / n;
    let (mut sse, mut sst) = (0.0, 0.0);
    for &i in idx {
        let r = data.row(i);
        sse += (net.eval_f64(&r[..6])[0] - r[6]).powi(2);
        sst += (r[6] - mean).powi(2);
    }
    (1.0 - sse / sst, (sse / n).sqrt())
}

/// Stage 2: train the six controllers on the regenerated data: the five data-driven
/// methods, and the closed-loop method (issue 18) with its reach rounds.
pub fn train(ctx: &Ctx, st: &mut Stages) -> Result<Vec<String>, ReproError> {
    let data =
        read_table(&ctx.path("data/training_data.csv")).map_err(|e| stage_err("train", e))?;
    let mm = MinMax::of(&data);
    let lo = mm.min[..6].to_vec();
    let hi: Vec<f64> = (0..6).map(|j| mm.min[j] + mm.range[j]).collect();
    let props =
        training_properties(ctx.spec(), &mm, &lo, &hi).map_err(|e| stage_err("train", e))?;
    let epochs = if ctx.opts.quick { 200 } else { 1000 };
    let pb = ctx.bar(METHODS.len() as u64, "training controllers");
    let mut rows = Vec::new();
    let mut files = Vec::new();
    let mut cegis = None;
    for m in METHODS {
        if m == "closed-loop" {
            let (row, extra, figs) = train_closed_loop_stage(ctx, &data, &mm, epochs)?;
            rows.push(row);
            cegis = Some(extra);
            files.extend(figs);
            pb.inc(1);
            continue;
        }
        let method = match m {
            "plain" => Method::Plain,
            "adversarial" => Method::Adversarial(Attack::Fgsm),
            "lipschitz" => Method::Lipschitz {
                l: 0.5,
                weight: 10.0,
            },
            "dl2" => Method::Properties {
                logic: Logic::Dl2,
                props: props.clone(),
                weight: 1.0,
            },
            _ => Method::Properties {
                logic: Logic::Goedel,
                props: props.clone(),
                weight: 1.0,
            },
        };
        let o = TrainOptions {
            epochs,
            method,
            ..Default::default()
        };
        let t = std::time::Instant::now();
        let out = train_net(&data, Some(&mm), &o).map_err(|e| stage_err("train", e))?;
        let secs = t.elapsed().as_secs_f64();
        let net = out
            .network
            .with_names(&samara_nn::STATE_INPUTS, &["ex"])
            .map_err(|e| stage_err("train", e))?;
        let rel = format!("networks/{m}.onnx");
        samara_nn::onnx::save(&net, ctx.path(&rel), &Default::default())
            .map_err(|e| stage_err("train", e))?;
        files.push(rel.clone());
        let k = &out.metrics;
        rows.push(TrainedNetwork {
            attack_mean: Real(k.attack_mean),
            attack_worst: Real(k.attack_worst),
            epochs,
            eps: Real(o.eps),
            file: rel,
            mae: Real(k.mae),
            method: m.to_string(),
            r2: Real(k.r2),
            r2_all: Real(r2_all(&net, &data)),
            rmse: Real(k.rmse),
            seconds: Real(secs),
        });
        pb.inc(1);
    }
    pb.finish_and_clear();
    st.train = Some(TrainResult {
        closed_loop: cegis,
        domain_hi: reals(&hi),
        domain_lo: reals(&lo),
        networks: rows,
        norm_min: reals(&mm.min),
        norm_range: reals(&mm.range),
    });
    Ok(files)
}

/// P1-P4 as `spec` states them (`ystar` at its default), lowered in the trainer's
/// min-max units `mm` over the raw box `[lo, hi]` of the regenerated data: the DL2 and
/// Goedel constraints of the train stage.
pub(crate) fn training_properties(
    spec: &Spec,
    mm: &MinMax,
    lo: &[f64],
    hi: &[f64],
) -> Result<Vec<Property>, samara_train::SpecPropertyError> {
    spec_properties(
        spec,
        &P1_TO_P4.map(String::from),
        &Bindings::default(),
        mm,
        Some(lo.iter().cloned().zip(hi.iter().cloned()).collect()),
    )
}

/// The closed-loop method: data-only training of `epochs`, then train-and-reach rounds
/// (the reach budget of a round is the quick reproduction's: 16 sub-boxes, 50 samples).
/// Returns its row of the training table, its rounds, and the files written.
pub(crate) fn train_closed_loop_stage(
    ctx: &Ctx,
    data: &samara_train::Table,
    mm: &MinMax,
    epochs: usize,
) -> Result<(TrainedNetwork, ClosedLoopResult, Vec<String>), ReproError> {
    let base = published_loop(ctx.spec())
        .and_then(|lp| CegisOptions::from_loop(lp).map_err(|e| e.to_string()))
        .map_err(|e| stage_err("train", e))?;
    let o = CegisOptions {
        pretrain: TrainOptions {
            epochs,
            min_r2: 0.9,
            ..Default::default()
        },
        ..base
    };
    let t = std::time::Instant::now();
    let out = train_closed_loop(data, Some(mm), &o).map_err(|e| stage_err("train", e))?;
    let secs = t.elapsed().as_secs_f64();
    let net = out.network.clone();
    let rel = "networks/closed-loop.onnx".to_string();
    samara_nn::onnx::save(&net, ctx.path(&rel), &Default::default())
        .map_err(|e| stage_err("train", e))?;
    let (png, svg) = (
        "figures/closed_loop_rounds.png".to_string(),
        "figures/closed_loop_rounds.svg".to_string(),
    );
    samara_train::cegis::rounds_figure(
        &out.rounds,
        o.goal,
        &format!(
            "closed-loop training rounds: |x + y| <= {} at t = {}, {}",
            o.goal,
            o.loss.horizon,
            if out.proved { "proved" } else { "not proved" }
        ),
        &ctx.path(&png),
        &ctx.path(&svg),
    )
    .map_err(|e| stage_err("train", e))?;
    let rounds = out
        .rounds
        .iter()
        .map(|r| RoundRow {
            added: reals(&r.added),
            enclosure: pair(r.enclosure),
            loss: Real(r.loss),
            max_leaves: r.max_leaves,
            mse: Real(r.mse),
            penalty: Real(r.penalty),
            r2: Real(r.r2),
            round: r.round,
            sampled: pair(r.sampled),
            seconds: Real(r.train_seconds + r.reach_seconds),
            starts: r.starts,
            steps: r.steps,
            verdict: r.verdict.clone(),
        })
        .collect();
    // Test R^2 on the rows the data-only training held out (its split, seed 0).
    let (_, test) =
        samara_train::data::split(data.rows(), o.pretrain.test_fraction, o.pretrain.seed);
    let (r2_test, rmse_test) = r2_rows(&net, data, &test);
    // The closed-loop row has no attack, MAE or radius: null in results.json.
    let none = Real(f64::NAN);
    let row = TrainedNetwork {
        attack_mean: none,
        attack_worst: none,
        epochs,
        eps: none,
        file: rel.clone(),
        mae: none,
        method: "closed-loop".into(),
        r2: Real(r2_test),
        r2_all: Real(out.r2),
        rmse: Real(rmse_test),
        seconds: Real(secs),
    };
    let extra = ClosedLoopResult {
        data_weight: Real(o.data_weight),
        enclosure: pair(out.reach.final_x_plus_y),
        figure: png.clone(),
        goal_ystar: Real(o.goal),
        horizon: Real(o.loss.horizon),
        proved: out.proved,
        r2_all: Real(out.r2),
        rounds,
        seconds: Real(secs),
        steps_per_round: o.steps_per_round,
        training_bound: Real(o.loss.bound),
        verdict: out.reach.verdict.name().to_string(),
        y0: [Real(o.y0.0), Real(o.y0.1)],
    };
    Ok((row, extra, vec![rel, png, svg]))
}

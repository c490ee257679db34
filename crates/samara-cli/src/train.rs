//! `samara train`.

use anyhow::{anyhow, bail, Context, Result};
use samara_train::{
    case_study, read_table, train, Attack, Logic, Method, MinMax, TrainOptions, Units,
};
use std::fmt::Write as _;
use std::io::IsTerminal;
use std::path::PathBuf;
use std::process::ExitCode;

/// Flags of `samara train`. Defaults are the published setting (6-6-4-1, ReLU on every
/// layer, Adam lr 0.06, batch 50, 1000 epochs, 10% test split).
#[derive(clap::Args, Debug)]
pub struct TrainArgs {
    /// Data set (CSV with or without header, or IDX): input columns then the output.
    #[arg(long)]
    pub data: PathBuf,
    /// Min-max constants file (row 1 minimum, row 2 range, like Normalisation_Constants.csv);
    /// computed from the data when absent.
    #[arg(long)]
    pub normalisation: Option<PathBuf>,
    /// plain | adversarial | lipschitz | dl2 | goedel.
    #[arg(long, default_value = "plain")]
    pub method: String,
    /// Adversarial attack: fgsm (the published training) or pgd.
    #[arg(long, default_value = "fgsm")]
    pub attack: String,
    /// Layer widths, inputs first.
    #[arg(long, default_value = "6,6,4,1")]
    pub arch: String,
    /// Epochs.
    #[arg(long, default_value_t = 1000)]
    pub epochs: usize,
    /// Mini-batch size.
    #[arg(long, default_value_t = 50)]
    pub batch: usize,
    /// Adam learning rate.
    #[arg(long, default_value_t = 0.06)]
    pub lr: f64,
    /// Seed (same seed, same data: bit-identical network).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Attack radius in normalised input units.
    #[arg(long, default_value_t = 0.005)]
    pub eps: f64,
    /// Lipschitz constant L for `lipschitz` (normalised units).
    #[arg(long, default_value_t = 0.5)]
    pub lipschitz: f64,
    /// Weight of the Lipschitz or property term.
    #[arg(long)]
    pub weight: Option<f64>,
    /// ystar of the built-in case-study properties P1-P4 used by dl2/goedel.
    #[arg(long, default_value_t = 2.0)]
    pub ystar: f64,
    /// Take the dl2/goedel properties from a specification instead of the built-in P1-P4.
    #[arg(long)]
    pub spec: Option<PathBuf>,
    /// Properties of --spec to train for (comma-separated; default: every property
    /// without data-set quantifiers).
    #[arg(long)]
    pub properties: Option<String>,
    /// Parameter bindings for --spec (repeatable): --param ystar=2.
    #[arg(long = "param", value_name = "NAME=VALUE")]
    pub params: Vec<String>,
    /// Output network (ONNX, raw units with its normalisation layers).
    #[arg(long)]
    pub out: PathBuf,
    /// Training log CSV (default: next to --out, `<stem>.log.csv`).
    #[arg(long)]
    pub log: Option<PathBuf>,
    /// Print the metrics as JSON.
    #[arg(long)]
    pub json: bool,
}

/// Properties from a spec, moved into the units of the network being trained.
fn spec_properties(
    path: &std::path::Path,
    a: &TrainArgs,
    mm: &MinMax,
) -> Result<Vec<samara_train::Property>> {
    let spec = samara_spec::Spec::read(path).map_err(|e| anyhow!("{e}"))?;
    let mut b = samara_spec::Bindings::default();
    for s in &a.params {
        let (k, v) = s
            .split_once('=')
            .ok_or_else(|| anyhow!("--param {s:?}: expected NAME=VALUE"))?;
        b.params.insert(
            k.trim().into(),
            v.trim()
                .parse()
                .map_err(|_| anyhow!("--param {s:?}: not a number"))?,
        );
    }
    let names: Vec<String> = match &a.properties {
        Some(p) => p.split(',').map(|s| s.trim().to_string()).collect(),
        None => spec
            .properties
            .iter()
            .filter(|p| p.binders.is_empty())
            .map(|p| p.name.clone())
            .collect(),
    };
    let decl = spec
        .networks
        .first()
        .ok_or_else(|| anyhow!("the spec declares no network"))?;
    let n = decl.inputs.len();
    if n + decl.outputs.len() != mm.min.len().min(n + decl.outputs.len()) || mm.min.len() < n + 1 {
        bail!(
            "--spec: the network `{}` has {n} inputs; the data must have them and one output",
            decl.name
        );
    }
    // spec units -> raw -> trainer units: old = a * new + b.
    let inputs: Vec<(f64, f64)> = (0..n)
        .map(|k| {
            let (c, s) = decl.input_map(k);
            (mm.range[k] / s, (mm.min[k] - c) / s)
        })
        .collect();
    let (oc, os) = decl.output_map(0);
    let outputs = vec![(mm.range[n] / os, (mm.min[n] - oc) / os)];
    let mut props = Vec::new();
    for name in names {
        let inst = spec.lower_prove(&name, &b).map_err(|e| anyhow!("{e}"))?;
        for i in inst {
            let q = samara_train::rescale_query(&i.query, &inputs, &outputs);
            props.extend(samara_train::from_query(&q)?);
        }
    }
    if props.is_empty() {
        bail!("--spec: no property to train for");
    }
    Ok(props)
}

/// Run `samara train`.
pub fn run(a: &TrainArgs) -> Result<ExitCode> {
    let arch: Vec<usize> = a
        .arch
        .split(',')
        .map(|s| s.trim().parse::<usize>())
        .collect::<Result<_, _>>()
        .map_err(|_| {
            anyhow!(
                "--arch {:?}: expected comma-separated widths such as 6,6,4,1",
                a.arch
            )
        })?;
    let data = read_table(&a.data)?;
    let mm = match &a.normalisation {
        Some(p) => MinMax::read(p)?,
        None => MinMax::of(&data),
    };
    let method = match a.method.as_str() {
        "plain" => Method::Plain,
        "adversarial" => Method::Adversarial(match a.attack.as_str() {
            "fgsm" => Attack::Fgsm,
            "pgd" => Attack::Pgd { steps: 10 },
            other => bail!("--attack {other:?}: choose fgsm or pgd"),
        }),
        "lipschitz" => Method::Lipschitz {
            l: a.lipschitz,
            weight: a.weight.unwrap_or(10.0),
        },
        "dl2" | "goedel" => {
            if data.cols != 7 || arch.first() != Some(&6) {
                bail!("--method {}: the built-in properties P1-P4 need the case study's 6 inputs and 1 output", a.method);
            }
            let n = 6;
            let units = Units {
                c: mm.min[..n].to_vec(),
                s: mm.range[..n].to_vec(),
                c_out: mm.min[n],
                s_out: mm.range[n],
            };
            let data_mm = MinMax::of(&data);
            let lo = data_mm.min[..n].to_vec();
            let hi: Vec<f64> = (0..n).map(|j| data_mm.min[j] + data_mm.range[j]).collect();
            let logic = if a.method == "dl2" {
                Logic::Dl2
            } else {
                Logic::Goedel
            };
            let props = match &a.spec {
                None => case_study(&units, &lo, &hi, a.ystar),
                Some(path) => spec_properties(path, a, &mm)?,
            };
            Method::Properties {
                logic,
                props,
                weight: a.weight.unwrap_or(1.0),
            }
        }
        other => bail!("--method {other:?}: choose plain, adversarial, lipschitz, dl2 or goedel"),
    };
    let o = TrainOptions {
        arch,
        epochs: a.epochs,
        batch: a.batch,
        lr: a.lr,
        seed: a.seed,
        eps: a.eps,
        method,
        progress: std::io::stderr().is_terminal() && !a.json,
        ..Default::default()
    };
    let outcome = train(&data, Some(&mm), &o)?;
    let mut net = outcome.network;
    if net.n_inputs() == 6 && net.n_outputs() == 1 {
        net = net.with_names(&samara_nn::STATE_INPUTS, &["ex"])?;
    }
    samara_nn::onnx::save(&net, &a.out, &Default::default())
        .with_context(|| format!("cannot write {}; choose a writable --out", a.out.display()))?;
    let log_path = a
        .log
        .clone()
        .unwrap_or_else(|| a.out.with_extension("log.csv"));
    let mut log = String::from("epoch,loss,test_rmse\n");
    for r in &outcome.log {
        let _ = writeln!(log, "{},{:?},{:?}", r.epoch, r.loss, r.test_rmse);
    }
    samara_report::write_atomic(&log_path, log.as_bytes())?;
    let m = &outcome.metrics;
    if a.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({
                "method": a.method, "out": a.out.display().to_string(), "log": log_path.display().to_string(),
                "test_rows": m.n_test, "r2": m.r2, "rmse": m.rmse, "mae": m.mae,
                "eps": a.eps, "attack_worst_deviation": m.attack_worst, "attack_mean_deviation": m.attack_mean,
            }))?
        );
    } else {
        eprintln!(
            "trained {} network: test R^2 {:.4}, RMSE {:.3e}, MAE {:.3e}, worst attack deviation at eps {} = {:.3e}; wrote {} and {}",
            a.method,
            m.r2,
            m.rmse,
            m.mae,
            a.eps,
            m.attack_worst,
            a.out.display(),
            log_path.display()
        );
    }
    Ok(ExitCode::SUCCESS)
}

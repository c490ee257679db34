//! A specification with its networks, parameters and data sets bound and checked, and
//! the argument checks both front ends share. The messages name the argument the way
//! the caller's users wrote it ([`Front`]).

use crate::{input, AppError};
use samara_nn::Network;
use samara_spec::lower::{nearest, NetDecl};
use samara_spec::syntax::Binder;
use samara_spec::{Bindings, Instance, Spec};
use std::borrow::Cow;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Largest magnitude of an initial state value of `simulate` and `reach`: the model is
/// nondimensional and the published states are O(1) (heights 1.43 to 4.29).
pub const MAX_STATE: f64 = 1000.0;

/// Where the published training points live (relative to a samara checkout).
pub const PUBLISHED_DATA: &str = "../shared/reference/Training_Data_Normalised.csv";

/// Shortest control period of a closed-loop run (1 ms); below it the hold is shorter
/// than the integrator's useful steps.
pub const MIN_PERIOD: f64 = 1e-3;
/// Longest control period of a closed-loop run.
pub const MAX_PERIOD: f64 = 100.0;

/// Who called: the command line (arguments are flags: `--network f=FILE`) or Python
/// (arguments are keyword arguments and dict entries: `networks["f"]`). Only the
/// wording of messages depends on it, never a check.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Front {
    /// `samara` on the command line.
    Cli,
    /// The `samara` Python package.
    Python,
}

impl Front {
    /// An argument's name: `--horizon` / `horizon`.
    pub fn arg(self, name: &str) -> String {
        match self {
            Front::Cli => format!("--{}", name.replace('_', "-")),
            Front::Python => name.to_string(),
        }
    }

    /// A message of a lower library in this front's words: on the CLI as it is; for
    /// Python every command-line flag it names (`--min-r2`, "raise --timeout") becomes
    /// the keyword argument of the same meaning (`min_r2`, "raise timeout"), since
    /// samara's Python functions name their arguments after the flags.
    pub fn words(self, msg: &str) -> String {
        if self == Front::Cli {
            return msg.to_string();
        }
        let b = msg.as_bytes();
        let mut out = String::with_capacity(msg.len());
        let mut i = 0;
        while i < msg.len() {
            let flag_start = b[i] == b'-'
                && b.get(i + 1) == Some(&b'-')
                && b.get(i + 2).is_some_and(u8::is_ascii_lowercase)
                && (i == 0 || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'-'));
            if flag_start {
                let mut j = i + 2;
                while j < b.len() && (b[j].is_ascii_alphanumeric() || b[j] == b'-') {
                    j += 1;
                }
                out.push_str(&msg[i + 2..j].replace('-', "_"));
                i = j;
            } else {
                let c = msg[i..].chars().next().expect("in bounds");
                out.push(c);
                i += c.len_utf8();
            }
        }
        out
    }

    /// An example setting: `--horizon 20` / `horizon=20`.
    pub fn eg(self, name: &str, value: &str) -> String {
        match self {
            Front::Cli => format!("{} {value}", self.arg(name)),
            Front::Python => format!("{name}={value}"),
        }
    }

    /// What a bound network is to the user: a file or a `Network` object.
    fn net_noun(self) -> &'static str {
        match self {
            Front::Cli => "the file",
            Front::Python => "the network",
        }
    }

    /// How to bind network `n`.
    fn pass_network(self, n: &str) -> String {
        match self {
            Front::Cli => format!("pass --network {n}=FILE.onnx"),
            Front::Python => format!("pass networks={{{n:?}: Network}}"),
        }
    }

    /// How to bind data set `d`.
    fn pass_dataset(self, d: &str) -> String {
        match self {
            Front::Cli => {
                format!(
                    "pass --dataset {d}=FILE (the published training points are {PUBLISHED_DATA})"
                )
            }
            Front::Python => format!("pass datasets={{{d:?}: FILE or array}}"),
        }
    }
}

/// `did you mean` for a name among candidates, else the list of them.
pub fn suggest<'a>(name: &str, candidates: impl IntoIterator<Item = &'a str> + Clone) -> String {
    match nearest(name, candidates.clone()) {
        Some(c) => format!("did you mean `{c}`?"),
        None => {
            let mut all: Vec<&str> = candidates.into_iter().collect();
            all.sort();
            if all.is_empty() {
                "it declares none".into()
            } else {
                format!("it declares {}", all.join(", "))
            }
        }
    }
}

/// A spec with its bindings, built one binding at a time ([`Loaded::bind_network`],
/// [`Loaded::bind_param`], [`Loaded::bind_dataset`]) and closed by [`Loaded::finish`].
/// Each step checks its binding against the spec and refuses a bad one with a message
/// naming it (the `label` the caller passes: the flag or argument as written).
#[derive(Clone, Debug)]
pub struct Loaded<'a> {
    /// The spec (borrowed from a Python `Spec`, owned by a CLI run).
    pub spec: Cow<'a, Spec>,
    /// How the spec is named in messages (its path as given).
    pub spec_name: String,
    /// Networks by name.
    pub nets: HashMap<String, Network>,
    /// The bindings handed to the lowering.
    pub b: Bindings,
    /// The files the networks came from (for output guards; empty for objects).
    pub net_files: Vec<PathBuf>,
    /// Warnings (a network whose units cannot be checked), in binding order.
    pub warnings: Vec<String>,
    /// Who called (the wording of messages).
    pub front: Front,
}

impl<'a> Loaded<'a> {
    /// A spec with nothing bound yet.
    pub fn new(spec: Cow<'a, Spec>, spec_name: String, front: Front) -> Self {
        Loaded {
            spec,
            spec_name,
            nets: HashMap::new(),
            b: Bindings::default(),
            net_files: Vec::new(),
            warnings: Vec::new(),
            front,
        }
    }

    /// The declaration of network `name`; `label` names the binding in the message
    /// (`--network f=...`, `networks["f"]`).
    pub fn declared_network(&self, name: &str, label: &str) -> Result<&NetDecl, AppError> {
        match self.spec.networks.iter().find(|n| n.name == name) {
            Some(nd) => Ok(nd),
            None => input(format!(
                "{label}: the spec {} declares no network `{name}`; {}",
                self.spec_name,
                suggest(name, self.spec.networks.iter().map(|n| n.name.as_str()))
            )),
        }
    }

    /// Bind network `name`: declared, of the declared signature, in the declared units
    /// ([`units_check`]; a warning where they cannot be checked). `file`: where it came
    /// from, if a file.
    pub fn bind_network(
        &mut self,
        name: &str,
        net: Network,
        label: &str,
        file: Option<&Path>,
    ) -> Result<(), AppError> {
        let nd = self.declared_network(name, label)?;
        if net.n_inputs() != nd.inputs.len() || net.n_outputs() != nd.outputs.len() {
            return input(format!(
                "{label}: dimension mismatch: {} has {} inputs and {} outputs but {} declares `{name}({})` with {} inputs and {} outputs; pass a network of that signature",
                self.front.net_noun(),
                net.n_inputs(),
                net.n_outputs(),
                self.spec_name,
                nd.inputs.join(", "),
                nd.inputs.len(),
                nd.outputs.len()
            ));
        }
        if let Some(w) = units_check(self.front, &self.spec_name, name, label, nd, &net)? {
            self.warnings.push(w);
        }
        self.b
            .network_dims
            .insert(name.to_string(), (net.n_inputs(), net.n_outputs()));
        self.nets.insert(name.to_string(), net);
        if let Some(f) = file {
            self.net_files.push(f.to_path_buf());
        }
        Ok(())
    }

    /// Check that parameter `name` is declared (`label` names the binding).
    pub fn declared_param(&self, name: &str, label: &str) -> Result<(), AppError> {
        if self.spec.params.contains_key(name) {
            return Ok(());
        }
        input(format!(
            "{label}: the spec {} declares no parameter `{name}`; {}",
            self.spec_name,
            suggest(name, self.spec.params.keys().map(String::as_str))
        ))
    }

    /// Bind parameter `name` to `x`: declared, finite, not the parameter to search
    /// (`free`). The declared range is checked by [`Loaded::finish`].
    pub fn bind_param(
        &mut self,
        name: &str,
        x: f64,
        label: &str,
        free: Option<&str>,
    ) -> Result<(), AppError> {
        self.declared_param(name, label)?;
        if !x.is_finite() {
            let eg = match self.front {
                Front::Cli => format!(", e.g. --param {name}=2"),
                Front::Python => String::new(),
            };
            return input(format!(
                "{label}: not a finite number; pass a finite value{eg}"
            ));
        }
        if free == Some(name) {
            let searched = match self.front {
                Front::Cli => format!("--param {name}"),
                Front::Python => format!("param={name:?}"),
            };
            return input(format!(
                "{label}: `{name}` is also the parameter to search ({searched}); drop one of them"
            ));
        }
        self.b.params.insert(name.to_string(), x);
        Ok(())
    }

    /// Bind data set `name` to the file `path`: declared, and the file exists.
    pub fn bind_dataset(&mut self, name: &str, path: &Path, label: &str) -> Result<(), AppError> {
        if !self.spec.datasets.contains_key(name) {
            return input(format!(
                "{label}: the spec {} declares no data set `{name}`; {}",
                self.spec_name,
                suggest(name, self.spec.datasets.keys().map(String::as_str))
            ));
        }
        if !path.is_file() {
            let (what, hint) = match self.front {
                Front::Cli => (
                    "the CSV or IDX file",
                    format!(" (the published training points are {PUBLISHED_DATA})"),
                ),
                Front::Python => ("the CSV or IDX file (or a numpy array)", String::new()),
            };
            return input(format!(
                "{label}: no such file; pass {what} of data set `{name}`{hint}"
            ));
        }
        self.b.datasets.insert(name.to_string(), path.to_path_buf());
        Ok(())
    }

    /// The bound parameters' values against their declared ranges (`params_label`:
    /// `--param`, `params`).
    pub fn finish(self, params_label: &str) -> Result<Self, AppError> {
        self.spec
            .check_bindings(&self.b)
            .map_err(|e| AppError::Input(format!("{params_label}: {e}")))?;
        Ok(self)
    }

    /// The data sets property `name` quantifies over whose file is missing, as a message
    /// naming the argument to pass; `None` if it needs none or they exist.
    pub fn missing_data(&self, name: &str) -> Option<String> {
        let p = self.spec.properties.iter().find(|p| p.name == name)?;
        for bnd in &p.binders {
            if let Binder::Data { dataset, .. } = bnd {
                let path = match self.b.datasets.get(dataset) {
                    Some(p) => p.clone(),
                    None => match self.spec.datasets.get(dataset) {
                        Some(p) if p.is_absolute() => p.clone(),
                        Some(p) => self.spec.dir.join(p),
                        None => continue, // the lowering names it
                    },
                };
                if !path.is_file() {
                    return Some(format!(
                        "property `{name}` quantifies over data set `{dataset}`, whose file {} (the spec's path, relative to the spec file) does not exist; {}",
                        path.display(),
                        self.front.pass_dataset(dataset)
                    ));
                }
            }
        }
        None
    }

    /// The names of the selected property (unchecked) or of all properties.
    pub fn selected(&self, property: Option<&str>) -> Vec<String> {
        match property {
            Some(p) => vec![p.to_string()],
            None => self
                .spec
                .property_names()
                .iter()
                .map(|s| s.to_string())
                .collect(),
        }
    }

    /// Every network the instances call is bound.
    pub fn require_networks(&self, qs: &[&Instance]) -> Result<(), AppError> {
        for i in qs {
            for a in &i.query.applications {
                if !self.nets.contains_key(&a.network) {
                    return input(format!(
                        "property `{}` uses network `{}`; {}",
                        i.label,
                        a.network,
                        self.front.pass_network(&a.network)
                    ));
                }
            }
        }
        Ok(())
    }
}

/// A network whose file carries its own normalisation, bound to a network the spec
/// declares with normalised units (or the reverse where the file says so) would have
/// its units converted twice: refused. Where the network carries no information, the
/// warning to show.
pub fn units_check(
    front: Front,
    spec_name: &str,
    name: &str,
    label: &str,
    nd: &NetDecl,
    net: &Network,
) -> Result<Option<String>, AppError> {
    let noun = front.net_noun();
    if nd.in_norm.is_some() && net.input_norm.is_some() {
        return input(format!(
            "{label}: units mismatch: {noun} normalises its own inputs (it has a raw-to-normalised input layer: a raw-unit network such as a `*_denorm` file) but {spec_name} declares `normalise {name} input`, i.e. `{name}` takes normalised inputs, so the inputs would be normalised twice; pass the network that takes normalised inputs (e.g. base_model_norm.onnx) or remove the `normalise {name}` lines from the spec"
        ));
    }
    if nd.out_norm.is_some() && net.output_denorm.is_some() {
        return input(format!(
            "{label}: units mismatch: {noun} denormalises its own output but {spec_name} declares `normalise {name} output`, so the output would be converted twice; pass the network with a normalised output or remove the `normalise {name} output` line"
        ));
    }
    if nd.in_norm.is_none() && net.input_norm.is_none() {
        return Ok(Some(format!(
            "{label}: {spec_name} declares `{name}` in raw units (no `normalise {name}` line) and {noun} carries no normalisation layer: samara cannot check that it takes raw inputs; if it takes normalised ones, add the `normalise {name} input ...` line"
        )));
    }
    Ok(None)
}

/// A `NAME=VALUE` flag value split at its first `=`, both sides trimmed; `flag` is the
/// flag's name without dashes (`network`), named in the message.
pub fn kv(s: &str, flag: &str) -> Result<(String, String), AppError> {
    let (k, v) = s.split_once('=').ok_or_else(|| {
        AppError::Input(format!(
            "--{flag} {s:?}: expected NAME=VALUE (e.g. --{flag} NAME=VALUE)"
        ))
    })?;
    Ok((k.trim().to_string(), v.trim().to_string()))
}

/// Load an ONNX network, naming the flag on failure (the error's own text only: its
/// source is already part of it).
/// (`flag` ends with `=` for a `NAME=FILE` flag. The loaders' errors start with the
/// file's path, so the message reads `--flag FILE: what`.)
pub fn load_network(path: &Path, flag: &str) -> Result<samara_nn::Network, AppError> {
    samara_nn::load(path).map_err(|e| AppError::Input(format!("{}{e}", flag_prefix(flag))))
}

/// [`load_network`] within a time limit: `Ok(None)` when `deadline` passed while the
/// network was read or lowered ([`samara_nn::load_until`]).
pub fn load_network_until(
    path: &Path,
    flag: &str,
    deadline: Option<std::time::Instant>,
) -> Result<Option<samara_nn::Network>, AppError> {
    match samara_nn::load_until(path, deadline) {
        Ok(n) => Ok(Some(n)),
        Err(e) if e.timed_out() => Ok(None),
        Err(e) => Err(AppError::Input(format!("{}{e}", flag_prefix(flag)))),
    }
}

/// Read a data set (CSV or IDX), naming the flag on failure.
pub fn read_data(path: &Path, flag: &str) -> Result<samara_nn::data::Table, AppError> {
    samara_nn::data::read_table(path)
        .map_err(|e| AppError::Input(format!("{}{e}", flag_prefix(flag))))
}

/// `flag` as the start of a message: `--network=` as is, any other followed by a space.
pub(crate) fn flag_prefix(flag: &str) -> String {
    if flag.ends_with('=') {
        flag.to_string()
    } else {
        format!("{flag} ")
    }
}

/// `--timeout` (the verify commands' whole-command limit) as a `Timeout`: a number of
/// seconds >= 0, `inf` for none.
pub fn timeout_flag(t: f64) -> Result<samara_num::Timeout, AppError> {
    samara_num::Timeout::from_secs_f64(t).map_err(|_| {
        AppError::Input(format!(
            "--timeout {t}: must be a number of seconds >= 0 (e.g. --timeout 60; inf for no limit)"
        ))
    })
}

/// A number as messages show it: plain, or in exponent form when very large or small.
pub fn num(v: f64) -> String {
    let a = v.abs();
    if a != 0.0 && a.is_finite() && !(1e-4..1e7).contains(&a) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// The horizon and the control period of a closed-loop run: positive finite numbers,
/// the period in [[`MIN_PERIOD`], [`MAX_PERIOD`]].
pub fn check_horizon_period(front: Front, horizon: f64, period: f64) -> Result<(), AppError> {
    let (h, p) = (front.arg("horizon"), front.arg("period"));
    if !(horizon.is_finite() && horizon > 0.0) {
        return input(format!(
            "{h} {}: the horizon must be positive (e.g. {})",
            num(horizon),
            front.eg("horizon", "20")
        ));
    }
    if !(period.is_finite() && period > 0.0) {
        return input(format!(
            "{p} {}: the period must be positive (e.g. {})",
            num(period),
            front.eg("period", "0.5")
        ));
    }
    if !(MIN_PERIOD..=MAX_PERIOD).contains(&period) {
        return input(format!(
            "{p} {}: the control period must lie in [{MIN_PERIOD}, {MAX_PERIOD}] (a hold shorter than 1 ms or longer than 100 time units is outside what the model and integrators are meant for); e.g. {}",
            num(period),
            front.eg("period", "0.5")
        ));
    }
    Ok(())
}

/// At most `max` control periods (`horizon / period`), and at least one.
pub fn check_period_count(
    front: Front,
    horizon: f64,
    period: f64,
    max: f64,
) -> Result<(), AppError> {
    let (h, p) = (front.arg("horizon"), front.arg("period"));
    let k = horizon / period;
    if k > max + 0.5 {
        return input(format!(
            "{h} {} / {p} {} = {} control periods; at most {max} are allowed (time and memory grow with every period; the published run has 40): pass a shorter {h} or a longer {p}",
            num(horizon),
            num(period),
            num(k)
        ));
    }
    if k < 0.5 {
        return input(format!(
            "{h} {} is shorter than one {p} {}: the horizon must be a positive multiple of the period (e.g. {})",
            num(horizon),
            num(period),
            front.eg("horizon", "20")
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::Front;

    #[test]
    fn python_words_name_keyword_arguments_instead_of_flags() {
        let m = "R^2 on the training rows is 0.5, below the required 0.9 (--min-r2); --epochs 0 is out of range; time limit reached (raise --timeout)";
        assert_eq!(
            Front::Python.words(m),
            "R^2 on the training rows is 0.5, below the required 0.9 (min_r2); epochs 0 is out of range; time limit reached (raise timeout)"
        );
        assert_eq!(Front::Cli.words(m), m);
        // Not a flag: a negative number, a dash inside a word, an em dash, a lone `--`.
        for keep in ["x in [-1, 2]", "a--b", "range 1 -- 2", "Gödel — --", "ε--"] {
            assert_eq!(Front::Python.words(keep), keep);
        }
    }
}

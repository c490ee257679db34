//! Proving the instances of a spec's properties and the critical value of a parameter,
//! as typed results.

use crate::bind::Loaded;
use crate::{input, AppError, Reason};
use samara_spec::normal::{Goal, Query, Sense};
use samara_spec::Instance;
use samara_verify::point::Point;
use samara_verify::{
    left_after, optimise, prove, vacuity, Prepared, Settings, Timeout, UnknownReason, Verdict,
};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::time::Instant;

/// The values of one network call at a point, by the spec's variable names, in the
/// spec's units (the declared normalisation undone).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct NamedValues {
    /// The network's name in the spec.
    pub network: String,
    /// Input and output values by name.
    pub values: BTreeMap<String, f64>,
}

/// A point of query `q` by the spec's names, one entry per network call.
pub fn named_point(l: &Loaded, q: &Query, p: &Point) -> Vec<NamedValues> {
    let mut apps = Vec::new();
    for (ai, app) in q.applications.iter().enumerate() {
        let Some(nd) = l.spec.networks.iter().find(|n| n.name == app.network) else {
            continue;
        };
        let mut m = BTreeMap::new();
        for (k, name) in nd.inputs.iter().enumerate() {
            let (c, s) = nd.input_map(k);
            m.insert(name.clone(), c + s * p.inputs[ai][k]);
        }
        for (k, name) in nd.outputs.iter().enumerate() {
            let (c, s) = nd.output_map(k);
            m.insert(name.clone(), c + s * p.outputs[ai][k]);
        }
        apps.push(NamedValues {
            network: app.network.clone(),
            values: m,
        });
    }
    apps
}

/// The verdict word of a row.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum VerdictTag {
    /// The property holds on the instance.
    Proved,
    /// A concrete, re-evaluated counterexample exists.
    Violated,
    /// Not settled (see the reason).
    Unknown,
}

impl VerdictTag {
    /// `proved`, `violated` or `unknown`.
    pub fn text(self) -> &'static str {
        match self {
            VerdictTag::Proved => "proved",
            VerdictTag::Violated => "violated",
            VerdictTag::Unknown => "unknown",
        }
    }
}

/// The `counterexample` field of a row: the point of a violated instance, or (kept for
/// the `--json` format) the reason of an unknown one.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum RowCounterexample {
    /// A violated instance's point.
    Point {
        /// The point by the spec's names.
        point: Vec<NamedValues>,
        /// Worst constraint value there (< 0 strictly inside the counterexample region).
        #[serde(with = "crate::nan_as_null")]
        margin: f64,
        /// Whether exact rational arithmetic confirmed it (`null`: not needed).
        exact_check: Option<bool>,
    },
    /// An unknown instance's reason text.
    Reason {
        /// The reason's message.
        reason: String,
    },
}

/// One instance's verdict: a row of `samara verify --json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct VerdictRow {
    /// The instance's label (`p1`, `p5[17]`).
    pub property: String,
    /// `proved`, `violated` or `unknown`.
    pub verdict: VerdictTag,
    /// The counterexample (violated) or the reason text (unknown).
    pub counterexample: Option<RowCounterexample>,
    /// Wall time of the instance's search.
    pub seconds: f64,
    /// Proved only because no point of the domain meets the premise.
    pub vacuous: bool,
    /// Why it is vacuous.
    pub vacuity: Option<String>,
    /// Why it is unknown.
    pub unknown_reason: Option<Reason>,
}

/// One property's instances, summarised.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PropertyRun {
    /// The property's name.
    pub name: String,
    /// Its instances' rows.
    pub rows: Vec<VerdictRow>,
    /// Wall time of its searches.
    pub seconds: f64,
    /// Labels of the instances proved only vacuously.
    pub vacuous: Vec<String>,
    /// Unknown instances by reason kind, in order of first appearance.
    pub unknown_kinds: Vec<(String, usize)>,
}

impl PropertyRun {
    /// How many instances have verdict `v`.
    pub fn count(&self, v: VerdictTag) -> usize {
        self.rows.iter().filter(|r| r.verdict == v).count()
    }
}

/// The result of [`run_verify`].
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct VerifyRun {
    /// The properties that ran, in the spec's order.
    pub properties: Vec<PropertyRun>,
    /// Properties not run because their data set is missing (messages naming the
    /// argument to pass).
    pub skipped: Vec<String>,
}

impl VerifyRun {
    /// Every instance's row, in order.
    pub fn rows(&self) -> impl Iterator<Item = &VerdictRow> {
        self.properties.iter().flat_map(|p| p.rows.iter())
    }

    /// Every instance proved (and none skipped).
    pub fn all_proved(&self) -> bool {
        self.skipped.is_empty() && self.rows().all(|r| r.verdict == VerdictTag::Proved)
    }
}

/// Prove every instance of `property` (or of all properties). `settings.timeout` is a
/// deadline for the whole call counted from `start`: every instance gets what is left
/// (an instance reached after it is `unknown` (timeout), never proved or violated).
/// A property whose data set is missing is an error when it was asked for by name or
/// `skip_missing` is false, else skipped ([`VerifyRun::skipped`]). `each` sees every
/// property when its instances are done.
pub fn run_verify(
    l: &Loaded,
    property: Option<&str>,
    settings: &Settings,
    start: Instant,
    skip_missing: bool,
    mut each: impl FnMut(&PropertyRun),
) -> Result<VerifyRun, AppError> {
    let names = l.selected(property);
    let mut run = VerifyRun::default();
    let mut lowered = Vec::new();
    for n in &names {
        if let Some(m) = l.missing_data(n) {
            if property.is_some() || !skip_missing {
                return input(m);
            }
            run.skipped.push(m);
            continue;
        }
        let inst = l
            .spec
            .lower_prove(n, &l.b)
            .map_err(|e| AppError::Input(e.to_string()))?;
        lowered.push((n.clone(), inst));
    }
    l.require_networks(
        &lowered
            .iter()
            .flat_map(|(_, v)| v.iter())
            .collect::<Vec<_>>(),
    )?;
    let prep = Prepared::new(&l.nets);
    // Deciding vacuity (is the premise empty over the domain?) is one root LP in
    // practice; it gets at most 10 s of what the deadline leaves (undecided: not called
    // vacuous).
    let vacuity_settings = || Settings {
        timeout: left_after(settings, start)
            .timeout
            .min(Timeout::from_secs(10)),
        ..*settings
    };
    for (name, inst) in &lowered {
        let t0 = Instant::now();
        let mut verdicts: Vec<(&Instance, Verdict, f64)> = Vec::new();
        for i in inst {
            let ti = Instant::now();
            let left = left_after(settings, start);
            let v = if !left.timeout.is_zero() {
                prove(&i.query, &prep, &left)?
            } else {
                Verdict::Unknown(UnknownReason::Timeout { nodes: 0 })
            };
            verdicts.push((i, v, ti.elapsed().as_secs_f64()));
        }
        let mut p = PropertyRun {
            name: name.clone(),
            rows: Vec::new(),
            seconds: t0.elapsed().as_secs_f64(),
            vacuous: Vec::new(),
            unknown_kinds: Vec::new(),
        };
        for (i, verdict, isecs) in &verdicts {
            let q = &i.query;
            let mut row = VerdictRow {
                property: i.label.clone(),
                verdict: VerdictTag::Proved,
                counterexample: None,
                seconds: *isecs,
                vacuous: false,
                vacuity: None,
                unknown_reason: None,
            };
            match verdict {
                Verdict::Proved => {
                    if let Some(why) = vacuity(q, &prep, &vacuity_settings())? {
                        p.vacuous.push(i.label.clone());
                        row.vacuous = true;
                        row.vacuity = Some(why);
                    }
                }
                Verdict::Violated(c) => {
                    row.verdict = VerdictTag::Violated;
                    row.counterexample = Some(RowCounterexample::Point {
                        point: named_point(l, q, &c.point),
                        margin: c.margin,
                        exact_check: c.exact,
                    });
                }
                Verdict::Unknown(r) => {
                    row.verdict = VerdictTag::Unknown;
                    match p.unknown_kinds.iter_mut().find(|k| k.0 == r.kind()) {
                        Some(k) => k.1 += 1,
                        None => p.unknown_kinds.push((r.kind().to_string(), 1)),
                    }
                    row.unknown_reason = Some(r.into());
                    row.counterexample = Some(RowCounterexample::Reason {
                        reason: r.to_string(),
                    });
                }
            }
            p.rows.push(row);
        }
        each(&p);
        run.properties.push(p);
    }
    Ok(run)
}

/// Where a property holds as a function of the searched parameter.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Holds {
    /// Above the threshold (the counterexamples end below it).
    Above,
    /// Below the threshold.
    Below,
    /// For every value in the declared range (no counterexample at all).
    Everywhere,
    /// For no value in the declared range.
    Nowhere,
    /// A search was cut short: no claim.
    Unknown,
}

impl Holds {
    /// The word of `--json`'s `holds`.
    pub fn text(self) -> &'static str {
        match self {
            Holds::Above => "above",
            Holds::Below => "below",
            Holds::Everywhere => "everywhere",
            Holds::Nowhere => "nowhere",
            Holds::Unknown => "unknown",
        }
    }
}

/// The critical value of a parameter: the document of `samara critical --json`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct CriticalValue {
    /// The property.
    pub property: String,
    /// The searched parameter.
    pub parameter: String,
    /// Where the property holds.
    pub holds: Holds,
    /// The parameter value at the best concrete witness of the chosen end.
    pub critical: Option<f64>,
    /// The search's sound bound at that end.
    pub bound: Option<f64>,
    /// The sound threshold (`above`/`below` only): the property is proved beyond it.
    pub threshold: Option<f64>,
    /// Witness value and bound agree to the gap.
    pub attained: bool,
    /// The critical value lies at the edge of what the domain reaches.
    pub vacuous: bool,
    /// The objective's extreme over the input domain alone.
    pub domain_extreme: Option<f64>,
    /// The counterexamples' parameter values lie in `[inf, sup]`.
    pub counterexample_range: [Option<f64>; 2],
    /// The chosen end's witness, by the spec's names.
    pub witness: Option<Vec<NamedValues>>,
    /// Both searches finished within their limits.
    pub complete: bool,
    /// Why not, if not.
    pub unknown_reason: Option<Reason>,
    /// Wall time of both searches.
    pub seconds: f64,
}

/// The critical value of parameter `param` for `property`, from both ends of the
/// counterexample set (a supremum and an infimum search sharing `settings.timeout`).
/// `holds` is `unknown` (with `unknown_reason`) when either search was cut short: no
/// claim is made from an incomplete search.
pub fn critical_value(
    l: &Loaded,
    property: &str,
    param: &str,
    settings: &Settings,
) -> Result<CriticalValue, AppError> {
    if let Some(m) = l.missing_data(property) {
        return input(m);
    }
    let inst = l
        .spec
        .lower_critical(property, param, &l.b)
        .map_err(|e| AppError::Input(e.to_string()))?;
    if inst.len() != 1 {
        return input(format!("critical values are computed for properties without data-set quantifiers; `{property}` has {} instances", inst.len()));
    }
    l.require_networks(&inst.iter().collect::<Vec<_>>())?;
    let prep = Prepared::new(&l.nets);
    let t0 = Instant::now();
    let q_max = inst[0].query.clone();
    let mut q_min = q_max.clone();
    if let Goal::Optimise { sense, .. } = &mut q_min.goal {
        *sense = Sense::Min;
    }
    // The timeout is a deadline for both searches together (the second gets what the
    // first left).
    let sup = optimise(&q_max, &prep, settings)?;
    // A complete supremum search without a counterexample shows that the set of
    // counterexamples (over the parameter's whole range) is empty: the infimum search
    // would search the same empty set (on generated Lipschitz networks where P1 holds
    // for every ystar, as long again as the first), so its answer is the same.
    let inf = if sup.unknown.is_none() && sup.value.is_none() {
        sup.clone()
    } else {
        optimise(&q_min, &prep, &left_after(settings, t0))?
    };
    let Some((lo, hi)) = l.spec.params[param].range else {
        return input(format!("parameter `{param}` has no range"));
    };
    let tol = 1e-9 * (1.0 + hi.abs().max(lo.abs()));
    let unknown = sup.unknown.clone().or(inf.unknown.clone());
    // Counterexamples exist for parameter values in [inf, sup] (within [lo, hi]); the
    // property holds above sup if sup is inside the range, else below inf if inf is,
    // else nowhere in the range. Only from complete searches.
    let (holds, chosen) = match (&unknown, inf.value, sup.value) {
        (Some(_), _, _) => (Holds::Unknown, None),
        (None, None, _) | (None, _, None) => (Holds::Everywhere, None),
        (None, _, Some(s)) if s < hi - tol => (Holds::Above, Some(&sup)),
        (None, Some(i), _) if i > lo + tol => (Holds::Below, Some(&inf)),
        _ => (Holds::Nowhere, Some(&inf)),
    };
    // The sound threshold: the property is proved beyond the search's bound (the
    // critical value lies between the witness value and it).
    let threshold = match holds {
        Holds::Above | Holds::Below => chosen.map(|c| c.bound),
        _ => None,
    };
    Ok(CriticalValue {
        property: property.to_string(),
        parameter: param.to_string(),
        holds,
        critical: chosen.and_then(|c| c.value),
        bound: chosen.map(|c| c.bound),
        threshold,
        attained: chosen.map(|c| c.attained).unwrap_or(false),
        vacuous: chosen.map(|c| c.vacuous).unwrap_or(false),
        domain_extreme: chosen.and_then(|c| c.domain_extreme),
        counterexample_range: [inf.value, sup.value],
        witness: chosen
            .and_then(|c| c.witness.as_ref())
            .map(|w| named_point(l, &q_max, w)),
        complete: unknown.is_none(),
        unknown_reason: unknown.as_ref().map(Reason::from),
        seconds: t0.elapsed().as_secs_f64(),
    })
}

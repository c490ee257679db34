//! `samara check`: a spec parsed, type-checked and every property lowered, as a report.

use crate::bind::Loaded;

/// What `samara check` found.
#[derive(Clone, Debug, PartialEq)]
pub struct CheckReport {
    /// The summary: the spec's counts, one line per network and per property.
    pub lines: Vec<String>,
    /// How many properties could not be lowered (their lines say `FAILED` and why).
    pub failed: usize,
}

impl CheckReport {
    /// The closing message when a property failed (exit 1), none otherwise.
    pub fn failure(&self) -> Option<String> {
        (self.failed > 0).then(|| {
            format!(
                "check failed: {} propert(ies) could not be lowered (see above)",
                self.failed
            )
        })
    }
}

/// Lower every property of the loaded spec (named `spec` in the report): its instances,
/// network calls and counterexample region, or why it cannot be lowered (a missing data
/// set, a lowering error with its hint).
pub fn check(l: &Loaded, spec: &str) -> CheckReport {
    let mut lines = vec![format!(
        "{spec}: {} network(s), {} parameter(s), {} propert(ies)",
        l.spec.networks.len(),
        l.spec.params.len(),
        l.spec.properties.len()
    )];
    for n in &l.spec.networks {
        lines.push(format!(
            "  network {}({}) -> ({})",
            n.name,
            n.inputs.join(", "),
            n.outputs.join(", ")
        ));
    }
    let mut failed = 0;
    for name in l.spec.property_names() {
        if let Some(m) = l.missing_data(name) {
            lines.push(format!("  property {name}: FAILED: {m}"));
            failed += 1;
            continue;
        }
        match l.spec.lower_prove(name, &l.b) {
            Ok(inst) => {
                let q = &inst[0].query;
                lines.push(format!(
                    "  property {name}: {} instance(s), {} network call(s), counterexample region of {} disjunct(s)",
                    inst.len(),
                    q.applications.len(),
                    q.region.len()
                ));
            }
            Err(e) => {
                lines.push(format!(
                    "  property {name}: FAILED: {} ({})",
                    e.message, e.hint
                ));
                failed += 1;
            }
        }
    }
    CheckReport { lines, failed }
}

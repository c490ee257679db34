//! The human lines of `samara verify` and `samara critical`: what the CLI prints when
//! `--json` is not given, made from the same typed results as the JSON.

use crate::verify::{PropertyRun, RowCounterexample, VerdictTag};
use crate::{CriticalValue, Holds};

impl PropertyRun {
    /// One line: the verdict of a single instance (with its counterexample, reason or
    /// vacuity) or the counts of several, and the wall time.
    pub fn human_line(&self) -> String {
        let (name, secs) = (&self.name, self.seconds);
        if let [last] = self.rows.as_slice() {
            let extra = match (&last.counterexample, &last.unknown_reason, &last.vacuity) {
                (Some(RowCounterexample::Point { point, .. }), _, _) => {
                    format!(
                        " counterexample {}",
                        serde_json::to_string(point).unwrap_or_default()
                    )
                }
                (_, Some(r), _) => format!(" ({}: {})", r.kind, r.message),
                (_, _, Some(why)) => format!(" VACUOUS: {why}"),
                _ => String::new(),
            };
            return format!("{name:<16} {:<9} {secs:>8.3} s{extra}", last.verdict.text());
        }
        let kinds: Vec<String> = self
            .unknown_kinds
            .iter()
            .map(|(k, n)| format!("{k}: {n}"))
            .collect();
        format!(
            "{name:<16} {} instances: {} proved{}, {} violated, {} unknown{}  {secs:>8.3} s",
            self.rows.len(),
            self.count(VerdictTag::Proved),
            if self.vacuous.is_empty() {
                String::new()
            } else {
                format!(" ({} vacuously)", self.vacuous.len())
            },
            self.count(VerdictTag::Violated),
            self.count(VerdictTag::Unknown),
            if kinds.is_empty() {
                String::new()
            } else {
                format!(" ({})", kinds.join(", "))
            }
        )
    }

    /// The warning when instances were proved only vacuously (the network was never
    /// checked there), naming at most five of them.
    pub fn vacuity_warning(&self) -> Option<String> {
        if self.vacuous.is_empty() {
            return None;
        }
        Some(format!(
            "warning: {}: {} instance(s) proved only vacuously ({}): no point of the input domain meets the premise there (or a data point outside the declared domain has its ball clipped away), so the network was never checked; `samara robustness` evaluates the whole ball of a data point",
            self.name,
            self.vacuous.len(),
            self.vacuous.iter().take(5).cloned().collect::<Vec<_>>().join(", ")
        ))
    }
}

impl CriticalValue {
    /// One line: where `property` holds as a function of the parameter `of`, the sound
    /// threshold and whether it is attained, or why there is no claim.
    pub fn human_line(&self, property: &str, of: &str) -> String {
        let v = self;
        match (v.holds, v.critical) {
            (Holds::Unknown, _) => {
                let (kind, message) = v
                    .unknown_reason
                    .as_ref()
                    .map_or(("", ""), |r| (r.kind.as_str(), r.message.as_str()));
                format!("{property}: unknown ({kind}: {message}); no claim about {of}")
            }
            (Holds::Everywhere, _) => format!("{property}: holds for every {of} in its range"),
            (Holds::Nowhere, Some(c)) => format!(
                "{property}: fails for every {of} in its declared range (counterexamples from {of} = {c:.3e} up){}",
                if v.vacuous {
                    "; VACUOUS: it holds only where the precondition is empty"
                } else {
                    ""
                }
            ),
            (h @ (Holds::Above | Holds::Below), Some(c)) => {
                let t = v.threshold.unwrap_or(c);
                format!(
                    "{property}: holds for {of} {} {t:.9}{}{}  ({:.3} s)",
                    if h == Holds::Above { ">" } else { "<" },
                    if v.attained {
                        String::new()
                    } else {
                        format!(" (sound bound; the critical value lies between {c:.9} and it, not attained)")
                    },
                    if v.vacuous { "  VACUOUS: the precondition is empty there" } else { "" },
                    v.seconds
                )
            }
            _ => format!(
                "{property}: {}",
                serde_json::to_value(v).map(|j| j.to_string()).unwrap_or_default()
            ),
        }
    }
}

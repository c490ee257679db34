//! The one answer vocabulary of samara's questions.
//!
//! Every exact question samara answers (a VNN-LIB query in `samara-bounds`, a spec
//! property in `samara-verify`, a smooth-network search) ends in one of three ways: the
//! property is **proved**, it is **violated** by a concrete witness, or the answer is
//! **unknown** for a stated reason. [`Outcome`] is that answer, generic over what a
//! witness and a reason are in each engine, so the engines share one vocabulary and one
//! set of names (`proved`, `violated`, `unknown`) instead of five enums with their own.
//! Reachability adds a fourth status, no goal stated; [`Status`] names all four and is
//! what reports and JSON documents print.

/// The answer to an exact question: proved, violated with a witness `W`, or unknown with
/// a reason `R`.
#[derive(Clone, Debug, PartialEq)]
pub enum Outcome<W, R> {
    /// No counterexample exists: the property holds.
    Proved,
    /// A concrete counterexample (re-evaluated by the engine that reports it).
    Violated(W),
    /// Not settled, with the reason.
    Unknown(R),
}

impl<W, R> Outcome<W, R> {
    /// The status this answer has.
    pub fn status(&self) -> Status {
        match self {
            Outcome::Proved => Status::Proved,
            Outcome::Violated(_) => Status::Violated,
            Outcome::Unknown(_) => Status::Unknown,
        }
    }

    /// The witness, if the property is violated.
    pub fn witness(&self) -> Option<&W> {
        match self {
            Outcome::Violated(w) => Some(w),
            _ => None,
        }
    }

    /// The reason, if the answer is unknown.
    pub fn reason(&self) -> Option<&R> {
        match self {
            Outcome::Unknown(r) => Some(r),
            _ => None,
        }
    }

    /// The same answer with the witness mapped (an engine's witness lifted into its
    /// caller's terms).
    pub fn map_witness<V>(self, f: impl FnOnce(W) -> V) -> Outcome<V, R> {
        match self {
            Outcome::Proved => Outcome::Proved,
            Outcome::Violated(w) => Outcome::Violated(f(w)),
            Outcome::Unknown(r) => Outcome::Unknown(r),
        }
    }

    /// The same answer with the reason mapped.
    pub fn map_reason<S>(self, f: impl FnOnce(R) -> S) -> Outcome<W, S> {
        match self {
            Outcome::Proved => Outcome::Proved,
            Outcome::Violated(w) => Outcome::Violated(w),
            Outcome::Unknown(r) => Outcome::Unknown(f(r)),
        }
    }
}

/// The status of an answer, without its witness or reason: what reports print.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Status {
    /// The property holds.
    Proved,
    /// A concrete counterexample exists.
    Violated,
    /// Not settled.
    Unknown,
    /// No goal was stated, so nothing was asked (reachability without a goal).
    NoGoal,
}

impl Status {
    /// The status's name in every report and JSON document: `proved`, `violated`,
    /// `unknown` or `none`.
    pub fn name(self) -> &'static str {
        match self {
            Status::Proved => "proved",
            Status::Violated => "violated",
            Status::Unknown => "unknown",
            Status::NoGoal => "none",
        }
    }
}

impl std::fmt::Display for Status {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn answers_map_and_name_their_status() {
        let v: Outcome<u8, &str> = Outcome::Violated(3);
        assert_eq!(v.status(), Status::Violated);
        assert_eq!(v.witness(), Some(&3));
        assert_eq!(v.clone().map_witness(|w| w * 2), Outcome::Violated(6));
        let u: Outcome<u8, &str> = Outcome::Unknown("timeout");
        assert_eq!(u.reason(), Some(&"timeout"));
        assert_eq!(u.map_reason(str::len), Outcome::Unknown(7));
        assert_eq!(Outcome::<u8, u8>::Proved.status().name(), "proved");
        assert_eq!(Status::NoGoal.to_string(), "none");
    }
}

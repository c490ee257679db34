//! [`Timeout`]: the one time-limit type of samara's settings (verify, bounds, the
//! application layer), replacing bare seconds as `f64` (where `inf` meant "none"),
//! `Option<Duration>` and `Option<f64>`. A limit is either none or a finite duration; it
//! becomes a deadline when the work starts, and serialises as seconds (`null` for none,
//! since JSON has no infinity).

use serde::{Deserialize, Deserializer, Serialize, Serializer};
use std::time::{Duration, Instant};

/// The largest limit kept, in seconds (about 31 years): longer finite limits are
/// clamped to it, so that `Instant + limit` never overflows.
pub const MAX_SECS: f64 = 1e9;

/// A time limit: none, or a finite non-negative duration.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct Timeout(Option<Duration>);

/// A number of seconds that is not a time limit (NaN or negative).
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error("{0}: must be a number of seconds >= 0 (inf for no limit)")]
pub struct BadTimeout(pub f64);

impl Timeout {
    /// No time limit.
    pub const fn none() -> Self {
        Timeout(None)
    }

    /// A limit of `d`.
    pub const fn from_duration(d: Duration) -> Self {
        Timeout(Some(d))
    }

    /// A limit of `secs` whole seconds (defaults and tests: `Timeout::from_secs(60)`).
    pub const fn from_secs(secs: u64) -> Self {
        Timeout(Some(Duration::from_secs(secs)))
    }

    /// A limit of `secs` seconds: `inf` is none, finite values above `MAX_SECS` are
    /// clamped to it; NaN and negative numbers are refused.
    pub fn from_secs_f64(secs: f64) -> Result<Self, BadTimeout> {
        if secs.is_nan() || secs < 0.0 {
            return Err(BadTimeout(secs));
        }
        if secs.is_infinite() {
            return Ok(Timeout(None));
        }
        Ok(Timeout(Some(Duration::from_secs_f64(secs.min(MAX_SECS)))))
    }

    /// Whether there is no limit.
    pub fn is_none(self) -> bool {
        self.0.is_none()
    }

    /// Whether the limit is zero: no time at all (what [`Timeout::left`] gives once a
    /// limit is spent). None is not zero.
    pub fn is_zero(self) -> bool {
        self.0 == Some(Duration::ZERO)
    }

    /// The limit as a duration (`None`: no limit).
    pub fn duration(self) -> Option<Duration> {
        self.0
    }

    /// The limit in seconds, `inf` for none.
    pub fn secs(self) -> f64 {
        self.0.map_or(f64::INFINITY, |d| d.as_secs_f64())
    }

    /// The deadline of work that starts now (`None`: no limit).
    pub fn deadline(self) -> Option<Instant> {
        self.deadline_from(Instant::now())
    }

    /// The deadline of work that started at `start` (`None`: no limit).
    pub fn deadline_from(self, start: Instant) -> Option<Instant> {
        self.0.map(|d| start + d)
    }

    /// What is left of the limit at `now` of work that started at `start` (zero once
    /// spent; none stays none).
    pub fn left_at(self, start: Instant, now: Instant) -> Timeout {
        Timeout(
            self.0
                .map(|d| d.saturating_sub(now.saturating_duration_since(start))),
        )
    }

    /// What is left of the limit now, of work that started at `start`.
    pub fn left(self, start: Instant) -> Timeout {
        self.left_at(start, Instant::now())
    }

    /// Whether the limit is spent at `now` for work that started at `start`.
    pub fn expired(self, start: Instant, now: Instant) -> bool {
        self.0
            .is_some_and(|d| now.saturating_duration_since(start) >= d)
    }

    /// The smaller of two limits (none is the largest).
    pub fn min(self, other: Timeout) -> Timeout {
        match (self.0, other.0) {
            (Some(a), Some(b)) => Timeout(Some(a.min(b))),
            (a, b) => Timeout(a.or(b)),
        }
    }
}

impl From<Option<Duration>> for Timeout {
    fn from(d: Option<Duration>) -> Self {
        Timeout(d)
    }
}

impl Serialize for Timeout {
    /// Seconds as a number; `null` for no limit.
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        match self.0 {
            Some(d) => s.serialize_f64(d.as_secs_f64()),
            None => s.serialize_none(),
        }
    }
}

impl<'de> Deserialize<'de> for Timeout {
    /// Seconds (`null` or `inf`: no limit); NaN and negative numbers are refused.
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        match Option::<f64>::deserialize(d)? {
            None => Ok(Timeout(None)),
            Some(x) => Timeout::from_secs_f64(x).map_err(serde::de::Error::custom),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seconds_infinity_and_bad_numbers() {
        assert!(Timeout::from_secs_f64(f64::INFINITY).unwrap().is_none());
        assert_eq!(Timeout::from_secs_f64(2.5).unwrap().secs(), 2.5);
        assert_eq!(Timeout::from_secs_f64(0.0).unwrap().secs(), 0.0);
        assert_eq!(Timeout::from_secs_f64(1e300).unwrap().secs(), MAX_SECS);
        assert!(Timeout::from_secs_f64(f64::NAN).is_err());
        assert!(Timeout::from_secs_f64(-1.0).is_err());
        assert_eq!(Timeout::none().secs(), f64::INFINITY);
        assert_eq!(Timeout::from_secs(3).secs(), 3.0);
        assert!(Timeout::from_secs(0).is_zero());
        assert!(!Timeout::none().is_zero() && !Timeout::from_secs(1).is_zero());
    }

    #[test]
    fn deadlines_and_what_is_left() {
        let t0 = Instant::now();
        let t = Timeout::from_secs_f64(2.0).unwrap();
        assert_eq!(t.deadline_from(t0), Some(t0 + Duration::from_secs(2)));
        assert_eq!(Timeout::none().deadline_from(t0), None);
        let later = t0 + Duration::from_millis(500);
        assert_eq!(t.left_at(t0, later).secs(), 1.5);
        assert_eq!(t.left_at(t0, t0 + Duration::from_secs(3)).secs(), 0.0);
        assert!(t.expired(t0, t0 + Duration::from_secs(2)));
        assert!(!t.expired(t0, later));
        assert!(!Timeout::none().expired(t0, t0 + Duration::from_secs(1 << 40)));
        assert_eq!(t.min(Timeout::none()), t);
        assert_eq!(Timeout::none().min(t), t);
    }

    #[test]
    fn serde_is_seconds_and_null_for_none() {
        let t = Timeout::from_secs_f64(1.25).unwrap();
        assert_eq!(serde_json::to_string(&t).unwrap(), "1.25");
        assert_eq!(serde_json::to_string(&Timeout::none()).unwrap(), "null");
        assert_eq!(serde_json::from_str::<Timeout>("1.25").unwrap(), t);
        assert!(serde_json::from_str::<Timeout>("null").unwrap().is_none());
        assert!(serde_json::from_str::<Timeout>("-3").is_err());
    }
}

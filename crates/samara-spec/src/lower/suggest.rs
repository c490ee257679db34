//! "Did you mean" suggestions: the nearest name by edit distance.

pub use samara_text::levenshtein;

/// The closest candidate to `name`, for "did you mean" hints.
pub fn nearest<'a>(name: &str, candidates: impl IntoIterator<Item = &'a str>) -> Option<&'a str> {
    // Long names get no suggestion: the distance costs the product of the lengths.
    if name.len() > 128 {
        return None;
    }
    candidates
        .into_iter()
        .filter(|c| c.len() <= 128)
        .map(|c| (levenshtein(name, c), c))
        .filter(|(d, c)| *d <= 2.max(c.len() / 3))
        .min_by_key(|(d, _)| *d)
        .map(|(_, c)| c)
}

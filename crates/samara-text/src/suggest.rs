//! Edit distance, for "did you mean" suggestions in both languages.

/// Levenshtein's edit distance between two names, in characters (the classic two-row
/// dynamic programme); shared with the system language's suggestions.
pub fn levenshtein(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut cur = vec![i + 1];
        for (j, cb) in b.iter().enumerate() {
            cur.push(
                (prev[j] + usize::from(ca != *cb))
                    .min(prev[j + 1] + 1)
                    .min(cur[j] + 1),
            );
        }
        prev = cur;
    }
    prev[b.len()]
}

#[cfg(test)]
mod tests {
    use super::levenshtein;

    #[test]
    fn textbook_distances() {
        // The textbook example (kitten -> sitting: two substitutions, one insertion).
        assert_eq!(levenshtein("kitten", "sitting"), 3);
        assert_eq!(levenshtein("", "abc"), 3);
        assert_eq!(levenshtein("abc", ""), 3);
        assert_eq!(levenshtein("theta", "theta"), 0);
        // Characters, not bytes.
        assert_eq!(levenshtein("ω", "w"), 1);
    }
}

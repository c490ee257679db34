//! The line scanner and number literals of both line-based languages.

/// The line scanner of both line-based languages (the property language here, the
/// system language in `samara-system`): for each line of `src`, skips white space, stops
/// at a `#` comment or at a `\` that ends the line (a continuation), and hands every
/// other place to `token` (with `state`, the line's index, the line, its characters and
/// the place's index), which returns the index after the token it read; then calls
/// `line_end` (with `state`, the line's index, its length in characters and whether it
/// continues on the next line). Returns the number of lines.
pub fn scan_lines<S, E>(
    src: &str,
    state: &mut S,
    mut token: impl FnMut(&mut S, usize, &str, &[char], usize) -> Result<usize, E>,
    mut line_end: impl FnMut(&mut S, usize, usize, bool),
) -> Result<usize, E> {
    let mut n_lines = 0;
    for (li, line) in src.lines().enumerate() {
        let chars: Vec<char> = line.chars().collect();
        let mut i = 0;
        let mut continued = false;
        while i < chars.len() {
            let c = chars[i];
            if c == '#' {
                break;
            }
            if c.is_whitespace() {
                i += 1;
                continue;
            }
            if c == '\\' && chars[i + 1..].iter().all(|c| c.is_whitespace()) {
                continued = true;
                break;
            }
            i = token(state, li, line, &chars, i)?;
        }
        line_end(state, li, chars.len(), continued);
        n_lines = li + 1;
    }
    Ok(n_lines)
}

/// The end of the number literal that starts at `chars[start]` (a digit, or a `.` before
/// one): digits and dots, then an exponent (`e` or `E`, an optional sign, digits) when
/// digits follow the `e`.
pub fn number_end(chars: &[char], start: usize) -> usize {
    let mut i = start;
    while i < chars.len() && (chars[i].is_ascii_digit() || chars[i] == '.') {
        i += 1;
    }
    if i < chars.len() && (chars[i] == 'e' || chars[i] == 'E') {
        let mut j = i + 1;
        if j < chars.len() && (chars[j] == '+' || chars[j] == '-') {
            j += 1;
        }
        if j < chars.len() && chars[j].is_ascii_digit() {
            i = j;
            while i < chars.len() && chars[i].is_ascii_digit() {
                i += 1;
            }
        }
    }
    i
}

#[cfg(test)]
mod tests {
    use super::*;

    fn end(s: &str) -> usize {
        let c: Vec<char> = s.chars().collect();
        number_end(&c, 0)
    }

    #[test]
    fn number_literals_take_their_exponent_only_when_digits_follow() {
        assert_eq!(end("12.5 + x"), 4);
        assert_eq!(end("1e-3*y"), 4);
        assert_eq!(end("2E+10"), 5);
        assert_eq!(end("3e"), 1);
        assert_eq!(end("3e-x"), 1);
        assert_eq!(end(".5"), 2);
    }

    #[test]
    fn lines_skip_comments_and_continuations() {
        let src = "a b # c\n  d \\\ne\n";
        let mut seen = Vec::new();
        let n = scan_lines::<_, ()>(
            src,
            &mut seen,
            |seen, li, _, chars, i| {
                seen.push(format!("{li}:{}", chars[i]));
                Ok(i + 1)
            },
            |seen, li, len, cont| seen.push(format!("end {li} {len} {cont}")),
        )
        .unwrap();
        assert_eq!(n, 3);
        assert_eq!(
            seen,
            [
                "0:a",
                "0:b",
                "end 0 7 false",
                "1:d",
                "end 1 5 true",
                "2:e",
                "end 2 1 false"
            ]
        );
    }
}

//! Text read from files and options: numbers ([`parse_number`]), lines ([`split_lines`])
//! and how messages quote it ([`escaped`], [`quoted`]). A leaf module: the profile
//! loaders, [`crate::io`]'s JSON reader, the angle grids and the CLI all read numbers here,
//! so they agree on what one is.

/// `t` (text from a file) with control characters, a byte-order mark and other invisible
/// characters escaped as Rust writes them (`\0`, `\u{feff}`), so a message echoing it
/// shows what the file holds (a mid-line BOM made `'0' is not a number` look absurd).
pub(crate) fn escaped(t: &str) -> String {
    let mut out = String::with_capacity(t.len());
    for c in t.chars() {
        match c {
            // Printable, and escape_debug would backslash them.
            '\'' | '"' | '\\' => out.push(c),
            _ => out.extend(c.escape_debug()),
        }
    }
    out
}

/// `t` from a file as messages quote it: `'...'`, [`escaped`], cut after
/// [`QUOTE_MAX_CHARS`] characters (a 10 MB cell was echoed whole) with its length said.
pub(crate) fn quoted(t: &str) -> String {
    match cut_at(t, QUOTE_MAX_CHARS) {
        (head, Some(n)) => format!("'{}...' ({n} characters)", escaped(head)),
        (_, None) => format!("'{}'", escaped(t)),
    }
}

/// `t` [`escaped`], cut after `max` characters with `...` and its length in characters.
pub(crate) fn cut_text(t: &str, max: usize) -> String {
    match cut_at(t, max) {
        (head, Some(n)) => format!("{}... ({n} characters)", escaped(head)),
        (_, None) => escaped(t),
    }
}

/// The first `max` characters of `t` and, when that cuts it, its length in characters.
fn cut_at(t: &str, max: usize) -> (&str, Option<usize>) {
    match t.char_indices().nth(max) {
        Some((cut, _)) => (&t[..cut], Some(t.chars().count())),
        None => (t, None),
    }
}

/// Characters of a file's text a message quotes before cutting it ([`quoted`]).
const QUOTE_MAX_CHARS: usize = 80;

/// A number as a text file writes it (trimmed): Rust's f64 syntax, `nan` and `inf` in any
/// case included. `Err` is a message for the caller to place: not a number, or a nonzero
/// number below the f64 range (`1e-400`), which would read as 0 (a silently invalid
/// value, a zero sigma); its twin above the range (`1e400`) reads as infinite and each
/// field's check refuses it.
pub(crate) fn parse_number(t: &str) -> std::result::Result<f64, String> {
    let v: f64 = t
        .parse()
        .map_err(|_| format!("{} is not a number", quoted(t)))?;
    let mantissa = t.split(['e', 'E']).next().unwrap_or("");
    if v == 0.0 && mantissa.bytes().any(|b| (b'1'..=b'9').contains(&b)) {
        return Err(format!(
            "{} is below the f64 range (about 5e-324) and would read as 0; write 0 if it \
             is a zero",
            quoted(t)
        ));
    }
    Ok(v)
}

/// Split text into lines at `\n`, `\r\n` or a lone `\r` (old Mac and some instrument
/// exports end lines with CR only), so every text reader numbers lines alike and a CR-only
/// file is not one long line. The line breaks are not part of the lines.
pub(crate) fn split_lines(bytes: &[u8]) -> impl Iterator<Item = &[u8]> {
    let mut rest = Some(bytes);
    std::iter::from_fn(move || {
        let r = rest?;
        match r.iter().position(|b| *b == b'\n' || *b == b'\r') {
            None => {
                rest = None;
                Some(r)
            }
            Some(i) => {
                let crlf = r[i] == b'\r' && r.get(i + 1) == Some(&b'\n');
                rest = Some(&r[i + 1 + usize::from(crlf)..]);
                Some(&r[..i])
            }
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_split_at_lf_crlf_and_lone_cr() {
        let lines: Vec<&[u8]> = split_lines(b"a\nb\r\nc\rd\r\re\n").collect();
        let want: Vec<&[u8]> = vec![b"a", b"b", b"c", b"d", b"", b"e", b""];
        assert_eq!(lines, want);
        assert_eq!(split_lines(b"").count(), 1);
    }
}

//! What metadata says of the data's origin: the `synthetic` label rules shared by the
//! profile headers of every format and a species folder's `metadata.json`.

use crate::text::quoted;

/// What a metadata entry says of the data's origin (shared by profile headers and a
/// species folder's `metadata.json`): `synthetic` (any case) set to true/yes/1 is
/// `Some(true)`, to false/no/0 `Some(false)`; a `source` (any case) mentioning "synthetic"
/// or "simulat" (simulated, simulation: DATA.md's word) is `Some(true)`; else `None`.
pub fn says_synthetic(key: &str, value: &str) -> Option<bool> {
    let v = value.trim().to_ascii_lowercase();
    if key.trim().eq_ignore_ascii_case("synthetic") {
        match v.as_str() {
            "true" | "yes" | "1" => Some(true),
            "false" | "no" | "0" => Some(false),
            _ => None,
        }
    } else if key.trim().eq_ignore_ascii_case("source")
        && (v.contains("synthetic") || v.contains("simulat"))
    {
        Some(true)
    } else {
        None
    }
}

/// A `synthetic` entry (any case) whose value [`says_synthetic`] does not understand is
/// an error: the label is what keeps synthetic data from being reported as measured, so
/// "true # simulated" or "maybe" must not read as no label at all.
pub(crate) fn check_synthetic_label(key: &str, value: &str) -> std::result::Result<(), String> {
    if key.trim().eq_ignore_ascii_case("synthetic") && says_synthetic(key, value).is_none() {
        return Err(format!(
            "{} is not a value of 'synthetic' that furfit reads (true, yes, 1 or false, \
             no, 0, in any case, and nothing else after it)",
            quoted(value.trim())
        ));
    }
    Ok(())
}

/// The note for a metadata entry `key` on `line` whose text was not valid UTF-8 (a Latin-1
/// lab name, say): it is kept with U+FFFD in place of the bad bytes, which the user should
/// know before that text lands in a fit file (audit, 2026-12-02). Data lines that are not
/// UTF-8 are errors; a comment is not data, so it does not stop the load.
pub(crate) fn non_utf8_metadata_note(line: usize, key: &str) -> String {
    format!(
        "line {line}: metadata '{key}' is not valid UTF-8 (Latin-1?); its bad bytes are kept \
         as U+FFFD (save the file as UTF-8 to keep the text)"
    )
}

/// The loader note for a `#` comment on `line` that is not a `key: value` entry but
/// mentions "synthetic" (e.g. `# synthetic=true`): it labels nothing, and the reader
/// should know why the data then read as measured.
pub(crate) fn unlabelled_synthetic_note(line: usize, comment: &str) -> Option<String> {
    comment.to_ascii_lowercase().contains("synthetic").then(|| {
        format!(
            "line {line}: the comment '#{}' mentions synthetic but is no '# synthetic: true' \
             entry, so it labels nothing",
            comment.trim_end()
        )
    })
}

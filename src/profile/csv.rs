//! The DATA.md CSV profile format: reader and writer.
//!
//! # Reading
//! - Each record is one line: a quoted field may not span lines, and a quote left open is
//!   an error naming its line and column. Lines end in `\n`, `\r\n` or a lone `\r`
//!   (old Mac / instrument exports); line numbers count any of them.
//! - Lines before the header that start with `#` are metadata `# key: value` (split at the
//!   first `:`, both sides trimmed), kept in file order. A `#` line without a `:` or with
//!   an empty key is a free comment and ignored. Blank lines and `#` lines are tolerated
//!   anywhere (after the header they are comments), and so are rows holding only commas
//!   (a spreadsheet's padding, e.g. `,,,`), counted in a note.
//! - A first line `sep=,` (Excel's separator declaration) is skipped; `sep=` with any
//!   other separator is an error. The separator is always a comma: a missing-column error
//!   on a header that holds `;` or a tab says so.
//! - The first other line is the header. Column names are trimmed and matched
//!   case-insensitively; any order. Required: `theta_i, theta_r, phi, value`; optional:
//!   `sigma, channel, phi_i`; any other column is ignored (its cells are never parsed).
//!   A known column named twice is an error.
//! - Angles: `theta_i`, `theta_r` in [-90, 90], `phi` in [-360, 360] degrees, finite.
//!   phi is wrapped to MODEL.md's (-180, 180] as every reader does ([`super::read_phi`]:
//!   `-180` is read as `180`, `270` as `-90`; a phi already in (-180, 180] is kept as
//!   written) and `-0` as `0`, so a grid has one spelling per direction. The convention
//!   options of [`LoadOptions`] apply as each row is read ([`parse_with`]).
//! - `value`: empty, `nan` (any case), or `<= 0` gives an *invalid* sample, kept and counted
//!   ([`Profile::n_invalid`]). An infinite value is an error (it is not a measurement).
//! - `sigma`: empty or `nan` means "no sigma"; otherwise finite and `>= 0`.
//! - `phi_i`: empty or `nan` means none (as NaN does in an npz); otherwise a finite angle in
//!   [-360, 360] degrees, as phi (kept as written: it is only carried for round trips).
//! - A nonzero number below the f64 range (`1e-400`) is an error, as one above it (`1e400`)
//!   is for a value or an angle: read as 0 it would silently make an invalid sample.
//! - The value/sigma/phi_i rules are [`super::check_measured`], shared with the npz reader.
//! - `channel`: any non-empty text (trimmed; an empty cell is an error); channels are
//!   numbered in order of first appearance.
//!   Without a `channel` column the profile has one unnamed channel.
//! - Two rows with the same `(theta_i, theta_r, phi, channel)`: if every other field is
//!   identical (NaN equal to NaN) the repeat is dropped and a note says how many were
//!   collapsed (concatenated files are common and harmless); any difference is an error
//!   naming both lines (on the phi column, saying so, when the two phi differ as written
//!   and only wrap alike, e.g. a sweep's 0 and 360).
//! - Errors name the file, the 1-based line and the column (number and name): a non-number,
//!   a non-finite or out-of-range angle, a missing required column, a row with the wrong
//!   number of fields, a conflicting duplicate. An empty file (no header) or a header with
//!   no rows is an error naming the file.
//!
//! # Writing
//! Metadata as `# key: value` lines, then the header `theta_i,theta_r,phi,value` plus
//! `sigma` (if any sample has one), `channel` (if the profile names its channels) and
//! `phi_i` (if any sample has one), then one row per sample in the profile's order.
//! Numbers use Rust's shortest round-trip formatting (`Display`, or `LowerExp` for very
//! large or small magnitudes), so every finite f64 reads back bit for bit; NaN is written
//! as `nan`, a missing sigma/phi_i as an empty cell. Metadata keys may not contain `:` or
//! line breaks and values may not contain line breaks (an error, not a silent edit).

use super::checks::{check_angle, check_channel_name, check_measured, convert_theta_r, read_phi};
use super::merge::dedupe_rows;
use super::sample::{Field, Layout, LoadOptions, Origin, Profile, Sample};
use crate::error::{Error, Result};
use crate::text::{escaped, parse_number, split_lines};
use std::path::Path;

/// Parse CSV bytes without convention options; `path` is used in error messages only.
/// Returns the profile and notes.
pub fn parse(bytes: &[u8], path: &Path) -> Result<(Profile, Vec<String>)> {
    parse_with(bytes, path, &LoadOptions::default())
}

/// [`parse`] with the convention options of `opts` (`flip_phi`, `phi_offset`,
/// `flip_theta_r`) applied to each row as it is read.
pub fn parse_with(bytes: &[u8], path: &Path, opts: &LoadOptions) -> Result<(Profile, Vec<String>)> {
    let lines = first_pass(bytes, path)?;
    let header_line = lines.header_line;
    let Rows {
        names,
        cols,
        mut samples,
        raw_phi,
        channels,
    } = read_rows(&lines, path, opts)?;
    if samples.is_empty() {
        return Err(Error::file(
            path,
            format!("no sample rows after the header on line {header_line}"),
        ));
    }
    let label = |i: usize| format!("column {} ({})", i + 1, names[i]);
    let mut notes = dedupe_rows(
        &mut samples,
        &channels,
        &raw_phi,
        path,
        opts,
        &label(cols.phi),
        &|f| label(cols.of(f)),
    )?;
    notes.extend(lines.label_notes);
    if lines.separator_rows > 0 {
        notes.push(format!(
            "{} row(s) holding only separators (e.g. a spreadsheet's ',,,') skipped",
            lines.separator_rows
        ));
    }
    Ok((
        Profile {
            samples,
            channels,
            metadata: lines.metadata,
            source: Some(path.to_path_buf()),
            files: vec![path.to_path_buf()],
            layouts: vec![Layout::Rows {
                value_column: label(cols.value),
                sigma_column: cols.sigma.map(label),
                phi_i_column: cols.phi_i.map(label),
            }],
        },
        notes,
    ))
}

/// What the first pass over a file's lines keeps.
struct Lines {
    /// The `# key: value` lines before the header, in file order.
    metadata: Vec<(String, String)>,
    /// The header's line (1-based).
    header_line: usize,
    /// The header and the data lines, for the csv reader.
    kept: Vec<u8>,
    /// The file's line (1-based) of each line of `kept` (the csv crate does not count
    /// lines it is not given).
    orig_line: Vec<usize>,
    /// Rows holding only separators, skipped.
    separator_rows: usize,
    /// Notes on the metadata lines (synthetic labels, non-UTF-8).
    label_notes: Vec<String>,
}

/// Pass 1: metadata lines before the header; blank and comment lines dropped everywhere.
/// The remaining lines go to the csv reader, with a table back to the file's line
/// numbers.
fn first_pass(bytes: &[u8], path: &Path) -> Result<Lines> {
    let mut metadata = Vec::new();
    let mut header_line = None;
    let mut kept: Vec<u8> = Vec::with_capacity(bytes.len());
    let mut orig_line: Vec<usize> = Vec::new();
    let mut separator_rows = 0usize;
    let mut seen_line = false;
    let mut label_notes = Vec::new();
    for (k, raw) in split_lines(bytes).enumerate() {
        let raw = if k == 0 {
            raw.strip_prefix("\u{feff}".as_bytes()).unwrap_or(raw)
        } else {
            raw
        };
        let t = raw.trim_ascii();
        if t.is_empty() {
            continue;
        }
        if !seen_line {
            seen_line = true;
            if is_sep_line(t, k + 1, path)? {
                continue;
            }
        }
        // Spreadsheets pad a table with rows of bare separators: they hold no sample.
        if t.iter().all(|b| *b == b',' || b.is_ascii_whitespace()) {
            separator_rows += 1;
            continue;
        }
        if let Some(c) = t.strip_prefix(b"#") {
            if header_line.is_none() {
                metadata_line(c, k + 1, path, &mut metadata, &mut label_notes)?;
            }
            continue;
        }
        header_line.get_or_insert(k + 1);
        kept.extend_from_slice(raw);
        kept.push(b'\n');
        orig_line.push(k + 1);
    }
    let header_line = header_line.ok_or_else(|| {
        Error::file(
            path,
            "empty file: no header line (expected theta_i,theta_r,phi,value)",
        )
    })?;
    Ok(Lines {
        metadata,
        header_line,
        kept,
        orig_line,
        separator_rows,
        label_notes,
    })
}

/// Whether the first line `t` (trimmed, on `line`) is Excel's `sep=,`, to skip. Excel's
/// `sep=` line names the separator; any other separator is refused here, where the
/// reason is clear, rather than as a header without its columns.
fn is_sep_line(t: &[u8], line: usize, path: &Path) -> Result<bool> {
    let u = t.to_ascii_lowercase();
    let u = u
        .strip_prefix(b"\"")
        .and_then(|u| u.strip_suffix(b"\""))
        .unwrap_or(&u[..]);
    let Some(sep) = u.strip_prefix(b"sep=") else {
        return Ok(false);
    };
    if sep == b"," {
        return Ok(true);
    }
    Err(Error::parse(
        path,
        line,
        "column 1".into(),
        format!(
            "the file declares the separator '{}' (Excel's sep= line); the separator must be a comma",
            escaped(&String::from_utf8_lossy(t))
        ),
    ))
}

/// A `#` line before the header (`c`: after the `#`, on `line`): a `key: value` goes to
/// `metadata`, anything else is a free comment (with a note if it looks like an
/// unlabelled synthetic label).
fn metadata_line(
    c: &[u8],
    line: usize,
    path: &Path,
    metadata: &mut Vec<(String, String)>,
    label_notes: &mut Vec<String>,
) -> Result<()> {
    let utf8 = std::str::from_utf8(c).is_ok();
    let c = String::from_utf8_lossy(c);
    match c.split_once(':') {
        Some((key, val)) if !key.trim().is_empty() => {
            let key = key.trim();
            super::label::check_synthetic_label(key, val)
                .map_err(|m| Error::parse(path, line, "metadata".into(), m))?;
            if !utf8 {
                label_notes.push(super::label::non_utf8_metadata_note(line, key));
            }
            metadata.push((key.to_string(), val.trim().to_string()));
        }
        _ => label_notes.extend(super::label::unlabelled_synthetic_note(line, &c)),
    }
    Ok(())
}

/// The rows of a file as read: the header's names and columns, the samples (before
/// duplicates are collapsed), each sample's phi as written, the channel names.
struct Rows {
    names: Vec<String>,
    cols: Columns,
    samples: Vec<Sample>,
    /// Each sample's phi as written (for a wrap's duplicate message).
    raw_phi: Vec<f64>,
    channels: Vec<String>,
}

/// Pass 2: the header and the data rows of `lines.kept`, each row checked.
fn read_rows(lines: &Lines, path: &Path, opts: &LoadOptions) -> Result<Rows> {
    let line_of = |pos: Option<&::csv::Position>| -> usize {
        pos.and_then(|p| lines.orig_line.get((p.line() as usize).saturating_sub(1)))
            .copied()
            .unwrap_or(lines.header_line)
    };
    // No `Trim` here: it would strip the line break an unterminated quote swallows, which
    // is how one is detected below. Cells and names are trimmed where they are read.
    let mut rdr = ::csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .from_reader(lines.kept.as_slice());

    let mut header: Option<Vec<String>> = None;
    let mut cols = Columns::default();
    let mut samples: Vec<Sample> = Vec::new();
    let mut raw_phi: Vec<f64> = Vec::new();
    let mut channels: Vec<String> = Vec::new();
    let mut record = ::csv::ByteRecord::new();
    loop {
        let more = rdr.read_byte_record(&mut record).map_err(|e| {
            Error::parse(
                path,
                line_of(e.position()),
                "-".into(),
                format!("unreadable CSV: {e}"),
            )
        })?;
        if !more {
            break;
        }
        let line = line_of(record.position());
        // Records are single lines, so a field holding a line break is a quote that was
        // never closed (the csv crate reads on to the next quote or the end of the file).
        if let Some(k) = record.iter().position(|f| f.contains(&b'\n')) {
            let column = match &header {
                Some(names) if k < names.len() => format!("column {} ({})", k + 1, names[k]),
                _ => format!("column {}", k + 1),
            };
            return Err(Error::parse(
                path,
                line,
                column,
                "unterminated quoted field (a quote must close on the same line)".into(),
            ));
        }
        let Some(names) = &header else {
            let names: Vec<String> = record
                .iter()
                .map(|f| String::from_utf8_lossy(f).trim().to_ascii_lowercase())
                .collect();
            cols = Columns::from_header(&names, |c, m| Error::parse(path, line, c, m))?;
            header = Some(names);
            continue;
        };
        if record.len() != names.len() {
            let col = record.len().min(names.len()) + 1;
            return Err(Error::parse(
                path,
                line,
                format!("column {col}"),
                format!(
                    "expected {} fields (as in the header), found {}",
                    names.len(),
                    record.len()
                ),
            ));
        }
        let row = Row {
            record: &record,
            names,
            cols: &cols,
            line,
            path,
        };
        let (sample, phi_as_written) = row.sample(opts, &mut channels)?;
        super::checks::check_sample_count(
            samples.len(),
            super::checks::MAX_READ_CELLS,
            path,
            line,
        )?;
        samples.push(sample);
        raw_phi.push(phi_as_written);
    }
    Ok(Rows {
        names: header.unwrap_or_default(),
        cols,
        samples,
        raw_phi,
        channels,
    })
}

/// One data row being read, with what its errors name.
struct Row<'a> {
    record: &'a ::csv::ByteRecord,
    names: &'a [String],
    cols: &'a Columns,
    line: usize,
    path: &'a Path,
}

impl Row<'_> {
    /// An error on column `i` of this row.
    fn err(&self, i: usize, msg: String) -> Error {
        Error::parse(self.path, self.line, self.label(i), msg)
    }

    fn label(&self, i: usize) -> String {
        format!("column {} ({})", i + 1, self.names[i])
    }

    /// Cell `i`, trimmed.
    fn text(&self, i: usize) -> Result<&str> {
        std::str::from_utf8(self.record.get(i).unwrap_or(b""))
            .map(str::trim)
            .map_err(|_| self.err(i, "not valid UTF-8".into()))
    }

    /// Cell `i` as a number (`None`: empty).
    fn number(&self, i: usize) -> Result<Option<f64>> {
        let t = self.text(i)?;
        if t.is_empty() {
            return Ok(None);
        }
        parse_number(t).map(Some).map_err(|m| self.err(i, m))
    }

    fn angle(&self, i: usize) -> Result<f64> {
        self.number(i)?
            .ok_or_else(|| self.err(i, "missing angle".into()))
    }

    fn theta(&self, i: usize) -> Result<f64> {
        check_angle(&self.names[i], self.angle(i)?, 90.0).map_err(|m| self.err(i, m))
    }

    /// The row's sample (its channel numbered in `channels`, a new name added) and its
    /// phi as written.
    fn sample(&self, opts: &LoadOptions, channels: &mut Vec<String>) -> Result<(Sample, f64)> {
        let cols = self.cols;
        let theta_i = self.theta(cols.theta_i)?;
        let theta_r = convert_theta_r(opts, self.theta(cols.theta_r)?);
        let phi_as_written = self.angle(cols.phi)?;
        let phi = read_phi(&self.names[cols.phi], phi_as_written, opts)
            .map_err(|m| self.err(cols.phi, m))?;
        let value = self.number(cols.value)?.unwrap_or(f64::NAN);
        // CSV's spellings of "none": an empty cell, and `nan` for sigma and phi_i (as
        // an npz's NaN).
        let sigma = match cols.sigma {
            Some(i) => self.number(i)?.filter(|s| !s.is_nan()),
            None => None,
        };
        let phi_i = match cols.phi_i {
            Some(i) => self.number(i)?.filter(|p| !p.is_nan()).map(|p| p + 0.0),
            None => None,
        };
        check_measured(value, sigma, phi_i)
            .map_err(|(field, msg)| self.err(cols.of(field), msg))?;
        let channel = match cols.channel {
            None => 0,
            Some(i) => {
                let name = self.text(i)?;
                check_channel_name(name).map_err(|m| self.err(i, m))?;
                match channels.iter().position(|c| c == name) {
                    Some(k) => k,
                    None => {
                        channels.push(name.to_string());
                        channels.len() - 1
                    }
                }
            }
        };
        let sample = Sample {
            theta_i,
            theta_r,
            phi,
            value,
            sigma,
            channel,
            phi_i,
            origin: Origin::at_line(self.line),
        };
        Ok((sample, phi_as_written))
    }
}

/// Column indices found in the header.
#[derive(Default)]
struct Columns {
    theta_i: usize,
    theta_r: usize,
    phi: usize,
    value: usize,
    sigma: Option<usize>,
    channel: Option<usize>,
    phi_i: Option<usize>,
}

impl Columns {
    /// The column of a measured field (the value column for one the file lacks, which
    /// cannot then differ or be invalid).
    fn of(&self, field: Field) -> usize {
        match field {
            Field::Value => Some(self.value),
            Field::Sigma => self.sigma,
            Field::PhiI => self.phi_i,
        }
        .unwrap_or(self.value)
    }

    fn from_header(names: &[String], err: impl Fn(String, String) -> Error) -> Result<Columns> {
        let find = |want: &str| -> Result<Option<usize>> {
            let mut hits = names.iter().enumerate().filter(|(_, n)| *n == want);
            let first = hits.next().map(|(i, _)| i);
            if let Some((j, _)) = hits.next() {
                return Err(err(
                    format!("column {} ({want})", j + 1),
                    format!(
                        "column '{want}' appears twice in the header (also column {})",
                        first.unwrap_or(0) + 1
                    ),
                ));
            }
            Ok(first)
        };
        // A semicolon- or tab-separated file reads as one column: say why.
        let hint = if names.iter().any(|n| n.contains(';')) {
            "; the header looks separated by ';': the separator must be a comma"
        } else if names.iter().any(|n| n.contains('\t')) {
            "; the header looks separated by tabs: the separator must be a comma"
        } else {
            ""
        };
        let required = |want: &str| -> Result<usize> {
            find(want)?.ok_or_else(|| {
                err(
                    format!("column '{want}'"),
                    format!(
                        "required column '{want}' is missing from the header (found: {}){hint}",
                        crate::text::cut_text(&names.join(", "), 200)
                    ),
                )
            })
        };
        Ok(Columns {
            theta_i: required("theta_i")?,
            theta_r: required("theta_r")?,
            phi: required("phi")?,
            value: required("value")?,
            sigma: find("sigma")?,
            channel: find("channel")?,
            phi_i: find("phi_i")?,
        })
    }
}

/// Format a float so that it parses back to the identical f64 (NaN as `nan`).
pub fn fmt_f64(v: f64) -> String {
    if v.is_nan() {
        "nan".into()
    } else if v != 0.0 && v.is_finite() && (v.abs() >= 1e16 || v.abs() < 1e-5) {
        format!("{v:e}")
    } else {
        format!("{v}")
    }
}

/// The CSV text of a profile (see the module doc for the layout).
pub fn to_string(profile: &Profile) -> Result<String> {
    let mut out = String::new();
    for (k, v) in &profile.metadata {
        if k.contains(':') || k.contains(['\n', '\r']) || k.trim().is_empty() {
            return Err(Error::Invalid(format!(
                "metadata key '{k}' cannot be written to CSV (empty, or holds ':' or a line break)"
            )));
        }
        if v.contains(['\n', '\r']) {
            return Err(Error::Invalid(format!(
                "metadata '{k}' cannot be written to CSV: its value holds a line break"
            )));
        }
        out.push_str(&format!("# {k}: {v}\n"));
    }
    let has_sigma = profile.samples.iter().any(|s| s.sigma.is_some());
    let has_channel = !profile.channels.is_empty();
    let has_phi_i = profile.samples.iter().any(|s| s.phi_i.is_some());
    let mut w = ::csv::WriterBuilder::new()
        .terminator(::csv::Terminator::Any(b'\n'))
        .from_writer(Vec::new());
    let csv_err = |e: ::csv::Error| Error::Invalid(format!("writing CSV: {e}"));
    let mut head = vec!["theta_i", "theta_r", "phi", "value"];
    if has_sigma {
        head.push("sigma");
    }
    if has_channel {
        head.push("channel");
    }
    if has_phi_i {
        head.push("phi_i");
    }
    w.write_record(&head).map_err(csv_err)?;
    for s in &profile.samples {
        let mut row = vec![
            fmt_f64(s.theta_i),
            fmt_f64(s.theta_r),
            fmt_f64(s.phi),
            fmt_f64(s.value),
        ];
        if has_sigma {
            row.push(s.sigma.map(fmt_f64).unwrap_or_default());
        }
        if has_channel {
            let name = profile.channels.get(s.channel).ok_or_else(|| {
                Error::Invalid(format!(
                    "sample channel {} out of range ({} channels)",
                    s.channel,
                    profile.channels.len()
                ))
            })?;
            row.push(name.clone());
        }
        if has_phi_i {
            row.push(s.phi_i.map(fmt_f64).unwrap_or_default());
        }
        w.write_record(&row).map_err(csv_err)?;
    }
    let body = w
        .into_inner()
        .map_err(|e| Error::Invalid(format!("writing CSV: {e}")))?;
    out.push_str(&String::from_utf8_lossy(&body));
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(text: &str) -> Result<(Profile, Vec<String>)> {
        parse(text.as_bytes(), Path::new("t.csv"))
    }

    #[test]
    fn float_format_round_trips() {
        for v in [
            0.0,
            -0.0,
            1.0,
            0.1,
            1.0 / 3.0,
            -2.5e-300,
            1.7976931348623157e308,
            5e-324,
            123456.789,
            1e16,
            9.999e15,
            1e-5,
        ] {
            let s = fmt_f64(v);
            let back: f64 = s.parse().unwrap();
            assert_eq!(back.to_bits(), v.to_bits(), "{v} -> {s}");
        }
        assert!(fmt_f64(f64::NAN).parse::<f64>().unwrap().is_nan());
    }

    /// Metadata that is not UTF-8 loads (a comment is not data) but says so; the same byte
    /// in a data row is an error naming its line and column.
    #[test]
    fn non_utf8_metadata_is_noted_and_non_utf8_data_refused() {
        let (pr, notes) = parse(
            b"# source: M\xfcller lab\n# \xff\ntheta_i,theta_r,phi,value\n0,0,0,1\n",
            Path::new("t.csv"),
        )
        .unwrap();
        assert_eq!(pr.meta("source"), Some("M\u{fffd}ller lab"));
        assert_eq!(notes.len(), 1, "{notes:?}");
        assert!(
            notes[0].starts_with("line 1: metadata 'source' is not valid UTF-8"),
            "{notes:?}"
        );
        let e = parse(
            b"theta_i,theta_r,phi,value\n0,0,0\xfc,1\n",
            Path::new("t.csv"),
        )
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("t.csv:2") && e.contains("not valid UTF-8"),
            "{e}"
        );
    }

    #[test]
    fn minimal_and_invalid_values() {
        let (pr, notes) =
            p("theta_i,theta_r,phi,value\n0,0,0,1\n0,0,10,\n0,0,20,-1\n0,0,30,nan\n0,0,-180,0\n")
                .unwrap();
        assert!(notes.is_empty());
        assert_eq!(pr.samples.len(), 5);
        assert_eq!(pr.n_valid(), 1);
        assert_eq!(pr.n_invalid(), 4);
        assert_eq!(pr.samples[4].phi, 180.0);
        assert!(pr.channels.is_empty());
    }

    #[test]
    fn identical_duplicates_collapse_with_a_note() {
        let (pr, notes) =
            p("theta_i,theta_r,phi,value\n0,0,0,1\n0,0,0,1\n0,0,-180,2\n0,0,180,2\n").unwrap();
        assert_eq!(pr.samples.len(), 2);
        assert_eq!(notes.len(), 1);
        assert!(notes[0].contains('2'), "{}", notes[0]);
    }

    /// phi in [0, 360) reads (270 was "out of range [-180, 180]"), wrapped to (-180, 180],
    /// with the offset applied before the wrap.
    #[test]
    fn phi_up_to_360_wraps() {
        let text = "theta_i,theta_r,phi,value\n0,0,270,1\n0,0,355,2\n0,0,-360,3\n";
        let (pr, _) = p(text).unwrap();
        let phis: Vec<f64> = pr.samples.iter().map(|s| s.phi).collect();
        assert_eq!(phis, vec![-90.0, -5.0, 0.0]);
        let opts = LoadOptions {
            phi_offset: -180.0,
            ..Default::default()
        };
        let (pr, _) = parse_with(text.as_bytes(), Path::new("t.csv"), &opts).unwrap();
        let phis: Vec<f64> = pr.samples.iter().map(|s| s.phi).collect();
        assert_eq!(phis, vec![90.0, 175.0, 180.0]);
        let e = p("theta_i,theta_r,phi,value\n0,0,-360.5,1\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("t.csv:2: column 3 (phi): phi = -360.5 deg is out of range [-360, 360]"),
            "{e}"
        );
    }

    /// Rows clashing only because phi wrapped (0 and 360) are named as such on the phi
    /// column (it quoted "phi 0" for a line saying 360 and pointed at the value column);
    /// an ordinary clash keeps its message, identical endpoints still collapse.
    #[test]
    fn wrap_endpoint_clash_says_so() {
        let e = p("theta_i,theta_r,phi,value\n30,10,0,1\n30,10,360,1.1\n")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "t.csv:3: column 3 (phi): phi 360 wraps to 0, which line 2 already holds with a \
             different value (1 vs 1.1); drop one of the two endpoint measurements"
        );
        let e = p("theta_i,theta_r,phi,value\n30,10,5,1\n30,10,5,1.1\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with(
                "t.csv:3: column 4 (value): duplicate sample (theta_i 30, theta_r 10, phi 5) with"
            ) && e.ends_with("first on line 2"),
            "{e}"
        );
        let (pr, notes) = p("theta_i,theta_r,phi,value\n30,10,0,1\n30,10,360,1\n").unwrap();
        assert_eq!((pr.samples.len(), notes.len()), (1, 1));
        // The collapse note says the two rows wrote one direction as two phi.
        assert!(
            notes[0].contains("1 of them the same direction written as two phi, e.g. 0 and 360"),
            "{notes:?}"
        );
        // A plain repeat says nothing of wrapping.
        let (_, notes) = p("theta_i,theta_r,phi,value\n30,10,5,1\n30,10,5,1\n").unwrap();
        assert!(!notes[0].contains("wrapped"), "{notes:?}");
    }

    /// A repeat that differs only in sigma or phi_i is reported on that column, in one file
    /// and across the files of a folder (the value column was named before).
    #[test]
    fn duplicate_names_the_column_that_differs() {
        // Copies without signal are one invalid sample whatever their sigma (README).
        let (pr, notes) =
            p("sigma,theta_i,theta_r,phi,value\n0.1,0,0,0,nan\n0.2,0,0,0,-1\n").unwrap();
        assert_eq!(pr.samples.len(), 1);
        assert!(
            notes[0].contains("not identical but both without signal"),
            "{notes:?}"
        );
        let e = p("sigma,theta_i,theta_r,phi,value\n0.1,0,0,0,1\n0.2,0,0,0,1\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(":3: column 1 (sigma): duplicate") && e.contains("sigma (0.1 vs 0.2)"),
            "{e}"
        );
        let e = p("theta_i,theta_r,phi,value,phi_i\n0,0,0,1,5\n0,0,0,1,6\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains(":3: column 5 (phi_i): duplicate"), "{e}");
        // phi_i is a direction: 5 and -355 (or 180 and -180) are one, and the copies
        // collapse as a phi written two ways does.
        for (a, b) in [("5", "-355"), ("180", "-180"), ("0", "360")] {
            let (pr, _) = p(&format!(
                "theta_i,theta_r,phi,value,phi_i\n0,0,0,1,{a}\n0,0,0,1,{b}\n"
            ))
            .unwrap();
            assert_eq!(pr.samples.len(), 1, "phi_i {a} and {b}");
        }
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::write(
            d.join("a.csv"),
            "theta_i,theta_r,phi,value,sigma\n0,0,0,1,0.5\n",
        )
        .unwrap();
        std::fs::write(d.join("b.csv"), "theta_i,theta_r,phi,value\n0,0,0,1\n").unwrap();
        let e = super::super::load_dir(d, &LoadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("b.csv:2: column 4 (value): duplicate")
                && e.contains("a.csv:2: column 5 (sigma)"),
            "{e}"
        );
    }

    /// A clash names the channel as the file does (`channel r`, not its index 0); a file
    /// without a `channel` column names none.
    #[test]
    fn duplicate_names_the_channel_by_its_name() {
        let e =
            p("theta_i,theta_r,phi,value,channel\n0,-60,-30,1,r\n0,-60,-30,1,g\n0,-60,-30,2,r\n")
                .unwrap_err()
                .to_string();
        assert!(
            e.contains("duplicate sample (theta_i 0, theta_r -60, phi -30, channel r) with a different value (1 vs 2)"),
            "{e}"
        );
        // g is index 1: its name, not the index.
        let e =
            p("theta_i,theta_r,phi,value,channel\n0,-60,-30,1,r\n0,-60,-30,1,g\n0,-60,-30,2,g\n")
                .unwrap_err()
                .to_string();
        assert!(e.contains("phi -30, channel g) with"), "{e}");
    }

    #[test]
    fn duplicate_with_different_sigma_is_an_error() {
        let e = p("theta_i,theta_r,phi,value,sigma\n0,0,0,1,0.1\n0,0,0,1,0.2\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("t.csv:3:") && e.contains("sigma (0.1 vs 0.2)") && e.contains("line 2"),
            "{e}"
        );
        // A missing sigma reads "none", not Rust's `None`.
        let e = p("theta_i,theta_r,phi,value,sigma\n0,0,0,1,0.1\n0,0,0,1,\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("sigma (0.1 vs none)"), "{e}");
    }

    #[test]
    fn metadata_free_comments_and_blank_lines() {
        let (pr, _) = p("\n# species: red fox\n# just a note\n\n#fiber:3\ntheta_i,theta_r,phi,value\n\n# mid comment\n0,0,0,1\n  \n")
            .unwrap();
        assert_eq!(
            pr.metadata,
            vec![
                ("species".to_string(), "red fox".to_string()),
                ("fiber".to_string(), "3".to_string())
            ]
        );
        assert_eq!(pr.samples.len(), 1);
    }

    #[test]
    fn unterminated_quote_is_an_error() {
        // Alone on the last line the csv crate would read it as a plain `1`.
        let e = p("theta_i,theta_r,phi,value\n0,0,0,\"1\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("t.csv:2: column 4 (value): unterminated"),
            "{e}"
        );
        // Followed by more rows it would swallow them into one field.
        let e = p("theta_i,theta_r,phi,value\n0,0,\"0,1\n\n# c\n0,0,1,2\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("t.csv:2: column 3 (phi): unterminated"),
            "{e}"
        );
        let e = p("theta_i,theta_r,phi,\"value\n0,0,0,1\n")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("t.csv:1: column 4: unterminated"), "{e}");
        // Closed quotes, with doubled quotes and padding, still read.
        let (pr, _) =
            p("theta_i,theta_r,phi,value,note\n 0 ,\"0\", 0 ,\" 1 \",\"a \"\"b\"\", c\"\n")
                .unwrap();
        assert_eq!(pr.samples[0].value, 1.0);
    }

    #[test]
    fn lone_cr_line_endings() {
        let e = p("theta_i,theta_r,phi,value\r0,0,0,1\r0,0,1,2\r0,0,x,3\r")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("t.csv:4: column 3 (phi)"), "{e}");
        let (pr, _) =
            p("# species: fox\r# fiber: 3\rtheta_i,theta_r,phi,value\r0,0,0,1\r").unwrap();
        assert_eq!(pr.meta("species"), Some("fox"));
        assert_eq!(pr.meta("fiber"), Some("3"));
        assert_eq!(pr.samples.len(), 1);
        // Mixed endings count one line each.
        let e = p("theta_i,theta_r,phi,value\r\n0,0,0,1\r0,0,1,2\n0,0,x,3\n")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("t.csv:4:"), "{e}");
    }

    #[test]
    fn separator_only_rows_are_skipped_with_a_note() {
        let (pr, notes) =
            p("theta_i,theta_r,phi,value\n0,0,0,1\n,,,\n0,0,1,2\n,,,\n , ,,,\n").unwrap();
        assert_eq!(pr.samples.len(), 2);
        assert_eq!(notes.len(), 1);
        assert!(
            notes[0].starts_with("3 row(s) holding only separators"),
            "{notes:?}"
        );
        // A row with a value somewhere is still a row (and here a short one).
        let e = p("theta_i,theta_r,phi,value\n0,0,0,1\n,,,5\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("t.csv:3: column 1 (theta_i): missing angle"),
            "{e}"
        );
    }

    #[test]
    fn excel_sep_line_and_separator_hint() {
        let (pr, _) = p("sep=,\ntheta_i,theta_r,phi,value\n0,0,0,1\n").unwrap();
        assert_eq!(pr.samples.len(), 1);
        let (pr, _) = p("\u{feff}\"sep=,\"\r\ntheta_i,theta_r,phi,value\r\n0,0,0,1\r\n").unwrap();
        assert_eq!(pr.samples.len(), 1);
        let e = p("sep=;\ntheta_i;theta_r;phi;value\n0;0;0;1\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("t.csv:1: column 1:") && e.contains("must be a comma"),
            "{e}"
        );
        for (text, what) in [
            ("theta_i;theta_r;phi;value\n0;0;0;1\n", "';'"),
            ("theta_i\ttheta_r\tphi\tvalue\n0\t0\t0\t1\n", "tabs"),
        ] {
            let e = p(text).unwrap_err().to_string();
            assert!(
                e.contains("required column 'theta_i' is missing")
                    && e.contains(what)
                    && e.contains("the separator must be a comma"),
                "{e}"
            );
        }
        // A plain missing column gets no separator hint.
        let e = p("theta_i,theta_r,value\n0,0,1\n").unwrap_err().to_string();
        assert!(!e.contains("separator"), "{e}");
    }

    #[test]
    fn wrong_field_count_names_line() {
        let e = p("theta_i,theta_r,phi,value\n0,0,0,1\n0,0,1\n")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("t.csv:3: column 4"), "{e}");
    }

    #[test]
    fn sigma_rules() {
        let (pr, _) =
            p("theta_i,theta_r,phi,value,sigma\n0,0,0,1,\n0,0,1,1,nan\n0,0,2,1,0.5\n").unwrap();
        assert_eq!(pr.samples[0].sigma, None);
        assert_eq!(pr.samples[1].sigma, None);
        assert_eq!(pr.samples[2].sigma, Some(0.5));
        let e = p("theta_i,theta_r,phi,value,sigma\n0,0,0,1,-1\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("t.csv:2: column 5 (sigma)"), "{e}");
    }

    #[test]
    fn writer_rejects_unwritable_metadata() {
        let mut pr = Profile::default();
        pr.metadata.push(("a:b".into(), "x".into()));
        assert!(to_string(&pr).is_err());
        pr.metadata[0] = ("a".into(), "x\ny".into());
        assert!(to_string(&pr).is_err());
    }

    #[test]
    fn channels_in_first_appearance_order() {
        let (pr, _) =
            p("channel,theta_i,theta_r,phi,value\ng,0,0,0,1\nr,0,0,0,2\ng,0,0,1,3\n").unwrap();
        assert_eq!(pr.channels, vec!["g".to_string(), "r".to_string()]);
        assert_eq!(
            pr.samples.iter().map(|s| s.channel).collect::<Vec<_>>(),
            vec![0, 1, 0]
        );
        let text = to_string(&pr).unwrap();
        let (back, _) = p(&text).unwrap();
        assert_eq!(back.samples, pr.samples);
        assert_eq!(back.channels, pr.channels);
    }

    /// phi_i: `nan` means none, as an empty cell and an npz's NaN do (it was "must be a
    /// finite angle"); a value is an angle within [-360, 360] like phi (1e9 read).
    #[test]
    fn phi_i_nan_is_none_and_range_checked() {
        let (pr, _) =
            p("theta_i,theta_r,phi,value,phi_i\n0,0,0,1,\n0,0,1,1,NaN\n0,0,2,1,-360\n").unwrap();
        let got: Vec<_> = pr.samples.iter().map(|s| s.phi_i).collect();
        assert_eq!(got, vec![None, None, Some(-360.0)]);
        for bad in ["1e9", "-5000", "360.5"] {
            let e = p(&format!("theta_i,theta_r,phi,value,phi_i\n0,0,0,1,{bad}\n"))
                .unwrap_err()
                .to_string();
            assert!(
                e.starts_with("t.csv:2: column 5 (phi_i): phi_i = ")
                    && e.contains("out of range [-360, 360]"),
                "{e}"
            );
        }
        let e = p("theta_i,theta_r,phi,value,phi_i\n0,0,0,1,inf\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("column 5 (phi_i): phi_i must be a finite angle"),
            "{e}"
        );
    }

    /// A cell holding an invisible character is quoted with it escaped (a mid-line BOM
    /// made "'0' is not a number", a NUL went to the terminal raw); the header list too.
    #[test]
    fn echoed_cells_escape_invisible_characters() {
        let e = p("theta_i,theta_r,phi,value\n\u{feff}0,0,0,1\n")
            .unwrap_err()
            .to_string();
        assert_eq!(
            e,
            "t.csv:2: column 1 (theta_i): '\\u{feff}0' is not a number"
        );
        let e = p("theta_i,theta_r,phi,value\n0,0,0,1\0\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.ends_with("column 4 (value): '1\\0' is not a number"),
            "{e}"
        );
        let e = p("theta_i,theta_r,\x07phi,value\n0,0,0,1\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("(found: theta_i, theta_r, \\u{7}phi, value)"),
            "{e}"
        );
        // Printable text, quotes and non-ASCII letters are shown as they are.
        let e = p("theta_i,theta_r,phi,value\n0,0,0,\"'5°'\"\n")
            .unwrap_err()
            .to_string();
        assert!(e.ends_with("''5°'' is not a number"), "{e}");
    }

    /// A value below the f64 range (1e-400 reads as 0) is an error naming line and column,
    /// as 1e400 is; it was silently an invalid sample.
    #[test]
    fn underflowing_value_is_an_error() {
        let e = p("theta_i,theta_r,phi,value\n0,0,0,1\n0,0,5,1e-400\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("t.csv:3: column 4 (value): '1e-400' is below the f64 range"),
            "{e}"
        );
        let e = p("theta_i,theta_r,phi,value,sigma\n0,0,0,1,-2.5E-500\n")
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("t.csv:2: column 5 (sigma): '-2.5E-500'"),
            "{e}"
        );
        let (pr, _) = p("theta_i,theta_r,phi,value\n0,0,0,0e-500\n0,0,1,4.9e-324\n").unwrap();
        assert_eq!(pr.samples[0].value, 0.0);
        assert!(pr.samples[1].value > 0.0);
    }

    /// Two no-signal markers for one direction (NaN at a sweep's 0, -1 at its 360; or 0
    /// and empty) are one invalid sample: collapsed with the note, not a conflict. A
    /// marker against a real value still is one.
    #[test]
    fn two_no_signal_markers_collapse() {
        let (pr, notes) =
            p("theta_i,theta_r,phi,value\n0,0,0,nan\n0,0,5,0\n0,0,360,-1\n0,0,5,\n").unwrap();
        assert_eq!(pr.samples.len(), 2);
        assert!(pr.samples[0].value.is_nan() && pr.samples[1].value == 0.0);
        assert_eq!(notes.len(), 1, "{notes:?}");
        assert!(
            notes[0].starts_with("2 identical duplicate row(s) collapsed")
                && notes[0].contains(
                    "2 of them not identical but both without signal, e.g. values NaN and -1"
                ),
            "{notes:?}"
        );
        let e = p("theta_i,theta_r,phi,value\n0,0,0,nan\n0,0,360,2\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("different value (NaN vs 2)"), "{e}");
    }
}

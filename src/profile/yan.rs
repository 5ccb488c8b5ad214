//! The Yan-2015 text format: one file per incident angle, whitespace-separated rows
//! `phi theta value`.
//!
//! # Layout
//! - Each data row holds exactly three whitespace-separated fields `phi theta value`.
//!   `value` is a number or `?` for a missing measurement (read as NaN: an *invalid* sample,
//!   kept and counted, as DATA.md asks for missing values); `nan` is accepted as well.
//! - `#` starts a comment line. A comment of the form `# key: value` is metadata (kept in
//!   file order), except `# theta_i: <deg>`, which gives the file's incident angle. A
//!   comment line need not be UTF-8 (comments are not data; as in CSV, its text is read
//!   with replacement characters); a data line must be.
//! - The first line that is neither blank nor a comment may be the column-name line labs
//!   export, `phi theta value` (those three names in that order, any case): it is skipped.
//!   Any other non-numeric first line is an error, named like a bad row.
//! - Blank lines are ignored. Lines end in `\n`, `\r\n` or a lone `\r` (old Mac /
//!   instrument exports); line numbers count any of them.
//! - The incident angle comes from the `# theta_i:` line or from [`LoadOptions::theta_i`]
//!   (exactly one value). If both are given they must agree; if neither is, it is an error.
//!   When `theta_i` is also the axis of a lone `.npy` read in the same run
//!   ([`LoadOptions::theta_i_for_npy`]), a file with its own line keeps it and ignores the
//!   option (with a note when they differ): the option cannot be meant for it.
//!
//! # Angle convention (an assumption, stated here because the files do not carry it)
//! The files give `phi` and `theta` in degrees. We read `theta` as `theta_r` with MODEL.md's
//! sign (positive toward the fiber tip) and `phi` as MODEL.md's relative azimuth
//! `phi_r - phi_i` (0 = backward scattering, +-180 = forward), possibly written in
//! [0, 360): any finite `phi` in [-360, 360] is accepted and wrapped to (-180, 180]
//! (`-180` becomes `180`), as in every format ([`super::read_phi`]). If a data set uses
//! another origin or handedness, the loader options fix it without editing the file:
//! [`LoadOptions::flip_phi`] negates phi, [`LoadOptions::phi_offset`] then adds a constant
//! (e.g. 180 when the file's 0 is forward scattering) before the wrap, and
//! [`LoadOptions::flip_theta_r`] negates theta
//! (`furfit inspect --flip-phi --phi-offset 180 --flip-theta-r`); the same options convert
//! CSV and npz files too.
//!
//! # Errors
//! Like the CSV reader: a non-number, a non-finite or out-of-range angle, a row with other
//! than three fields, two rows for the same direction with different values (identical
//! repeats are collapsed with a note; rows whose phi differ as written but wrap alike, a
//! sweep's 0 and 360, are named as such on the phi column), a bad `# theta_i:` line; each
//! names the file, the 1-based line and the column (`column 2 (theta)`). A file without
//! data rows is an error.

use super::checks::{check_angle, convert_theta_r, read_phi};
use super::merge::dedupe_rows;
use super::sample::{Layout, LoadOptions, Origin, Profile, Sample};
use crate::error::{Error, Num, Result};
use crate::text::{parse_number, quoted, split_lines};
use std::path::Path;

const NAMES: [&str; 3] = ["phi", "theta", "value"];

/// The value of a `# theta_i: <deg>` comment (`c` is the text after `#`), trimmed; `None`
/// for any other comment.
pub(crate) fn theta_i_comment(c: &str) -> Option<&str> {
    let (key, val) = c.split_once(':')?;
    key.trim()
        .eq_ignore_ascii_case("theta_i")
        .then_some(val.trim())
}

/// Parse a Yan-2015 text file; `path` is used in error messages.
pub fn parse(bytes: &[u8], path: &Path, opts: &LoadOptions) -> Result<(Profile, Vec<String>)> {
    let mut r = Lines::default();
    // Until the first data (or column-name) line, which alone may name the columns.
    let mut before_data = true;
    for (k, raw) in split_lines(bytes).enumerate() {
        let line = k + 1;
        let text = match std::str::from_utf8(raw) {
            Ok(t) => std::borrow::Cow::Borrowed(t),
            // Comments are not data: a Latin-1 note is read as CSV reads it.
            Err(_) if is_comment(raw) => String::from_utf8_lossy(raw),
            Err(_) => {
                return Err(Error::parse(
                    path,
                    line,
                    "column 1".into(),
                    "not valid UTF-8".into(),
                ));
            }
        };
        let t = text.trim().trim_start_matches('\u{feff}');
        if t.is_empty() {
            continue;
        }
        if let Some(c) = t.strip_prefix('#') {
            // Owned only when the lossy decoding above replaced bad bytes.
            let lossy = matches!(text, std::borrow::Cow::Owned(_));
            r.comment(c, line, lossy, path)?;
            continue;
        }
        let fields: Vec<&str> = t.split_whitespace().collect();
        if std::mem::take(&mut before_data) && is_column_names(&fields, t, line, path)? {
            continue;
        }
        let (s, raw_phi) = data_row(&fields, t, line, path, opts)?;
        // theta_i is set below, from the file's comment or --theta-i.
        super::checks::check_sample_count(
            r.samples.len(),
            super::checks::MAX_READ_CELLS,
            path,
            line,
        )?;
        r.samples.push(s);
        r.raw_phi.push(raw_phi);
    }
    let Lines {
        metadata,
        label_notes,
        file_theta_i,
        mut samples,
        raw_phi,
    } = r;
    let mut notes = Vec::new();
    let opt_theta_i = option_theta_i(opts, file_theta_i, path, &mut notes)?;
    // Before the incident angle: a file without data says so, not that theta_i is missing.
    if samples.is_empty() {
        return Err(Error::file(path, "no data rows (phi theta value)"));
    }
    let theta_i = incident_angle(file_theta_i, opt_theta_i, path)?;
    for s in &mut samples {
        s.theta_i = theta_i;
    }
    notes.extend(dedupe_rows(
        &mut samples,
        &[],
        &raw_phi,
        path,
        opts,
        &label(0),
        // Yan-2015 rows have only a value.
        &|_| label(2),
    )?);
    notes.extend(label_notes);
    Ok((
        Profile {
            samples,
            channels: Vec::new(),
            metadata,
            source: Some(path.to_path_buf()),
            files: vec![path.to_path_buf()],
            layouts: vec![Layout::Rows {
                value_column: label(2),
                sigma_column: None,
                phi_i_column: None,
            }],
        },
        notes,
    ))
}

/// The name of data column `i` in errors: `column 2 (theta)`.
fn label(i: usize) -> String {
    format!("column {} ({})", i + 1, NAMES[i])
}

/// What the lines of a file give, as they are read.
#[derive(Default)]
struct Lines {
    /// The `# key: value` comments (but `theta_i`), in file order.
    metadata: Vec<(String, String)>,
    /// Notes on the comments (synthetic labels, non-UTF-8).
    label_notes: Vec<String>,
    /// The `# theta_i:` line's angle and line.
    file_theta_i: Option<(f64, usize)>,
    /// The data rows (theta_i not yet set).
    samples: Vec<Sample>,
    /// Per sample: its phi as written (for a wrap's duplicate message).
    raw_phi: Vec<f64>,
}

impl Lines {
    /// A comment line (`c`: the text after `#`, on `line`; `lossy`: its bad bytes were
    /// replaced): the incident angle, metadata or a free comment.
    fn comment(&mut self, c: &str, line: usize, lossy: bool, path: &Path) -> Result<()> {
        let Some((key, val)) = c.split_once(':') else {
            self.label_notes
                .extend(super::label::unlabelled_synthetic_note(line, c));
            return Ok(());
        };
        let key = key.trim();
        let val = val.trim();
        if key.eq_ignore_ascii_case("theta_i") {
            let col = "theta_i comment".to_string();
            let v = parse_number(val).map_err(|m| Error::parse(path, line, col.clone(), m))?;
            let v = check_angle("theta_i", v, 90.0)
                .map_err(|m| Error::parse(path, line, col.clone(), m))?;
            if let Some((old, l0)) = self.file_theta_i {
                if old != v {
                    return Err(Error::parse(
                        path,
                        line,
                        col,
                        format!(
                            "theta_i {} contradicts theta_i {} on line {l0}",
                            Num(v),
                            Num(old)
                        ),
                    ));
                }
            }
            self.file_theta_i = Some((v, line));
        } else if !key.is_empty() {
            super::label::check_synthetic_label(key, val)
                .map_err(|m| Error::parse(path, line, "metadata".into(), m))?;
            if lossy {
                self.label_notes
                    .push(super::label::non_utf8_metadata_note(line, key));
            }
            self.metadata.push((key.to_string(), val.to_string()));
        } else {
            self.label_notes
                .extend(super::label::unlabelled_synthetic_note(line, c));
        }
        Ok(())
    }
}

/// Whether the first data line (`t`, split into `fields`) is the column-name line
/// `phi theta value`, to skip; another line naming columns is an error (saying what is
/// read, not that 'theta' is no number).
fn is_column_names(fields: &[&str], t: &str, line: usize, path: &Path) -> Result<bool> {
    if fields.len() == NAMES.len()
        && fields
            .iter()
            .zip(NAMES)
            .all(|(f, n)| f.eq_ignore_ascii_case(n))
    {
        return Ok(true);
    }
    let named = |f: &&str| NAMES.iter().any(|n| f.eq_ignore_ascii_case(n));
    if fields
        .first()
        .is_some_and(|f| f.parse::<f64>().is_err() && *f != "?")
        && fields.iter().any(named)
    {
        return Err(Error::parse(
            path,
            line,
            "column 1".into(),
            format!(
                "column-name line {}: a Yan-2015 file may name its columns only as \
                 'phi theta value' (in that order), or not at all",
                quoted(t)
            ),
        ));
    }
    Ok(false)
}

/// A data row (`t`, split into `fields`) as a sample (theta_i not yet set) and its phi
/// as written.
fn data_row(
    fields: &[&str],
    t: &str,
    line: usize,
    path: &Path,
    opts: &LoadOptions,
) -> Result<(Sample, f64)> {
    if fields.len() < 3 && t.contains(',') {
        return Err(Error::parse(
            path,
            line,
            "column 1".into(),
            "fields separated by commas: a Yan-2015 file separates phi, theta and value \
             by spaces or tabs (a comma-separated profile is read as CSV when named .csv)"
                .into(),
        ));
    }
    if fields.len() != 3 {
        return Err(Error::parse(
            path,
            line,
            format!("column {}", fields.len().min(3) + 1),
            format!(
                "expected 3 fields (phi theta value), found {}",
                fields.len()
            ),
        ));
    }
    let num = |i: usize| -> Result<f64> {
        parse_number(fields[i]).map_err(|m| Error::parse(path, line, label(i), m))
    };
    let raw = num(0)?;
    let phi = read_phi("phi", raw, opts).map_err(|m| Error::parse(path, line, label(0), m))?;
    let theta =
        check_angle("theta", num(1)?, 90.0).map_err(|m| Error::parse(path, line, label(1), m))?;
    let value = if fields[2] == "?" {
        f64::NAN
    } else {
        let v = num(2)?;
        if v.is_infinite() {
            return Err(Error::parse(
                path,
                line,
                label(2),
                format!("value {v} is infinite or beyond the f64 range, 1.8e308 (write ? for a missing value)"),
            ));
        }
        v
    };
    let mut s = Sample::new(0.0, convert_theta_r(opts, theta), phi, value);
    s.origin = Origin::at_line(line);
    Ok((s, raw))
}

/// The incident angle `--theta-i` gives this file (`opts.theta_i`; `file`: its own
/// `# theta_i:` line): one value, or none beside a lone .npy whose axis it is (with a
/// note in `notes` when it differs from the file's line).
fn option_theta_i(
    opts: &LoadOptions,
    file: Option<(f64, usize)>,
    path: &Path,
    notes: &mut Vec<String>,
) -> Result<Option<f64>> {
    Ok(match (&opts.theta_i, file) {
        // Beside a lone .npy the option is its axis; this file says its own angle.
        (Some(v), Some((f, l))) if opts.theta_i_for_npy => {
            if v.as_slice() != [f] {
                let v: Vec<String> = v.iter().map(|x| Num(*x).to_string()).collect();
                notes.push(format!(
                    "--theta-i {} (the lone .npy's axis) ignored: line {l} gives this file's \
                     theta_i, {}",
                    v.join(","),
                    Num(f)
                ));
            }
            None
        }
        (None, _) => None,
        (Some(v), _) if v.len() == 1 => Some(
            check_angle("--theta-i", v[0], 90.0)
                .map_err(|m| Error::Invalid(format!("{}: {m}", path.display())))?,
        ),
        (Some(v), _) => {
            let fix = if opts.theta_i_for_npy {
                " (the lone .npy's axis); give this file its own '# theta_i: <deg>' line"
            } else {
                ""
            };
            return Err(Error::Invalid(format!(
                "{}: a Yan-2015 file holds one incident angle; --theta-i gave {} values{fix}",
                path.display(),
                v.len()
            )));
        }
    })
}

/// The file's incident angle: its `# theta_i:` line (`file`) or the option's (`opt`),
/// which must agree when both are given.
fn incident_angle(file: Option<(f64, usize)>, opt: Option<f64>, path: &Path) -> Result<f64> {
    match (file, opt) {
        (Some((f, l)), Some(o)) if f != o => Err(Error::parse(
            path,
            l,
            "theta_i comment".into(),
            format!(
                "the file says theta_i {} but --theta-i is {}",
                Num(f),
                Num(o)
            ),
        )),
        (Some((f, _)), _) => Ok(f),
        (None, Some(o)) => Ok(o),
        (None, None) => Err(Error::file(
            path,
            "no incident angle: add a '# theta_i: <deg>' line or pass --theta-i <deg>",
        )),
    }
}

/// Is `raw` a `#` comment line (blanks and a byte-order mark before the `#`)?
fn is_comment(raw: &[u8]) -> bool {
    let t = raw.trim_ascii_start();
    t.strip_prefix("\u{feff}".as_bytes())
        .unwrap_or(t)
        .trim_ascii_start()
        .starts_with(b"#")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(text: &str, opts: &LoadOptions) -> Result<(Profile, Vec<String>)> {
        parse(text.as_bytes(), Path::new("y.txt"), opts)
    }

    #[test]
    fn reads_rows_question_marks_and_theta_i() {
        let (pr, _) = p(
            "# theta_i: 30\n# fiber: 2\n0 10 1.5\n90 -10 ?\n270 0 2\n-180 5 1\n",
            &LoadOptions::default(),
        )
        .unwrap();
        assert_eq!(pr.samples.len(), 4);
        assert!(pr.samples.iter().all(|s| s.theta_i == 30.0));
        assert!(pr.samples[1].value.is_nan());
        assert_eq!(pr.n_invalid(), 1);
        assert_eq!(pr.samples[2].phi, -90.0, "270 wraps to -90");
        assert_eq!(pr.samples[3].phi, 180.0, "-180 maps to 180");
        assert_eq!(pr.metadata, vec![("fiber".to_string(), "2".to_string())]);
    }

    /// A sweep's two endpoints (0 and 360) with different values: the message quotes the
    /// line's own phi and the wrap, on the phi column (it said "phi 0" on the value column).
    #[test]
    fn wrap_endpoint_clash_says_so() {
        let e = p(
            "# theta_i: 30\n0 10 1\n360 10 1.1\n",
            &LoadOptions::default(),
        )
        .unwrap_err()
        .to_string();
        assert_eq!(
            e,
            "y.txt:3: column 1 (phi): phi 360 wraps to 0, which line 2 already holds with a \
             different value (1 vs 1.1); drop one of the two endpoint measurements"
        );
        // Under an offset both land elsewhere; the message names the options.
        let o = LoadOptions {
            phi_offset: 90.0,
            ..Default::default()
        };
        let e = p("# theta_i: 30\n-180 10 1\n180 10 2\n", &o)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("y.txt:3: column 1 (phi): phi 180 and phi -180 on line 2 are the same direction (both -90 after --flip-phi / --phi-offset")
                && e.contains("different value (1 vs 2)"),
            "{e}"
        );
    }

    #[test]
    fn theta_i_from_options_and_conflicts() {
        let text = "0 10 1\n";
        let e = p(text, &LoadOptions::default()).unwrap_err().to_string();
        assert!(e.contains("y.txt") && e.contains("theta_i"), "{e}");
        let o = LoadOptions {
            theta_i: Some(vec![45.0]),
            ..Default::default()
        };
        assert_eq!(p(text, &o).unwrap().0.samples[0].theta_i, 45.0);
        let e = p("# theta_i: 30\n0 10 1\n", &o).unwrap_err().to_string();
        assert!(e.starts_with("y.txt:1:"), "{e}");
    }

    /// A file may repeat its `# theta_i:` line (a header template pasted twice), but not
    /// contradict it: the second line is named, with the first. A contradiction read as
    /// the last value would move every row to another incident angle without a word.
    #[test]
    fn repeated_theta_i_lines_must_agree() {
        let (pr, _) = p(
            "# theta_i: 30\n0 10 1\n# theta_i: 30.0\n5 10 2\n",
            &LoadOptions::default(),
        )
        .unwrap();
        assert!(pr.samples.iter().all(|s| s.theta_i == 30.0));
        let e = p(
            "# theta_i: 30\n0 10 1\n# theta_i: 45\n5 10 2\n",
            &LoadOptions::default(),
        )
        .unwrap_err()
        .to_string();
        assert_eq!(
            e,
            "y.txt:3: theta_i comment: theta_i 45 contradicts theta_i 30 on line 1"
        );
    }

    #[test]
    fn offset_and_flips() {
        let o = LoadOptions {
            theta_i: Some(vec![0.0]),
            phi_offset: 180.0,
            flip_phi: true,
            flip_theta_r: true,
            ..Default::default()
        };
        let (pr, _) = p("30 20 1\n", &o).unwrap();
        // -30 + 180 = 150
        assert_eq!(pr.samples[0].phi, 150.0);
        assert_eq!(pr.samples[0].theta_r, -20.0);
    }

    #[test]
    fn lone_cr_line_endings() {
        let (pr, _) = p("# theta_i: 30\r0 10 1\r5 10 2\r", &LoadOptions::default()).unwrap();
        assert_eq!(pr.samples.len(), 2);
        assert!(pr.samples.iter().all(|s| s.theta_i == 30.0));
        let e = p("# theta_i: 30\r0 10 1\r5 1x 2\r", &LoadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("y.txt:3: column 2 (theta)"), "{e}");
    }

    #[test]
    fn bad_token_and_field_count() {
        let o = LoadOptions {
            theta_i: Some(vec![0.0]),
            ..Default::default()
        };
        let e = p("0 10 1\n# c\n5 1x 2\n", &o).unwrap_err().to_string();
        assert!(e.starts_with("y.txt:3: column 2 (theta): '1x'"), "{e}");
        let e = p("0 10 1 4\n", &o).unwrap_err().to_string();
        assert!(e.starts_with("y.txt:1: column 4"), "{e}");
        let e = p("0 95 1\n", &o).unwrap_err().to_string();
        assert!(e.contains("out of range"), "{e}");
    }

    /// A comma-separated row, an empty file and a huge angle get messages that say what is
    /// wrong (they said "column 2: expected 3 fields", "no incident angle" and printed 301
    /// digits).
    #[test]
    fn commas_empty_files_and_huge_angles_are_named() {
        let e = p("# theta_i: 10\n0,10,1\n", &LoadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("y.txt:2") && e.contains("commas"), "{e}");
        let e = p("", &LoadOptions::default()).unwrap_err().to_string();
        assert!(e.contains("no data rows"), "{e}");
        let e = p("# theta_i: 10\n1e300 10 1\n", &LoadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("1e300") && e.len() < 200, "{e}");
    }

    /// The column-name line labs export (`phi theta value`, any case) is skipped as a
    /// header before the data (it was "'phi' is not a number"); any other column-name line,
    /// or that line among the data, is an error naming line and column.
    #[test]
    fn column_name_line_is_a_header() {
        let o = LoadOptions::default();
        let (pr, notes) = p("# theta_i: 0\nPhi  THETA\tvalue\n0 10 1\n5 10 2\n", &o).unwrap();
        assert_eq!(pr.samples.len(), 2);
        assert!(notes.is_empty(), "{notes:?}");
        // Before any comment too, and with a BOM.
        let (pr, _) = p("\u{feff}phi theta value\n# theta_i: 0\n0 10 1\n", &o).unwrap();
        assert_eq!(pr.samples.len(), 1);
        let e = p("# theta_i: 0\ntheta phi value\n0 10 1\n", &o)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("y.txt:2: column 1: column-name line 'theta phi value'")
                && e.contains("'phi theta value'"),
            "{e}"
        );
        let e = p("# theta_i: 0\n0 10 1\nphi theta value\n", &o)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("y.txt:3: column 1 (phi): 'phi' is not a number"),
            "{e}"
        );
    }

    /// A comment line that is not UTF-8 is read with replacement characters, as CSV reads
    /// it (it was an error); a data line that is not UTF-8 is still one.
    #[test]
    fn non_utf8_comment_is_accepted_but_not_data() {
        let o = LoadOptions::default();
        let (pr, notes) = parse(
            b"# theta_i: 30\n# op: M\xfcller\n  # \xff\n0 10 1\n",
            Path::new("y.txt"),
            &o,
        )
        .unwrap();
        assert_eq!(pr.samples.len(), 1);
        assert_eq!(pr.meta("op"), Some("M\u{fffd}ller"));
        // The altered metadata is noted; the bare comment on line 3 holds none.
        assert_eq!(notes.len(), 1, "{notes:?}");
        assert!(
            notes[0].starts_with("line 2: metadata 'op' is not valid UTF-8"),
            "{notes:?}"
        );
        let e = parse(b"# theta_i: 30\n0 10 1\xff\n", Path::new("y.txt"), &o)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("y.txt:2: column 1: not valid UTF-8"), "{e}");
    }

    /// Beside a lone .npy (`theta_i_for_npy`), --theta-i is the .npy's axis: a file with
    /// its own `# theta_i:` keeps it, with a note when they differ (it was an error, even
    /// for one value, so the two could not be read together); a file without the line
    /// still takes a single value, and several are an error saying what to do. Without a
    /// .npy a disagreement stays an error.
    #[test]
    fn theta_i_meant_for_a_lone_npy_leaves_headed_files_alone() {
        let npy = |t: &[f64]| LoadOptions {
            theta_i: Some(t.to_vec()),
            theta_i_for_npy: true,
            ..Default::default()
        };
        let (pr, notes) = p("# theta_i: 30\n0 10 1\n", &npy(&[0.0, 30.0])).unwrap();
        assert_eq!(pr.samples[0].theta_i, 30.0);
        assert_eq!(
            notes,
            vec!["--theta-i 0,30 (the lone .npy's axis) ignored: line 1 gives this file's theta_i, 30"]
        );
        let (pr, notes) = p("# theta_i: 30\n0 10 1\n", &npy(&[45.0])).unwrap();
        assert_eq!((pr.samples[0].theta_i, notes.len()), (30.0, 1));
        let (_, notes) = p("# theta_i: 30\n0 10 1\n", &npy(&[30.0])).unwrap();
        assert!(notes.is_empty(), "{notes:?}");
        let (pr, _) = p("0 10 1\n", &npy(&[45.0])).unwrap();
        assert_eq!(pr.samples[0].theta_i, 45.0);
        let e = p("0 10 1\n", &npy(&[0.0, 30.0])).unwrap_err().to_string();
        assert!(
            e.contains("--theta-i gave 2 values (the lone .npy's axis); give this file its own"),
            "{e}"
        );
        let alone = LoadOptions {
            theta_i_for_npy: false,
            ..npy(&[45.0])
        };
        let e = p("# theta_i: 30\n0 10 1\n", &alone)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("the file says theta_i 30 but --theta-i is 45"),
            "{e}"
        );
    }

    /// A number below the f64 range reads as 0; it is an error naming line and column, as
    /// one above the range is (a value of 1e-400 was silently an invalid sample).
    #[test]
    fn underflowing_numbers_are_errors() {
        let o = LoadOptions::default();
        let e = p("# theta_i: 30\n0 10 1e-400\n", &o)
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("y.txt:2: column 3 (value): '1e-400' is below the f64 range"),
            "{e}"
        );
        let e = p("# theta_i: 1e-999\n0 10 1\n", &o)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("y.txt:1: theta_i comment: '1e-999'"), "{e}");
        // Zero spelled any way, and the smallest subnormal, still read.
        let (pr, _) = p("# theta_i: 0e-400\n0 10 0.0e-999\n5 10 5e-324\n", &o).unwrap();
        assert_eq!((pr.samples[0].value, pr.samples[1].value), (0.0, 5e-324));
    }
}

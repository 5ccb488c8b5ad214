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
    let perr = |line: usize, column: String, msg: String| Error::Parse {
        file: path.to_path_buf(),
        line,
        column,
        msg,
    };
    let label = |i: usize| format!("column {} ({})", i + 1, NAMES[i]);
    let mut metadata = Vec::new();
    let mut label_notes = Vec::new();
    let mut file_theta_i: Option<(f64, usize)> = None;
    let mut samples = Vec::new();
    // Per sample: its line and its phi as written (for a wrap's duplicate message).
    let mut raw_phi = Vec::new();
    // Until the first data (or column-name) line, which alone may name the columns.
    let mut before_data = true;
    for (k, raw) in split_lines(bytes).enumerate() {
        let line = k + 1;
        let text = match std::str::from_utf8(raw) {
            Ok(t) => std::borrow::Cow::Borrowed(t),
            // Comments are not data: a Latin-1 note is read as CSV reads it.
            Err(_) if is_comment(raw) => String::from_utf8_lossy(raw),
            Err(_) => {
                return Err(perr(line, "column 1".into(), "not valid UTF-8".into()));
            }
        };
        let t = text.trim().trim_start_matches('\u{feff}');
        if t.is_empty() {
            continue;
        }
        if let Some(c) = t.strip_prefix('#') {
            if let Some((key, val)) = c.split_once(':') {
                let key = key.trim();
                let val = val.trim();
                if key.eq_ignore_ascii_case("theta_i") {
                    let col = "theta_i comment".to_string();
                    let v = parse_number(val).map_err(|m| perr(line, col.clone(), m))?;
                    let v =
                        check_angle("theta_i", v, 90.0).map_err(|m| perr(line, col.clone(), m))?;
                    if let Some((old, l0)) = file_theta_i {
                        if old != v {
                            return Err(perr(
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
                    file_theta_i = Some((v, line));
                } else if !key.is_empty() {
                    super::label::check_synthetic_label(key, val)
                        .map_err(|m| perr(line, "metadata".into(), m))?;
                    // Owned only when the lossy decoding above replaced bad bytes.
                    if matches!(text, std::borrow::Cow::Owned(_)) {
                        label_notes.push(super::label::non_utf8_metadata_note(line, key));
                    }
                    metadata.push((key.to_string(), val.to_string()));
                } else {
                    label_notes.extend(super::label::unlabelled_synthetic_note(line, c));
                }
            } else {
                label_notes.extend(super::label::unlabelled_synthetic_note(line, c));
            }
            continue;
        }
        let fields: Vec<&str> = t.split_whitespace().collect();
        if std::mem::take(&mut before_data) {
            if fields.len() == NAMES.len()
                && fields
                    .iter()
                    .zip(NAMES)
                    .all(|(f, n)| f.eq_ignore_ascii_case(n))
            {
                continue;
            }
            // Another column-name line: say what is read, not that 'theta' is no number.
            let named = |f: &&str| NAMES.iter().any(|n| f.eq_ignore_ascii_case(n));
            if fields
                .first()
                .is_some_and(|f| f.parse::<f64>().is_err() && *f != "?")
                && fields.iter().any(named)
            {
                return Err(perr(
                    line,
                    "column 1".into(),
                    format!(
                        "column-name line {}: a Yan-2015 file may name its columns only as \
                         'phi theta value' (in that order), or not at all",
                        quoted(t)
                    ),
                ));
            }
        }
        if fields.len() < 3 && t.contains(',') {
            return Err(perr(
                line,
                "column 1".into(),
                "fields separated by commas: a Yan-2015 file separates phi, theta and value \
                 by spaces or tabs (a comma-separated profile is read as CSV when named .csv)"
                    .into(),
            ));
        }
        if fields.len() != 3 {
            return Err(perr(
                line,
                format!("column {}", fields.len().min(3) + 1),
                format!(
                    "expected 3 fields (phi theta value), found {}",
                    fields.len()
                ),
            ));
        }
        let num = |i: usize| -> Result<f64> {
            parse_number(fields[i]).map_err(|m| perr(line, label(i), m))
        };
        let raw = num(0)?;
        let phi = read_phi("phi", raw, opts).map_err(|m| perr(line, label(0), m))?;
        let theta = check_angle("theta", num(1)?, 90.0).map_err(|m| perr(line, label(1), m))?;
        let value = if fields[2] == "?" {
            f64::NAN
        } else {
            let v = num(2)?;
            if v.is_infinite() {
                return Err(perr(
                    line,
                    label(2),
                    format!("value {v} is infinite or beyond the f64 range, 1.8e308 (write ? for a missing value)"),
                ));
            }
            v
        };
        // theta_i is set below, from the file's comment or --theta-i.
        super::checks::check_sample_count(
            samples.len(),
            super::checks::MAX_READ_CELLS,
            path,
            line,
        )?;
        let mut s = Sample::new(0.0, convert_theta_r(opts, theta), phi, value);
        s.origin = Origin::at_line(line);
        samples.push(s);
        raw_phi.push(raw);
    }
    let mut notes = Vec::new();
    let opt_theta_i = match (&opts.theta_i, file_theta_i) {
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
    };
    // Before the incident angle: a file without data says so, not that theta_i is missing.
    if samples.is_empty() {
        return Err(Error::file(path, "no data rows (phi theta value)"));
    }
    let theta_i = match (file_theta_i, opt_theta_i) {
        (Some((f, l)), Some(o)) if f != o => {
            return Err(perr(
                l,
                "theta_i comment".into(),
                format!(
                    "the file says theta_i {} but --theta-i is {}",
                    Num(f),
                    Num(o)
                ),
            ))
        }
        (Some((f, _)), _) => f,
        (None, Some(o)) => o,
        (None, None) => {
            return Err(Error::file(
                path,
                "no incident angle: add a '# theta_i: <deg>' line or pass --theta-i <deg>",
            ))
        }
    };
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

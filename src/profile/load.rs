//! Loading and saving by file name: [`load`] / [`load_full`] pick the reader by extension,
//! [`save`] writes `.csv` or `.npz`, [`load_dir`] reads and merges a species folder; the
//! text checks and the radians warning every load runs.

use super::checks::{MAX_FILE_BYTES, MAX_READ_CELLS};
use super::merge::{collapsed_note, merge_loaded};
use super::sample::{
    is_profile_file, samples_sha256, Format, LoadOptions, Loaded, Profile, ReadFile,
};
use super::{csv, npz, provenance, yan};
use crate::error::{Error, Result};
use crate::text::split_lines;
use std::path::{Path, PathBuf};

/// Load a profile file, choosing the loader by extension: `.csv` ([`csv`]), `.npz`
/// ([`npz`]), `.npy` ([`npz::parse_npy`], needs the three axis grids in `opts`),
/// `.txt`/`.dat` ([`yan`]). The convention options of `opts` (`flip_phi`, `phi_offset`,
/// `flip_theta_r`) apply to every format, as each reader reads its angles ([`read_phi`](super::checks::read_phi),
/// [`convert_theta_r`](super::checks::convert_theta_r)). `Profile::source` is set to `path`.
pub fn load(path: &Path, opts: &LoadOptions) -> Result<Profile> {
    load_full(path, opts).map(|l| l.profile)
}

/// [`load`], also returning the format and the loader's notes. A `metadata.json` beside
/// the file that labels the data synthetic labels the profile too
/// ([`provenance::apply_folder_label`]; one that does not read is an error).
pub fn load_full(path: &Path, opts: &LoadOptions) -> Result<Loaded> {
    let mut l = load_file(path, opts)?;
    let notes = provenance::apply_folder_label(&mut l.profile, &crate::io::parent_dir(path))?;
    l.notes.extend(notes);
    Ok(l)
}

/// A profile file's bytes read as `format` (`path` names it in errors): the text checks of
/// CSV and Yan-2015 files (not binary, not UTF-16), then that format's loader. What
/// [`load_full`] does once the file is read; also the entry of the loader fuzz target.
pub fn parse_bytes(
    format: Format,
    bytes: &[u8],
    path: &Path,
    opts: &LoadOptions,
) -> Result<(Profile, Vec<String>)> {
    if matches!(format, Format::Csv | Format::Yan) {
        check_not_binary(bytes, path)?;
        check_not_utf16(bytes, path)?;
    }
    match format {
        Format::Csv => csv::parse_with(bytes, path, opts),
        Format::Npz => npz::parse_npz_with(bytes, path, opts),
        Format::Npy => npz::parse_npy(bytes, path, opts),
        Format::Yan => yan::parse(bytes, path, opts),
    }
}

/// [`load_full`] without its folder's `metadata.json` label ([`load_dir`] applies that
/// once to the merged profile).
fn load_file(path: &Path, opts: &LoadOptions) -> Result<Loaded> {
    let format = Format::from_path(path)?;
    // Read whole (the fit records its digest), so bounded first: an archive padded with
    // a gigabyte of other members was read into memory before its arrays were looked at.
    let size = std::fs::metadata(path)
        .map_err(|e| Error::io(path, e))?
        .len();
    if size > MAX_FILE_BYTES {
        return Err(Error::file(
            path,
            format!(
                "{size} bytes: a profile file may hold at most {MAX_FILE_BYTES} bytes (a \
                 profile of the most samples a file may hold, {MAX_READ_CELLS}, fits); split it"
            ),
        ));
    }
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let (mut profile, notes) = parse_bytes(format, &bytes, path, opts)?;
    profile.source = Some(path.to_path_buf());
    let mut notes = notes;
    notes.extend(radians_warning(&profile));
    let content = samples_sha256(&profile);
    Ok(Loaded {
        profile,
        format,
        files: vec![ReadFile {
            path: path.to_path_buf(),
            format,
            sha256: crate::io::sha256_hex(&bytes),
            samples_sha256: content,
        }],
        notes,
    })
}

/// A text profile that is a NumPy file under a text name (an `.npz` renamed `.csv`) would
/// otherwise read as a header of zip bytes: its signature names it.
fn check_not_binary(bytes: &[u8], path: &Path) -> Result<()> {
    let what = if bytes.starts_with(b"PK\x03\x04") {
        "a zip/npz archive; a NumPy grid is read when named .npz"
    } else if bytes.starts_with(b"\x93NUMPY") {
        "a NumPy .npy array; a lone array is read when named .npy"
    } else {
        return Ok(());
    };
    Err(Error::file(
        path,
        format!("binary file (looks like {what}), not a text profile"),
    ))
}

/// Text profiles are UTF-8 (or ASCII). Excel's "Unicode Text" export is UTF-16, which
/// would otherwise read as garbled header names; its byte-order mark names it.
fn check_not_utf16(bytes: &[u8], path: &Path) -> Result<()> {
    let bom = match bytes {
        [0xFF, 0xFE, ..] => "FF FE",
        [0xFE, 0xFF, ..] => "FE FF",
        _ => return Ok(()),
    };
    Err(Error::Parse {
        file: path.to_path_buf(),
        line: 1,
        column: "column 1".into(),
        msg: format!(
            "the file is UTF-16 (byte-order mark {bom}); save it as UTF-8 (e.g. Excel's \"CSV UTF-8\")"
        ),
    })
}

/// Largest |angle| of a profile whose angles look like radians: pi, plus slack for
/// rounded exports.
const RADIANS_LIMIT: f64 = 3.2;
/// Slack on pi/2 and 2 pi for [`radians_warning`]'s second test (rounded exports).
const RADIANS_SLACK: f64 = 0.01;

/// A warning (a loader note, not an error) when `profile`'s angles look like radians:
/// files hold degrees (DATA.md), a real goniometer sweep spans far more than a few degrees,
/// and radians read as degrees load silently and fit to absurd parameters. Either every
/// `theta_i`, `theta_r` and `phi` lies within +-3.2 and not all are 0, or every theta lies
/// within +-pi/2 and every phi within +-2 pi (azimuths written 0..2 pi, the usual radian
/// form), 0.01 of slack each, over at least two directions.
pub fn radians_warning(profile: &Profile) -> Option<String> {
    let (mut theta, mut phi) = (0.0f64, 0.0f64);
    let mut first: Option<(f64, f64, f64)> = None;
    let mut two_directions = false;
    for s in &profile.samples {
        if [s.theta_i, s.theta_r, s.phi].iter().any(|a| a.is_nan()) {
            return None;
        }
        theta = theta.max(s.theta_i.abs()).max(s.theta_r.abs());
        phi = phi.max(s.phi.abs());
        let here = (s.theta_i, s.theta_r, s.phi);
        two_directions |= *first.get_or_insert(here) != here;
    }
    let largest = theta.max(phi);
    if largest > 0.0 && largest <= RADIANS_LIMIT {
        return Some(format!(
            "warning: every theta_i, theta_r and phi lies within +-{RADIANS_LIMIT} (largest |angle| {largest}): \
             the values look like radians, but files hold degrees (DATA.md); convert them (x 180/pi) before fitting"
        ));
    }
    let (theta_max, phi_max) = (
        std::f64::consts::FRAC_PI_2 + RADIANS_SLACK,
        std::f64::consts::TAU + RADIANS_SLACK,
    );
    (two_directions && theta <= theta_max && phi <= phi_max).then(|| {
        format!(
            "warning: every theta_i and theta_r lies within +-pi/2 and every phi within +-2 pi \
             (largest |theta| {theta}, largest |phi| {phi}): the values look like radians, but \
             files hold degrees (DATA.md); convert them (x 180/pi) before fitting"
        )
    })
}

/// The format [`save`] writes to `path`: `.csv` or `.npz` by extension (case-insensitive);
/// any other name is an error naming the path, so a caller can check it before the work.
pub fn save_format(path: &Path) -> Result<Format> {
    match Format::from_path(path) {
        Ok(f @ (Format::Csv | Format::Npz)) => Ok(f),
        found => {
            let what = match (found, path.extension()) {
                (Ok(f), _) => format!("{} files", f.name()),
                (Err(_), Some(e)) => format!("'.{}' files", e.to_string_lossy()),
                (Err(_), None) => "a file without an extension".into(),
            };
            Err(Error::file(
                path,
                format!("cannot write {what}; the extension picks the format: .csv or .npz"),
            ))
        }
    }
}

/// The bytes [`save`] would write to `path` (format by extension, see [`save_format`]).
pub fn encode(path: &Path, profile: &Profile) -> Result<Vec<u8>> {
    match save_format(path)? {
        Format::Npz => npz::to_bytes(profile),
        _ => csv::to_string(profile).map(String::into_bytes),
    }
}

/// Save a profile as `.csv` or `.npz` (by extension), atomically via [`crate::io`].
pub fn save(path: &Path, profile: &Profile) -> Result<()> {
    let bytes = encode(path, profile)?;
    crate::io::write_atomic(path, &bytes)
}

/// Is this text meant as a Yan-2015 profile? It has a `# theta_i:` line (anywhere), or its
/// first line that is neither blank nor a `#` comment names the columns (two to four
/// fields, each `phi`, `theta` or `value`, also with a suffix such as `theta_r` or
/// `phi(deg)`, as labs export), or more than half of its first [`SNIFF_LINES`] such lines
/// are rows of three or four numbers (`?` and the spellings `NA`, `None`, `null`, `n/a` of
/// a missing value count as numbers).
///
/// The whole head decides, not the first line: a notes file may begin like a row (`20 C
/// freezer`, `2017 06 12`) and a profile may begin with a typo (`0 l0 1`) or a misspelt
/// header (`phi theta vlaue`). A folder's `.txt`/`.dat` that is not a profile
/// (`notes.txt`) is skipped with a note, not an error; a profile whose first row or
/// header the reader does not take ([`yan`] skips only `phi theta value`) still counts,
/// so it is read and its error reported.
pub fn looks_like_yan(bytes: &[u8]) -> bool {
    let names_a_column = |f: &str| {
        let f = f.trim_matches(['"', '\'']).to_ascii_lowercase();
        ["phi", "theta", "value"].iter().any(|n| {
            f.strip_prefix(n)
                .is_some_and(|rest| !rest.starts_with(|c: char| c.is_ascii_alphabetic()))
        })
    };
    let number = |f: &str| {
        f == "?"
            || f.parse::<f64>().is_ok()
            || ["na", "none", "null", "n/a"].contains(&f.to_ascii_lowercase().as_str())
    };
    let (mut lines, mut rows) = (0usize, 0usize);
    for raw in split_lines(bytes) {
        let text = String::from_utf8_lossy(raw);
        let t = text.trim().trim_start_matches('\u{feff}').trim();
        if let Some(c) = t.strip_prefix('#') {
            if yan::theta_i_comment(c).is_some() {
                return true;
            }
            continue;
        }
        if t.is_empty() || lines >= SNIFF_LINES {
            continue;
        }
        let fields: Vec<&str> = t
            .split(|c: char| c.is_whitespace() || c == ',' || c == ';')
            .filter(|f| !f.is_empty())
            .collect();
        if lines == 0 && (2..=4).contains(&fields.len()) && fields.iter().all(|f| names_a_column(f))
        {
            return true;
        }
        lines += 1;
        if (3..=4).contains(&fields.len()) && fields.iter().all(|f| number(f)) {
            rows += 1;
        }
    }
    2 * rows > lines
}

/// Lines (neither blank nor comments) whose rows [`looks_like_yan`] counts.
const SNIFF_LINES: usize = 50;

/// The profile files of a directory that [`load_dir`] reads, sorted, and a note for each
/// `.txt`/`.dat` it skips because it is not a Yan-2015 profile ([`looks_like_yan`]), each
/// subfolder and each hidden file with a profile extension.
pub fn dir_profile_files(dir: &Path) -> Result<(Vec<PathBuf>, Vec<String>)> {
    let rd = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    let mut files = Vec::new();
    // What a user may have meant as data but is not read: subfolders and hidden profile
    // files (a dot-folder such as `.git` is nobody's data and gets no note).
    let mut unread = Vec::new();
    for entry in rd {
        let entry = entry.map_err(|e| Error::io(dir, e))?;
        let p = entry.path();
        let name = entry.file_name().to_string_lossy().into_owned();
        if is_profile_file(&p) {
            files.push(p);
        } else if p.is_dir() && !name.starts_with('.') {
            unread.push(format!("skipped {name}/: subfolders are not read"));
        } else if name.starts_with('.') && p.is_file() && Format::from_path(&p).is_ok() {
            unread.push(format!("skipped {name}: hidden file"));
        }
    }
    files.sort();
    unread.sort();
    let mut kept = Vec::new();
    let mut notes = unread;
    for f in files {
        if Format::from_path(&f).ok() == Some(Format::Yan) {
            let bytes = std::fs::read(&f).map_err(|e| Error::io(&f, e))?;
            if !looks_like_yan(&bytes) {
                let name = f.file_name().unwrap_or_default().to_string_lossy();
                notes.push(format!("skipped {name}: not a Yan-2015 profile"));
                continue;
            }
        }
        kept.push(f);
    }
    Ok((kept, notes))
}

/// Load every profile file of a directory (e.g. `measurements/<species>/`), in file-name
/// order, and [`merge`](super::merge::merge) them into one profile whose `source` is the directory. A `.txt` or
/// `.dat` that does not read as a Yan-2015 profile is skipped with a note
/// ([`dir_profile_files`]); named on its own ([`load_full`]) it is an error.
pub fn load_dir(dir: &Path, opts: &LoadOptions) -> Result<Loaded> {
    let (files, skipped) = dir_profile_files(dir)?;
    if files.is_empty() {
        let why = if skipped.is_empty() {
            String::new()
        } else {
            format!(" ({})", skipped.join("; "))
        };
        return Err(Error::file(
            dir,
            format!("no profile files (.csv, .npz, .npy, .txt, .dat) in this directory{why}"),
        ));
    }
    let mut parts = Vec::new();
    let mut notes = skipped;
    let mut format = None;
    let mut read = Vec::new();
    let mut total = 0usize;
    for f in &files {
        let mut l = load_file(f, opts)?;
        // Each file is bounded by MAX_READ_CELLS; the folder as a whole is too, so a few
        // small archives of large grids cannot together exhaust memory.
        total += l.profile.samples.len();
        if total > MAX_READ_CELLS {
            return Err(Error::file(
                dir,
                format!(
                    "its files hold more than {MAX_READ_CELLS} samples together (up to {} read); fit them as several folders",
                    f.display()
                ),
            ));
        }
        format.get_or_insert(l.format);
        read.extend(l.files.iter().cloned());
        notes.extend(l.notes.drain(..).map(|n| format!("{}: {n}", f.display())));
        parts.push(l);
    }
    let (mut profile, collapsed) = merge_loaded(parts, opts)?;
    notes.extend(collapsed_note(collapsed, "files"));
    notes.extend(provenance::apply_folder_label(&mut profile, dir)?);
    profile.source = Some(dir.to_path_buf());
    Ok(Loaded {
        profile,
        format: format.unwrap_or(Format::Csv),
        files: read,
        notes,
    })
}

//! Goniometric fiber profiles: the in-memory [`Profile`] and its loaders and writers
//! (CSV per DATA.md, `.npy`/`.npz` dense grids, the Yan-2015 text format).
//!
//! Angles are stored in **degrees**, exactly as read (unless [`LoadOptions`] asks for a
//! convention conversion, or a phi written outside (-180, 180] is wrapped into it), so that a
//! profile round-trips through every format bit for bit; use [`Sample::angles_rad`] to get
//! the radians the model needs.
//!
//! Entry points: [`load`] / [`load_full`] pick the reader by extension ([`csv`], [`npz`]
//! for `.npz` and lone `.npy`, [`yan`] for `.txt`/`.dat`), [`save`] writes `.csv` or `.npz`
//! atomically, [`load_dir`] reads and [`merge`]s a species folder (skipping, with a note,
//! a `.txt`/`.dat` that is not a Yan-2015 profile, e.g. `notes.txt`: [`looks_like_yan`]).
//! [`summary`] computes what `furfit inspect` prints.
//!
//! Choices shared by every reader (each documented again in its module):
//! - angles are normalised once: `-0` -> `0`, and any finite phi in [-360, 360] (files
//!   written in [0, 360) are common) is converted by the [`LoadOptions`] conventions and
//!   wrapped to MODEL.md's (-180, 180] (`-180` -> `180`, `270` -> `-90`) by one function,
//!   [`read_phi`], so one direction has one spelling whatever the format;
//! - a repeated direction (same `theta_i, theta_r, phi, channel`) whose other fields are
//!   identical is collapsed into its first occurrence with a note in [`Loaded::notes`]; a
//!   repeat that differs is an error naming both places (and, when the two were written
//!   with different phi that wrap alike, e.g. a sweep's 0 and 360, saying so:
//!   [`wrap_conflict`]);
//! - invalid values (NaN, `<= 0`) are kept as samples, never dropped; two of them for one
//!   direction (NaN and -1 at a sweep's two ends) are one invalid sample, collapsed;
//! - a file whose every angle lies within +-3.2 (not all 0), or whose thetas lie within
//!   +-pi/2 and phi within +-2 pi, gets a warning note: the values look like radians, but
//!   files hold degrees ([`radians_warning`]);
//! - text echoed from a file in a message is [`escaped`] (a BOM, a NUL), and a number
//!   below the f64 range (`1e-400`) is an error like one above it ([`parse_number`]).

use crate::error::{Error, Num, Result};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Most samples (or grid cells) a loader reads from one file: a loaded sample takes ~190
/// bytes (an audit measured 185), so 20 M is ~3.8 GB; a 512 MiB float64 npz array (67 M
/// cells) would need ~13 GB. Beyond, the file is refused before the memory is spent.
pub const MAX_READ_CELLS: usize = 20_000_000;

/// Before reading sample `n + 1` on `line` of `path`: an error once `n` reaches `limit`
/// ([`MAX_READ_CELLS`] for the text loaders).
/// Largest profile file the loaders read (1 GiB): above the largest profile of
/// [`MAX_READ_CELLS`] samples in any format (a CSV row of ~40 bytes, an npz cell of value,
/// sigma, phi_i and mask in 25).
pub const MAX_FILE_BYTES: u64 = 1 << 30;

pub(crate) fn check_sample_count(n: usize, limit: usize, path: &Path, line: usize) -> Result<()> {
    if n < limit {
        return Ok(());
    }
    Err(Error::file(
        path,
        format!(
            "line {line}: more than {limit} samples, the most a profile file may hold (each \
             takes ~190 bytes once loaded); split it into several files"
        ),
    ))
}

pub mod csv;
pub mod npz;
pub mod provenance;
pub mod summary;
pub mod yan;

/// One goniometer sample: light from `theta_i`, camera at `(theta_r, phi)`.
#[derive(Clone, Debug)]
pub struct Sample {
    /// Incident inclination, degrees.
    pub theta_i: f64,
    /// Outgoing inclination, degrees.
    pub theta_r: f64,
    /// Relative azimuth `phi_r - phi_i`, degrees in (-180, 180].
    pub phi: f64,
    /// Measured linear intensity; `<= 0` or NaN marks an invalid sample (DATA.md).
    pub value: f64,
    /// Standard error of `value`, if known.
    pub sigma: Option<f64>,
    /// Index into [`Profile::channels`] (0 when the profile has a single channel).
    pub channel: usize,
    /// Optional absolute incident azimuth, degrees (kept for round trips, unused by the model).
    pub phi_i: Option<f64>,
    /// Where it was read, for messages; not part of the measurement (equality ignores it).
    pub origin: Origin,
}

impl PartialEq for Sample {
    fn eq(&self, o: &Sample) -> bool {
        (
            self.theta_i,
            self.theta_r,
            self.phi,
            self.value,
            self.sigma,
            self.channel,
            self.phi_i,
        ) == (
            o.theta_i, o.theta_r, o.phi, o.value, o.sigma, o.channel, o.phi_i,
        )
    }
}

/// Where a sample was read: an index into [`Profile::files`] and a place in that file, so
/// an error found after loading (a conflict between two files of a folder, `--weighted`
/// without a sigma) can still name it. `line` is the line of a text row, or for a cell of
/// a `.npy`/`.npz` grid 1 + the cell's row-major index in `value` (the file's
/// [`Layout::Grid`] gives the shape to name it by), so a sample stays as small as it was;
/// 0 for a sample made in memory.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Origin {
    pub file: u32,
    pub line: u32,
}

impl Origin {
    /// Line `line` (1-based) of the profile's first file; a line beyond `u32::MAX` (a file
    /// of over four billion lines, far past [`MAX_READ_CELLS`] samples) is not named.
    pub fn at_line(line: usize) -> Origin {
        Origin {
            file: 0,
            line: u32::try_from(line).unwrap_or(0),
        }
    }

    /// The cell of row-major index `flat` in the `value` array of the profile's first file
    /// (a grid: [`Layout::Grid`]); an index past `u32::MAX - 1` (beyond [`MAX_READ_CELLS`])
    /// is not named.
    pub fn at_cell(flat: usize) -> Origin {
        Origin::at_line(flat.saturating_add(1))
    }
}

/// How messages name a place in one of [`Profile::files`] ([`Profile::layouts`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub enum Layout {
    /// Not known (a profile made in memory): a place is `FILE line N`, or `FILE`.
    #[default]
    Unknown,
    /// A text file (CSV, Yan-2015): [`Origin::line`] is a row's line; `value_column`
    /// labels its value column as the file's own errors do (`column 4 (value)`), and
    /// likewise its sigma and phi_i columns if it has them.
    Rows {
        value_column: String,
        sigma_column: Option<String>,
        phi_i_column: Option<String>,
    },
    /// A `.npz` / lone `.npy` grid whose `value` array has this shape: [`Origin::line`] is
    /// 1 + the cell's row-major index; whether it has `sigma` and `phi_i` arrays.
    Grid {
        shape: Vec<usize>,
        sigma: bool,
        phi_i: bool,
    },
}

impl Layout {
    /// The index `[i, j, k(, c)]` of grid cell `o` (by its shape), if `o` is one.
    fn cell(&self, o: Origin) -> Option<Vec<usize>> {
        let Layout::Grid { shape, .. } = self else {
            return None;
        };
        let mut flat = (o.line as usize).checked_sub(1)?;
        let mut ix = vec![0; shape.len()];
        for (k, &n) in shape.iter().enumerate().rev() {
            if n == 0 {
                return None;
            }
            ix[k] = flat % n;
            flat /= n;
        }
        (flat == 0).then_some(ix)
    }
}

/// [`Profile::origin_of`] given the profile's files and their layouts.
fn origin_text(files: &[PathBuf], layouts: &[Layout], o: Origin) -> Option<String> {
    let file = files.get(o.file as usize)?.display();
    let layout = layouts.get(o.file as usize).unwrap_or(&Layout::Unknown);
    if let Layout::Grid { .. } = layout {
        return Some(match layout.cell(o) {
            Some(ix) => format!("{file} index {ix:?}"),
            None => file.to_string(),
        });
    }
    Some(match o.line {
        0 => file.to_string(),
        n => format!("{file} line {n}"),
    })
}

/// Where a duplicate's copy sits, as a single file's own duplicate error names it:
/// `FILE:LINE: column N (value)` for a text row, `FILE: array 'value' index [i, j, k]` for
/// a grid cell, naming the column or array of `field` (the one that differs);
/// [`origin_text`] when the layout is unknown.
fn place_text(files: &[PathBuf], layouts: &[Layout], o: Origin, field: Field) -> Option<String> {
    let file = files.get(o.file as usize)?.display();
    match layouts.get(o.file as usize) {
        Some(Layout::Rows {
            value_column,
            sigma_column,
            phi_i_column,
        }) if o.line > 0 => {
            let column = match field {
                Field::Value => None,
                Field::Sigma => sigma_column.as_ref(),
                Field::PhiI => phi_i_column.as_ref(),
            };
            Some(format!(
                "{file}:{}: {}",
                o.line,
                column.unwrap_or(value_column)
            ))
        }
        Some(l @ Layout::Grid { sigma, phi_i, .. }) => l.cell(o).map(|ix| {
            // The differing field's array, if the file has one (else its value array).
            let array = match field {
                Field::Sigma if *sigma => "sigma",
                Field::PhiI if *phi_i => "phi_i",
                _ => "value",
            };
            // A lone .npy is one unnamed array; an .npz names its `value` array.
            let lone = files[o.file as usize]
                .extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("npy"));
            if lone {
                format!("{file}: index {ix:?}")
            } else {
                format!("{file}: array '{array}' index {ix:?}")
            }
        }),
        _ => None,
    }
    .or_else(|| origin_text(files, layouts, o))
}

impl Sample {
    /// A channel-0 sample at `(theta_i, theta_r, phi)` (degrees) without sigma or
    /// incident azimuth.
    pub fn new(theta_i: f64, theta_r: f64, phi: f64, value: f64) -> Sample {
        Sample {
            theta_i,
            theta_r,
            phi,
            value,
            sigma: None,
            channel: 0,
            phi_i: None,
            origin: Origin::default(),
        }
    }

    /// A sample with usable signal: finite and strictly positive.
    pub fn is_valid(&self) -> bool {
        self.value.is_finite() && self.value > 0.0
    }

    /// `(theta_i, theta_r, phi)` in radians.
    pub fn angles_rad(&self) -> (f64, f64, f64) {
        (
            self.theta_i.to_radians(),
            self.theta_r.to_radians(),
            self.phi.to_radians(),
        )
    }
}

/// A goniometric profile: samples plus the file's metadata.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Profile {
    pub samples: Vec<Sample>,
    /// Channel names (`r`, `g`, `b`, `650nm` ...). Empty means one unnamed channel.
    pub channels: Vec<String>,
    /// `# key: value` metadata, in file order.
    pub metadata: Vec<(String, String)>,
    /// Where the profile was read from, if anywhere.
    pub source: Option<PathBuf>,
    /// The files its samples were read from ([`Sample::origin`] indexes them); empty for
    /// a profile made in memory.
    pub files: Vec<PathBuf>,
    /// How messages name a place in each of `files` (same order; a missing entry is
    /// [`Layout::Unknown`]).
    pub layouts: Vec<Layout>,
}

impl Profile {
    /// Number of valid samples.
    pub fn n_valid(&self) -> usize {
        self.samples.iter().filter(|s| s.is_valid()).count()
    }

    /// Number of invalid samples (kept, never used in a logarithm).
    pub fn n_invalid(&self) -> usize {
        self.samples.len() - self.n_valid()
    }

    /// Where `s` was read, as messages name it: `FILE line N` for a text row,
    /// `FILE index [i, j, k]` for a grid cell, `None` for a sample made in memory.
    pub fn origin_of(&self, s: &Sample) -> Option<String> {
        origin_text(&self.files, &self.layouts, s.origin)
    }

    /// Number of channels (at least 1).
    pub fn n_channels(&self) -> usize {
        self.channels.len().max(1)
    }

    /// First metadata value for `key`.
    pub fn meta(&self, key: &str) -> Option<&str> {
        self.metadata
            .iter()
            .find(|(k, _)| k == key)
            .map(|(_, v)| v.as_str())
    }

    /// Set (replace or append) a metadata entry.
    pub fn set_meta(&mut self, key: &str, value: impl Into<String>) {
        let value = value.into();
        match self.metadata.iter_mut().find(|(k, _)| k == key) {
            Some(e) => e.1 = value,
            None => self.metadata.push((key.to_string(), value)),
        }
    }

    /// Does the profile say it is synthetic ([`says_synthetic`] of any metadata entry)?
    pub fn is_synthetic(&self) -> bool {
        self.metadata
            .iter()
            .any(|(k, v)| says_synthetic(k, v) == Some(true))
    }

    /// Is the profile explicitly labelled measured: a `synthetic: false` entry (any
    /// spelling [`says_synthetic`] reads as false) and nothing saying synthetic?
    pub fn is_labelled_measured(&self) -> bool {
        !self.is_synthetic()
            && self
                .metadata
                .iter()
                .any(|(k, v)| says_synthetic(k, v) == Some(false))
    }
}

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

impl Profile {
    /// Sort the samples into grid order: `theta_i`, `theta_r`, `phi`, `channel` ascending
    /// (the order an `.npz` load yields), so two profiles holding the same sample set write
    /// byte-identical files.
    pub fn sort_grid_order(&mut self) {
        self.samples.sort_by(|a, b| {
            a.theta_i
                .total_cmp(&b.theta_i)
                .then(a.theta_r.total_cmp(&b.theta_r))
                .then(a.phi.total_cmp(&b.phi))
                .then(a.channel.cmp(&b.channel))
        });
    }
}

/// File formats the loaders understand.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// DATA.md CSV (`.csv`).
    Csv,
    /// Dense grid archive (`.npz`), see [`npz`].
    Npz,
    /// A lone `value` array (`.npy`); the axes come from [`LoadOptions`].
    Npy,
    /// Yan-2015 whitespace text, one incident angle per file (`.txt`, `.dat`).
    Yan,
}

impl Format {
    /// The format implied by a file's extension (case-insensitive).
    pub fn from_path(path: &Path) -> Result<Format> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase())
            .unwrap_or_default();
        match ext.as_str() {
            "csv" => Ok(Format::Csv),
            "npz" => Ok(Format::Npz),
            "npy" => Ok(Format::Npy),
            "txt" | "dat" => Ok(Format::Yan),
            _ => {
                let what = if ext.is_empty() {
                    "no file extension to tell the profile format".to_string()
                } else {
                    format!("unknown profile format '.{ext}'")
                };
                Err(Error::file(
                    path,
                    format!("{what} (expected .csv, .npz, .npy, or Yan-2015 .txt/.dat)"),
                ))
            }
        }
    }

    /// Short human name.
    pub fn name(self) -> &'static str {
        match self {
            Format::Csv => "csv",
            Format::Npz => "npz",
            Format::Npy => "npy",
            Format::Yan => "yan-2015 text",
        }
    }
}

/// Options for loaders whose files do not carry everything themselves.
#[derive(Clone, Debug, Default)]
pub struct LoadOptions {
    /// Incident angle grid (degrees). A Yan-2015 file uses it (exactly one value) when it
    /// has no `# theta_i:` line; a lone `.npy` uses it as its first axis.
    pub theta_i: Option<Vec<f64>>,
    /// Outgoing angle grid (degrees) for a lone `.npy`.
    pub theta_r: Option<Vec<f64>>,
    /// Azimuth grid (degrees) for a lone `.npy`; read like a file's phi ([`read_phi`]).
    pub phi: Option<Vec<f64>>,
    /// Degrees added to every file's phi (after `flip_phi`) before wrapping to (-180, 180]:
    /// data written in another azimuth convention, whatever the format ([`read_phi`]).
    pub phi_offset: f64,
    /// Negate every file's phi (applied before `phi_offset`).
    pub flip_phi: bool,
    /// Negate every file's theta_r.
    pub flip_theta_r: bool,
    /// `theta_i` is (also) the axis of a lone `.npy` read in the same run, so a Yan-2015
    /// file with its own `# theta_i:` line keeps its line and ignores `theta_i` (with a
    /// note when they differ), where it is otherwise an error (the file and the option
    /// disagree). Set by [`LoadOptions::for_inputs`]; not an option of its own.
    pub theta_i_for_npy: bool,
}

impl LoadOptions {
    /// These options for a run reading `inputs` (files and species folders):
    /// [`LoadOptions::theta_i_for_npy`] is set when one of them is, or a folder holds, a
    /// lone `.npy`. Every caller that loads inputs together derives it alike (`inspect`,
    /// `fit`, and `report` re-reading a fit's data), so none records it.
    pub fn for_inputs(&self, inputs: &[PathBuf]) -> LoadOptions {
        let npy = |p: &Path| Format::from_path(p).ok() == Some(Format::Npy);
        let has_npy = inputs.iter().any(|p| {
            if p.is_dir() {
                // An unreadable folder is reported by its load.
                std::fs::read_dir(p).is_ok_and(|rd| {
                    rd.flatten()
                        .any(|e| is_profile_file(&e.path()) && npy(&e.path()))
                })
            } else {
                npy(p)
            }
        });
        LoadOptions {
            theta_i_for_npy: has_npy,
            ..self.clone()
        }
    }

    /// Refuse an axis option that none of the loaded files' `formats` reads: `theta_i`
    /// is read by a lone `.npy` and a Yan-2015 file, `theta_r` and `phi` only by a lone
    /// `.npy`. A CSV or npz carries its own angles, so such an option would be recorded as
    /// if applied while changing nothing.
    pub fn check_used(&self, formats: &[Format]) -> Result<()> {
        let has = |f: Format| formats.contains(&f);
        if self.theta_i.is_some() && !has(Format::Npy) && !has(Format::Yan) {
            return Err(Error::Invalid(
                "--theta-i was given but no input is a lone .npy or Yan-2015 file (.csv and .npz files carry their own angles)".into(),
            ));
        }
        for (given, opt) in [(&self.theta_r, "--theta-r"), (&self.phi, "--phi")] {
            if given.is_some() && !has(Format::Npy) {
                return Err(Error::Invalid(format!(
                    "{opt} was given but no input is a lone .npy file (.csv, .npz and Yan-2015 files carry their own angles)"
                )));
            }
        }
        Ok(())
    }
}

/// Largest |phi| (degrees) a profile may hold as written, in every format: azimuths come in
/// (-180, 180] or [0, 360) (or negated), and are wrapped to (-180, 180] by [`read_phi`].
/// Beyond one turn a value is a typo, not a convention.
pub(crate) const PHI_LIMIT: f64 = 360.0;

/// A phi as a file (or a lone `.npy`'s `--phi` grid) writes it, read under `opts`: finite and
/// within [-[`PHI_LIMIT`], `PHI_LIMIT`], negated if `flip_phi`, plus `phi_offset`, then
/// wrapped to (-180, 180]. Every reader calls it, so the formats cannot drift apart and the
/// offset applies before the wrap (a file in [0, 360) may take `--phi-offset -180`). With
/// no conversion a phi in (-180, 180] comes back bit for bit ([`wrap_phi`] is the identity
/// there, `-0` and `-180` aside). `name` labels the message, which the caller places.
pub(crate) fn read_phi(name: &str, v: f64, opts: &LoadOptions) -> std::result::Result<f64, String> {
    let v = check_angle(name, v, PHI_LIMIT)?;
    let p = if opts.flip_phi { -v } else { v } + opts.phi_offset;
    if !p.is_finite() {
        return Err(format!(
            "{name} {} plus the phi offset {} is not finite",
            Num(v),
            Num(opts.phi_offset)
        ));
    }
    Ok(wrap_phi(p))
}

/// A theta_r as a file writes it (already range-checked), under `opts`: negated if
/// `flip_theta_r`; `-0` becomes `0`.
pub(crate) fn convert_theta_r(opts: &LoadOptions, theta_r: f64) -> f64 {
    let t = if opts.flip_theta_r { -theta_r } else { theta_r };
    t + 0.0
}

/// Does `opts` change phi as read (so a message about a wrap names the options too)?
fn converts_phi(opts: &LoadOptions) -> bool {
    opts.flip_phi || opts.phi_offset != 0.0
}

/// The message for two conflicting samples of one file that are one direction only because
/// their phi, written differently, wrapped alike (a full sweep's 0 and 360, or -180 and
/// 180); `None` when both were written alike (an ordinary duplicate). `raw_first` and
/// `raw_repeat` are the phi as written, `first_at` the first one's place (`line 2`,
/// `element 0`), `c` the conflict, `cells` optional extra context after the difference
/// (npz cells). Shared by the readers so they word it alike.
pub(crate) fn wrap_conflict(
    raw_first: f64,
    raw_repeat: f64,
    first_at: &str,
    c: &Conflict,
    cells: &str,
    opts: &LoadOptions,
) -> Option<String> {
    if raw_first == raw_repeat {
        return None;
    }
    let (diff, phi) = (&c.diff, c.phi);
    let head = if raw_first == phi && !converts_phi(opts) {
        format!("phi {raw_repeat} wraps to {phi}, which {first_at} already holds with a different {diff}{cells}")
    } else {
        let how = if converts_phi(opts) {
            "after --flip-phi / --phi-offset and the wrap to (-180, 180]"
        } else {
            "once wrapped to (-180, 180]"
        };
        format!(
            "phi {raw_repeat} and phi {raw_first} on {first_at} are the same direction (both {phi} {how}), with a different {diff}{cells}"
        )
    };
    Some(format!("{head}; drop one of the two endpoint measurements"))
}

/// One file a loader read: its path, format and the SHA-256 of the bytes it parsed (what
/// a fit file records, so the digest is of exactly the data fitted).
#[derive(Clone, Debug)]
pub struct ReadFile {
    pub path: PathBuf,
    pub format: Format,
    /// SHA-256 of the file's bytes.
    pub sha256: String,
    /// SHA-256 of the samples it holds as read ([`samples_sha256`]): the same for a file
    /// rewritten with other number formatting or comments, e.g. the recorded `simulate`
    /// command re-run by another build.
    pub samples_sha256: String,
}

/// SHA-256 of a profile's samples in order: each sample's angles, value, sigma, channel
/// name and `phi_i` (little-endian f64 bits; a missing optional as a marker byte), so two
/// files holding the same samples have one digest whatever their format or layout.
pub fn samples_sha256(p: &Profile) -> String {
    let mut bytes = Vec::with_capacity(p.samples.len() * 64);
    let opt = |b: &mut Vec<u8>, v: Option<f64>| match v {
        Some(x) => {
            b.push(1);
            b.extend_from_slice(&x.to_bits().to_le_bytes());
        }
        None => b.push(0),
    };
    for s in &p.samples {
        for x in [s.theta_i, s.theta_r, s.phi, s.value] {
            bytes.extend_from_slice(&x.to_bits().to_le_bytes());
        }
        opt(&mut bytes, s.sigma);
        opt(&mut bytes, s.phi_i);
        let name = p.channels.get(s.channel).map_or("", String::as_str);
        bytes.extend_from_slice(&(name.len() as u64).to_le_bytes());
        bytes.extend_from_slice(name.as_bytes());
    }
    crate::io::sha256_hex(&bytes)
}

/// A loaded profile with what the loader noticed on the way.
#[derive(Clone, Debug)]
pub struct Loaded {
    pub profile: Profile,
    pub format: Format,
    /// The files read (one for [`load_full`], the folder's for [`load_dir`]).
    pub files: Vec<ReadFile>,
    /// Things the loader did that a user should know about (e.g. identical duplicate
    /// samples collapsed into one). Never errors: those are returned as `Err`.
    pub notes: Vec<String>,
}

/// Load a profile file, choosing the loader by extension: `.csv` ([`csv`]), `.npz`
/// ([`npz`]), `.npy` ([`npz::parse_npy`], needs the three axis grids in `opts`),
/// `.txt`/`.dat` ([`yan`]). The convention options of `opts` (`flip_phi`, `phi_offset`,
/// `flip_theta_r`) apply to every format, as each reader reads its angles ([`read_phi`],
/// [`convert_theta_r`]). `Profile::source` is set to `path`.
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

/// Is this directory entry a profile file [`load_dir`] should read? Profile extensions
/// only; `metadata.json`, README files and hidden files are skipped.
pub fn is_profile_file(path: &Path) -> bool {
    let name = match path.file_name() {
        Some(n) => n.to_string_lossy().to_ascii_lowercase(),
        None => return false,
    };
    if name.starts_with('.') || name.starts_with("readme") || name.starts_with("metadata") {
        return false;
    }
    path.is_file() && Format::from_path(path).is_ok()
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
/// order, and [`merge`] them into one profile whose `source` is the directory. A `.txt` or
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

/// Merge profiles into one: channels are matched by name (the union, in order of first
/// appearance; parts with one unnamed channel merge with each other, and mixing them with
/// named channels is an error: which channel they belong to is not known),
/// metadata entries are concatenated with exact repeats dropped, samples concatenated. A sample present in two parts with a different value is an error naming
/// both sources; identical copies are collapsed (their count is returned).
pub fn merge(parts: Vec<Profile>) -> Result<(Profile, usize)> {
    merge_with(parts, |_, _| None)
}

/// [`merge`], adding `hint(first_part, repeat_part)` (if any) to a conflict's error.
fn merge_with(
    parts: Vec<Profile>,
    hint: impl Fn(usize, usize) -> Option<String>,
) -> Result<(Profile, usize)> {
    let mut out = Profile::default();
    let mut origin: Vec<usize> = Vec::new();
    let sources: Vec<String> = parts
        .iter()
        .map(|p| {
            p.source
                .as_ref()
                .map(|s| s.display().to_string())
                .unwrap_or_else(|| "<memory>".into())
        })
        .collect();
    let unnamed = parts.iter().position(|p| p.channels.is_empty());
    let named = parts.iter().position(|p| !p.channels.is_empty());
    if let (Some(u), Some(n)) = (unnamed, named) {
        return Err(Error::Invalid(format!(
            "{} has no channel name but {} names its channels ({}): say which channel the \
             unnamed samples are (a `channel` column) or fit the files separately",
            sources[u],
            sources[n],
            parts[n].channels.join(", ")
        )));
    }
    for (k, part) in parts.into_iter().enumerate() {
        let file_base = out.files.len() as u32;
        let mut layouts = part.layouts;
        layouts.resize(part.files.len(), Layout::Unknown);
        out.layouts.extend(layouts);
        out.files.extend(part.files);
        let mut map = Vec::new();
        if part.channels.is_empty() {
            // One unnamed channel, merged with the other unnamed parts.
            map.push(0);
        }
        for name in &part.channels {
            let idx = match out.channels.iter().position(|c| c == name) {
                Some(i) => i,
                None => {
                    out.channels.push(name.clone());
                    out.channels.len() - 1
                }
            };
            map.push(idx);
        }
        for kv in part.metadata {
            if !out.metadata.contains(&kv) {
                out.metadata.push(kv);
            }
        }
        for mut s in part.samples {
            s.channel = *map.get(s.channel).ok_or_else(|| {
                Error::Invalid(format!(
                    "{}: sample channel {} out of range",
                    sources[k], s.channel
                ))
            })?;
            s.origin.file += file_base;
            out.samples.push(s);
            origin.push(k);
        }
    }
    // The dedupe holds the samples; a conflict names its two rows from a copy of the origins.
    let origins: Vec<Origin> = out.samples.iter().map(|s| s.origin).collect();
    let (files, layouts) = (out.files.clone(), out.layouts.clone());
    let collapsed = dedupe(&mut out.samples, &out.channels, |c| {
        let (a, b) = (origin[c.first], origin[c.repeat]);
        let hint = hint(a, b).map(|h| format!("; {h}")).unwrap_or_default();
        // Each copy named as its own file's duplicate error would name it.
        let name = |i: usize, part: usize| {
            place_text(&files, &layouts, origins[i], c.field)
                .unwrap_or_else(|| sources[part].clone())
        };
        Error::Invalid(format!(
            "{}: {}; the first copy is in {}{hint}",
            name(c.repeat, b),
            c.what(),
            name(c.first, a)
        ))
    })?;
    Ok((out, collapsed))
}

/// The loader note for `collapsed` duplicate samples found across `parts` (files, inputs)
/// by [`merge_loaded`], if any.
pub(crate) fn collapsed_note(collapsed: usize, parts: &str) -> Option<String> {
    (collapsed > 0).then(|| {
        format!(
            "{collapsed} identical duplicate sample(s) across {parts} collapsed (values equal \
             to 1e-12 of themselves: computed copies may differ in the last digits)"
        )
    })
}

/// [`merge`] of parts loaded with `opts` (files, or folders from [`load_dir`]). When a
/// conflicting sample lies in two parts made only of Yan-2015 files and `opts.theta_i`
/// gave their incident angle, the error adds that `--theta-i` applies to every Yan file:
/// the usual cause is a folder of files without `# theta_i:` lines read with one
/// `--theta-i`, which puts every file at the same incident angle.
pub fn merge_loaded(parts: Vec<Loaded>, opts: &LoadOptions) -> Result<(Profile, usize)> {
    let all_yan: Vec<bool> = parts
        .iter()
        .map(|l| l.files.iter().all(|f| f.format == Format::Yan))
        .collect();
    let hint = |a: usize, b: usize| -> Option<String> {
        let t = opts.theta_i.as_deref()?;
        (all_yan[a] && all_yan[b]).then(|| {
            let t = t.iter().map(f64::to_string).collect::<Vec<_>>().join(",");
            // Beside a lone .npy, files with their own line keep it.
            let which = if opts.theta_i_for_npy {
                " without a '# theta_i:' line"
            } else {
                ""
            };
            format!(
                "--theta-i {t} applies to every Yan-2015 file{which} (each file of a folder \
                 too), so they all read as theta_i {t}; give each file its own \
                 '# theta_i: <deg>' line"
            )
        })
    };
    merge_with(parts.into_iter().map(|l| l.profile).collect(), hint)
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

/// Normalise an angle as every loader does: `-0` becomes `0` and `phi = -180` becomes
/// `180`, following MODEL.md's wrap of phi to (-180, 180]; the two spellings are the same
/// direction, and one canonical spelling keeps grids and duplicate checks exact.
pub fn canonical_phi(phi: f64) -> f64 {
    if phi == -180.0 {
        180.0
    } else {
        phi + 0.0
    }
}

/// Wrap any finite azimuth (degrees) to (-180, 180].
pub fn wrap_phi(phi: f64) -> f64 {
    let mut p = phi % 360.0;
    if p <= -180.0 {
        p += 360.0;
    } else if p > 180.0 {
        p -= 360.0;
    }
    canonical_phi(p)
}

/// Check an angle read from a file: finite and within `[-limit, limit]` degrees.
/// Returns a message for the caller to place (file, line, column or array).
pub(crate) fn check_angle(name: &str, v: f64, limit: f64) -> std::result::Result<f64, String> {
    if !v.is_finite() {
        return Err(format!("{name} must be a finite angle, found {v}"));
    }
    if v < -limit || v > limit {
        return Err(format!(
            "{name} = {} deg is out of range [-{limit}, {limit}]",
            Num(v)
        ));
    }
    Ok(v + 0.0)
}

/// A measured field of a sample, as named by [`check_measured`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Field {
    Value,
    Sigma,
    PhiI,
}

impl Field {
    /// The column / array name of the field.
    pub(crate) fn name(self) -> &'static str {
        match self {
            Field::Value => "value",
            Field::Sigma => "sigma",
            Field::PhiI => "phi_i",
        }
    }
}

/// The rules every loader applies to a sample's measured fields, once the format's own
/// spelling of "none" has been decoded (CSV: an empty cell, or `nan` for sigma; npz: NaN).
/// One function, so the formats cannot drift apart:
/// - `value`: NaN or `<= 0` is an *invalid* sample (DATA.md: no usable signal), kept;
///   infinite is an error — no detector reports it, so it is corruption, not a gap;
/// - `sigma`, if given: finite and `>= 0`;
/// - `phi_i`, if given: a finite angle in [-360, 360], as a phi is (DATA.md: an angle out
///   of range is an error), kept as written (only carried for round trips).
///
/// Returns the field at fault and a message for the caller to place (file, line and
/// column, or array and cell).
pub(crate) fn check_measured(
    value: f64,
    sigma: Option<f64>,
    phi_i: Option<f64>,
) -> std::result::Result<(), (Field, String)> {
    if value.is_infinite() {
        return Err((
            Field::Value,
            format!("value {value} is infinite or beyond the f64 range, 1.8e308 (mark a missing sample with NaN)"),
        ));
    }
    if let Some(s) = sigma {
        if !(s.is_finite() && s >= 0.0) {
            return Err((
                Field::Sigma,
                format!("sigma must be finite and >= 0, found {}", Num(s)),
            ));
        }
    }
    if let Some(p) = phi_i {
        check_angle("phi_i", p, PHI_LIMIT).map_err(|m| (Field::PhiI, m))?;
    }
    Ok(())
}

/// A channel name as read from a file (trimmed): it may not be empty, since an empty
/// `channel` cell is a forgotten label, not a channel (DATA.md names channels such as `r`
/// or `650nm`), and it would merge by name with every other unlabelled row.
pub(crate) fn check_channel_name(name: &str) -> std::result::Result<(), String> {
    if name.trim().is_empty() {
        return Err("empty channel name (label every sample, e.g. r, g, b or 650nm)".into());
    }
    Ok(())
}

/// Same f64, treating NaN as equal to NaN (for duplicate checks and round-trip tests).
pub fn same_f64(a: f64, b: f64) -> bool {
    (a.is_nan() && b.is_nan()) || a == b
}

fn same_opt(a: Option<f64>, b: Option<f64>) -> bool {
    both(a, b, same_f64)
}

/// Do two incident azimuths `phi_i` name one direction? Wrapped to (-180, 180] as every
/// loader wraps phi ([`read_phi`]), so `5` and `-355` (one sweep written two ways) agree.
fn same_azimuth(a: Option<f64>, b: Option<f64>) -> bool {
    both(a, b, |x, y| same_f64(wrap_phi(x), wrap_phi(y)))
}

/// Both absent, or both present and `eq`.
fn both(a: Option<f64>, b: Option<f64>, eq: fn(f64, f64) -> bool) -> bool {
    match (a, b) {
        (None, None) => true,
        (Some(x), Some(y)) => eq(x, y),
        _ => false,
    }
}

/// Do two copies of one direction agree on the value? Equal to [`VALUE_MATCH`] (NaN equal
/// to NaN), or both no-signal markers (NaN, `<= 0`): a sweep's 0 and 360 may mark one gap
/// as NaN and -1, and no value of either enters a fit, so they are one invalid sample, not
/// a conflict.
fn same_value(a: &Sample, b: &Sample) -> bool {
    close_f64(a.value, b.value) || (!a.is_valid() && !b.is_valid())
}

/// Equal to [`VALUE_MATCH`] (NaN equal to NaN; an infinity only to itself).
fn close_f64(a: f64, b: f64) -> bool {
    same_f64(a, b)
        || (a.is_finite() && b.is_finite() && (a - b).abs() <= VALUE_MATCH * a.abs().max(b.abs()))
}

/// Both absent, or both present and [`close_f64`] (a sigma, like a value, computed twice).
fn close_opt(a: Option<f64>, b: Option<f64>) -> bool {
    both(a, b, close_f64)
}

/// Relative difference within which two copies of one direction are one value (the first
/// kept). Computed profiles differ there only by rounding: `synth` sums a direction's
/// terms in an order that depends on the rest of its grid, so two overlapping grids agree
/// to a few ulp, not bit for bit (audit, 2026-11-28: merging them failed). No measurement
/// is written to 12 digits, so a real conflict is never this close.
const VALUE_MATCH: f64 = 1e-12;

/// Do two samples agree in every field (NaN equal to NaN)?
pub fn same_sample(a: &Sample, b: &Sample) -> bool {
    same_f64(a.theta_i, b.theta_i)
        && same_f64(a.theta_r, b.theta_r)
        && same_f64(a.phi, b.phi)
        && a.channel == b.channel
        && same_f64(a.value, b.value)
        && same_opt(a.sigma, b.sigma)
        && same_opt(a.phi_i, b.phi_i)
}

/// Two samples of one direction that differ, as [`dedupe`] reports them.
#[derive(Clone, Debug)]
pub(crate) struct Conflict {
    /// Index (into the samples given to [`dedupe`]) of the first occurrence.
    pub first: usize,
    /// Index of the repeat that differs from it.
    pub repeat: usize,
    /// What differs, e.g. `value (1 vs 1.1)`.
    pub diff: String,
    /// The field that differs (the first of value, sigma, phi_i that does).
    pub field: Field,
    /// The direction, e.g. `theta_i 30, theta_r 10, phi 0, channel r` (the channel by its
    /// name; none for the one channel of a profile without names).
    pub at: String,
    /// The direction's phi as stored (both samples' phi, once wrapped).
    pub phi: f64,
}

impl Conflict {
    /// `duplicate sample (<at>) with a different <diff>`.
    pub(crate) fn what(&self) -> String {
        format!(
            "duplicate sample ({}) with a different {}",
            self.at, self.diff
        )
    }
}

/// [`dedupe`], returning the loader notes it warrants (one line when rows were collapsed).
/// `raw_phi` holds each sample's phi as written: a collapse of two rows that wrote one
/// direction as two phi (0 and 360, -180 and 180: a sweep's endpoint measured twice) is
/// counted apart, with an example.
pub(crate) fn dedupe_notes<F>(
    samples: &mut Vec<Sample>,
    channels: &[String],
    raw_phi: &[f64],
    what: &str,
    conflict: F,
) -> Result<Vec<String>>
where
    F: Fn(Conflict) -> Error,
{
    let (pairs, markers) = dedupe_pairs(samples, channels, conflict)?;
    if pairs.is_empty() {
        return Ok(Vec::new());
    }
    let wrapped: Vec<&(usize, usize)> = pairs
        .iter()
        .filter(|(i, j)| raw_phi.get(*i) != raw_phi.get(*j))
        .collect();
    let mut why = match wrapped.first() {
        Some((i, j)) => format!(
            " ({} of them the same direction written as two phi, e.g. {} and {}: wrapped alike)",
            wrapped.len(),
            raw_phi[*i],
            raw_phi[*j]
        ),
        None => String::new(),
    };
    // Two different no-signal markers (NaN and -1) collapse too ([`same_value`]): said, so
    // the kept one's spelling is no surprise.
    if let Some((a, b)) = markers.first() {
        why.push_str(&format!(
            " ({} of them not identical but both without signal, e.g. values {} and {}: one \
             invalid sample, the first kept)",
            markers.len(),
            Num(*a),
            Num(*b)
        ));
    }
    Ok(vec![format!(
        "{} {what} collapsed into their first occurrence{why}",
        pairs.len()
    )])
}

/// [`dedupe_notes`] for a text loader (CSV, Yan): sample `k` came from line
/// `samples[k].origin.line` of `path`, its phi written as `raw_phi[k]`. A clash is named on
/// `phi_column` when only the wrap made the two rows one direction ([`wrap_conflict`]),
/// else on the column of the field that differs (`column`: its label).
pub(crate) fn dedupe_rows(
    samples: &mut Vec<Sample>,
    channels: &[String],
    raw_phi: &[f64],
    path: &Path,
    opts: &LoadOptions,
    phi_column: &str,
    column: &dyn Fn(Field) -> String,
) -> Result<Vec<String>> {
    let lines: Vec<usize> = samples.iter().map(|s| s.origin.line as usize).collect();
    dedupe_notes(
        samples,
        channels,
        raw_phi,
        "identical duplicate row(s)",
        |c| {
            let (i, j) = (c.first, c.repeat);
            let first_at = format!("line {}", lines[i]);
            let (column, msg) = match wrap_conflict(raw_phi[i], raw_phi[j], &first_at, &c, "", opts)
            {
                Some(m) => (phi_column.to_string(), m),
                None => (
                    column(c.field),
                    format!("{}; first on {first_at}", c.what()),
                ),
            };
            Error::Parse {
                file: path.to_path_buf(),
                line: lines[j],
                column,
                msg,
            }
        },
    )
}

/// An optional sample field as a message shows it: the number, or "none".
fn opt_text(v: Option<f64>) -> String {
    v.map_or_else(|| "none".to_string(), |x| Num(x).to_string())
}

/// Remove identical duplicate samples (same `theta_i, theta_r, phi, channel` and the same
/// value, or two no-signal values ([`same_value`]), sigma and phi_i), keeping the first;
/// returns how many were removed. A repeat
/// with any different field is an error built by `conflict` from the [`Conflict`] (indices
/// into the original `samples`); `channels` are the names of the samples' channel indices.
pub(crate) fn dedupe<F>(
    samples: &mut Vec<Sample>,
    channels: &[String],
    conflict: F,
) -> Result<usize>
where
    F: Fn(Conflict) -> Error,
{
    Ok(dedupe_pairs(samples, channels, conflict)?.0.len())
}

/// [`dedupe`], returning the `(kept, removed)` index pairs (into the original `samples`)
/// and the two values of each pair of different no-signal markers collapsed
/// ([`same_value`]).
#[allow(clippy::type_complexity)]
fn dedupe_pairs<F>(
    samples: &mut Vec<Sample>,
    channels: &[String],
    conflict: F,
) -> Result<(Vec<(usize, usize)>, Vec<(f64, f64)>)>
where
    F: Fn(Conflict) -> Error,
{
    let mut seen: HashMap<(u64, u64, u64, usize), usize> = HashMap::with_capacity(samples.len());
    let mut drop = vec![false; samples.len()];
    let mut pairs = Vec::new();
    let mut markers = Vec::new();
    for (j, s) in samples.iter().enumerate() {
        let key = (
            (s.theta_i + 0.0).to_bits(),
            (s.theta_r + 0.0).to_bits(),
            canonical_phi(s.phi).to_bits(),
            s.channel,
        );
        match seen.get(&key) {
            None => {
                seen.insert(key, j);
            }
            Some(&i) => {
                let a = &samples[i];
                // Two copies without signal are one invalid sample whatever their sigma or
                // phi_i say: none of it enters a fit (README: they collapse).
                let no_signal = !a.is_valid() && !s.is_valid();
                let diff = if !same_value(a, s) {
                    Some((
                        Field::Value,
                        format!("value ({} vs {})", Num(a.value), Num(s.value)),
                    ))
                } else if no_signal {
                    None
                } else if !close_opt(a.sigma, s.sigma) {
                    Some((
                        Field::Sigma,
                        format!("sigma ({} vs {})", opt_text(a.sigma), opt_text(s.sigma)),
                    ))
                } else if !same_azimuth(a.phi_i, s.phi_i) {
                    Some((
                        Field::PhiI,
                        format!("phi_i ({} vs {})", opt_text(a.phi_i), opt_text(s.phi_i)),
                    ))
                } else {
                    None
                };
                if let Some((field, diff)) = diff {
                    return Err(conflict(Conflict {
                        first: i,
                        repeat: j,
                        diff,
                        field,
                        at: format!(
                            "theta_i {}, theta_r {}, phi {}{}",
                            Num(s.theta_i),
                            Num(s.theta_r),
                            Num(s.phi),
                            // The name the file gives; an index would mean nothing to
                            // the reader (and a merge renumbers them).
                            channels
                                .get(s.channel)
                                .map(|n| format!(", channel {n}"))
                                .unwrap_or_default()
                        ),
                        phi: s.phi,
                    }));
                }
                let same_fields = same_f64(a.value, s.value)
                    && same_opt(a.sigma, s.sigma)
                    && same_opt(a.phi_i, s.phi_i);
                if no_signal && !same_fields {
                    markers.push((a.value, s.value));
                }
                drop[j] = true;
                pairs.push((i, j));
            }
        }
    }
    if !pairs.is_empty() {
        let mut k = 0;
        samples.retain(|_| {
            let keep = !drop[k];
            k += 1;
            keep
        });
    }
    Ok((pairs, markers))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sample_count_limit_names_file_and_line() {
        assert!(check_sample_count(2, 3, Path::new("a.csv"), 9).is_ok());
        let e = check_sample_count(3, 3, Path::new("a.csv"), 9)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("a.csv") && e.contains("line 9: more than 3 samples"),
            "{e}"
        );
    }

    fn at(theta_i: f64, theta_r: f64, phi: f64) -> Sample {
        Sample::new(theta_i, theta_r, phi, 1.0)
    }

    /// An unnamed channel merged with named ones used to land silently in the first named
    /// channel; now it is an error naming both files. Unnamed parts still merge together.
    #[test]
    fn merge_refuses_unnamed_with_named_channels() {
        let part = |src: &str, channels: &[&str], phi: f64| Profile {
            samples: vec![at(0.0, 10.0, phi)],
            channels: channels.iter().map(|c| c.to_string()).collect(),
            source: Some(src.into()),
            ..Default::default()
        };
        let e = merge(vec![
            part("rg.csv", &["r"], 0.0),
            part("plain.csv", &[], 5.0),
        ])
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("plain.csv") && e.contains("rg.csv") && e.contains('r'),
            "{e}"
        );
        let (m, _) = merge(vec![part("a.csv", &[], 0.0), part("b.csv", &[], 5.0)]).unwrap();
        assert_eq!((m.samples.len(), m.channels.len()), (2, 0));
    }

    /// A clash across a merge names the channel by name: `g` is channel 0 of its own files
    /// and channel 1 of the merged profile, neither of which the reader can see.
    #[test]
    fn merge_conflict_names_the_channel() {
        let part = |src: &str, channels: &[&str], value: f64| {
            let mut s = at(0.0, 10.0, 5.0);
            s.value = value;
            Profile {
                samples: vec![s],
                channels: channels.iter().map(|c| c.to_string()).collect(),
                source: Some(src.into()),
                ..Default::default()
            }
        };
        let e = merge(vec![
            part("r.csv", &["r"], 1.0),
            part("g1.csv", &["g"], 1.0),
            part("g2.csv", &["g"], 2.0),
        ])
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("duplicate sample (theta_i 0, theta_r 10, phi 5, channel g) with"),
            "{e}"
        );
    }

    /// A clash between two files of a merge names both rows by file and line (the files
    /// of each part are renumbered into the merged profile's list), and a sample made in
    /// memory by its part's source.
    #[test]
    fn merge_conflict_names_file_and_line_of_both_rows() {
        let part = |file: &str, lines: &[u32], value: f64| Profile {
            samples: lines
                .iter()
                .enumerate()
                .map(|(k, &line)| {
                    let mut s = Sample::new(0.0, 10.0, 5.0 * k as f64, value);
                    s.origin = Origin { file: 0, line };
                    s
                })
                .collect(),
            source: Some(file.into()),
            files: vec![file.into()],
            ..Default::default()
        };
        let e = merge(vec![
            part("a.csv", &[3], 1.0),
            part("b.csv", &[4, 9], 1.0),
            part("c.csv", &[6, 8], 2.0),
        ])
        .unwrap_err()
        .to_string();
        assert!(
            e.starts_with("c.csv line 6: duplicate sample (theta_i 0, theta_r 10, phi 0")
                && e.ends_with("the first copy is in a.csv line 3"),
            "{e}"
        );
        let (m, collapsed) =
            merge(vec![part("a.csv", &[3], 1.0), part("b.csv", &[4, 9], 1.0)]).unwrap();
        assert_eq!(collapsed, 1);
        assert_eq!(m.origin_of(&m.samples[1]).as_deref(), Some("b.csv line 9"));
        let mut memory = part("x", &[0], 2.0);
        memory.files.clear();
        let e = merge(vec![part("a.csv", &[3], 1.0), memory])
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("x: duplicate") && e.ends_with("in a.csv line 3"),
            "{e}"
        );
    }

    /// Any finite phi in [-360, 360] reads in every format (a CSV's 270 was "out of range
    /// [-180, 180]"), wrapped to (-180, 180] after the convention options; values already
    /// there keep their bits, so files still round-trip exactly.
    #[test]
    fn read_phi_takes_one_turn_and_wraps_after_the_offset() {
        let none = LoadOptions::default();
        let r = |v: f64, o: &LoadOptions| read_phi("phi", v, o);
        for (v, want) in [
            (270.0, -90.0),
            (360.0, 0.0),
            (-360.0, 0.0),
            (-180.0, 180.0),
            (355.0, -5.0),
            (-270.0, 90.0),
        ] {
            assert_eq!(r(v, &none), Ok(want), "{v}");
        }
        for v in [0.1, -179.99999999999997, 1.0 / 3.0, 180.0, -0.0] {
            assert_eq!(r(v, &none).unwrap().to_bits(), (v + 0.0).to_bits(), "{v}");
        }
        let e = r(360.5, &none).unwrap_err();
        assert!(e.contains("out of range [-360, 360]"), "{e}");
        assert!(r(f64::NAN, &none).unwrap_err().contains("finite"));
        // The offset applies before the wrap: 270 - 180 = 90 (a range check before the
        // offset refused it), and flip then offset: -270 + 0 -> 90.
        let off = LoadOptions {
            phi_offset: -180.0,
            ..Default::default()
        };
        assert_eq!(r(270.0, &off), Ok(90.0));
        let flip = LoadOptions {
            flip_phi: true,
            ..Default::default()
        };
        assert_eq!(r(270.0, &flip), Ok(90.0));
    }

    /// Two files of a folder read with one --theta-i clash: the error names both files and
    /// the direction, and says --theta-i applied to every Yan file (no hint otherwise).
    #[test]
    fn folder_clash_under_theta_i_says_it_applies_to_every_yan_file() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::write(d.join("f0.txt"), "0 10 1\n").unwrap();
        std::fs::write(d.join("f20.txt"), "0 10 2\n").unwrap();
        let opts = LoadOptions {
            theta_i: Some(vec![30.0]),
            ..Default::default()
        };
        let e = load_dir(d, &opts).unwrap_err().to_string();
        assert!(
            e.contains(
                "f20.txt:1: column 3 (value): duplicate sample (theta_i 30, theta_r 10, phi 0) with"
            ) && e.contains("first copy is in")
                && e.contains("f0.txt:1: column 3 (value);")
                && e.contains("--theta-i 30 applies to every Yan-2015 file"),
            "{e}"
        );
        // Without --theta-i (each file says its angle) there is no such hint.
        std::fs::write(d.join("f0.txt"), "# theta_i: 30\n0 10 1\n").unwrap();
        std::fs::write(d.join("f20.txt"), "# theta_i: 30\n0 10 2\n").unwrap();
        let e = load_dir(d, &LoadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("duplicate sample") && !e.contains("--theta-i"),
            "{e}"
        );
    }

    #[test]
    fn radians_look_alike_warns() {
        let prof = |s: Vec<Sample>| Profile {
            samples: s,
            ..Default::default()
        };
        let w = radians_warning(&prof(vec![at(0.0, -0.785, 0.5), at(0.52, 0.785, -3.1)]))
            .expect("radians");
        assert!(w.starts_with("warning:") && w.contains("radians"), "{w}");
        assert!(w.contains("largest |angle| 3.1)"), "{w}");
        // Degrees, all zero, or empty: no warning.
        assert!(radians_warning(&prof(vec![at(0.0, 0.0, 0.0), at(0.0, 3.0, 10.0)])).is_none());
        assert!(radians_warning(&prof(vec![at(0.0, 0.0, 0.0)])).is_none());
        assert!(radians_warning(&prof(Vec::new())).is_none());
        // Through the loader, as a note.
        let dir = tempfile::tempdir().unwrap();
        let f = dir.path().join("rad.csv");
        std::fs::write(
            &f,
            "theta_i,theta_r,phi,value\n0,0.785,0,1\n0,-0.785,1.5,2\n",
        )
        .unwrap();
        let l = load_full(&f, &LoadOptions::default()).unwrap();
        assert!(
            l.notes.iter().any(|n| n.contains("look like radians")),
            "{:?}",
            l.notes
        );
    }

    #[test]
    fn utf16_text_is_named() {
        let d = tempfile::tempdir().unwrap();
        for (name, bom) in [("a.csv", [0xFFu8, 0xFE]), ("b.txt", [0xFE, 0xFF])] {
            let p = d.path().join(name);
            let mut bytes = bom.to_vec();
            for ch in "theta_i,theta_r,phi,value\n".encode_utf16() {
                bytes.extend(if bom[0] == 0xFF {
                    ch.to_le_bytes()
                } else {
                    ch.to_be_bytes()
                });
            }
            std::fs::write(&p, bytes).unwrap();
            let e = load(&p, &LoadOptions::default()).unwrap_err().to_string();
            assert!(
                e.contains(&format!("{name}:1:")) && e.contains("UTF-16"),
                "{e}"
            );
        }
    }

    #[test]
    fn folder_skips_prose_txt_but_not_a_bad_yan_file() {
        assert!(looks_like_yan(b"# theta_i: 30\n\n0 10 1.5\n"));
        assert!(looks_like_yan(b"\xef\xbb\xbf-90 5 ?\r"));
        assert!(!looks_like_yan(b"Measured by A. Lab, 2015.\n0 10 1\n"));
        assert!(!looks_like_yan(b"# only comments\n"));
        // A long text is quoted cut, with its length.
        let long = "x".repeat(10_000);
        assert_eq!(
            quoted(&long),
            format!("'{}...' (10000 characters)", "x".repeat(80))
        );
        assert_eq!(quoted("a\u{feff}"), "'a\\u{feff}'");
        // A notes file is prose however its first line begins (a number and a unit, a
        // date); a profile is one whatever the typo in its first row or header, as its
        // other rows show.
        for first in [
            "1. Calibrate lamp",
            "12 June 2017",
            "2017 notes",
            "June 12, 2017",
            "3 of 5 fibres broke",
            "Phi and theta",
            "Value of phi",
            "20 C freezer",
            "5 V supply",
            "3 x 5 fibres",
            "2017 06 12",
            "1,5 mm hairs",
        ] {
            let notes = format!("{first}\nFox fiber 3, combed.\nSee a.csv.\n");
            assert!(!looks_like_yan(notes.as_bytes()), "{notes}");
        }
        for first in [
            "0 l0 1",
            "0 10deg 1",
            "0 10 abc",
            "0 ten 1",
            "l0 10 1",
            "0 NA 1",
            "phi theta valu",
            "phi theta vlaue",
            "ph theta value",
            "phi theta value extra",
            "0 10 1 5 6",
        ] {
            let data = format!("{first}\n0 20 1.5\n0 30 ?\n");
            assert!(looks_like_yan(data.as_bytes()), "{data}");
        }
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::write(d.join("a.csv"), "theta_i,theta_r,phi,value\n0,10,20,1\n").unwrap();
        std::fs::write(d.join("notes.txt"), "Fox fiber 3, combed.\nSee a.csv.\n").unwrap();
        let l = load_dir(d, &LoadOptions::default()).unwrap();
        assert_eq!(l.profile.samples.len(), 1);
        assert!(
            l.notes
                .contains(&"skipped notes.txt: not a Yan-2015 profile".to_string()),
            "{:?}",
            l.notes
        );
        // A file above the size limit is refused before it is read (a sparse file: no
        // disk used).
        let big = d.join("big.npz");
        std::fs::File::create(&big)
            .unwrap()
            .set_len(MAX_FILE_BYTES + 1)
            .unwrap();
        let e = load(&big, &LoadOptions::default()).unwrap_err().to_string();
        assert!(
            e.contains("a profile file may hold at most 1073741824 bytes"),
            "{e}"
        );
        std::fs::remove_file(&big).unwrap();
        // Data a user may have meant to include is named in a note, not read.
        std::fs::create_dir(d.join("sub")).unwrap();
        std::fs::write(
            d.join("sub/b.csv"),
            "theta_i,theta_r,phi,value\n0,10,30,1\n",
        )
        .unwrap();
        std::fs::write(d.join(".c.csv"), "theta_i,theta_r,phi,value\n0,10,40,1\n").unwrap();
        std::fs::create_dir(d.join(".git")).unwrap();
        let l = load_dir(d, &LoadOptions::default()).unwrap();
        assert_eq!(l.profile.samples.len(), 1);
        for note in [
            "skipped sub/: subfolders are not read",
            "skipped .c.csv: hidden file",
        ] {
            assert!(l.notes.contains(&note.to_string()), "{:?}", l.notes);
        }
        assert!(!l.notes.iter().any(|n| n.contains(".git")), "{:?}", l.notes);
        // Named on its own it is still read as Yan, and fails.
        let e = load(&d.join("notes.txt"), &LoadOptions::default()).unwrap_err();
        assert!(e.to_string().contains("notes.txt:1:"), "{e}");
        // A Yan file with a genuine bad row (after good ones) is still an error.
        std::fs::write(d.join("y.txt"), "# theta_i: 0\n0 10 1\n5 10 x\n").unwrap();
        let e = load_dir(d, &LoadOptions::default()).unwrap_err();
        assert!(e.to_string().contains("y.txt:3:"), "{e}");
        // So is one whose FIRST row has a typo: read and reported, never skipped.
        for first in ["0 10 1,5", "0, 10, 1", "0 10 1 7"] {
            std::fs::write(d.join("y.txt"), format!("# theta_i: 0\n{first}\n5 10 2\n")).unwrap();
            let e = load_dir(d, &LoadOptions::default()).unwrap_err();
            assert!(e.to_string().contains("y.txt:2:"), "{first}: {e}");
        }
    }

    #[test]
    fn convention_options_apply_to_csv_and_npz_like_yan() {
        let dir = tempfile::tempdir().unwrap();
        let csv = dir.path().join("c.csv");
        std::fs::write(&csv, "theta_i,theta_r,phi,value\n10,20,30,1\n10,-5,170,2\n").unwrap();
        let opts = LoadOptions {
            flip_phi: true,
            phi_offset: -160.0,
            flip_theta_r: true,
            ..Default::default()
        };
        let got = |p: &Profile| -> Vec<(f64, f64, f64)> {
            let mut v: Vec<_> = p
                .samples
                .iter()
                .map(|s| (s.theta_i, s.theta_r, s.phi))
                .collect();
            v.sort_by(|a, b| a.partial_cmp(b).unwrap());
            v
        };
        // -30 - 160 = -190 -> 170; -170 - 160 = -330 -> 30.
        let want = vec![(10.0, -20.0, 170.0), (10.0, 5.0, 30.0)];
        let mut want_sorted = want.clone();
        want_sorted.sort_by(|a, b| a.partial_cmp(b).unwrap());
        let c = load(&csv, &opts).unwrap();
        assert_eq!(got(&c), want_sorted);
        let npz = dir.path().join("c.npz");
        save(&npz, &load(&csv, &LoadOptions::default()).unwrap()).unwrap();
        assert_eq!(got(&load(&npz, &opts).unwrap()), want_sorted);
        // The Yan reader gives the same for the same rows.
        let yan = dir.path().join("c.txt");
        std::fs::write(&yan, "# theta_i: 10\n30 20 1\n170 -5 2\n").unwrap();
        assert_eq!(got(&load(&yan, &opts).unwrap()), want_sorted);
        // Without options nothing changes.
        assert_eq!(got(&load(&csv, &LoadOptions::default()).unwrap()), {
            let mut v = vec![(10.0, 20.0, 30.0), (10.0, -5.0, 170.0)];
            v.sort_by(|a, b| a.partial_cmp(b).unwrap());
            v
        });
    }

    #[test]
    fn axis_options_must_be_used_by_some_input() {
        let o = |ti: bool, tr: bool, ph: bool| LoadOptions {
            theta_i: ti.then(|| vec![0.0]),
            theta_r: tr.then(|| vec![0.0]),
            phi: ph.then(|| vec![0.0]),
            ..Default::default()
        };
        let e = o(true, false, false)
            .check_used(&[Format::Csv, Format::Npz])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("--theta-i was given but no input is a lone .npy or Yan"),
            "{e}"
        );
        assert!(o(true, false, false)
            .check_used(&[Format::Csv, Format::Yan])
            .is_ok());
        let e = o(true, false, true)
            .check_used(&[Format::Yan])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("--phi was given but no input is a lone .npy"),
            "{e}"
        );
        assert!(o(true, true, true).check_used(&[Format::Npy]).is_ok());
        assert!(o(false, false, false).check_used(&[Format::Csv]).is_ok());
    }

    #[test]
    fn lines_split_at_lf_crlf_and_lone_cr() {
        let lines: Vec<&[u8]> = split_lines(b"a\nb\r\nc\rd\r\re\n").collect();
        let want: Vec<&[u8]> = vec![b"a", b"b", b"c", b"d", b"", b"e", b""];
        assert_eq!(lines, want);
        assert_eq!(split_lines(b"").count(), 1);
    }

    #[test]
    fn measured_field_rules() {
        let nan = f64::NAN;
        let inf = f64::INFINITY;
        // Invalid-but-kept values and absent optional fields pass.
        for v in [1.0, 0.0, -2.0, nan] {
            assert_eq!(check_measured(v, None, None), Ok(()));
        }
        assert_eq!(check_measured(1.0, Some(0.0), Some(-30.0)), Ok(()));
        let field = |v, s, p| check_measured(v, s, p).unwrap_err().0;
        assert_eq!(field(inf, None, None), Field::Value);
        assert_eq!(field(-inf, None, None), Field::Value);
        for s in [-5.0, inf, -inf, nan] {
            assert_eq!(field(1.0, Some(s), None), Field::Sigma, "sigma {s}");
        }
        // phi_i is an angle: out of range is an error like phi's (1e9 was accepted).
        for p in [inf, nan, 1e9, -360.5] {
            assert_eq!(field(1.0, None, Some(p)), Field::PhiI, "phi_i {p}");
        }
        assert_eq!(check_measured(1.0, None, Some(360.0)), Ok(()));
        assert!(check_channel_name("650nm").is_ok());
        assert!(check_channel_name("").is_err());
        assert!(check_channel_name("  ").is_err());
        let (_, msg) = check_measured(1.0, Some(-5.0), None).unwrap_err();
        assert!(msg.contains("sigma must be finite and >= 0"), "{msg}");
    }

    /// A species folder's Yan file with a column-name line and/or a `# theta_i:` line is a
    /// profile: read (the `phi theta value` header skipped) or, with a header the reader
    /// does not take, an error naming file, line and column; it was skipped with a note,
    /// silently dropping its data from the fit.
    #[test]
    fn folder_reads_yan_files_with_a_column_name_line() {
        assert!(looks_like_yan(b"# theta_i: 0\nphi theta value\n0 10 1\n"));
        assert!(looks_like_yan(b"Phi(deg)\tTheta(deg)\tValue\n0 10 1\n"));
        // Prose first, but a theta_i line further down.
        assert!(looks_like_yan(b"Fox, fiber 3.\n# theta_i: 20\n"));
        assert!(!looks_like_yan(b"The phi sweep was noisy.\n0 10 1\n"));
        // A notes line naming two columns in a sentence is prose (review M7).
        assert!(!looks_like_yan(b"phi and theta were swapped\n0 10 1\n"));
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        std::fs::write(d.join("ti0.txt"), "# theta_i: 0\nphi theta value\n0 10 1\n").unwrap();
        std::fs::write(d.join("ti20.txt"), "# theta_i: 20\n0 10 2\n").unwrap();
        std::fs::write(d.join("notes.txt"), "Fox fiber 3, combed.\n").unwrap();
        let l = load_dir(d, &LoadOptions::default()).unwrap();
        assert_eq!(l.profile.samples.len(), 2);
        assert_eq!(l.files.len(), 2, "{:?}", l.files);
        assert_eq!(l.notes, vec!["skipped notes.txt: not a Yan-2015 profile"]);
        // A header in another order: the folder's load fails on it, naming the place.
        std::fs::write(d.join("ti0.txt"), "# theta_i: 0\ntheta phi value\n0 10 1\n").unwrap();
        let e = load_dir(d, &LoadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("ti0.txt:2: column 1: column-name line"), "{e}");
        // Prose with a theta_i line is read, and its error reported.
        std::fs::write(d.join("ti0.txt"), "Fiber 3\n# theta_i: 0\n0 10 1\n").unwrap();
        let e = load_dir(d, &LoadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("ti0.txt:1: column 3: expected 3 fields"), "{e}");
    }

    /// Radians with phi written 0..2 pi (phi up to 6.28 > 3.2) got no warning.
    #[test]
    fn radians_with_phi_to_two_pi_warn() {
        let prof = |s: Vec<Sample>| Profile {
            samples: s,
            ..Default::default()
        };
        let w =
            radians_warning(&prof(vec![at(0.0, -1.2, 0.0), at(0.52, 1.2, 6.02)])).expect("radians");
        assert!(
            w.contains("within +-pi/2 and every phi within +-2 pi")
                && w.contains("largest |theta| 1.2, largest |phi| 6.02)")
                && w.contains("look like radians"),
            "{w}"
        );
        // At the slack's edge, still; beyond it (a theta of 2 deg, a phi of 7), not.
        assert!(radians_warning(&prof(vec![at(0.0, 1.58, 0.0), at(0.0, 0.0, -6.29)])).is_some());
        assert!(radians_warning(&prof(vec![at(0.0, 2.0, 0.0), at(0.0, 0.0, 6.0)])).is_none());
        assert!(radians_warning(&prof(vec![at(0.0, 1.0, 0.0), at(0.0, 0.0, 7.0)])).is_none());
        // One direction is no sweep to judge.
        assert!(radians_warning(&prof(vec![at(0.5, 1.0, 6.0), at(0.5, 1.0, 6.0)])).is_none());
    }

    /// Copies of one direction that differ by rounding (two synth grids: a few ulp) are
    /// one sample; a difference a measurement could show is still a clash.
    #[test]
    fn copies_equal_to_rounding_merge_and_others_clash() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        // `values` of one direction as the rows of `name`.
        let write = |name: &str, values: &[&str]| {
            let rows: String = values.iter().map(|v| format!("0,-10,90,{v}\n")).collect();
            std::fs::write(d.join(name), format!("theta_i,theta_r,phi,value\n{rows}")).unwrap();
        };
        write("a.csv", &["0.06136276893559789"]);
        write("b.csv", &["0.061362768935597896"]);
        let p = load_dir(d, &LoadOptions::default()).unwrap();
        assert_eq!(p.profile.samples.len(), 1);
        assert_eq!(p.profile.samples[0].value, 0.06136276893559789);
        write("b.csv", &["0.0613627689357"]);
        let e = load_dir(d, &LoadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(e.contains("with a different value"), "{e}");
        // Within one file too, and a valid sample is not called a no-signal marker.
        std::fs::remove_file(d.join("b.csv")).unwrap();
        write("a.csv", &["0.06136276893559789", "0.061362768935597896"]);
        let l = load_dir(d, &LoadOptions::default()).unwrap();
        assert_eq!(l.profile.samples.len(), 1);
        assert!(
            l.notes.iter().all(|n| !n.contains("no-signal")),
            "{:?}",
            l.notes
        );
        // An infinity is close only to itself.
        assert!(close_f64(f64::INFINITY, f64::INFINITY) && !close_f64(f64::INFINITY, 1e300));
    }

    /// A clash between two files names each copy as a single file's own duplicate error
    /// does: `FILE:LINE: column N (value)` for a CSV or Yan row, `FILE: array 'value' index
    /// [i, j, k]` for a grid cell (it said `FILE line N`, and only `FILE` for a cell).
    #[test]
    fn clash_across_files_names_column_and_cell_of_both_copies() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let grid = |name: &str, v: f64| {
            let mut p = Profile::default();
            for (k, phi) in [0.0, 10.0, 20.0].into_iter().enumerate() {
                p.samples
                    .push(Sample::new(30.0, -10.0, phi, 1.0 + k as f64));
                p.samples.push(Sample::new(30.0, 5.0, phi, v + k as f64));
            }
            save(&d.join(name), &p).unwrap();
        };
        grid("a.npz", 1.0);
        grid("b.npz", 2.0);
        let e = load_dir(d, &LoadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(
                "b.npz: array 'value' index [0, 1, 0]: duplicate sample (theta_i 30, theta_r 5, \
                 phi 0) with a different value (1 vs 2); the first copy is in "
            ) && e.ends_with("a.npz: array 'value' index [0, 1, 0]"),
            "{e}"
        );
        std::fs::remove_file(d.join("b.npz")).unwrap();
        std::fs::write(
            d.join("c.csv"),
            "# x\nvalue,phi,theta_r,theta_i\n3,20,5,30\n9,10,5,30\n",
        )
        .unwrap();
        let e = load_dir(d, &LoadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(
                "c.csv:4: column 1 (value): duplicate sample (theta_i 30, theta_r 5, phi 10)"
            ) && e.ends_with("a.npz: array 'value' index [0, 1, 1]"),
            "{e}"
        );
        // A grid cell elsewhere (a --weighted message) is named by its index too.
        let l = load_full(&d.join("a.npz"), &LoadOptions::default()).unwrap();
        let name = l.profile.origin_of(&l.profile.samples[5]).unwrap();
        assert!(name.ends_with("a.npz index [0, 1, 2]"), "{name}");
        let g = Layout::Grid {
            shape: vec![2, 3, 4, 2],
            sigma: false,
            phi_i: false,
        };
        assert_eq!(g.cell(Origin::at_cell(47)), Some(vec![1, 2, 3, 1]));
        assert_eq!(g.cell(Origin::at_cell(48)), None);
        assert_eq!(g.cell(Origin::default()), None);
        // A lone .npy is one unnamed array: its cells are named by index alone.
        let files = [PathBuf::from("v.npy"), PathBuf::from("w.npz")];
        let layouts = [
            Layout::Grid {
                shape: vec![2, 1, 1],
                sigma: false,
                phi_i: false,
            },
            Layout::Grid {
                shape: vec![2, 1, 1],
                sigma: true,
                phi_i: false,
            },
        ];
        let at = |file| Origin { file, line: 2 };
        assert_eq!(
            place_text(&files, &layouts, at(0), Field::Value).unwrap(),
            "v.npy: index [1, 0, 0]"
        );
        assert_eq!(
            place_text(&files, &layouts, at(1), Field::Value).unwrap(),
            "w.npz: array 'value' index [1, 0, 0]"
        );
        // A clash in sigma names the sigma array, one in phi_i the value array of a file
        // without a phi_i array.
        assert_eq!(
            place_text(&files, &layouts, at(1), Field::Sigma).unwrap(),
            "w.npz: array 'sigma' index [1, 0, 0]"
        );
        assert_eq!(
            place_text(&files, &layouts, at(1), Field::PhiI).unwrap(),
            "w.npz: array 'value' index [1, 0, 0]"
        );
    }

    /// An npz renamed .csv (or .txt) is named as binary: its zip bytes were echoed as the
    /// "header".
    #[test]
    fn zip_or_npy_under_a_text_name_is_named_binary() {
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path();
        let mut p = Profile::default();
        p.samples.push(Sample::new(0.0, 10.0, 0.0, 1.0));
        let npz = npz::to_bytes(&p).unwrap();
        for name in ["fake.csv", "fake.txt"] {
            std::fs::write(d.join(name), &npz).unwrap();
            let e = load(&d.join(name), &LoadOptions::default())
                .unwrap_err()
                .to_string();
            assert!(
                e.ends_with(&format!(
                    "{name}: binary file (looks like a zip/npz archive; a NumPy grid is read \
                     when named .npz), not a text profile"
                )),
                "{e}"
            );
        }
        std::fs::write(d.join("v.csv"), b"\x93NUMPY\x01\x00").unwrap();
        let e = load(&d.join("v.csv"), &LoadOptions::default())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("binary file (looks like a NumPy .npy array"),
            "{e}"
        );
    }
}

//! The in-memory profile: [`Sample`], [`Profile`] and where each sample was read
//! ([`Origin`], [`Layout`]), the [`Format`]s, the [`LoadOptions`] and what a load
//! returns ([`Loaded`], [`ReadFile`]).

use super::label::says_synthetic;
use crate::error::{Error, Result};
use std::path::{Path, PathBuf};

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
    /// Index into [`Profile::files`].
    pub file: u32,
    /// 1-based line of a text row, or 1 + the row-major cell index of a grid; 0 if unknown.
    pub line: u32,
}

impl Origin {
    /// Line `line` (1-based) of the profile's first file; a line beyond `u32::MAX` (a file
    /// of over four billion lines, far past [`MAX_READ_CELLS`](super::checks::MAX_READ_CELLS) samples) is not named.
    pub fn at_line(line: usize) -> Origin {
        Origin {
            file: 0,
            line: u32::try_from(line).unwrap_or(0),
        }
    }

    /// The cell of row-major index `flat` in the `value` array of the profile's first file
    /// (a grid: [`Layout::Grid`]); an index past `u32::MAX - 1` (beyond [`MAX_READ_CELLS`](super::checks::MAX_READ_CELLS))
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
        /// The file's label of its value column (`column 4 (value)`).
        value_column: String,
        /// The label of its sigma column, if it has one.
        sigma_column: Option<String>,
        /// The label of its phi_i column, if it has one.
        phi_i_column: Option<String>,
    },
    /// A `.npz` / lone `.npy` grid whose `value` array has this shape: [`Origin::line`] is
    /// 1 + the cell's row-major index; whether it has `sigma` and `phi_i` arrays.
    Grid {
        /// Shape of the `value` array (3-D, or 4-D with channels).
        shape: Vec<usize>,
        /// Whether the file has a `sigma` array.
        sigma: bool,
        /// Whether the file has a `phi_i` array.
        phi_i: bool,
    },
}

impl Layout {
    /// The index `[i, j, k(, c)]` of grid cell `o` (by its shape), if `o` is one.
    pub(super) fn cell(&self, o: Origin) -> Option<Vec<usize>> {
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
pub(super) fn place_text(
    files: &[PathBuf],
    layouts: &[Layout],
    o: Origin,
    field: Field,
) -> Option<String> {
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
    /// The samples, in file order (grid order for `.npy`/`.npz`).
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
    /// Dense grid archive (`.npz`), see [`super::npz`].
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
    /// Azimuth grid (degrees) for a lone `.npy`; read like a file's phi ([`read_phi`](super::checks::read_phi)).
    pub phi: Option<Vec<f64>>,
    /// Degrees added to every file's phi (after `flip_phi`) before wrapping to (-180, 180]:
    /// data written in another azimuth convention, whatever the format ([`read_phi`](super::checks::read_phi)).
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

/// Is this directory entry a profile file [`load_dir`](super::load::load_dir) should read? Profile extensions
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

/// One file a loader read: its path, format and the SHA-256 of the bytes it parsed (what
/// a fit file records, so the digest is of exactly the data fitted).
#[derive(Clone, Debug)]
pub struct ReadFile {
    /// The file as the user named it (or as found in the folder).
    pub path: PathBuf,
    /// The format it was read as.
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
    /// The profile read.
    pub profile: Profile,
    /// Its format (of the first file, for a folder).
    pub format: Format,
    /// The files read (one for [`load_full`](super::load::load_full), the folder's for [`load_dir`](super::load::load_dir)).
    pub files: Vec<ReadFile>,
    /// Things the loader did that a user should know about (e.g. identical duplicate
    /// samples collapsed into one). Never errors: those are returned as `Err`.
    pub notes: Vec<String>,
}

/// A measured field of a sample, as named by [`check_measured`](super::checks::check_measured).
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

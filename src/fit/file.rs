//! The reader of fit files (`fits/*.json`, `fits/<model>/*.json`) shared by the reports:
//! [`FitFile`] holds what they use of one channel's fit, of any model.

use crate::error::{Error, Num, Result};
use crate::model::far::FarOptions;
use crate::models::{ModelParams, Param};
use serde_json::Value;
use std::path::{Path, PathBuf};

/// The loader options a fit file records, as the build that wrote it applied them. Before
/// the build was identified in `tool_version` (`furfit 0.1.0` without `(git ...)`), the
/// conventions `flip_phi`, `phi_offset` and `flip_theta_r` converted Yan-2015 files only,
/// yet were recorded for any input: for a fit of CSV / npz files alone they are dropped,
/// or the report would plot converted data under a fit of unconverted data.
pub(crate) fn legacy_load(v: &Value, files: &[PathBuf]) -> crate::profile::LoadOptions {
    let mut load = crate::fit::job::load_options_from_json(&v["data"]["load"]);
    let identified = v["tool_version"]
        .as_str()
        .is_some_and(|t| t.contains("(git "));
    let any_yan = files
        .iter()
        .any(|f| crate::profile::Format::from_path(f).ok() == Some(crate::profile::Format::Yan));
    if !identified && !any_yan {
        load.flip_phi = false;
        load.flip_theta_r = false;
        load.phi_offset = 0.0;
    }
    load
}

/// The parts of a fit file the reports use.
#[derive(Clone, Debug)]
pub struct FitFile {
    /// Where the fit file was read from.
    pub path: PathBuf,
    /// See [`FitFile::label`].
    pub(crate) label: String,
    /// The file's top-level (primary) channel; false for its other channels.
    pub primary: bool,
    /// Parameters held fixed by `--fix` (`uncertainty.fixed`).
    pub fixed: Vec<String>,
    /// Species the fit records (`species`).
    pub species: String,
    /// The fitted parameters, with their model.
    pub params: ModelParams,
    /// Exposure `k` of the channel.
    pub exposure: f64,
    /// The NRMSE the report shows: the file's own, replaced by the one recomputed from
    /// `params` on the fit's data when those differ ([`FitFile::check_nrmse`]).
    pub nrmse: f64,
    /// The file's own NRMSE when the one recomputed (`nrmse`) differs from it: the file
    /// was edited after the fit (e.g. a parameter changed by hand), or made by a build
    /// that computed the model otherwise (`tool_version`).
    pub nrmse_recorded: Option<f64>,
    /// The build that wrote the fit (`tool_version`; empty when not recorded).
    pub tool_version: String,
    /// Whether the fitted data are labelled synthetic (`data.synthetic`).
    pub synthetic: bool,
    /// Data files recorded in the fit, where they are found now (see `candidates`).
    pub files: Vec<PathBuf>,
    /// Where the report found the fit's own data ([`FitFile::load_data`]; empty before
    /// it looked or when it found none): what [`FitFile::fitted_from`] tests.
    pub(crate) verified: Vec<PathBuf>,
    /// The places the recorded files may be, in the order [`FitFile::load_data`] tries.
    candidates: Vec<Vec<PathBuf>>,
    /// Their SHA-256 digests as recorded (empty in fit files that did not record them).
    pub sha256: Vec<String>,
    /// The SHA-256 of each recorded file's samples (empty for fit files from before it).
    pub samples_sha256: Vec<String>,
    /// Loader options the fit read them with (`data.load`).
    pub load: crate::profile::LoadOptions,
    /// Channel name fitted at the top level ("" for a single channel).
    pub channel: String,
    /// Convergence trace: `(stage, iter, time_s, value)`; the value is the NRMSE of the
    /// stage's data for an unweighted fit, the RMS of the weighted normalised log
    /// residuals for a weighted one (see [`FitFile::weighted`]).
    pub trace: Vec<(String, u64, f64, f64)>,
    /// Fitted with `--weighted` (`solver.weighted`): then the trace values are weighted
    /// RMS residuals, not NRMSE (the fitter records them under `nrmse` all the same).
    pub weighted: bool,
    /// The fit left out valid samples below `floor` times the channel's largest valid
    /// value (`data.floor`; `None` in fit files from before it was recorded).
    pub floor: Option<f64>,
    /// Valid samples of the channel (`data.n_valid`).
    pub n_valid: Option<u64>,
    /// Of those, the ones below the floor, left out of the fit and its NRMSE
    /// (`data.n_below_floor`).
    pub n_below_floor: Option<u64>,
    /// Wall seconds of the fit (`solver.wall_time_s`).
    pub wall_time_s: f64,
    /// Model evaluations of the solve (`solver.evaluations`).
    pub evaluations: Option<u64>,
    /// Samples the fit used (`data.n_used`).
    pub n_used: Option<u64>,
    /// Parameters the fit flagged as not constrained by the data
    /// (`uncertainty.unconstrained`).
    pub unconstrained: Vec<String>,
    /// Standard errors (file units) per parameter, `None` if fixed/infinite.
    pub se: Vec<Option<f64>>,
    /// Sweep-robust standard errors (`uncertainty.robust`; `None` where the fit has none,
    /// or from before they were recorded).
    pub se_robust: Vec<Option<f64>>,
    /// The far field the fit used (`solver.segments`, `.tol`, `.scattered_step`; fits
    /// written before `tol` was recorded used the fixed segmentation).
    pub far: FarOptions,
}

/// The far-field options a fit file records (see [`FitFile::far`]).
fn recorded_far(solver: &Value) -> FarOptions {
    let d = FarOptions::default();
    let count = |key: &str, default: usize| {
        solver["segments"][key]
            .as_u64()
            .map_or(default, |n| n.clamp(1, 4096) as usize)
    };
    FarOptions {
        n_unscattered: count("unscattered", d.n_unscattered),
        n_scattered: count("scattered", d.n_scattered),
        tol: solver["tol"].as_f64().filter(|t| *t > 0.0 && *t < 1.0),
        scattered_step: solver["scattered_step"]
            .as_f64()
            .filter(|s| *s > 0.0 && *s <= 1.0)
            .unwrap_or(d.scattered_step),
        ..d
    }
}

/// The places a fit's recorded data files may be, in order (see [`FitFile::load_data`]),
/// and the first whose files all exist (else the files as given): `(files, candidates)`.
fn data_places(path: &Path, v: &Value) -> (Vec<PathBuf>, Vec<Vec<PathBuf>>) {
    // Where the recorded files may be, in order: as given to `furfit fit` (usually
    // relative to the project folder it ran in), relative to the fit file (`from_fit`:
    // a report run from elsewhere, or a project moved), under the folder above the fits
    // folder. `load_data` takes the first place whose files all exist and hold the
    // recorded data; `files` is the first whose files exist.
    let fit_dir = crate::io::parent_dir(path);
    let project = path.parent().and_then(Path::parent);
    let entries = v["data"]["files"].as_array().cloned().unwrap_or_default();
    let given: Vec<PathBuf> = entries
        .iter()
        .filter_map(|f| f["path"].as_str().map(PathBuf::from))
        .collect();
    let mut candidates = vec![given.clone()];
    let from_fit: Option<Vec<PathBuf>> = entries
        .iter()
        .map(|f| f["from_fit"].as_str().map(|r| fit_dir.join(r)))
        .collect();
    candidates.extend(from_fit);
    if let Some(root) = project {
        candidates.push(
            given
                .iter()
                .map(|g| {
                    if g.is_relative() {
                        root.join(g)
                    } else {
                        g.clone()
                    }
                })
                .collect(),
        );
    }
    candidates.retain(|c| c.len() == given.len() && !c.is_empty());
    // Each place once (with a one-folder relative --fits the project's place is the
    // given one), in order.
    let mut seen = Vec::new();
    candidates.retain(|c| {
        let fresh = !seen.contains(c);
        if fresh {
            seen.push(c.clone());
        }
        fresh
    });
    let files = candidates
        .iter()
        .find(|c| c.iter().all(|f| f.exists()))
        .cloned()
        .unwrap_or(given);
    (files, candidates)
}

/// The fit's convergence trace `(stage, iter, time_s, value)`, as [`FitFile::trace`].
fn recorded_trace(v: &Value) -> Vec<(String, u64, f64, f64)> {
    v["trace"]
        .as_array()
        .map(|a| {
            a.iter()
                .map(|t| {
                    (
                        t["stage"].as_str().unwrap_or("").to_string(),
                        t["iter"].as_u64().unwrap_or(0),
                        t["time_s"].as_f64().unwrap_or(f64::NAN),
                        t["nrmse"].as_f64().unwrap_or(f64::NAN),
                    )
                })
                .collect()
        })
        .unwrap_or_default()
}

impl FitFile {
    /// Read one fit file: one entry, or one per channel for a fit of several channels
    /// (each labelled `<stem>-<channel>`; the file's primary channel first).
    pub fn read(path: &Path) -> Result<Vec<FitFile>> {
        let v: Value = crate::io::read_json(path)?;
        let stem = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        let mut top = Self::from_value(path, &v, &v)?;
        top.label = stem.clone();
        let Some(channels) = v["channels"].as_array().filter(|c| c.len() > 1) else {
            return Ok(vec![top]);
        };
        let mut out = Vec::with_capacity(channels.len());
        for c in channels {
            let mut f = Self::from_value(path, &v, c)?;
            f.primary = f.channel == top.channel;
            // The channel name comes from the data: only file-name-safe characters.
            let safe: String = f
                .channel
                .chars()
                .map(|ch| {
                    if ch.is_ascii_alphanumeric() || ch == '_' {
                        ch
                    } else {
                        '_'
                    }
                })
                .collect();
            f.label = format!("{stem}-{safe}");
            out.push(f);
        }
        out.sort_by_key(|f| !f.primary);
        Ok(out)
    }

    /// One channel's fit object `v` of the file `top` (the file itself for one channel).
    fn from_value(path: &Path, top: &Value, v: &Value) -> Result<FitFile> {
        let (params, exposure) = ModelParams::from_json_value(v, None).map_err(|e| match e {
            Error::Param { key, msg } => Error::Param {
                key,
                msg: format!("{msg} (in {})", path.display()),
            },
            Error::Invalid(m) => Error::Invalid(format!("{}: {m}", path.display())),
            o => o,
        })?;
        let species = top["species"]
            .as_str()
            .map(str::to_string)
            .or_else(|| path.file_stem().map(|s| s.to_string_lossy().into_owned()))
            .unwrap_or_default();
        let nrmse = match &v["nrmse"] {
            Value::Null => return Err(Error::file(path, "fit file has no 'nrmse'")),
            x => x
                .as_f64()
                .filter(|x| *x >= 0.0 && x.is_finite())
                .map(|x| x + 0.0)
                .ok_or_else(|| {
                    Error::file(
                        path,
                        format!("'nrmse' must be a non-negative number (found {x})"),
                    )
                })?,
        };
        let recorded = |key: &str| -> Vec<String> {
            v["data"]["files"]
                .as_array()
                .map(|a| {
                    a.iter()
                        .filter_map(|f| f[key].as_str().map(str::to_string))
                        .collect()
                })
                .unwrap_or_default()
        };
        let (files, candidates) = data_places(path, v);
        let load = legacy_load(v, &files);
        let sha256 = recorded("sha256");
        let samples_sha256 = recorded("samples_sha256");
        let trace = recorded_trace(v);
        let unconstrained = v["uncertainty"]["unconstrained"]
            .as_array()
            .map(|a| {
                a.iter()
                    .filter_map(|u| u["key"].as_str().map(str::to_string))
                    .collect()
            })
            .unwrap_or_default();
        let se = Param::all(params.model)
            .map(|id| v["uncertainty"]["standard_error"][id.name()].as_f64())
            .collect();
        let se_robust = Param::all(params.model)
            .map(|id| v["uncertainty"]["robust"]["standard_error"][id.name()].as_f64())
            .collect();
        let fixed = v["uncertainty"]["fixed"]
            .as_array()
            .map(|a| {
                a.iter()
                    .filter_map(|k| k.as_str().map(str::to_string))
                    .collect()
            })
            .unwrap_or_default();
        Ok(FitFile {
            path: path.to_path_buf(),
            label: String::new(),
            primary: true,
            fixed,
            species,
            params,
            exposure,
            nrmse,
            nrmse_recorded: None,
            tool_version: v["tool_version"].as_str().unwrap_or("").to_string(),
            synthetic: v["data"]["synthetic"].as_bool().unwrap_or(false),
            files,
            verified: Vec::new(),
            sha256,
            samples_sha256,
            candidates,
            load,
            channel: v["data"]["channel"].as_str().unwrap_or("").to_string(),
            trace,
            weighted: v["solver"]["weighted"].as_bool().unwrap_or(false),
            floor: match &v["data"]["floor"] {
                Value::Null => None,
                x => Some(
                    x.as_f64()
                        .filter(|f| (0.0..1.0).contains(f))
                        .ok_or_else(|| {
                            Error::file(
                                path,
                                format!("'data.floor' must be a number in [0, 1) (found {x})"),
                            )
                        })?,
                ),
            },
            n_valid: v["data"]["n_valid"].as_u64(),
            n_below_floor: v["data"]["n_below_floor"].as_u64(),
            wall_time_s: v["solver"]["wall_time_s"].as_f64().unwrap_or(f64::NAN),
            evaluations: v["solver"]["evaluations"].as_u64(),
            n_used: v["data"]["n_used"].as_u64(),
            unconstrained,
            se,
            se_robust,
            far: recorded_far(&v["solver"]),
        })
    }

    /// The name the reports give this fit: its file's stem (the species for
    /// `fits/<species>.json`), so two fits of one species (`red-fox.json`,
    /// `red-fox-v2.json`) get their own columns and figures; `<stem>-<channel>` for each
    /// channel of a fit of several.
    pub fn label(&self) -> String {
        self.label.clone()
    }

    /// Recompute the NRMSE from the file's parameters on `data` (its own data, read back
    /// as recorded) with the fit's floor and far field, as `furfit fit` computed it: a
    /// report must not pair edited parameters with the error of the ones fitted. When the
    /// two differ by more than [`NRMSE_MATCH`] of the larger plus [`NRMSE_FLOOR`], `nrmse`
    /// becomes the recomputed one and `nrmse_recorded` keeps the file's.
    pub fn check_nrmse(&mut self, data: &crate::Profile) {
        // A channel the data do not name is only safe to guess when there is one.
        let ch = match data.channels.iter().position(|c| *c == self.channel) {
            Some(c) => c,
            None if data.channels.len() <= 1 => 0,
            None => return,
        };
        let (floor, far) = truth_settings(Some(self));
        let Some(now) = nrmse_at(&self.params, data, ch, floor, &far) else {
            return;
        };
        let slack = NRMSE_MATCH * self.nrmse.max(now.nrmse) + NRMSE_FLOOR;
        if (now.nrmse - self.nrmse).abs() > slack {
            self.nrmse_recorded = Some(self.nrmse);
            self.nrmse = now.nrmse;
        }
    }

    /// The note for a fit whose recorded NRMSE did not match its parameters: the file
    /// was edited, or (another `tool_version`) made by a build whose model differs.
    pub(crate) fn nrmse_note(&self) -> Option<String> {
        self.nrmse_recorded.map(|rec| {
            let why = if self.tool_version == crate::TOOL_VERSION {
                "the file was changed after the fit".to_string()
            } else {
                format!(
                    "the file was changed after the fit, or its build ({}) computed the \
                     model otherwise",
                    if self.tool_version.is_empty() {
                        "unrecorded"
                    } else {
                        &self.tool_version
                    }
                )
            };
            format!(
                "{}: the file records NRMSE {} but its parameters give {} on its data with \
                 this build: {why}; the report shows the recomputed value",
                self.label,
                Num(rec),
                Num(self.nrmse)
            )
        })
    }

    /// This fit's data, reloaded with its loader options, and where they were read: the
    /// first of its `candidates` whose files all exist, then `measurements/<species>/`,
    /// that holds files with the recorded SHA-256 digests, so a figure never shows a fit
    /// over other data than it was fitted to (fit files without digests are taken on
    /// trust).
    pub(crate) fn load_data(&self, measurements: &Path) -> Result<(crate::Profile, Vec<PathBuf>)> {
        let mut first_err = None;
        let places = self
            .candidates
            .iter()
            .filter(|c| c.iter().all(|p| p.is_file()))
            .cloned()
            .chain(
                Some(measurements.join(&self.species))
                    .filter(|d| d.is_dir())
                    .map(|d| vec![d]),
            );
        // The first place holding the recorded data; a copy of other data (a project's
        // own measurements/ beside the one fitted) does not hide a later one that matches.
        for inputs in places {
            match crate::fit::job::load_inputs_full(&inputs, &self.load)
                .and_then(|l| self.check_digests(&inputs, &l.files).map(|()| l.profile))
            {
                Ok(p) => return Ok((p, inputs)),
                Err(e) => {
                    first_err.get_or_insert(e);
                }
            }
        }
        Err(first_err.unwrap_or_else(|| {
            Error::Invalid(format!(
                "its recorded data files are missing and there is no {}",
                measurements.join(&self.species).display()
            ))
        }))
    }

    /// The files read from `inputs` have the digests this fit recorded (fit files without
    /// digests are taken on trust).
    pub(crate) fn check_digests(
        &self,
        inputs: &[PathBuf],
        read: &[crate::profile::ReadFile],
    ) -> Result<()> {
        if self.sha256.len() != self.files.len() || self.sha256.is_empty() {
            return Ok(());
        }
        // The same bytes, or the same samples written otherwise (the recorded simulate
        // command re-run by another build formats numbers and its tool line its own way).
        let same = |have: Vec<&str>, want: &[String]| {
            let mut have = have;
            let mut want: Vec<&str> = want.iter().map(String::as_str).collect();
            have.sort_unstable();
            want.sort_unstable();
            have == want
        };
        if same(
            read.iter().map(|f| f.sha256.as_str()).collect(),
            &self.sha256,
        ) || (self.samples_sha256.len() == self.files.len()
            && same(
                read.iter().map(|f| f.samples_sha256.as_str()).collect(),
                &self.samples_sha256,
            ))
        {
            return Ok(());
        }
        let what = inputs
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", ");
        Err(Error::Invalid(format!(
            "{what} does not hold the data this fit was made from (SHA-256 differs from {}); \
             refit or restore the data",
            self.path.display()
        )))
    }

    /// Whether the fit's data lie in `dir` (so its loader options apply to `dir` and its
    /// NRMSE is comparable with one computed there): where the report found them, else
    /// every file the fit recorded.
    pub(crate) fn fitted_from(&self, dir: &Path) -> bool {
        let Ok(dir) = dir.canonicalize() else {
            return false;
        };
        let files = if self.verified.is_empty() {
            &self.files
        } else {
            &self.verified
        };
        !files.is_empty()
            && files
                .iter()
                .all(|p| p.canonicalize().is_ok_and(|p| p.starts_with(&dir)))
    }
}

/// Relative difference above which a fit file's recorded NRMSE counts as not its
/// parameters' ([`FitFile::check_nrmse`]). The recomputation repeats the fitter's
/// arithmetic on the same samples, so an untouched file agrees to rounding (the shipped
/// fits agree to ~1e-15); a hand edit of a parameter moves the NRMSE far more.
const NRMSE_MATCH: f64 = 1e-9;
/// Absolute slack of that comparison: a fit at rounding level (a noise-free round trip,
/// NRMSE ~1e-14) moves by more than 1e-9 of itself when an angle reads back from the file
/// one ulp off (about one angle in seven does), and no reader sees 1e-12 of NRMSE.
const NRMSE_FLOOR: f64 = 1e-12;

/// `(name, why)`: a fit file or report part left out.
pub type Skipped = (String, String);

/// Every readable fit file in `dir` ([`crate::io::fit_files`]), sorted by file name, and `(file name, why)`
/// for those that could not be read: a damaged file is skipped like a fit whose data
/// changed, not a stop for the whole report. An error when no fit file is readable, or
/// when two fits would get the same column and figure name ([`FitFile::label`]).
pub fn read_fits(dir: &Path) -> Result<(Vec<FitFile>, Vec<Skipped>)> {
    let paths = crate::io::fit_files(dir)?;
    if paths.is_empty() {
        return Err(Error::file(
            dir,
            "no fit files (*.json); run `furfit fit` first",
        ));
    }
    let mut out: Vec<FitFile> = Vec::new();
    let mut bad = Vec::new();
    for p in &paths {
        match FitFile::read(p) {
            Ok(fits) => {
                for f in fits {
                    if let Some(o) = out.iter().find(|o| o.label == f.label) {
                        let why = if o.path == f.path {
                            format!(
                                "its channels '{}' and '{}' would both be named '{}'; rename \
                                 one of the channels",
                                o.channel, f.channel, f.label
                            )
                        } else {
                            format!(
                                "its column and figure would be named '{}', as those of {}; \
                                 rename one of the two files",
                                f.label,
                                o.path.display()
                            )
                        };
                        return Err(Error::file(&f.path, why));
                    }
                    out.push(f);
                }
            }
            Err(e) => bad.push((
                p.file_name()
                    .map(|n| n.to_string_lossy().into_owned())
                    .unwrap_or_default(),
                format!("not read: {e}"),
            )),
        }
    }
    if out.is_empty() {
        let (name, why) = bad.into_iter().next().expect("paths is not empty");
        return Err(Error::file(
            dir,
            format!("no readable fit file ({name}: {why})"),
        ));
    }
    Ok((out, bad))
}

/// The sample floor and far field of "NRMSE at truth": those the fit recorded
/// (`data.floor`, `solver.tol` / `.segments` / `.scattered_step`), so it covers the same
/// samples with the same model as the fit's NRMSE; `furfit fit`'s defaults without a fit.
/// A fit file without `data.floor` was made before the floor existed, with every valid
/// sample.
pub fn truth_settings(fit: Option<&FitFile>) -> (f64, FarOptions) {
    match fit {
        Some(f) => (f.floor.unwrap_or(0.0), f.far),
        None => (super::DEFAULT_FLOOR, FarOptions::default()),
    }
}

/// NRMSE at the true parameters, and what it covers.
#[derive(Clone, Copy, Debug)]
pub struct TruthNrmse {
    /// NRMSE (MODEL.md) with the optimal exposure.
    pub nrmse: f64,
    /// The optimal exposure `k` at the truth.
    pub exposure: f64,
    /// Samples used: valid and at least the floor x the channel's peak.
    pub n_used: usize,
    /// Valid samples left out below the floor.
    pub n_below_floor: usize,
}

/// NRMSE (MODEL.md, optimal exposure) of the far field `far` at `params` on channel
/// `channel` of `profile`, over the samples a fit with relative floor `floor` uses (the
/// fitter's own selection, [`super::channel_data`]: valid, at least `floor` x the
/// channel's largest valid value, normalised by their log range); `None` when the
/// channel has no valid sample.
pub fn nrmse_at(
    params: &crate::models::ModelParams,
    profile: &crate::Profile,
    channel: usize,
    floor: f64,
    far: &FarOptions,
) -> Option<TruthNrmse> {
    let data = super::channel_data(profile, channel, false, floor).ok()?;
    let mut m = vec![0.0; data.ln_y.len()];
    crate::fit::forward::predict_model(params, &data.points, far, &mut m);
    let (nrmse, exposure) = super::problem::nrmse(&m, &data.ln_y, data.range);
    Some(TruthNrmse {
        nrmse,
        exposure,
        n_used: data.ln_y.len(),
        n_below_floor: data.n_below_floor,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Fit files from before the identified builds recorded the convention options for
    /// CSV / npz inputs without applying them: the report drops them there, and only there.
    #[test]
    fn legacy_conventions_apply_to_yan_only() {
        let fit = |tool: &str, file: &str| {
            let v = serde_json::json!({
                "tool_version": tool,
                "data": {"load": {"flip_phi": true, "phi_offset": 90.0, "flip_theta_r": true}},
            });
            (v, vec![PathBuf::from(file)])
        };
        for (tool, file, kept) in [
            ("furfit 0.1.0", "a.csv", false),
            ("furfit 0.1.0", "a.npz", false),
            ("furfit 0.1.0", "a.txt", true),
            ("furfit 0.1.0 (git 0123456789ab)", "a.csv", true),
        ] {
            let (v, files) = fit(tool, file);
            let l = legacy_load(&v, &files);
            assert_eq!(
                (l.flip_phi, l.flip_theta_r, l.phi_offset != 0.0),
                (kept, kept, kept),
                "{tool} {file}"
            );
        }
    }
}

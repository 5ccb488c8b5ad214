//! Fitting whole species: load the profile file(s) or species folder, fit every channel,
//! and write `fits/<species>.json` atomically.
//!
//! A multi-channel profile is fitted per channel (see the module doc of [`super`]). The
//! top level of the fit file is the *primary* channel (the one named `y` if any, else the
//! first), so `FurParams::load` reads it like any fit; with more than one channel a
//! `channels` array holds every channel's complete fit object.

use super::output::{fit_json, DataInfo};
use super::{channel_data, fit_data, FitOptions, FitOutcome, Progress};
use crate::error::{Error, Result};
use crate::profile::{self, Format, LoadOptions, Profile, ReadFile};
use serde_json::Value;
use std::path::{Path, PathBuf};

/// One species to fit.
#[derive(Clone, Debug, PartialEq)]
pub struct Job {
    /// Species name ([`species_name`]).
    pub species: String,
    /// Profile files and/or species folders, merged.
    pub inputs: Vec<PathBuf>,
    /// The fit file to write.
    pub out: PathBuf,
    /// `--force`: replace a fit file of other data at `out`.
    pub force: bool,
}

/// Species name of an input: the folder name, or the file stem (the folder's name for a
/// `profile.*` file).
pub fn species_name(p: &Path) -> String {
    // The folder's own name, as given (a symlinked folder keeps its link's name); `.` and
    // `..` have none, so their real name is looked up.
    let folder_name = |d: &Path| {
        d.file_name()
            .map(|n| n.to_owned())
            .or_else(|| d.canonicalize().ok()?.file_name().map(|n| n.to_owned()))
            .map(|n| n.to_string_lossy().trim_matches('.').to_string())
            .filter(|n| !n.is_empty())
    };
    if p.is_dir() {
        if let Some(n) = folder_name(p) {
            return n;
        }
    } else if p
        .file_stem()
        .is_some_and(|s| s.eq_ignore_ascii_case("profile"))
    {
        // `measurements/<species>/profile.csv`, the layout's name for a species' profile,
        // is named after its folder (as `fit <folder>` is): two species' `profile.csv`
        // would otherwise both become "profile" and write one fit file.
        if let Some(n) = folder_name(&crate::io::parent_dir(p)) {
            return n;
        }
    }
    // Dots trimmed: `..csv` has the stem ".", whose fit file `..json` hides in listings.
    p.file_stem()
        .map(|s| s.to_string_lossy().trim_matches('.').to_string())
        .filter(|s| !s.is_empty())
        .unwrap_or_else(|| "profile".into())
}

/// Check that writing the fit of `files` to `out` loses no other fit: an existing fit file
/// is replaced freely when it was made from the same data (a file it records has one of
/// `files`' paths or contents: a refit, also after the data were edited or from another
/// folder), and only with `force` otherwise (two datasets whose fits take one name).
pub fn check_replace_fit(out: &Path, files: &[ReadFile], force: bool) -> Result<()> {
    if force || !out.exists() {
        return Ok(());
    }
    let v = crate::io::read_json(out)?;
    let recorded = v["data"]["files"].as_array().cloned().unwrap_or_default();
    let fit_dir = crate::io::resolve_path(&crate::io::parent_dir(out));
    let inputs: Vec<PathBuf> = files
        .iter()
        .map(|f| crate::io::resolve_path(&f.path))
        .collect();
    let same = recorded.iter().any(|r| {
        let sha = r["sha256"].as_str().unwrap_or_default();
        let samples = r["samples_sha256"].as_str().unwrap_or_default();
        // The path relative to the fit file names the file wherever the fit ran from;
        // fit files without it fall back to the path as given (from the current folder).
        let path = match r["from_fit"].as_str() {
            Some(rel) => crate::io::resolve_path(&fit_dir.join(rel)),
            None => crate::io::resolve_path(Path::new(r["path"].as_str().unwrap_or_default())),
        };
        files
            .iter()
            .any(|f| f.sha256 == sha || f.samples_sha256 == samples)
            || inputs.contains(&path)
    });
    if same {
        return Ok(());
    }
    let names: Vec<&str> = recorded.iter().filter_map(|r| r["path"].as_str()).collect();
    Err(Error::file(
        out,
        format!(
            "exists and holds a fit of other data ({}); give --force to replace it, or --out \
             another path",
            if names.is_empty() {
                "no data files recorded".to_string()
            } else {
                names.join(", ")
            }
        ),
    ))
}

/// Every species folder under `measurements` (sorted), one job each (replacing a fit of
/// other data when `force`), and the folders passed over for holding no profile file or
/// a simulation kept from a refused run (`*.kept-<pid>`; the caller says so); a hidden
/// folder without profile files (`.git`) is not listed.
pub fn jobs_for_all(
    measurements: &Path,
    fits_dir: &Path,
    force: bool,
) -> Result<(Vec<Job>, Vec<PathBuf>)> {
    let rd = std::fs::read_dir(measurements).map_err(|e| Error::io(measurements, e))?;
    let (mut dirs, mut passed): (Vec<PathBuf>, Vec<PathBuf>) = rd
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_dir())
        .partition(|p| {
            // A simulation kept beside its refused output is no species.
            !crate::io::is_kept_path(p)
                && profile::dir_profile_files(p).is_ok_and(|(f, _)| !f.is_empty())
        });
    dirs.sort();
    // A hidden folder without data (`.git`) is nobody's species: passed over unsaid.
    passed.retain(|p| {
        !p.file_name()
            .is_some_and(|n| n.to_string_lossy().starts_with('.'))
            || crate::io::is_kept_path(p)
    });
    passed.sort();
    if dirs.is_empty() {
        return Err(Error::file(
            measurements,
            "no species folder with profile files",
        ));
    }
    let jobs = dirs
        .into_iter()
        .map(|d| {
            let species = species_name(&d);
            Job {
                out: fits_dir.join(format!("{species}.json")),
                species,
                inputs: vec![d],
                force,
            }
        })
        .collect();
    Ok((jobs, passed))
}

/// The inputs of a fit, loaded and merged.
#[derive(Clone, Debug)]
pub struct LoadedInputs {
    /// The merged profile.
    pub profile: Profile,
    /// The files read (folders expanded).
    pub files: Vec<ReadFile>,
    /// The loaders' notes, each naming its file (`inspect` prints the same ones).
    pub notes: Vec<String>,
}

impl LoadedInputs {
    /// The formats of the files read (for [`LoadOptions::check_used`]).
    pub fn formats(&self) -> Vec<Format> {
        self.files.iter().map(|f| f.format).collect()
    }
}

/// Load and merge the inputs into one profile with the loader options `opts`.
pub fn load_inputs(inputs: &[PathBuf], opts: &LoadOptions) -> Result<Profile> {
    Ok(load_inputs_full(inputs, opts)?.profile)
}

/// [`load_inputs`], also keeping the loader notes.
pub fn load_inputs_full(inputs: &[PathBuf], opts: &LoadOptions) -> Result<LoadedInputs> {
    let opts = &opts.for_inputs(inputs);
    let mut parts = Vec::new();
    let mut notes = Vec::new();
    let mut files = Vec::new();
    for p in inputs {
        let l = if p.is_dir() {
            // load_dir already names the file in each note.
            let mut l = profile::load_dir(p, opts)?;
            notes.append(&mut l.notes);
            l
        } else {
            let mut l = profile::load_full(p, opts)?;
            notes.extend(l.notes.drain(..).map(|n| format!("{}: {n}", p.display())));
            l
        };
        files.extend(l.files.iter().cloned());
        parts.push(l);
    }
    let profile = if parts.len() == 1 {
        parts.pop().expect("one part").profile
    } else {
        let (merged, collapsed) = profile::merge_loaded(parts, opts)?;
        notes.extend(profile::collapsed_note(collapsed, "inputs"));
        merged
    };
    Ok(LoadedInputs {
        profile,
        files,
        notes,
    })
}

/// The loader options as a fit file records them (`data.load`), so a report reads the
/// data as the fit did.
pub fn load_options_json(o: &LoadOptions) -> Value {
    serde_json::json!({
        "theta_i": o.theta_i,
        "theta_r": o.theta_r,
        "phi": o.phi,
        "phi_offset": o.phi_offset,
        "flip_phi": o.flip_phi,
        "flip_theta_r": o.flip_theta_r,
    })
}

/// [`load_options_json`] read back; absent keys (fit files written before they were
/// recorded) are the defaults.
pub fn load_options_from_json(v: &Value) -> LoadOptions {
    let grid = |k: &str| {
        v[k].as_array()
            .map(|a| a.iter().filter_map(Value::as_f64).collect::<Vec<f64>>())
    };
    LoadOptions {
        theta_i: grid("theta_i"),
        theta_r: grid("theta_r"),
        phi: grid("phi"),
        phi_offset: v["phi_offset"].as_f64().unwrap_or(0.0),
        flip_phi: v["flip_phi"].as_bool().unwrap_or(false),
        flip_theta_r: v["flip_theta_r"].as_bool().unwrap_or(false),
        // Derived from the inputs when they are loaded (LoadOptions::for_inputs).
        theta_i_for_npy: false,
    }
}

/// Refuse an output path that is not a `.json` file, or that holds anything but an earlier
/// fit (a species' `metadata.json` with the true parameters, a parameter file, a
/// directory): a fit must never overwrite data. Inputs are profiles, never `.json`.
pub fn check_out(out: &Path) -> Result<()> {
    if out.extension().and_then(|e| e.to_str()) != Some("json") {
        return Err(Error::file(out, "a fit file must end in .json"));
    }
    if out.is_dir() {
        return Err(Error::file(out, "is a directory, not a fit file path"));
    }
    // A read-only folder fails here, not after a fit of minutes (audit, 2026-11-28).
    crate::io::probe_file_writable(out)?;
    if out.exists() {
        let is_fit = crate::io::read_json(out)
            .is_ok_and(|v| v.get("solver").is_some() && v.get("tool_version").is_some());
        if !is_fit {
            return Err(Error::file(
                out,
                "exists and is not a furfit fit file; refusing to overwrite it",
            ));
        }
    }
    Ok(())
}

/// Write a finished fit that may not go to `out` beside it, under a name no file has yet
/// ([`crate::io::kept_path`]). Not `*.json`, so `report` and
/// `render --all` do not take it for a fit of the folder until the user renames it.
fn keep_refused(out: &Path, text: &[u8]) -> Option<PathBuf> {
    crate::io::kept_path(out).filter(|p| crate::io::write_atomic(p, text).is_ok())
}

/// Summary of one channel's fit, for printing.
#[derive(Clone, Debug)]
pub struct ChannelSummary {
    /// The channel's name (empty for one unnamed channel).
    pub channel: String,
    /// Its fit.
    pub outcome: FitOutcome,
}

/// Fit one species (its inputs read with the loader options `load`, an axis option no
/// input reads being an error) and write its fit file. Returns the JSON written and per-channel
/// summaries.
pub fn run_job(
    job: &Job,
    opts: &FitOptions,
    load: &LoadOptions,
    progress: Option<Progress>,
) -> Result<(Value, Vec<ChannelSummary>)> {
    check_out(&job.out)?;
    let inputs = load_inputs_full(&job.inputs, load)?;
    load.check_used(&inputs.formats())?;
    fit_loaded(job, &inputs, opts, load, progress)
}

/// [`run_job`] on inputs already loaded (with `load`) by [`load_inputs_full`] (and checked
/// with [`LoadOptions::check_used`]); the fit file records their loader notes under
/// `data.notes`.
pub fn fit_loaded(
    job: &Job,
    inputs: &LoadedInputs,
    opts: &FitOptions,
    load: &LoadOptions,
    progress: Option<Progress>,
) -> Result<(Value, Vec<ChannelSummary>)> {
    check_out(&job.out)?;
    let fit = fit_species(&job.species, inputs, opts, load, progress)?;
    let top = fit.to_json(&job.out);
    let text = fit_text(&top)?;
    // Again: a user's file, or another run's fit of other data, may have appeared there
    // during the fit (audit, 2026-11-28). Refused, the finished fit is kept beside it.
    if let Err(e) =
        check_out(&job.out).and_then(|()| check_replace_fit(&job.out, &inputs.files, job.force))
    {
        let kept = keep_refused(&job.out, text.as_bytes())
            .map(|k| format!("; the fit is written to {} instead", k.display()))
            .unwrap_or_default();
        return Err(Error::Invalid(format!(
            "{} can no longer be written (it changed while fitting): {e}{kept}",
            job.out.display()
        )));
    }
    crate::io::write_atomic(&job.out, text.as_bytes())
        .map_err(|e| Error::Invalid(format!("the fit finished but was not written: {e}")))?;
    Ok((top, fit.summaries()))
}

/// The text of a fit file: its JSON, pretty-printed, and a final newline.
fn fit_text(top: &Value) -> Result<String> {
    Ok(serde_json::to_string_pretty(top).map_err(|e| Error::Invalid(format!("JSON: {e}")))? + "\n")
}

/// One species fitted, every channel, before its fit file is written ([`fit_species`]):
/// what [`fit_loaded`] writes, for a caller that decides later where (or whether) it goes.
#[derive(Clone, Debug)]
pub struct SpeciesFit {
    /// Species name ([`species_name`]).
    pub species: String,
    /// Per channel, in the profile's order: the outcome and the provenance of its data
    /// (without the files, which [`SpeciesFit::to_json`] records relative to the fit file).
    pub channels: Vec<(ChannelSummary, DataInfo)>,
    /// The channel of the fit file's top level: the one named `y` if any, else the first.
    pub primary: usize,
    /// The files fitted.
    pub files: Vec<ReadFile>,
    /// The options of the fit (the fit file records them).
    pub opts: FitOptions,
}

/// Fit every channel of `inputs` (loaded with `load`, see [`fit_loaded`]) as species
/// `species`; nothing is written.
pub fn fit_species(
    species: &str,
    inputs: &LoadedInputs,
    opts: &FitOptions,
    load: &LoadOptions,
    progress: Option<Progress>,
) -> Result<SpeciesFit> {
    let prof = &inputs.profile;
    let n_ch = prof.n_channels();
    let name_of = |c: usize| prof.channels.get(c).cloned().unwrap_or_default();
    let primary = (0..n_ch)
        .find(|&c| name_of(c).eq_ignore_ascii_case("y"))
        .unwrap_or(0);
    let load_json = load_options_json(load);
    let mut channels = Vec::new();
    for c in 0..n_ch {
        let data = channel_data(prof, c, opts.weighted, opts.floor).map_err(|e| match e {
            Error::Invalid(m) => Error::Invalid(format!("{species}: {m}")),
            other => other,
        })?;
        let n_valid = prof
            .samples
            .iter()
            .filter(|s| s.channel == c && s.is_valid())
            .count();
        let n_all = prof.samples.iter().filter(|s| s.channel == c).count();
        let out = fit_data(&data, opts, progress).map_err(|e| match e {
            // Which channel, when there are several (r, g, b): each is fitted on its own.
            Error::Invalid(m) if n_ch > 1 => {
                Error::Invalid(format!("channel '{}': {m}", name_of(c)))
            }
            other => other,
        })?;
        let info = DataInfo {
            files: Vec::new(),
            n_valid,
            n_invalid: n_all - n_valid,
            n_below_floor: data.n_below_floor,
            synthetic: prof.is_synthetic(),
            channel: name_of(c),
            load: load_json.clone(),
            notes: inputs.notes.clone(),
        };
        let sum = ChannelSummary {
            channel: name_of(c),
            outcome: out,
        };
        channels.push((sum, info));
    }
    Ok(SpeciesFit {
        species: species.to_string(),
        channels,
        primary,
        files: inputs.files.clone(),
        opts: opts.clone(),
    })
}

impl SpeciesFit {
    /// The fit file's JSON as it is written to `out`: each file fitted is recorded with
    /// its path relative to `out`'s folder (see [`DataInfo::files`]).
    pub fn to_json(&self, out: &Path) -> Value {
        let fit_dir = crate::io::resolve_path(&crate::io::parent_dir(out));
        let file_info: Vec<(String, String, String, String)> = self
            .files
            .iter()
            .map(|f| {
                let rel = crate::io::relative_path(&fit_dir, &crate::io::resolve_path(&f.path));
                (
                    f.path.display().to_string(),
                    f.sha256.clone(),
                    rel.display().to_string(),
                    f.samples_sha256.clone(),
                )
            })
            .collect();
        let objs: Vec<Value> = self
            .channels
            .iter()
            .map(|(sum, info)| {
                let info = DataInfo {
                    files: file_info.clone(),
                    ..info.clone()
                };
                fit_json(&sum.outcome, &self.opts, &info)
            })
            .collect();
        let mut top = objs[self.primary].clone();
        if let Value::Object(m) = &mut top {
            m.insert("species".into(), Value::from(self.species.clone()));
            if objs.len() > 1 {
                m.insert("channels".into(), Value::Array(objs));
            }
        }
        top
    }

    /// The per-channel summaries, for printing.
    pub fn summaries(&self) -> Vec<ChannelSummary> {
        self.channels.iter().map(|(s, _)| s.clone()).collect()
    }

    /// Write the fit file to `out` (atomically), as `furfit fit --out` would: only over an
    /// earlier fit of the same data, or of other data with `force` ([`check_out`],
    /// [`check_replace_fit`]). Returns the JSON written.
    pub fn save(&self, out: &Path, force: bool) -> Result<Value> {
        check_out(out)?;
        check_replace_fit(out, &self.files, force)?;
        let top = self.to_json(out);
        crate::io::write_atomic(out, fit_text(&top)?.as_bytes())?;
        Ok(top)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A species fitted in memory: its fit file records the data relative to wherever it
    /// is saved, `fit_loaded` writes the same file, and `save` refuses a file that is no
    /// fit, as `furfit fit --out` does.
    #[test]
    fn species_fit_saves_the_file_fit_loaded_writes() {
        let dir = tempfile::tempdir().unwrap();
        let data = dir.path().join("data").join("fox.csv");
        std::fs::create_dir_all(data.parent().unwrap()).unwrap();
        let p: crate::models::ModelParams = crate::FurParams::preset("red-fox").unwrap().into();
        let prof = crate::synth::synthesize(
            &p,
            &[0.0, 30.0],
            &[-40.0, 0.0, 40.0],
            &[0.0, 90.0, 180.0],
            crate::models::Integral::Far,
            crate::model::LobeSet::ALL,
            2.0,
            &Default::default(),
        );
        crate::synth::save(&data, &prof).unwrap();
        // Every parameter fixed: the fit is the exposure alone (milliseconds).
        let mut opts = FitOptions::default();
        for (s, v) in p.model.specs().iter().zip(p.typed_file_units()) {
            opts.fix(s.name, v).unwrap();
        }
        let load = LoadOptions::default();
        let inputs = load_inputs_full(std::slice::from_ref(&data), &load).unwrap();
        let fit = fit_species("fox", &inputs, &opts, &load, None).unwrap();
        let near = dir.path().join("data").join("fit.json");
        let far = dir.path().join("fits").join("deep").join("fit.json");
        let rel = |v: &Value| {
            v["data"]["files"][0]["from_fit"]
                .as_str()
                .unwrap()
                .to_string()
        };
        assert_eq!(rel(&fit.to_json(&near)), "fox.csv");
        assert_eq!(rel(&fit.to_json(&far)), "../../data/fox.csv");
        let saved = fit.save(&far, false).unwrap();
        let text = std::fs::read_to_string(&far).unwrap();
        assert_eq!(serde_json::from_str::<Value>(&text).unwrap(), saved);
        assert_eq!(saved["species"], "fox");
        assert!((saved["exposure"].as_f64().unwrap() - 2.0).abs() < 1e-12);
        // The CLI's path: the same file but for the wall-clock fields.
        let job = Job {
            species: "fox".into(),
            inputs: vec![data.clone()],
            out: far.clone(),
            force: false,
        };
        let (top, _) = fit_loaded(&job, &inputs, &opts, &load, None).unwrap();
        let strip = |v: &Value| {
            let mut v = v.clone();
            for k in ["wall_time_s", "model_time_s", "model_time_share"] {
                v["solver"][k] = Value::Null;
            }
            for t in v["trace"].as_array_mut().unwrap() {
                t["time_s"] = Value::Null;
            }
            v
        };
        assert_eq!(strip(&top), strip(&saved));
        let other = dir.path().join("notes.json");
        std::fs::write(&other, "{}").unwrap();
        let e = fit.save(&other, true).unwrap_err().to_string();
        assert!(e.contains("is not a furfit fit file"), "{e}");
        assert_eq!(std::fs::read_to_string(&other).unwrap(), "{}");
    }

    /// A refused fit is kept under a name no file holds (a user's file of the first name
    /// stays as it was; review, 2026-11-28: `<stem>.<pid>.json` was overwritten, and pids
    /// repeat, e.g. 1 in containers), and not as `*.json`, which reports take for a fit.
    #[test]
    fn a_refused_fit_is_kept_beside_without_replacing_anything() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("mouse.json");
        let first = dir
            .path()
            .join(format!("mouse.json.kept-{}", std::process::id()));
        std::fs::write(&first, "mine").unwrap();
        let kept = keep_refused(&out, b"{}").unwrap();
        assert_ne!(kept, first);
        assert_eq!(std::fs::read_to_string(&first).unwrap(), "mine");
        assert_eq!(std::fs::read_to_string(&kept).unwrap(), "{}");
        assert!(crate::io::fit_files(dir.path()).unwrap().is_empty());
    }

    #[test]
    fn species_names_have_no_leading_or_trailing_dots() {
        assert_eq!(species_name(Path::new("/nowhere/red-fox.csv")), "red-fox");
        assert_eq!(species_name(Path::new("/nowhere/..csv")), "profile");
        assert_eq!(species_name(Path::new("/nowhere/.fox.csv")), "fox");
        // A folder's name too: `.fox/` would write a hidden `.fox.json`.
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path().join(".fox");
        std::fs::create_dir(&d).unwrap();
        assert_eq!(species_name(&d), "fox");
    }

    /// The inputs loaded together decide what --theta-i is: beside a lone .npy it is the
    /// .npy's axis and a Yan file in a species folder keeps its own `# theta_i:` line, as
    /// `report` re-reads a fit's data (the fit file does not record this; it is derived).
    #[test]
    fn theta_i_beside_a_lone_npy_is_derived_from_the_inputs() {
        use ndarray_npy::WriteNpyExt;
        let dir = tempfile::tempdir().unwrap();
        let d = dir.path().join("fox");
        std::fs::create_dir(&d).unwrap();
        ndarray::ArrayD::<f64>::from_elem(ndarray::IxDyn(&[2, 1, 1]), 1.0)
            .write_npy(std::fs::File::create(d.join("v.npy")).unwrap())
            .unwrap();
        std::fs::write(d.join("y.txt"), "# theta_i: 45\n0 10 1\n").unwrap();
        let opts = LoadOptions {
            theta_i: Some(vec![0.0, 30.0]),
            theta_r: Some(vec![10.0]),
            phi: Some(vec![0.0]),
            ..Default::default()
        };
        let l = load_inputs_full(std::slice::from_ref(&d), &opts).unwrap();
        let mut ti: Vec<f64> = l.profile.samples.iter().map(|s| s.theta_i).collect();
        ti.sort_by(f64::total_cmp);
        assert_eq!(ti, vec![0.0, 30.0, 45.0]);
        assert!(
            l.notes
                .iter()
                .any(|n| n.contains("(the lone .npy's axis) ignored")),
            "{:?}",
            l.notes
        );
        // The Yan file alone: the option is for it, and it disagrees.
        let e = load_inputs_full(&[d.join("y.txt")], &opts).unwrap_err();
        assert!(e.to_string().contains("--theta-i gave 2 values"), "{e}");
    }
}

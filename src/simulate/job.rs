//! One `furfit simulate` profile run from parsed options: the output checks, the
//! `--rel-noise` pilot run, the simulation, the measurement effects, the metadata and the
//! writing of the profile and `metadata.json`. The command line only parses and prints.

use super::{measure, output, SimResult, SimSettings};
use crate::error::{Error, Num, Result};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Largest paths per incidence angle of `--rel-noise` (its pilot run included) when
/// `--max-paths` is not given.
pub const DEFAULT_MAX_PATHS: u64 = 200_000_000;

/// What one simulation takes: the settings and measurement effects, already parsed and
/// checked ([`check_output`], [`check_effects`], [`SimSettings::validate`]), with the
/// text the metadata records.
#[derive(Clone, Debug)]
pub struct JobOptions {
    /// What to trace; `paths` is `--paths`, replaced by the pilot's choice with `rel_noise`.
    pub settings: SimSettings,
    /// The measurement effects applied to the simulated profile.
    pub effects: measure::Effects,
    /// `--rel-noise`: the median relative standard error to aim the path count at.
    pub rel_noise: Option<f64>,
    /// `--noise-above`: threshold (fraction of the peak) of the bins the median covers.
    pub noise_above: f64,
    /// `--max-paths`: upper bound on the paths of `--rel-noise`
    /// (default [`DEFAULT_MAX_PATHS`]).
    pub max_paths: Option<u64>,
    /// Output directory.
    pub out: PathBuf,
    /// Profile file name inside `out` (its extension picks the format).
    pub file: String,
    /// Replace the files of an earlier furfit simulation.
    pub force: bool,
    /// Species label for the metadata.
    pub species: Option<String>,
    /// The fit channel simulated, if the parameters came from a fit file.
    pub channel: Option<String>,
    /// The angle grids as given (`--theta-i`, `--theta-r`, `--phi`), for the metadata.
    pub grid_text: [String; 3],
    /// The command line the files record.
    pub command: String,
}

/// How far [`run`] is, for a progress display.
#[derive(Clone, Copy, Debug)]
pub enum Progress {
    /// The main run starts: this many paths in all.
    Start(u64),
    /// This many paths traced so far.
    Traced(u64),
    /// The tracing is done (measurement and writing follow).
    Finished,
}

/// What [`run`] did, for the summary the command prints.
#[derive(Clone, Debug)]
pub struct JobReport {
    /// The profile written.
    pub path: PathBuf,
    /// Whether the write created the output folder.
    pub created: bool,
    /// Samples in the profile.
    pub samples: usize,
    /// Valid samples among them.
    pub valid: usize,
    /// Paths traced per incidence angle.
    pub paths: u64,
    /// Paths traced in all.
    pub total_paths: u64,
    /// Wall time of the pilot and main runs (seconds).
    pub seconds: f64,
    /// Worker threads of the run.
    pub threads: usize,
    /// Median relative standard error above `noise_above` x peak (`None`: no light).
    pub rel_noise: Option<f64>,
    /// The simulated profile (incidence angles and their energy tallies).
    pub sim: SimResult,
}

/// The checks of the output before a simulation (a bad name or folder should not cost a
/// run): the file name, whether an existing file may be replaced, and that the folder
/// can take the file.
pub fn check_output(out: &Path, file: &str, force: bool) -> Result<()> {
    output::check_file_name(file)?;
    output::check_replace(out, file, force)?;
    // A folder no file can be created in fails now, not after the simulation (audit).
    crate::io::probe_file_writable(&out.join(file))
}

/// The ranges of the measurement effects and of `noise_above`, checked before a run.
pub fn check_effects(fx: &measure::Effects, noise_above: f64) -> Result<()> {
    let bad = |m: String| Err(Error::Invalid(m));
    for (name, v) in [
        ("--floor", fx.floor),
        ("--drop", fx.drop),
        ("--noise-above", noise_above),
    ] {
        if !(0.0..1.0).contains(&v) {
            return bad(format!("{name} {}: must be in [0, 1)", Num(v)));
        }
    }
    if !(fx.wedge_deg >= 0.0 && fx.wedge_deg < 90.0) {
        return bad(format!(
            "--wedge {}: must be in [0, 90) degrees",
            Num(fx.wedge_deg)
        ));
    }
    if !(fx.mult_noise >= 0.0 && fx.mult_noise.is_finite()) {
        return bad("--mult-noise must be >= 0".into());
    }
    if let Some(p) = fx.shot_photons {
        if !(p > 0.0 && p.is_finite()) {
            return bad("--shot-photons must be > 0".into());
        }
    }
    Ok(())
}

/// Simulate the profile of `o`, apply the measurement effects and write the profile and
/// `metadata.json`. `note` gets the lines for the user (the pilot run's choice, warnings),
/// `progress` how far the tracing is. Uses the current rayon pool.
pub fn run(
    o: &JobOptions,
    mut note: impl FnMut(&str),
    mut progress: impl FnMut(Progress),
) -> Result<JobReport> {
    let t0 = Instant::now();
    let mut s = o.settings.clone();
    let mut pilot_info = serde_json::Value::Null;
    if let Some(x) = o.rel_noise {
        let (paths, info) = pilot_paths(o, x, &mut note)?;
        s.paths = paths;
        pilot_info = info;
    }
    let total = s.paths * s.theta_i.len() as u64;
    progress(Progress::Start(total));
    let sim = super::simulate(&s, |done| progress(Progress::Traced(done)))?;
    progress(Progress::Finished);
    let secs = t0.elapsed().as_secs_f64();
    let m = measure::apply(&sim, &o.effects);
    let rel_after = super::median_rel_noise(&sim, o.noise_above);
    let valid = m.count(None);
    let prof = output::to_profile(&sim, &m, &profile_meta(o, &s));
    let md = metadata(o, &s, &sim, &m, pilot_info, rel_after, secs);
    let created = write(o, &prof, &md)?;
    Ok(JobReport {
        path: o.out.join(&o.file),
        created,
        samples: m.value.len(),
        valid,
        paths: s.paths,
        total_paths: total,
        seconds: secs,
        threads: rayon::current_num_threads(),
        rel_noise: rel_after,
        sim,
    })
}

/// `--rel-noise x`: the paths per incidence angle a pilot run says reach `x` (bounded by
/// `--max-paths`), and the pilot's record for the metadata.
fn pilot_paths(
    o: &JobOptions,
    x: f64,
    note: &mut impl FnMut(&str),
) -> Result<(u64, serde_json::Value)> {
    if !(x > 0.0 && x < 1.0) {
        return Err(Error::Invalid(format!(
            "--rel-noise {}: must be in (0, 1)",
            Num(x)
        )));
    }
    let max_paths = o.max_paths.unwrap_or(DEFAULT_MAX_PATHS);
    if !(2..=super::MAX_PATHS).contains(&max_paths) {
        return Err(Error::Invalid(format!(
            "--max-paths must be in 2..={:e}, found {max_paths}",
            super::MAX_PATHS as f64
        )));
    }
    let s = &o.settings;
    let mut pilot = s.clone();
    pilot.paths = (1 << 19).min(max_paths);
    pilot.seed = s.seed ^ 0xA5A5_5A5A;
    let r = super::simulate(&pilot, |_| {})?;
    let rel = super::median_rel_noise(&r, o.noise_above)
        .ok_or_else(|| Error::Invalid("the pilot run detected no light".into()))?;
    let n = (pilot.paths as f64 * (rel / x).powi(2)).ceil() as u64;
    let paths = n.clamp((1 << 16).min(max_paths), max_paths);
    note(&format!(
        "pilot: {} paths/angle give median rel. error {:.4} above {:.0e} x peak -> {} paths/angle",
        pilot.paths, rel, o.noise_above, paths
    ));
    if n > max_paths {
        // Noise falls as 1/sqrt(paths): what the cap leaves of the target.
        note(&format!(
            "warning: --rel-noise {} needs about {n} paths/angle; --max-paths {max_paths} \
             stops it short, at about {:.2e} (the run says what it reached)",
            Num(x),
            x * (n as f64 / max_paths as f64).sqrt()
        ));
    }
    let info = serde_json::json!({
        "pilot_paths": pilot.paths, "pilot_median_rel_noise": rel,
        "target_rel_noise": x, "noise_above": o.noise_above,
    });
    Ok((paths, info))
}

/// The profile file's metadata lines (`s`: the settings run, with their path count).
fn profile_meta(o: &JobOptions, s: &SimSettings) -> Vec<(String, String)> {
    let mut meta: Vec<(String, String)> = vec![
        ("synthetic".into(), "true".into()),
        (
            "source".into(),
            "furfit simulate (Monte Carlo virtual goniometer, 3-D double cylinder)".into(),
        ),
    ];
    if let Some(sp) = &o.species {
        meta.push(("species".into(), sp.clone()));
    }
    meta.push(("params".into(), s.params.to_json_value().to_string()));
    if let Some(c) = &o.channel {
        meta.push(("channel_of_fit".into(), c.clone()));
    }
    meta.push(("seed".into(), s.seed.to_string()));
    meta.push(("paths_per_theta_i".into(), s.paths.to_string()));
    meta.push((
        "value".into(),
        "exitant energy per unit incident energy per radian theta_r per radian phi (far field)"
            .into(),
    ));
    meta.push(("command".into(), o.command.clone()));
    meta.push(("tool".into(), crate::TOOL_VERSION.to_string()));
    meta
}

/// `metadata.json` of a run (`s`: the settings run, with their path count).
fn metadata(
    o: &JobOptions,
    s: &SimSettings,
    sim: &SimResult,
    m: &measure::Measured,
    pilot_info: serde_json::Value,
    rel_after: Option<f64>,
    secs: f64,
) -> serde_json::Value {
    let params = &s.params;
    let count = |w| m.count(Some(w));
    let [theta_i, theta_r, phi] = &o.grid_text;
    serde_json::json!({
        "synthetic": true,
        "what": "Synthetic goniometric fiber profile from furfit's Monte Carlo virtual goniometer (explicit ray tracing through a 3-D double-cylinder fiber); NOT a measurement.",
        "species": o.species,
        "command": o.command,
        "tool": crate::TOOL_VERSION.to_string(),
        // Which profile this record describes (simulate --force checks it).
        "file": o.file,
        "params": params.to_json_value(),
        "channel_of_fit": o.channel,
        "params_units": "angles in degrees, lengths per unit fiber radius",
        "seed": s.seed,
        "paths_per_theta_i": s.paths,
        "rel_noise_setting": pilot_info,
        "median_rel_noise_above": {"threshold": o.noise_above, "value": rel_after},
        "ellipse_axis_ratio": s.ellipse,
        "medulla_eta": s.medulla_eta.unwrap_or(params.eta),
        "grid": {"theta_i": theta_i, "theta_r": theta_r, "phi": phi,
                 "bins": "centred on grid values, width = grid step (uneven lists: the distance to the nearer neighbour; phi around the circle)"},
        "value_units": "exitant energy / incident energy / (rad theta_r * rad phi); far field over the fiber width; not divided by cos theta_r",
        "effects": o.effects,
        "samples": {"total": m.value.len(), "valid": m.count(None),
            "invalid_no_signal": count(measure::Invalid::NoSignal),
            "invalid_floor": count(measure::Invalid::Floor),
            "invalid_wedge": count(measure::Invalid::Wedge),
            "invalid_dropped": count(measure::Invalid::Dropped)},
        "peak": m.peak,
        "energy_per_theta_i": sim.tally,
        "wall_seconds": secs,
        "threads": rayon::current_num_threads(),
    })
}

/// Write the profile and its metadata to `o.out`, checking again first that they may be
/// replaced; says whether the write created the folder.
fn write(o: &JobOptions, prof: &crate::Profile, md: &serde_json::Value) -> Result<bool> {
    let out = &o.out;
    // Again: a file may have appeared, or the earlier run's been edited, during a run of
    // hours (review, 2026-11-28). Refused, the simulation is kept in a new folder beside.
    if let Err(e) = output::check_replace(out, &o.file, o.force) {
        let keep = crate::io::kept_path(&crate::io::resolve_path(out));
        let kept = match keep {
            Some(k) if output::write_all(&k, &o.file, prof, md).is_ok() => {
                format!("; the simulation is written to {} instead", k.display())
            }
            _ => String::new(),
        };
        return Err(Error::Invalid(format!(
            "{e} (it changed while simulating){kept}"
        )));
    }
    // The folder is made by the write (the probe before the run creates nothing).
    let created = !out.as_os_str().is_empty() && !out.exists();
    output::write_all(out, &o.file, prof, md)?;
    Ok(created)
}

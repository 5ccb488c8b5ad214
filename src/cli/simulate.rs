//! `furfit simulate`: the virtual goniometer (Monte Carlo ray tracing through a 3-D double
//! cylinder fiber) writing a synthetic profile (`.csv` or `.npz`) and `metadata.json`.

use crate::grid::{parse_grid, parse_phi_grid, parse_theta_grid};
use crate::simulate::{self, measure, output, SimSettings};
use crate::FurParams;
use anyhow::{bail, Context};
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Parameters: a preset name (e.g. red-fox), a parameter JSON or a fit JSON.
    #[arg(long, required_unless_present = "bench")]
    pub params: Option<String>,
    /// Incidence angles (degrees), list or start:stop:step.
    #[arg(long, default_value = "0,15,30,45", allow_hyphen_values = true)]
    pub theta_i: String,
    /// Outgoing inclinations (degrees), bin centres (at least two values).
    #[arg(long, default_value = "-80:80:2", allow_hyphen_values = true)]
    pub theta_r: String,
    /// Relative azimuths (degrees), bin centres (at least two values).
    #[arg(long, default_value = "-180:180:2", allow_hyphen_values = true)]
    pub phi: String,
    /// Paths traced per incidence angle.
    #[arg(
        long,
        allow_negative_numbers = true,
        default_value_t = 4_000_000,
        conflicts_with = "rel_noise"
    )]
    pub paths: u64,
    /// Instead of --paths: paths chosen for this median relative error of the bins above --noise-above.
    #[arg(long, allow_negative_numbers = true, value_parser = super::number)]
    pub rel_noise: Option<f64>,
    /// Fraction of the peak above which bins count for --rel-noise and the reported error.
    #[arg(long, default_value_t = 1e-3, allow_negative_numbers = true, value_parser = super::number)]
    pub noise_above: f64,
    /// Upper bound on the paths per incidence angle of --rel-noise, its pilot run
    /// included; default 200000000.
    #[arg(long, allow_negative_numbers = true)]
    pub max_paths: Option<u64>,
    /// Random seed (paths and measurement effects).
    #[arg(long, allow_negative_numbers = true, default_value_t = 1)]
    pub seed: u64,
    /// Worker threads (default or 0: all cores), at most 1024. The output does not depend
    /// on it.
    #[arg(long, allow_negative_numbers = true, value_parser = super::threads_parser())]
    pub threads: Option<usize>,
    /// Detector floor: values below this fraction of the peak are invalid (0 = off).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, value_parser = super::number)]
    pub floor: f64,
    /// Half-angle (degrees) of the cone around the light where samples are occluded (0 = off).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, value_parser = super::number)]
    pub wedge: f64,
    /// Fraction of samples dropped at random (invalid).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, value_parser = super::number)]
    pub drop: f64,
    /// Shot noise: photons counted at the profile peak (off by default).
    #[arg(long, allow_negative_numbers = true, value_parser = super::number)]
    pub shot_photons: Option<f64>,
    /// Multiplicative log-normal noise std (0 = off).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, value_parser = super::number)]
    pub mult_noise: f64,
    /// Elliptical cross-section: axis ratio minor/major in [0.01, 1] (Marschner 2003's a).
    #[arg(long, allow_negative_numbers = true, value_parser = super::number)]
    pub ellipse: Option<f64>,
    /// Medulla IOR (default: equal to eta, index matched).
    #[arg(long, allow_negative_numbers = true, value_parser = super::number)]
    pub medulla_eta: Option<f64>,
    /// Output directory (e.g. measurements/red-fox/).
    #[arg(long, required_unless_present = "bench")]
    pub out: Option<PathBuf>,
    /// Profile file name inside --out; .csv or .npz by extension.
    #[arg(long, default_value = "profile.csv")]
    pub file: String,
    /// Replace an earlier furfit simulation's profile and metadata.json in --out (never other files).
    #[arg(long)]
    pub force: bool,
    /// The channel of a multi-channel fit to simulate (default: its primary channel).
    #[arg(long)]
    pub channel: Option<String>,
    /// Species label for the metadata (default: the preset name, if --params is one).
    #[arg(long)]
    pub species: Option<String>,
    /// Print throughput (paths/s) of three fixed cases instead of simulating (only --threads).
    #[arg(long, conflicts_with_all = [
        "params", "theta_i", "theta_r", "phi", "paths", "rel_noise", "noise_above",
        "max_paths", "seed", "floor", "wedge", "drop", "shot_photons", "mult_noise",
        "ellipse", "medulla_eta", "out", "file", "force", "channel", "species",
    ])]
    pub bench: bool,
}

fn progress_bar(total: u64) -> indicatif::ProgressBar {
    let pb = indicatif::ProgressBar::with_draw_target(
        Some(total),
        indicatif::ProgressDrawTarget::stderr(),
    );
    if let Ok(style) = indicatif::ProgressStyle::with_template(
        "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} paths ({per_sec}, eta {eta})",
    ) {
        pb.set_style(style);
    }
    pb
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let mut pool = rayon::ThreadPoolBuilder::new();
    if let Some(t) = a.threads {
        // 0 = all cores (rayon's default), as for fit and render.
        pool = pool.num_threads(t);
    }
    let pool = pool.build().context("building the thread pool")?;
    pool.install(|| if a.bench { bench() } else { run_profile(a) })
}

fn run_profile(a: Args) -> anyhow::Result<()> {
    let spec = a.params.clone().unwrap_or_default();
    let out = a.out.clone().unwrap_or_default();
    // Before the simulation: a bad name should not cost a run.
    output::check_file_name(&a.file)?;
    output::check_replace(&out, &a.file, a.force)?;
    // A folder no file can be created in fails now, not after the simulation (audit).
    crate::io::probe_file_writable(&out.join(&a.file))?;
    let (params, _exposure, json) = super::load_params(&spec)?;
    let fitted = match &json {
        Some(v) => crate::params::fit_channels(v, &spec)?,
        None => Vec::new(),
    };
    // One channel per simulation (each costs a full run): --channel, else the fit's
    // primary channel (its top level), said on stderr and recorded.
    let (params, channel) = match a.channel.as_deref() {
        Some(c) => {
            let f = crate::params::select_channel(&fitted, c, &spec)?;
            (f.params, Some(f.name.clone()))
        }
        None if fitted.len() > 1 => {
            let primary = json.as_ref().and_then(|v| v["data"]["channel"].as_str());
            let names: Vec<&str> = fitted.iter().map(|c| c.name.as_str()).collect();
            let primary = primary.unwrap_or(names[0]).to_string();
            eprintln!(
                "note: {spec} has channels {}: simulating its primary channel {primary} (--channel NAME for another)",
                names.join(", ")
            );
            (params, Some(primary))
        }
        None => (params, fitted.first().map(|f| f.name.clone())),
    };
    let species = a
        .species
        .clone()
        .or_else(|| crate::params::preset_record(&spec).map(|p| p.name.to_string()));
    for (name, v) in [
        ("--floor", a.floor),
        ("--drop", a.drop),
        ("--noise-above", a.noise_above),
    ] {
        if !(0.0..1.0).contains(&v) {
            bail!("{name} {}: must be in [0, 1)", crate::error::Num(v));
        }
    }
    if !(a.wedge >= 0.0 && a.wedge < 90.0) {
        bail!(
            "--wedge {}: must be in [0, 90) degrees",
            crate::error::Num(a.wedge)
        );
    }
    if !(a.mult_noise >= 0.0 && a.mult_noise.is_finite()) {
        bail!("--mult-noise must be >= 0");
    }
    if let Some(p) = a.shot_photons {
        if !(p > 0.0 && p.is_finite()) {
            bail!("--shot-photons must be > 0");
        }
    }
    let mut s = SimSettings {
        params,
        theta_i: parse_theta_grid("--theta-i", &a.theta_i)?,
        theta_r: parse_grid("--theta-r", &a.theta_r)?,
        phi: parse_phi_grid("--phi", &a.phi)?,
        paths: a.paths,
        seed: a.seed,
        ellipse: a.ellipse,
        medulla_eta: a.medulla_eta,
        smooth: false,
    };
    s.validate()?;
    super::note_radian_grids(&[
        ("--theta-i", &s.theta_i),
        ("--theta-r", &s.theta_r),
        ("--phi", &s.phi),
    ]);
    if a.max_paths.is_some() && a.rel_noise.is_none() {
        eprintln!("warning: --max-paths only bounds --rel-noise: ignored (--paths sets the count)");
    }
    let t0 = Instant::now();
    let mut pilot_info = serde_json::Value::Null;
    if let Some(x) = a.rel_noise {
        if !(x > 0.0 && x < 1.0) {
            bail!("--rel-noise {}: must be in (0, 1)", crate::error::Num(x));
        }
        let max_paths = a.max_paths.unwrap_or(200_000_000);
        if !(2..=crate::simulate::MAX_PATHS).contains(&max_paths) {
            bail!(
                "--max-paths must be in 2..={:e}, found {max_paths}",
                crate::simulate::MAX_PATHS as f64
            );
        }
        let mut pilot = s.clone();
        pilot.paths = (1 << 19).min(max_paths);
        pilot.seed = s.seed ^ 0xA5A5_5A5A;
        let r = simulate::simulate(&pilot, |_| {})?;
        let rel = simulate::median_rel_noise(&r, a.noise_above)
            .context("the pilot run detected no light")?;
        let n = (pilot.paths as f64 * (rel / x).powi(2)).ceil() as u64;
        s.paths = n.clamp((1 << 16).min(max_paths), max_paths);
        eprintln!(
            "pilot: {} paths/angle give median rel. error {:.4} above {:.0e} x peak -> {} paths/angle",
            pilot.paths, rel, a.noise_above, s.paths
        );
        if n > max_paths {
            // Noise falls as 1/sqrt(paths): what the cap leaves of the target.
            eprintln!(
                "warning: --rel-noise {} needs about {n} paths/angle; --max-paths {max_paths} \
                 stops it short, at about {:.2e} (the run says what it reached)",
                crate::error::Num(x),
                x * (n as f64 / max_paths as f64).sqrt()
            );
        }
        pilot_info = serde_json::json!({
            "pilot_paths": pilot.paths, "pilot_median_rel_noise": rel,
            "target_rel_noise": x, "noise_above": a.noise_above,
        });
    }
    let total = s.paths * s.theta_i.len() as u64;
    let pb = progress_bar(total);
    // Without a terminal (a batch job, a log file) the bar is hidden: a plain line every
    // tenth of the run says how far it is instead (audit, 2026-11-28).
    let plain = !std::io::IsTerminal::is_terminal(&std::io::stderr());
    let started = Instant::now();
    let mut next_tenth = 1u64;
    let sim = simulate::simulate(&s, |done| {
        pb.set_position(done);
        if plain && total > 0 && done * 10 >= next_tenth * total && next_tenth < 10 {
            let secs = started.elapsed().as_secs_f64();
            let eta = secs * (total - done) as f64 / done.max(1) as f64;
            eprintln!(
                "simulate: {} % ({done} of {total} paths) in {secs:.0} s, about {eta:.0} s to go",
                done * 100 / total
            );
            next_tenth = done * 10 / total + 1;
        }
    })?;
    pb.finish_and_clear();
    let secs = t0.elapsed().as_secs_f64();
    let fx = measure::Effects {
        floor: a.floor,
        wedge_deg: a.wedge,
        drop: a.drop,
        shot_photons: a.shot_photons,
        mult_noise: a.mult_noise,
        seed: a.seed,
    };
    let m = measure::apply(&sim, &fx);
    let command = super::command_line();
    let rel_after = simulate::median_rel_noise(&sim, a.noise_above);
    let valid = m.count(None);
    let mut meta: Vec<(String, String)> = vec![
        ("synthetic".into(), "true".into()),
        (
            "source".into(),
            "furfit simulate (Monte Carlo virtual goniometer, 3-D double cylinder)".into(),
        ),
    ];
    if let Some(sp) = &species {
        meta.push(("species".into(), sp.clone()));
    }
    meta.push(("params".into(), params.to_json_value().to_string()));
    if let Some(c) = &channel {
        meta.push(("channel_of_fit".into(), c.clone()));
    }
    meta.push(("seed".into(), a.seed.to_string()));
    meta.push(("paths_per_theta_i".into(), s.paths.to_string()));
    meta.push((
        "value".into(),
        "exitant energy per unit incident energy per radian theta_r per radian phi (far field)"
            .into(),
    ));
    meta.push(("command".into(), command.clone()));
    meta.push(("tool".into(), crate::TOOL_VERSION.to_string()));
    let prof = output::to_profile(&sim, &m, &meta);
    let count = |w| m.count(Some(w));
    let md = serde_json::json!({
        "synthetic": true,
        "what": "Synthetic goniometric fiber profile from furfit's Monte Carlo virtual goniometer (explicit ray tracing through a 3-D double-cylinder fiber); NOT a measurement.",
        "species": species,
        "command": command,
        "tool": crate::TOOL_VERSION.to_string(),
        // Which profile this record describes (simulate --force checks it).
        "file": a.file,
        "params": params.to_json_value(),
        "channel_of_fit": channel,
        "params_units": "angles in degrees, lengths per unit fiber radius",
        "seed": a.seed,
        "paths_per_theta_i": s.paths,
        "rel_noise_setting": pilot_info,
        "median_rel_noise_above": {"threshold": a.noise_above, "value": rel_after},
        "ellipse_axis_ratio": a.ellipse,
        "medulla_eta": a.medulla_eta.unwrap_or(params.eta),
        "grid": {"theta_i": a.theta_i, "theta_r": a.theta_r, "phi": a.phi,
                 "bins": "centred on grid values, width = grid step (uneven lists: the distance to the nearer neighbour; phi around the circle)"},
        "value_units": "exitant energy / incident energy / (rad theta_r * rad phi); far field over the fiber width; not divided by cos theta_r",
        "effects": fx,
        "samples": {"total": m.value.len(), "valid": valid,
            "invalid_no_signal": count(measure::Invalid::NoSignal),
            "invalid_floor": count(measure::Invalid::Floor),
            "invalid_wedge": count(measure::Invalid::Wedge),
            "invalid_dropped": count(measure::Invalid::Dropped)},
        "peak": m.peak,
        "energy_per_theta_i": sim.tally,
        "wall_seconds": secs,
        "threads": rayon::current_num_threads(),
    });
    // Again: a file may have appeared, or the earlier run's been edited, during a run of
    // hours (review, 2026-11-28). Refused, the simulation is kept in a new folder beside.
    if let Err(e) = output::check_replace(&out, &a.file, a.force) {
        let keep = crate::io::kept_path(&crate::io::resolve_path(&out));
        let kept = match keep {
            Some(k) if output::write_all(&k, &a.file, &prof, &md).is_ok() => {
                format!("; the simulation is written to {} instead", k.display())
            }
            _ => String::new(),
        };
        anyhow::bail!("{e} (it changed while simulating){kept}");
    }
    // The folder is made by the write (the probe before the run creates nothing).
    let created = !out.as_os_str().is_empty() && !out.exists();
    output::write_all(&out, &a.file, &prof, &md)?;
    if created {
        super::note_created_folder(&out);
    }
    if valid == 0 {
        // Written (the metadata says why each sample is invalid), but no fit can use it.
        eprintln!(
            "warning: no sample of {} is valid (see metadata.json's samples: floor, wedge, \
             drop, noise); nothing in it can be fitted",
            out.join(&a.file).display()
        );
    }
    outln!(
        "{}: {} samples ({} valid), {} paths/angle x {} angles in {:.1} s on {} threads ({:.2e} paths/s); median rel. error above {:.0e} x peak: {}",
        out.join(&a.file).display(),
        m.value.len(),
        valid,
        s.paths,
        s.theta_i.len(),
        secs,
        rayon::current_num_threads(),
        total as f64 / secs,
        a.noise_above,
        rel_after.map_or("n/a".into(), |r| format!("{r:.4}")),
    );
    for (ti, t) in s.theta_i.iter().zip(&sim.tally) {
        outln!(
            "  theta_i {ti:>5}: exited {:.4}, binned {:.4}, guided {:.2e}, {:.1} s",
            t.exited,
            t.binned,
            t.guided,
            t.seconds
        );
    }
    Ok(())
}

fn bench() -> anyhow::Result<()> {
    let threads = rayon::current_num_threads();
    let mut human0 = FurParams::preset("human").context("preset")?;
    human0.kappa = 0.0;
    let mut fox_hi = FurParams::preset("red-fox").context("preset")?;
    fox_hi.sigma_m_s = 20.0; // tau = sigma_m_s * kappa = 17.2
    let cases = [
        ("kappa = 0 (human, kappa set to 0)", human0, 8_000_000u64),
        (
            "red-fox preset (tau = 2.7)",
            FurParams::preset("red-fox").context("preset")?,
            2_000_000,
        ),
        (
            "high-tau medulla (red-fox, sigma_m_s = 20, tau = 17)",
            fox_hi,
            500_000,
        ),
    ];
    for (name, p, n) in cases {
        let s = SimSettings {
            params: p,
            theta_i: vec![30.0],
            theta_r: parse_grid("--theta-r", "-80:80:2")?,
            phi: parse_phi_grid("--phi", "-180:180:2")?,
            paths: n,
            seed: 7,
            ellipse: None,
            medulla_eta: None,
            smooth: false,
        };
        let t0 = Instant::now();
        let c0 = crate::timing::cpu_seconds();
        let r = simulate::simulate(&s, |_| {})?;
        let dt = t0.elapsed().as_secs_f64();
        let cpu = match (c0, crate::timing::cpu_seconds()) {
            (Some(a), Some(b)) if b > a => format!(
                "; CPU {:.2} s = {:.3e} paths per CPU-second",
                b - a,
                n as f64 / (b - a)
            ),
            _ => String::new(),
        };
        outln!(
            "bench {name}: {n} paths in {dt:.2} s on {threads} threads = {:.3e} paths/s (exited {:.3}, scatter events/path {:.2}){cpu}",
            n as f64 / dt,
            r.tally[0].exited,
            r.tally[0].scatter_events as f64 / n as f64
        );
    }
    Ok(())
}

//! `furfit render`: preview fur on the built-in test lock (see `crate::render`).

use crate::model::LobeSet;
use crate::params::FurParams;
use crate::render::bsdf::{MedullaEnergy, Mode, Tint};
use crate::render::math::V3;
use crate::render::scene::{DirectionalLight, Environment, MAX_FIBERS};
use crate::render::{batch, output, RenderSettings};
use crate::render::{MAX_DEPTH, MAX_PIXELS, MAX_RADIANCE, MAX_SIDE, MAX_SPP};
use anyhow::{bail, Context};
use clap::builder::RangedU64ValueParser;
use std::path::{Path, PathBuf};

#[derive(clap::Args, Debug)]
/// Arguments of `furfit render` (its `--help` text is the [`super::Command`] variant's).
pub struct Args {
    /// Fit file (fits/X.json) to render.
    #[arg(long, conflicts_with = "params")]
    pub fit: Option<String>,
    /// Parameter file or preset name (e.g. red-fox, human).
    #[arg(long)]
    pub params: Option<String>,
    /// Render every fits/*.json and write a labelled contact sheet to --out.
    #[arg(long, conflicts_with_all = ["fit", "params"])]
    pub all: bool,
    /// Directory searched by --all [default: fits]; only with --all.
    #[arg(long)]
    pub fits_dir: Option<PathBuf>,
    /// BCSDF scale: near, far or multiscale.
    #[arg(long, default_value = "multiscale")]
    pub mode: String,
    /// Samples per pixel, 1..=1048576.
    #[arg(long, allow_negative_numbers = true, default_value_t = 64, value_parser = RangedU64ValueParser::<usize>::new().range(1..=MAX_SPP as u64))]
    pub spp: usize,
    /// Image size WxH (or WXH), each side 1..=8192 and at most 4096 x 4096 pixels in all.
    #[arg(long, default_value = "512x512")]
    pub size: String,
    /// Lobes to render: a list of R, TT, TRT, TTs, TRTs (each at most once), or all.
    #[arg(long, default_value = "all")]
    pub lobes: String,
    /// Seed of the path tracer's random numbers (same seed, same image).
    #[arg(long, allow_negative_numbers = true, default_value_t = 1)]
    pub seed: u64,
    /// Replace existing output files that furfit did not write (or that changed since).
    #[arg(long)]
    pub force: bool,
    /// Worker threads (0 = all cores), at most 1024.
    #[arg(long, allow_negative_numbers = true, default_value_t = 0, value_parser = super::threads_parser())]
    pub threads: usize,
    /// Camera distance from the lock's centre, in world units (the lock is about 1.1
    /// units long): finite and > 0.
    #[arg(long, default_value_t = 3.0, allow_negative_numbers = true, value_parser = super::number)]
    pub cam_dist: f64,
    /// Camera elevation in degrees above the horizontal, -90..=90 (90 = straight down from
    /// above).
    #[arg(long, default_value_t = 10.0, allow_negative_numbers = true, value_parser = super::number)]
    pub cam_elev: f64,
    /// Camera azimuth in degrees about the vertical (any finite value).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, value_parser = super::number)]
    pub cam_azim: f64,
    /// Vertical field of view in degrees, in (0, 170).
    #[arg(long, default_value_t = 26.0, allow_negative_numbers = true, value_parser = super::number)]
    pub fov: f64,
    /// Direction toward the key light, x,y,z: any finite, non-zero vector (only its
    /// direction is used).
    #[arg(long, default_value = "-0.5,0.6,0.62", allow_hyphen_values = true)]
    pub light_dir: String,
    /// Key light irradiance, 0..=1e6 (0 = no key light).
    #[arg(long, default_value_t = 2.5, allow_negative_numbers = true, value_parser = super::number)]
    pub light_intensity: f64,
    /// Environment radiance: one value (constant) or TOP,BOTTOM (vertical grey gradient),
    /// each in 0..=1e6.
    #[arg(long, default_value = "0.34,0.10", allow_hyphen_values = true)]
    pub env: String,
    /// Absorption ratios r,g,b, `melanin` or `grey` (default: a fit's own r, g, b channels, else melanin).
    #[arg(long, allow_hyphen_values = true)]
    pub tint: Option<String>,
    /// Exposure in stops (EV) before the tone map, -64..=64 (PNGs only; not a fit's exposure k).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true, value_parser = super::number)]
    pub exposure: f64,
    /// Fibers in the test lock, 1..=100000 (about 45 KB of memory each).
    #[arg(long, allow_negative_numbers = true, default_value_t = 1500, value_parser = RangedU64ValueParser::<usize>::new().range(1..=MAX_FIBERS as u64))]
    pub fibers: usize,
    /// Longest path in fiber vertices, 1..=1024.
    #[arg(long, allow_negative_numbers = true, default_value_t = 16, value_parser = RangedU64ValueParser::<usize>::new().range(1..=MAX_DEPTH as u64))]
    pub max_depth: usize,
    /// Multiplier of the pixel coverage in multiscale mode, >= 0 (0 = near field); default 1.
    #[arg(long, allow_negative_numbers = true, value_parser = super::number)]
    pub footprint_scale: Option<f64>,
    /// Evaluate the far field exactly at every query instead of the per-render table (slow).
    #[arg(long)]
    pub exact_far: bool,
    /// Also sample the environment at every vertex (NEE + MIS); off: it costs more than it gains here.
    #[arg(long)]
    pub env_nee: bool,
    /// Scattered lobes' energy: strand (physical albedo), fit (as fitted) or conserve (capped at 1).
    #[arg(long, default_value = "strand")]
    pub medulla_energy: String,
    /// Weights of `--medulla-energy strand` (default: built into the binary; rebuilt by
    /// `furfit tables strand`).
    #[arg(long)]
    pub energy_weights: Option<PathBuf>,
    /// BCSDF sampling: lobes (the lobes' Gaussians), ishair (Cauchy proposals) or uniform (baseline).
    #[arg(long, default_value = "lobes")]
    pub sampling: String,
    /// Pixel position and first vertices' BCSDF uniforms: stratified (jittered strata),
    /// sobol (scrambled Sobol streams) or independent (the pixel's RNG alone).
    #[arg(long, default_value = "stratified")]
    pub pixel_sampling: String,
    /// Skip the per-lobe AOV images.
    #[arg(long)]
    pub no_aovs: bool,
    /// Output PNG (a linear .exr is written beside it).
    #[arg(long)]
    pub out: PathBuf,
}

fn parse_list(what: &str, s: &str) -> anyhow::Result<Vec<f64>> {
    s.split(',')
        .map(|p| match super::number(p) {
            Ok(v) if v.is_finite() => Ok(v),
            Ok(_) => bail!("--{what}: '{}' is not finite", p.trim()),
            Err(m) => bail!("--{what}: {m}"),
        })
        .collect()
}

/// The render settings of `a`, every option checked (integer ranges are checked by clap).
pub fn settings_from(a: &Args) -> anyhow::Result<RenderSettings> {
    let (width, height) = super::parse_size("--size", &a.size, MAX_SIDE, MAX_PIXELS)?;
    // Checked here, not by clap's `requires`: a default-false flag satisfies that.
    if a.fits_dir.is_some() && !a.all {
        bail!("--fits-dir is only read with --all (give --all, or drop --fits-dir)");
    }
    let light_dir = light_direction(&parse_list("light-dir", &a.light_dir)?)?;
    let env = parse_list("env", &a.env)?;
    let radiance = |v: &f64| (0.0..=MAX_RADIANCE).contains(v);
    let env = match env.as_slice() {
        [v] if radiance(v) => Environment::constant(*v),
        [t, b] if radiance(t) && radiance(b) => Environment {
            top: [*t; 3],
            bottom: [*b; 3],
        },
        _ => bail!(
            "--env '{}': expected one or two radiances in 0..={MAX_RADIANCE:e}",
            a.env
        ),
    };
    let tint = match a.tint.as_deref().unwrap_or("melanin") {
        "melanin" => Tint::default(),
        "grey" | "gray" => Tint::GREY,
        s => {
            let v = parse_list("tint", s)?;
            if v.len() != 3 || v.iter().any(|x| *x < 0.0) {
                bail!("--tint: expected melanin, grey or three non-negative ratios r,g,b");
            }
            Tint::Ratios([v[0], v[1], v[2]])
        }
    };
    // One message per flag, naming the value given (NaN fails every test).
    if !radiance(&a.light_intensity) {
        bail!(
            "--light-intensity must be in 0..={MAX_RADIANCE:e}, got {}",
            crate::error::Num(a.light_intensity)
        );
    }
    let ev = output::MAX_EXPOSURE_EV;
    if !(-ev..=ev).contains(&a.exposure) {
        bail!(
            "--exposure must be in -{ev}..={ev} stops, got {}",
            crate::error::Num(a.exposure)
        );
    }
    if !(a.cam_dist > 0.0 && a.cam_dist.is_finite()) {
        bail!(
            "--cam-dist must be a finite number > 0, got {}",
            crate::error::Num(a.cam_dist)
        );
    }
    if !(a.fov > 0.0 && a.fov < 170.0) {
        bail!(
            "--fov must be in (0, 170) degrees, got {}",
            crate::error::Num(a.fov)
        );
    }
    // Past 90 degrees the camera would go over the pole and see the lock upside down.
    if !(-90.0..=90.0).contains(&a.cam_elev) {
        bail!(
            "--cam-elev must be in -90..=90 degrees, got {}",
            crate::error::Num(a.cam_elev)
        );
    }
    if !a.cam_azim.is_finite() {
        bail!(
            "--cam-azim must be finite, got {}",
            crate::error::Num(a.cam_azim)
        );
    }
    let png = a
        .out
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("png"));
    if !png {
        // The linear .exr and the AOVs are named after it; any other name would put PNG
        // bytes under a wrong extension or overwrite an unrelated file.
        bail!(
            "--out {}: must be a .png path (the .exr and per-lobe AOVs are written beside it)",
            a.out.display()
        );
    }
    let footprint_scale = a.footprint_scale.unwrap_or(1.0);
    if !(footprint_scale >= 0.0 && footprint_scale.is_finite()) {
        bail!(
            "--footprint-scale must be a finite number >= 0, got {}",
            crate::error::Num(footprint_scale)
        );
    }
    let mut s = RenderSettings {
        width,
        height,
        spp: a.spp,
        seed: a.seed,
        threads: a.threads,
        mode: Mode::parse(&a.mode).context("--mode")?,
        lobes: LobeSet::parse(&a.lobes).context("--lobes")?,
        max_depth: a.max_depth,
        footprint_scale,
        env,
        tint,
        far_table: !a.exact_far,
        env_nee: a.env_nee,
        medulla_energy: MedullaEnergy::parse(&a.medulla_energy).context("--medulla-energy")?,
        energy_weights: a.energy_weights.clone(),
        sampling: crate::render::ishair::Sampling::parse(&a.sampling).context("--sampling")?,
        pixel_sampling: crate::render::qmc::PixelSampling::parse(&a.pixel_sampling)
            .context("--pixel-sampling")?,
        ..RenderSettings::default()
    };
    s.camera.dist = a.cam_dist;
    s.camera.elev_deg = a.cam_elev;
    s.camera.azim_deg = a.cam_azim;
    s.camera.fov_deg = a.fov;
    s.light = (a.light_intensity > 0.0).then_some(DirectionalLight {
        dir: light_dir,
        irradiance: [a.light_intensity; 3],
    });
    s.strand.fibers = a.fibers;
    Ok(s)
}

/// The unit vector along `--light-dir` `v` (finite, as parsed). Scaled by its largest
/// component first: squaring 1e200 overflows and squaring 1e-320 underflows, and either
/// used to give another direction without a word.
fn light_direction(v: &[f64]) -> anyhow::Result<V3> {
    let m = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    if v.len() != 3 || !v.iter().all(|x| x.is_finite()) || m == 0.0 {
        bail!("--light-dir: expected a finite, non-zero x,y,z");
    }
    Ok(V3::new(v[0] / m, v[1] / m, v[2] / m).normalized())
}

/// One-line warnings for options `a` gives that the render `s` does not read.
fn ignored(a: &Args, s: &RenderSettings) -> Vec<String> {
    let mut w = Vec::new();
    if a.footprint_scale.is_some() && s.mode != Mode::Multiscale {
        w.push(format!(
            "--footprint-scale only acts in --mode multiscale: ignored with --mode {}",
            s.mode.name()
        ));
    }
    // As render_scene decides whether to build the table --exact-far replaces.
    let far = s.mode == Mode::Far || (s.mode == Mode::Multiscale && s.footprint_scale > 0.0);
    if a.exact_far && !far {
        w.push(format!(
            "--exact-far: --mode {}{} never evaluates the far field: ignored",
            s.mode.name(),
            if s.mode == Mode::Multiscale {
                " with --footprint-scale 0"
            } else {
                ""
            }
        ));
    }
    w
}

/// Run `furfit render`: parse the options and the parameters, then render and write
/// ([`batch::run`]).
pub fn run(a: Args) -> anyhow::Result<()> {
    let s = settings_from(&a)?;
    for w in ignored(&a, &s) {
        eprintln!("warning: {w}");
    }
    let jobs = load_jobs(&a)?;
    let opts = batch::BatchOptions {
        settings: s,
        out: a.out.clone(),
        sheet: a.all,
        aovs: !a.no_aovs,
        force: a.force,
        exposure: a.exposure,
        tint: a.tint.clone(),
        from_fits: a.fit.is_some() || a.all,
        command: super::command_line(),
    };
    let plan = batch::plan(&opts, &jobs)?;
    for d in &plan.dirs {
        super::prepare_out_dir(d)?;
    }
    batch::run(&opts, &jobs, &plan, |l| outln!("{l}"), |n| eprintln!("{n}"))?;
    Ok(())
}

/// The images of `--all`, `--fit` or `--params`: name, parameters, the fit file's r, g,
/// b colour when it has them, and where the parameters come from.
fn load_jobs(a: &Args) -> anyhow::Result<Vec<batch::RenderJob>> {
    let job = |name: String, (params, colour, about)| batch::RenderJob {
        name,
        params,
        colour,
        about,
    };
    if a.all {
        let dir = a.fits_dir.clone().unwrap_or_else(|| "fits".into());
        let files = crate::io::fit_files(&dir)?;
        if files.is_empty() {
            bail!("{}: no *.json fit files", dir.display());
        }
        return files
            .iter()
            .map(|f| {
                let spec = f.to_string_lossy();
                let name = f.file_stem().unwrap().to_string_lossy().into_owned();
                Ok(job(name, load_with_colour(&spec)?))
            })
            .collect();
    }
    if let Some(f) = &a.fit {
        if Path::new(f).is_dir() {
            bail!("--fit {f}: is a directory, not a fit file (--all --fits-dir DIR renders every fit in one)");
        }
        if !Path::new(f).is_file() {
            bail!("--fit {f}: no such fit file (a preset name goes with --params)");
        }
    }
    let spec = a
        .fit
        .clone()
        .or(a.params.clone())
        .context("give --fit FILE, --params FILE|PRESET or --all")?;
    let loaded = load_with_colour(&spec)?;
    let name = Path::new(&spec)
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or(spec.clone());
    Ok(vec![job(name, loaded)])
}

/// The parameters of a preset, parameter file or fit file, the colour of a fit file
/// with r, g, b channels ([`Tint::from_fit_channels`]; whether given as --fit or --params,
/// which takes fit files too), and where they come from (for the images' text: a fit says
/// whether its data were synthetic), from one read of the file. The fit's exposure k is a
/// measurement scale, not a light level: not used here.
fn load_with_colour(spec: &str) -> anyhow::Result<(batch::JobParams, Option<Tint>, String)> {
    // The file names its model (absent: yan2017); another model's fit is rendered through
    // the model interface.
    if let Ok((mp, _, Some(v))) = crate::models::ModelParams::load(spec, None) {
        if mp.fur().is_none() {
            return load_model_job(spec, mp, &v);
        }
    }
    let (p, colour, about) = load_fur_with_colour(spec)?;
    Ok((batch::JobParams::Fur(p), colour, about))
}

/// The job of a fit or parameter file `spec` of a model other than the fur model: its r,
/// g, b channels when it has them, else its parameters on all three (grey).
fn load_model_job(
    spec: &str,
    mp: crate::models::ModelParams,
    v: &serde_json::Value,
) -> anyhow::Result<(batch::JobParams, Option<Tint>, String)> {
    let channels = crate::models::fit_channels(v, spec).with_context(|| format!("--fit {spec}"))?;
    let pick = |names: [&str; 2]| {
        channels
            .iter()
            .find(|c| names.iter().any(|n| c.name.eq_ignore_ascii_case(n)))
            .map(|c| c.params.clone())
    };
    let rgb = match (
        pick(["r", "red"]),
        pick(["g", "green"]),
        pick(["b", "blue"]),
    ) {
        (Some(r), Some(g), Some(b)) => [r, g, b],
        _ => [mp.clone(), mp.clone(), mp],
    };
    let names: Vec<&str> = channels.iter().map(|c| c.name.as_str()).collect();
    let chans = if names.is_empty() {
        String::new()
    } else {
        format!(", channels {}", names.join(", "))
    };
    let model = rgb[0].model.name();
    let about = match v["species"].as_str() {
        Some(sp) if v.get("solver").is_some() => {
            format!("{model} fit file {spec} (species {sp}{chans})")
        }
        _ if v.get("solver").is_some() => format!("{model} fit file {spec}{chans}"),
        _ => format!("{model} parameter file {spec}"),
    };
    Ok((batch::JobParams::Model(Box::new(rgb)), None, about))
}

/// [`load_with_colour`] of the fur model's parameters.
fn load_fur_with_colour(spec: &str) -> anyhow::Result<(FurParams, Option<Tint>, String)> {
    let (p, _, json) = super::load_params(spec)?;
    let Some(v) = json else {
        return Ok((p, None, format!("preset {spec} (seed Table 4)")));
    };
    // Read once: the colour and the channel names both come from the channels.
    let fitted = crate::params::fit_channels(&v, spec).with_context(|| format!("--fit {spec}"))?;
    let colour = Tint::from_fit_channels(&fitted);
    let names: Vec<&str> = fitted.iter().map(|c| c.name.as_str()).collect();
    let channels = if names.is_empty() {
        String::new()
    } else {
        format!(", channels {}", names.join(", "))
    };
    let about = if v.get("solver").is_some() {
        let data = match v["data"]["synthetic"].as_bool() {
            Some(true) => "SYNTHETIC data",
            Some(false) => "data not marked synthetic",
            None => "data of unrecorded kind",
        };
        match v["species"].as_str() {
            Some(sp) => format!("fit file {spec} (species {sp}, fitted to {data}{channels})"),
            None => format!("fit file {spec} (fitted to {data}{channels})"),
        }
    } else if names.is_empty() {
        format!("parameter file {spec}")
    } else {
        format!("parameter file {spec} ({})", &channels[2..])
    };
    Ok((p, colour, about))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Components whose squares overflow (1e200) or underflow (1e-320) keep their
    /// direction (they used to give another one); zero is refused naming the option.
    #[test]
    fn light_direction_survives_extreme_components() {
        let close = |v: V3, w: [f64; 3]| {
            (v.x - w[0]).abs() < 1e-15 && (v.y - w[1]).abs() < 1e-15 && (v.z - w[2]).abs() < 1e-15
        };
        let h = std::f64::consts::FRAC_1_SQRT_2;
        for (v, want) in [
            ([1e200, 1e200, 0.0], [h, h, 0.0]),
            ([1e-320, 0.0, 0.0], [1.0, 0.0, 0.0]),
            ([0.0, -f64::MAX, 0.0], [0.0, -1.0, 0.0]),
            ([3.0, 0.0, 4.0], [0.6, 0.0, 0.8]),
        ] {
            let d = light_direction(&v).unwrap();
            assert!(close(d, want), "{v:?}: {d:?}");
        }
        for v in [&[0.0, 0.0, -0.0][..], &[1.0, 0.0], &[f64::NAN, 1.0, 0.0]] {
            let e = light_direction(v).unwrap_err().to_string();
            assert!(e.contains("--light-dir"), "{e}");
        }
    }
}

//! `furfit simulate`: the virtual goniometer (Monte Carlo ray tracing through a 3-D double
//! cylinder fiber) writing a synthetic profile (`.csv` or `.npz`) and `metadata.json`.

use crate::grid::{parse_grid, parse_phi_grid, parse_theta_grid};
use crate::simulate::{self, job, measure, SimSettings};
use crate::FurParams;
use anyhow::Context;
use std::path::PathBuf;
use std::time::Instant;

#[derive(clap::Args, Debug)]
/// Arguments of `furfit simulate` (its `--help` text is the [`super::Command`] variant's).
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

/// Run `furfit simulate`: a profile ([`job::run`]) or, with `--bench`, the throughput
/// figures, on a pool of `--threads`.
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
    job::check_output(&out, &a.file, a.force)?;
    let (params, _exposure, json) = super::load_params(&spec)?;
    let (params, channel) = pick_channel(&spec, params, json.as_ref(), a.channel.as_deref())?;
    let species = a
        .species
        .clone()
        .or_else(|| crate::params::preset_record(&spec).map(|p| p.name.to_string()));
    let effects = measure::Effects {
        floor: a.floor,
        wedge_deg: a.wedge,
        drop: a.drop,
        shot_photons: a.shot_photons,
        mult_noise: a.mult_noise,
        seed: a.seed,
    };
    job::check_effects(&effects, a.noise_above)?;
    let settings = SimSettings {
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
    settings.validate()?;
    super::note_radian_grids(&[
        ("--theta-i", &settings.theta_i),
        ("--theta-r", &settings.theta_r),
        ("--phi", &settings.phi),
    ]);
    if a.max_paths.is_some() && a.rel_noise.is_none() {
        eprintln!("warning: --max-paths only bounds --rel-noise: ignored (--paths sets the count)");
    }
    let opts = job::JobOptions {
        settings,
        effects,
        rel_noise: a.rel_noise,
        noise_above: a.noise_above,
        max_paths: a.max_paths,
        out: out.clone(),
        file: a.file.clone(),
        force: a.force,
        species,
        channel,
        grid_text: [a.theta_i.clone(), a.theta_r.clone(), a.phi.clone()],
        command: super::command_line(),
    };
    let mut shown = Shown::default();
    let r = job::run(&opts, |n| eprintln!("{n}"), |p| shown.update(p))?;
    if r.created {
        super::note_created_folder(&out);
    }
    if r.valid == 0 {
        // Written (the metadata says why each sample is invalid), but no fit can use it.
        eprintln!(
            "warning: no sample of {} is valid (see metadata.json's samples: floor, wedge, \
             drop, noise); nothing in it can be fitted",
            r.path.display()
        );
    }
    outln!(
        "{}: {} samples ({} valid), {} paths/angle x {} angles in {:.1} s on {} threads ({:.2e} paths/s); median rel. error above {:.0e} x peak: {}",
        r.path.display(),
        r.samples,
        r.valid,
        r.paths,
        r.sim.theta_i.len(),
        r.seconds,
        r.threads,
        r.total_paths as f64 / r.seconds,
        a.noise_above,
        r.rel_noise.map_or("n/a".into(), |r| format!("{r:.4}")),
    );
    for (ti, t) in r.sim.theta_i.iter().zip(&r.sim.tally) {
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

/// One channel per simulation (each costs a full run): `--channel`, else the fit's
/// primary channel (its top level), said on stderr and recorded.
fn pick_channel(
    spec: &str,
    params: FurParams,
    json: Option<&serde_json::Value>,
    channel: Option<&str>,
) -> anyhow::Result<(FurParams, Option<String>)> {
    let fitted = match json {
        Some(v) => crate::params::fit_channels(v, spec)?,
        None => Vec::new(),
    };
    Ok(match channel {
        Some(c) => {
            let f = crate::params::select_channel(&fitted, c, spec)?;
            (f.params, Some(f.name.clone()))
        }
        None if fitted.len() > 1 => {
            let primary = json.and_then(|v| v["data"]["channel"].as_str());
            let names: Vec<&str> = fitted.iter().map(|c| c.name.as_str()).collect();
            let primary = primary.unwrap_or(names[0]).to_string();
            eprintln!(
                "note: {spec} has channels {}: simulating its primary channel {primary} (--channel NAME for another)",
                names.join(", ")
            );
            (params, Some(primary))
        }
        None => (params, fitted.first().map(|f| f.name.clone())),
    })
}

/// The progress display of a run: a bar on a terminal; without one (a batch job, a log
/// file) the bar is hidden and a plain line every tenth of the run says how far it is
/// instead (audit, 2026-11-28).
#[derive(Default)]
struct Shown {
    bar: Option<indicatif::ProgressBar>,
    plain: bool,
    started: Option<Instant>,
    total: u64,
    next_tenth: u64,
}

impl Shown {
    fn update(&mut self, p: job::Progress) {
        match p {
            job::Progress::Start(total) => {
                self.bar = Some(progress_bar(total));
                self.plain = !std::io::IsTerminal::is_terminal(&std::io::stderr());
                self.started = Some(Instant::now());
                self.total = total;
                self.next_tenth = 1;
            }
            job::Progress::Traced(done) => {
                if let Some(pb) = &self.bar {
                    pb.set_position(done);
                }
                let total = self.total;
                if self.plain
                    && total > 0
                    && done * 10 >= self.next_tenth * total
                    && self.next_tenth < 10
                {
                    let secs = self.started.map_or(0.0, |t| t.elapsed().as_secs_f64());
                    let eta = secs * (total - done) as f64 / done.max(1) as f64;
                    eprintln!(
                        "simulate: {} % ({done} of {total} paths) in {secs:.0} s, about {eta:.0} s to go",
                        done * 100 / total
                    );
                    self.next_tenth = done * 10 / total + 1;
                }
            }
            job::Progress::Finished => {
                if let Some(pb) = &self.bar {
                    pb.finish_and_clear();
                }
            }
        }
    }
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

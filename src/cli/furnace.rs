//! `furfit furnace`: the white furnace of the renderer's BCSDF ([`crate::render::furnace`]).

use crate::render::bsdf::MedullaEnergy;
use crate::render::furnace::{
    default_thetas_deg, extremes, furnace, furnace_bsdf, report_csv, report_curves,
    report_markdown, report_png, DEFAULT_SAMPLES,
};
use anyhow::{bail, Context};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
/// Arguments of `furfit furnace` (its `--help` text is the [`super::Command`] variant's).
pub struct Args {
    /// Parameter file, fit file or preset; its directional albedo is printed.
    #[arg(long, required_unless_present = "report")]
    pub params: Option<String>,
    /// How the scattered lobes' energy is read: strand (default), fit or conserve.
    #[arg(long, default_value = "strand")]
    pub medulla_energy: String,
    /// Fiber model: the renderer's BCSDF is yan2017's (the only one it renders).
    #[arg(long, default_value = "yan2017")]
    pub model: String,
    /// Monte Carlo samples per inclination (>= 2).
    #[arg(long, allow_negative_numbers = true, default_value_t = DEFAULT_SAMPLES)]
    pub samples: usize,
    /// Seed of the Monte Carlo (same seed, same figures).
    #[arg(long, allow_negative_numbers = true, default_value_t = 1)]
    pub seed: u64,
    /// Strand weights file (default: the weights built into the binary).
    #[arg(long)]
    pub energy_weights: Option<PathBuf>,
    /// Also write DIR/furnace.{md,csv,png}: every fit of --fits-dir, lossless too, in all energy modes.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// Fits of --report.
    #[arg(long, default_value = "fits")]
    pub fits_dir: PathBuf,
}

/// Run `furfit furnace`.
pub fn run(a: Args) -> anyhow::Result<()> {
    let model = crate::models::by_name(&a.model).context("--model")?;
    if model.name() != "yan2017" {
        bail!(
            "--model {}: the renderer's BCSDF is the yan2017 fur model only; {} has no \
             renderer BCSDF to put in a furnace",
            a.model,
            model.name()
        );
    }
    let mode = MedullaEnergy::parse(&a.medulla_energy).context("--medulla-energy")?;
    let weights = a.energy_weights.as_deref();
    let mut last = None;
    if let Some(report) = &a.report {
        // The yan2017 fits: the folder's own .json files (other models live in subfolders).
        let mut paths: Vec<PathBuf> = std::fs::read_dir(&a.fits_dir)
            .with_context(|| format!("--fits-dir {}", a.fits_dir.display()))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.is_file() && p.extension().is_some_and(|e| e == "json"))
            .collect();
        paths.sort();
        if paths.is_empty() {
            bail!("--fits-dir {}: no .json fit files", a.fits_dir.display());
        }
        let mut named = Vec::new();
        for path in &paths {
            let (p, _, _) = crate::FurParams::load_json(&path.to_string_lossy())?;
            let name = path
                .file_stem()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned();
            named.push((name, p));
        }
        let modes = [
            MedullaEnergy::Strand,
            MedullaEnergy::Fit,
            MedullaEnergy::Conserve,
        ];
        let curves = report_curves(&named, &modes, weights, a.samples, a.seed)?;
        let cmd = format!(
            "furfit furnace --report {} --fits-dir {} --samples {} --seed {}",
            report.display(),
            a.fits_dir.display(),
            a.samples,
            a.seed
        );
        let png = report.join("furnace.png");
        let files = vec![
            (
                report.join("furnace.md"),
                report_markdown(&curves, &cmd, a.samples).into_bytes(),
            ),
            (report.join("furnace.csv"), report_csv(&curves).into_bytes()),
            (png.clone(), report_png(&curves, &png)?),
        ];
        crate::io::write_atomic_all(&files)?;
        for m in modes {
            let rows: Vec<_> = curves
                .iter()
                .filter(|c| c.mode == m)
                .flat_map(|c| c.rows.iter().copied())
                .collect();
            let (hi, lo) = extremes(&rows);
            outln!(
                "{}: albedo of every fit and variant in [{lo:.3}, {hi:.3}]",
                m.name()
            );
        }
        outln!("wrote {}", report.join("furnace.{md,csv,png}").display());
        let all: Vec<_> = curves
            .iter()
            .filter(|c| c.mode == mode)
            .flat_map(|c| c.rows.iter().copied())
            .collect();
        last = Some(extremes(&all));
    }
    if let Some(spec) = &a.params {
        let (p, _, _) = super::load_params(spec)?;
        let b = furnace_bsdf(&p, mode, weights)?;
        let rows = furnace(&b, &default_thetas_deg(), a.samples, a.seed)?;
        outln!(
            "# furnace of {spec}, --medulla-energy {}, {} samples per theta (Monte Carlo, BCSDF sampling)",
            mode.name(),
            a.samples
        );
        outln!("theta_deg albedo se");
        for r in &rows {
            outln!("{:6.1} {:.4} {:.4}", r.theta_deg, r.albedo, r.se);
        }
        last = Some(extremes(&rows));
    }
    if let Some((hi, lo)) = last {
        outln!("max albedo {hi:.4} min albedo {lo:.4}");
    }
    Ok(())
}

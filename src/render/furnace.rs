//! White furnace of the renderer's BCSDF: the directional albedo
//! `E(theta_o) = 1/2 ∫dh ∫∫ sum_p M_p N_p(h) dtheta dphi` (the module doc of
//! [`super::bsdf`]: in the `(theta, phi)` measure the integrand is the goniometer value),
//! i.e. the fraction of the light a fiber seen from `theta_o` returns under a uniform white
//! environment, averaged over the fiber's width (the far field's `h`).
//!
//! Estimator: Monte Carlo over the sphere with the renderer's own BCSDF sampler (`h`
//! uniform on [-1, 1], then a direction from the lobe mixture, weight `f cos / pdf`; the
//! chi-square tests of `bsdf_tests` show sampler and pdf agree), so the figure is what a
//! path tracer sees, including the [`MedullaEnergy`] mode. Each inclination has its own
//! seeded stream (deterministic) and reports the standard error of its mean.

use super::bsdf::{lobe_sum, FiberBsdf, HRange, MedullaEnergy, Tint};
use super::strand::{EnergyScale, StrandMlp};
use crate::error::{Error, Result};
use crate::model::LobeSet;
use crate::params::FurParams;
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use rayon::prelude::*;
use std::path::Path;
use std::sync::Arc;

/// Default samples per inclination: a standard error of ~0.001-0.003 on fur fits.
pub const DEFAULT_SAMPLES: usize = 40_000;

/// The default inclinations, -90 to 90 degrees in 10 degree steps (19 values). The poles
/// are evaluated 0.1 degree inside (the frame of a direction along the fiber degenerates).
pub fn default_thetas_deg() -> Vec<f64> {
    (0..19).map(|i| -90.0 + 10.0 * i as f64).collect()
}

/// One inclination's albedo.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FurnaceRow {
    /// Camera-side inclination, degrees.
    pub theta_deg: f64,
    /// Directional albedo at that inclination: the share of a white furnace's light the
    /// fiber returns.
    pub albedo: f64,
    /// Standard error of `albedo` (Monte Carlo).
    pub se: f64,
}

/// The params with no absorption (cortex and medulla): the "lossless variant".
pub fn lossless(p: &FurParams) -> FurParams {
    let mut q = *p;
    q.sigma_c_a = 0.0;
    q.sigma_m_a = 0.0;
    q
}

/// The renderer's BCSDF of `params` (grey: every channel the parameters' own absorption)
/// in energy mode `mode`; `weights` is the Strand weights file (`None`: built in).
pub fn furnace_bsdf(
    params: &FurParams,
    mode: MedullaEnergy,
    weights: Option<&Path>,
) -> Result<FiberBsdf> {
    params.validate()?;
    let mut b = FiberBsdf::new(params, Tint::GREY, LobeSet::ALL);
    b.medulla_energy = mode;
    // The renderer's default sampler: the furnace measures what a render integrates.
    b.sampling = super::ishair::Sampling::default();
    if mode == MedullaEnergy::Strand {
        let mlp = match weights {
            Some(p) => StrandMlp::load(p)?,
            None => StrandMlp::builtin()?,
        };
        b.energy = Some(Arc::new(EnergyScale::build(params, Tint::GREY, &mlp)));
    }
    b.build_select_table();
    Ok(b)
}

/// Monte Carlo directional albedo at camera-side `theta_o` (radians): mean and standard
/// error over `n` samples (channel 0; the BCSDF is grey).
pub fn directional_albedo(b: &FiberBsdf, theta_o: f64, n: usize, seed: u64) -> (f64, f64) {
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    let side = b.camera_side(theta_o);
    let (mut s, mut s2) = (0.0, 0.0);
    for _ in 0..n {
        let u = [rng.random(), rng.random(), rng.random(), rng.random()];
        // A sample the sampler refuses (no lobe with energy) contributes 0.
        let w = b
            .sample(&side, HRange::Span(-1.0, 1.0), u)
            .map_or(0.0, |smp| lobe_sum(&smp.weight)[0]);
        s += w;
        s2 += w * w;
    }
    let nf = n.max(1) as f64;
    let mean = s / nf;
    let var = (s2 / nf - mean * mean).max(0.0);
    (mean, (var / nf).sqrt())
}

/// The furnace over `thetas_deg` (each in [-90, 90]) with `n` samples each.
pub fn furnace(b: &FiberBsdf, thetas_deg: &[f64], n: usize, seed: u64) -> Result<Vec<FurnaceRow>> {
    if n < 2 {
        return Err(Error::Invalid(format!(
            "--samples {n}: at least 2 (the standard error needs two)"
        )));
    }
    if let Some(t) = thetas_deg
        .iter()
        .find(|t| !(t.is_finite() && t.abs() <= 90.0))
    {
        return Err(Error::Invalid(format!(
            "theta {t}: must be within [-90, 90] degrees"
        )));
    }
    Ok(thetas_deg
        .par_iter()
        .enumerate()
        .map(|(i, &t)| {
            let to = t.clamp(-89.9, 89.9).to_radians();
            let seed_i = seed
                .wrapping_mul(0x9E37_79B9_7F4A_7C15)
                .wrapping_add(i as u64);
            let (albedo, se) = directional_albedo(b, to, n, seed_i);
            FurnaceRow {
                theta_deg: t,
                albedo,
                se,
            }
        })
        .collect())
}

/// `(max, min)` albedo of rows.
pub fn extremes(rows: &[FurnaceRow]) -> (f64, f64) {
    rows.iter()
        .fold((f64::NEG_INFINITY, f64::INFINITY), |(hi, lo), r| {
            (hi.max(r.albedo), lo.min(r.albedo))
        })
}

/// One curve of the furnace report: a fit, its variant, a mode.
#[derive(Clone, Debug)]
pub struct Curve {
    /// The fit's name (file stem).
    pub fit: String,
    /// `fitted` or `lossless`.
    pub variant: &'static str,
    /// How the scattered lobes' energy was treated.
    pub mode: MedullaEnergy,
    /// One row per inclination.
    pub rows: Vec<FurnaceRow>,
}

/// The furnace of every fit in `fits` (name, params), fitted and lossless, in each of
/// `modes`.
pub fn report_curves(
    fits: &[(String, FurParams)],
    modes: &[MedullaEnergy],
    weights: Option<&Path>,
    n: usize,
    seed: u64,
) -> Result<Vec<Curve>> {
    let thetas = default_thetas_deg();
    let mut out = Vec::new();
    for (name, p) in fits {
        for (variant, q) in [("fitted", *p), ("lossless", lossless(p))] {
            for &mode in modes {
                let b = furnace_bsdf(&q, mode, weights)?;
                out.push(Curve {
                    fit: name.clone(),
                    variant,
                    mode,
                    rows: furnace(&b, &thetas, n, seed)?,
                });
            }
        }
    }
    Ok(out)
}

/// The report's CSV: one row per curve and inclination.
pub fn report_csv(curves: &[Curve]) -> String {
    let mut s = String::from("fit,variant,medulla_energy,theta_deg,albedo,se\n");
    for c in curves {
        for r in &c.rows {
            s += &format!(
                "{},{},{},{},{:.6},{:.6}\n",
                c.fit,
                c.variant,
                c.mode.name(),
                r.theta_deg,
                r.albedo,
                r.se
            );
        }
    }
    s
}

/// The report's Markdown: min / max albedo per fit, variant and mode.
pub fn report_markdown(curves: &[Curve], command: &str, n: usize) -> String {
    let mut s = String::from("# White furnace of the renderer's BCSDF\n\n");
    s += &format!("Command: `{command}` (furfit {})\n\n", crate::TOOL_VERSION);
    s += &format!(
        "Directional albedo `E(theta_o) = 1/2 ∫dh ∫∫ sum_p M_p N_p dtheta dphi` at 19 \
inclinations -90..90 degrees (the poles 0.1 degree inside), Monte Carlo with the renderer's \
own BCSDF sampler, {n} samples per inclination (`h` uniform on [-1, 1]); `se` is the largest \
standard error of the curve. `lossless` is the fit with `sigma_c_a = sigma_m_a = 0`, which a \
physical fiber returns in full (albedo 1).\n\n"
    );
    s += "| fit | variant | medulla energy | min albedo | max albedo | max se |\n|---|---|---|---|---|---|\n";
    for c in curves {
        let (hi, lo) = extremes(&c.rows);
        let se = c.rows.iter().map(|r| r.se).fold(0.0, f64::max);
        s += &format!(
            "| {} | {} | {} | {:.3} | {:.3} | {:.4} |\n",
            c.fit,
            c.variant,
            c.mode.name(),
            lo,
            hi,
            se
        );
    }
    s
}

/// The report's plot (PNG bytes): albedo vs theta of every curve of `mode`, one line per
/// fit and variant (lossless dashed in spirit: drawn thinner).
pub fn report_png(curves: &[Curve], path: &Path) -> Result<Vec<u8>> {
    use plotters::prelude::*;
    crate::report::plot::register_fonts();
    let modes: Vec<MedullaEnergy> = {
        let mut m: Vec<MedullaEnergy> = Vec::new();
        for c in curves {
            if !m.contains(&c.mode) {
                m.push(c.mode);
            }
        }
        m
    };
    let hi = curves
        .iter()
        .flat_map(|c| c.rows.iter().map(|r| r.albedo))
        .fold(1.1, f64::max)
        .min(3.0);
    let fits: Vec<&str> = {
        let mut f: Vec<&str> = Vec::new();
        for c in curves {
            if !f.contains(&c.fit.as_str()) {
                f.push(&c.fit);
            }
        }
        f
    };
    let w = 420 * modes.len().max(1) as u32;
    crate::report::plot::png_bytes((w, 420), path, |root| {
        let err = |e: String| Error::file(path, format!("plot: {e}"));
        root.fill(&WHITE).map_err(|e| err(e.to_string()))?;
        let panels = root.split_evenly((1, modes.len().max(1)));
        for (panel, mode) in panels.iter().zip(&modes) {
            let mut chart = ChartBuilder::on(panel)
                .caption(
                    format!("--medulla-energy {}", mode.name()),
                    (crate::report::plot::FONT, 16),
                )
                .margin(8)
                .x_label_area_size(32)
                .y_label_area_size(44)
                .build_cartesian_2d(-90.0..90.0, 0.0..hi)
                .map_err(|e| err(e.to_string()))?;
            chart
                .configure_mesh()
                .x_desc("theta_o (deg)")
                .y_desc("albedo")
                .label_style((crate::report::plot::FONT, 12))
                .draw()
                .map_err(|e| err(e.to_string()))?;
            for c in curves.iter().filter(|c| c.mode == *mode) {
                let k = fits.iter().position(|f| *f == c.fit).unwrap_or(0);
                let col = Palette99::pick(k).to_rgba();
                let width = if c.variant == "lossless" { 3 } else { 1 };
                chart
                    .draw_series(LineSeries::new(
                        c.rows.iter().map(|r| (r.theta_deg, r.albedo)),
                        col.stroke_width(width),
                    ))
                    .map_err(|e| err(e.to_string()))?;
            }
            chart
                .draw_series(LineSeries::new(
                    [(-90.0, 1.0), (90.0, 1.0)],
                    BLACK.stroke_width(1),
                ))
                .map_err(|e| err(e.to_string()))?;
        }
        root.present().map_err(|e| err(e.to_string()))?;
        Ok(())
    })
}

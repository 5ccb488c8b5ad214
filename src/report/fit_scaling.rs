//! `furfit bench-model --fit-scaling`: how a blind fit's wall time grows with the number of
//! samples and of `theta_i` rows (issue #60). Three series, each a blind fit with default
//! options (the default model) per point:
//! * a species' profile, randomly subsampled (seeded) from 1k samples to all of them;
//! * a dense synthetic grid (the model's preset named like the species, else its first;
//!   8 `theta_i` x 81 `theta_r` x 180 `phi` = 116,640 samples, noise-free), randomly
//!   subsampled from 1k to 100k;
//! * whole `theta_i` rows of that grid: 1, 2, 4, 8 rows (14,580 samples each).
//!
//! Writes `fit_scaling.{csv,png,svg,md}`; the exponent of each series is the
//! least-squares slope of `ln t` against `ln n`. Times are wall times of one run each on
//! this machine, so they carry its load: the exponent, not the seconds, is the figure.

use crate::error::Result;
use crate::fit::problem::FitData;
use crate::fit::{channel_data, fit_data, starts, FitOptions, DEFAULT_FLOOR};
use crate::model::far::FarOptions;
use crate::model::LobeSet;
use crate::models::{default_model, Integral, ModelParams, Points};
use crate::report::plot::{loglog_chart, ChartSpec, Series};
use crate::timing::cpu_seconds;
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

/// One fit of the study.
#[derive(Clone, Debug)]
pub struct ScalingPoint {
    /// Which of the three series the fit belongs to.
    pub series: &'static str,
    /// Samples fitted.
    pub samples: usize,
    /// `theta_i` rows among them.
    pub theta_i_rows: usize,
    /// Wall seconds of the fit.
    pub wall_s: f64,
    /// Process CPU seconds (all threads) of the fit: less affected by other load.
    pub cpu_s: f64,
    /// Model evaluations the fit made.
    pub evaluations: u64,
    /// NRMSE of the fit on its samples.
    pub nrmse: f64,
}

/// Least-squares slope of `ln y` against `ln x` (`None` with fewer than two points).
pub fn loglog_slope(points: &[(f64, f64)]) -> Option<f64> {
    let v: Vec<(f64, f64)> = points
        .iter()
        .filter(|p| p.0 > 0.0 && p.1 > 0.0)
        .map(|p| (p.0.ln(), p.1.ln()))
        .collect();
    if v.len() < 2 {
        return None;
    }
    let n = v.len() as f64;
    let (mx, my) = (
        v.iter().map(|p| p.0).sum::<f64>() / n,
        v.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxx: f64 = v.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = v.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    (sxx > 0.0).then(|| sxy / sxx)
}

/// The dense grid's `theta_i` values (degrees).
const DENSE_THETA_I: [f64; 8] = [-60.0, -40.0, -20.0, 0.0, 10.0, 30.0, 50.0, 70.0];

/// The dense synthetic grid as fit data: `rows` of its `theta_i` values, noise-free
/// values of the default model's preset `preset` (or its first preset).
fn dense_grid(preset: &str, rows: usize) -> Result<FitData> {
    let m = default_model();
    let p = m
        .presets()
        .iter()
        .find(|p| p.name == preset)
        .unwrap_or(&m.presets()[0]);
    let params = ModelParams::from_file_units(m, p.values)?;
    let mut pts = Points::default();
    for &ti in &DENSE_THETA_I[..rows] {
        for k in 0..81 {
            for j in 0..180 {
                let tr = -80.0 + 2.0 * k as f64;
                let phi = -179.0 + 2.0 * j as f64;
                pts.push(ti.to_radians(), f64::to_radians(tr), f64::to_radians(phi));
            }
        }
    }
    let pred = m.predict(
        &params.values,
        &pts,
        &FarOptions::default(),
        LobeSet::ALL,
        Integral::Far,
    );
    let y: Vec<f64> = pred.lobes.iter().map(|l| l.sum()).collect();
    Ok(FitData::new(pts, &y, None))
}

/// A blind fit of `data` (a seeded random subsample of `n` samples when smaller).
fn timed_fit(
    series: &'static str,
    data: &FitData,
    n: usize,
    rows: usize,
    log: &mut dyn FnMut(&str),
) -> Result<ScalingPoint> {
    let d = if n < data.len() {
        data.subset(&starts::subsample(data.len(), n, 7))
    } else {
        data.clone()
    };
    let t = Instant::now();
    let c0 = cpu_seconds();
    let o = fit_data(&d, &FitOptions::for_model(default_model()), None)?;
    let cpu_s = match (c0, cpu_seconds()) {
        (Some(a), Some(b)) => b - a,
        _ => f64::NAN,
    };
    let p = ScalingPoint {
        series,
        samples: d.len(),
        theta_i_rows: rows,
        wall_s: t.elapsed().as_secs_f64(),
        cpu_s,
        evaluations: o.evaluations,
        nrmse: o.nrmse,
    };
    log(&format!(
        "  {series}: {} samples, {rows} theta_i rows: {:.2} s wall, {:.2} s CPU, {} evaluations, NRMSE {:.3}%",
        p.samples,
        p.wall_s,
        p.cpu_s,
        p.evaluations,
        100.0 * p.nrmse
    ));
    Ok(p)
}

/// Run the study on the profile at `species` and write its files into `out`.
pub fn run(out: &Path, species: &Path, log: &mut dyn FnMut(&str)) -> Result<Vec<ScalingPoint>> {
    let inputs = crate::fit::job::load_inputs_full(&[species.to_path_buf()], &Default::default())?;
    let name = crate::fit::job::species_name(species);
    let measured = channel_data(&inputs.profile, 0, false, DEFAULT_FLOOR)?;
    let rows_of = |d: &FitData| {
        let mut ti: Vec<u64> = d.points.pts.iter().map(|p| p.0.to_bits()).collect();
        ti.sort_unstable();
        ti.dedup();
        ti.len()
    };
    log(&format!(
        "fit scaling: {} threads; blind fits, default options",
        rayon::current_num_threads()
    ));
    let mut pts = Vec::new();
    let species_series: &'static str = "species profile, subsampled";
    for n in [1000, 2000, 4000, 8000, 16000, usize::MAX] {
        let n = n.min(measured.len());
        pts.push(timed_fit(
            species_series,
            &measured,
            n,
            rows_of(&measured),
            log,
        )?);
        if n == measured.len() {
            break;
        }
    }
    let dense = dense_grid(&name, DENSE_THETA_I.len())?;
    for n in [1000, 4000, 16000, 64000, 100_000] {
        pts.push(timed_fit(
            "dense synthetic grid, subsampled",
            &dense,
            n,
            8,
            log,
        )?);
    }
    for rows in [1, 2, 4, 8] {
        let d = dense_grid(&name, rows)?;
        pts.push(timed_fit(
            "dense grid, whole theta_i rows",
            &d,
            d.len(),
            rows,
            log,
        )?);
    }
    write(out, &name, species, &pts, log)?;
    Ok(pts)
}

/// The study's CSV, plot and summary.
fn write(
    out: &Path,
    name: &str,
    species: &Path,
    pts: &[ScalingPoint],
    log: &mut dyn FnMut(&str),
) -> Result<()> {
    let mut csv = String::from("series,samples,theta_i_rows,wall_s,cpu_s,evaluations,nrmse\n");
    for p in pts {
        let _ = writeln!(
            csv,
            "{},{},{},{:.4},{:.2},{},{:.6}",
            p.series, p.samples, p.theta_i_rows, p.wall_s, p.cpu_s, p.evaluations, p.nrmse
        );
    }
    let mut names: Vec<&'static str> = pts.iter().map(|p| p.series).collect();
    names.dedup();
    let series: Vec<Series> = names
        .iter()
        .map(|&s| Series {
            name: s.to_string(),
            points: pts
                .iter()
                .filter(|p| p.series == s)
                .map(|p| (p.samples as f64, p.cpu_s))
                .collect(),
            markers: true,
        })
        .collect();
    let mut md = format!(
        "# Fit time against problem size\n\nWritten by `furfit bench-model --fit-scaling`.\n\n\
         Data: SYNTHETIC. `{}` (the virtual goniometer's profile of {name}) subsampled at random, and a dense \
         noise-free grid of the default model (8 theta_i x 81 theta_r x 180 phi) subsampled at random \
         or cut to whole theta_i rows. One blind fit (default options) per point, {} threads. The plot and \
         the exponents use the fit's process CPU time (all threads), which other load on the machine \
         changes less than the wall time.\n\n\
         | series | exponent of CPU time in samples | exponent of wall time |\n|---|---:|---:|\n",
        species.display(),
        rayon::current_num_threads()
    );
    let show = |e: Option<f64>| e.map_or("-".into(), |e| format!("{e:.2}"));
    for s in &series {
        let e = loglog_slope(&s.points);
        let wall: Vec<(f64, f64)> = pts
            .iter()
            .filter(|p| p.series == s.name)
            .map(|p| (p.samples as f64, p.wall_s))
            .collect();
        let ew = loglog_slope(&wall);
        let _ = writeln!(md, "| {} | {} | {} |", s.name, show(e), show(ew));
        log(&format!(
            "  exponent, {}: {} (CPU time), {} (wall time)",
            s.name,
            show(e),
            show(ew)
        ));
    }
    md.push_str("\n| series | samples | theta_i rows | wall s | CPU s | evaluations | NRMSE |\n|---|---:|---:|---:|---:|---:|---:|\n");
    for p in pts {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {:.2} | {:.2} | {} | {:.3}% |",
            p.series,
            p.samples,
            p.theta_i_rows,
            p.wall_s,
            p.cpu_s,
            p.evaluations,
            100.0 * p.nrmse
        );
    }
    let spec = ChartSpec {
        title: "Blind fit time against samples (process CPU time)",
        x_label: "samples",
        y_label: "CPU time, all threads (s)",
        width: 900,
        height: 600,
    };
    let mut files = loglog_chart(
        Some(&out.join("fit_scaling.png")),
        Some(&out.join("fit_scaling.svg")),
        &spec,
        &series,
    )?;
    files.push((out.join("fit_scaling.csv"), csv.into_bytes()));
    files.push((out.join("fit_scaling.md"), md.into_bytes()));
    crate::io::write_outputs(&files)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The slope of an exact power law is its exponent (to rounding: 1e-12).
    #[test]
    fn loglog_slope_recovers_a_power_law() {
        let pts: Vec<(f64, f64)> = [1e3, 4e3, 2e4, 1e5]
            .iter()
            .map(|&n: &f64| (n, 3.0 * n.powf(0.8)))
            .collect();
        assert!((loglog_slope(&pts).unwrap() - 0.8).abs() < 1e-12);
        assert!(loglog_slope(&pts[..1]).is_none());
    }
}

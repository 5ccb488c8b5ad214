//! Are the fit's standard errors the spread they claim? (`furfit se-calibration`)
//!
//! Replicated profiles from the far field at known parameters (the red fox preset) with
//! multiplicative log-normal noise, each fitted as `furfit fit` does (default options, so
//! automatic starts); per parameter, the spread of the estimates against the mean
//! independent-residual standard error ([`crate::fit::uncertainty::estimate`]) and the
//! mean sweep-robust one ([`crate::fit::uncertainty::robust`]), and how often each
//! `+- 1.96 SE` covers the truth. Two noise models: independent per sample, and correlated
//! along the sweeps (AR(1) along `phi`, a row effect AR(1) in `theta_r`), the structure a
//! drifting lamp, a fiber's twist or a model's own error give real data. The model is the
//! data's own, so there is no model error here: the question is only the errors' scale.

use crate::error::{Error, Result};
use crate::fit::problem::{FitData, LogResidualProblem};
use crate::fit::{channel_data, fit_data, reparam, FitOptions, FitOutcome};
use crate::model::far::FarOptions;
use crate::model::LobeSet;
use crate::models::Integral;
use crate::params::{FurParams, ParamId, N_PARAMS};
use crate::synth::synthesize;
// Standard normal variates: the virtual goniometer's Box-Muller sampler.
use crate::simulate::trace::gauss as normal;
use nalgebra::DVector;
use rand::SeedableRng;
use rand_xoshiro::Xoshiro256PlusPlus;
use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// A noise model: log-space noise `sd_phi * a + sd_row * b + sd_white * w` per sample, `a`
/// AR(1) along `phi` within a row at `rho_phi`, `b` one value per row, AR(1) in `theta_r`
/// at `rho_row`, `w` independent; all standard normal.
#[derive(Clone, Copy, Debug)]
pub struct Noise {
    /// The noise model's name in the report.
    pub name: &'static str,
    /// SD of the AR(1) log-noise along `phi`.
    pub sd_phi: f64,
    /// Lag-one correlation of that noise between neighbouring `phi`.
    pub rho_phi: f64,
    /// SD of the per-row log-noise.
    pub sd_row: f64,
    /// Lag-one correlation of the row noise between neighbouring `theta_r` rows.
    pub rho_row: f64,
    /// SD of the independent per-sample log-noise.
    pub sd_white: f64,
}

/// The study's noise models: independent 5 %, and correlated noise of about the same
/// size (`sqrt(0.04^2 + 0.03^2 + 0.02^2)` = 5.4 %).
pub const NOISES: [Noise; 2] = [
    Noise {
        name: "independent",
        sd_phi: 0.0,
        rho_phi: 0.0,
        sd_row: 0.0,
        rho_row: 0.0,
        sd_white: 0.05,
    },
    Noise {
        name: "correlated along the sweeps",
        sd_phi: 0.04,
        rho_phi: 0.9,
        sd_row: 0.03,
        rho_row: 0.5,
        sd_white: 0.02,
    },
];

/// The study's grid (degrees): 2 x 31 x 60 = 3720 samples, 62 rows.
fn grid() -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let ti = vec![0.0, 30.0];
    let tr = (0..31).map(|k| -60.0 + 4.0 * k as f64).collect();
    let phi = (0..60).map(|j| -174.0 + 6.0 * j as f64).collect();
    (ti, tr, phi)
}

/// One parameter's calibration under one noise model.
#[derive(Clone, Debug)]
pub struct Row {
    /// The noise model's name ([`Noise::name`]).
    pub noise: &'static str,
    /// The parameter.
    pub param: ParamId,
    /// Replicates where the parameter was not flagged unconstrained (flagged ones, e.g.
    /// `Wide` for a large standard error, have no usable one), so SD, mean SEs and
    /// coverage are over these only.
    pub n: usize,
    /// Standard deviation of the estimates (file units).
    pub sd: f64,
    /// `1.4826 x` their median absolute deviation: the SD if they were normal, but not
    /// inflated by a few replicates far out (another basin, a curved valley).
    pub sd_mad: f64,
    /// Mean independent-residual standard error ([`crate::fit::uncertainty::estimate`]),
    /// file units.
    pub mean_se: f64,
    /// Mean sweep-robust standard error ([`crate::fit::uncertainty::robust`]), file units.
    pub mean_se_robust: f64,
    /// The robust estimator fed each replicate's own noise in place of its residuals
    /// ([`noise_fed_robust`]).
    pub mean_se_noise_fed: f64,
    /// Share of those replicates whose `+- 1.96 SE` interval covers the truth.
    pub cover: f64,
    /// Share covered by the robust `+- 1.96 SE` interval.
    pub cover_robust: f64,
    /// Share covered by the noise-fed robust interval.
    pub cover_noise_fed: f64,
}

/// Log-space noise per sample of `samples` (degrees), rows in `(theta_i, theta_r)` order
/// and `phi` ascending within a row, as the grid is generated.
fn noise_for(samples: &[(f64, f64, f64)], nz: &Noise, rng: &mut Xoshiro256PlusPlus) -> Vec<f64> {
    let order = crate::fit::uncertainty::sweep_order(samples);
    let mut out = vec![0.0; samples.len()];
    let (mut row, mut along) = (0.0, 0.0);
    let mut prev: Option<(f64, f64)> = None;
    for i in order {
        let (ti, tr, _) = samples[i];
        match prev {
            Some((pti, ptr)) if pti == ti && ptr == tr => {
                along = nz.rho_phi * along + (1.0 - nz.rho_phi * nz.rho_phi).sqrt() * normal(rng);
            }
            Some((pti, _)) if pti == ti => {
                row = nz.rho_row * row + (1.0 - nz.rho_row * nz.rho_row).sqrt() * normal(rng);
                along = normal(rng);
            }
            _ => {
                row = normal(rng);
                along = normal(rng);
            }
        }
        prev = Some((ti, tr));
        out[i] = nz.sd_phi * along + nz.sd_row * row + nz.sd_white * normal(rng);
    }
    out
}

/// One replicate's estimate of a parameter (file units), its SE, robust SE and
/// noise-fed robust SE (`None` where flagged unconstrained).
type Estimate = (f64, Option<f64>, Option<f64>, Option<f64>);

/// A sample's angles (radians) as a map key.
fn angle_key(&(a, b, c): &(f64, f64, f64)) -> [u64; 3] {
    [a.to_bits(), b.to_bits(), c.to_bits()]
}

/// Multiply each sample of `prof` by `exp(e)` (log-space noise, one per sample) and return
/// the noise keyed by the samples' angles ([`angle_key`]).
fn apply_noise(prof: &mut crate::profile::Profile, e: &[f64]) -> HashMap<[u64; 3], f64> {
    prof.samples
        .iter_mut()
        .zip(e)
        .map(|(s, &e)| {
            s.value *= e.exp();
            (angle_key(&s.angles_rad()), e)
        })
        .collect()
}

/// The residuals `data` would have at the true parameters given its log-space noise
/// (keyed by [`angle_key`]): `-sqrt(w) (e - mean_w e) / range`, the exposure taking the
/// weighted mean. `None` if a sample has no noise value.
fn noise_residuals(data: &FitData, noise: &HashMap<[u64; 3], f64>) -> Option<DVector<f64>> {
    let e: Vec<f64> = data
        .points
        .pts
        .iter()
        .map(|p| noise.get(&angle_key(p)).copied())
        .collect::<Option<_>>()?;
    let wsum: f64 = data.w.iter().sum();
    let mean = e.iter().zip(&data.w).map(|(e, w)| e * w).sum::<f64>() / wsum;
    Some(DVector::from_iterator(
        e.len(),
        e.iter()
            .zip(&data.w)
            .map(|(e, w)| -w.sqrt() * (e - mean) / data.range),
    ))
}

/// The sweep-robust standard errors ([`crate::fit::uncertainty::robust`]) of `fit` with
/// the replicate's own log-space noise (`noise`, keyed by the samples' angles in radians)
/// in place of the fit's residuals: their noise part before the fit absorbed any of it
/// (the exposure still takes the mean, and residuals are in units of the data's log
/// range). Only a simulation knows the noise. The fitted residuals are orthogonal to the
/// Jacobian, so the fit removes exactly the part of a smooth noise that looks like a
/// parameter's effect, and a long-run variance from residuals comes out low; the gap
/// between this and the residual-based SE measures that loss, and this one's own gap from
/// the spread is the estimator's (a Bartlett window truncated within sweeps of a few
/// tens of rows).
fn noise_fed_robust(
    data: &FitData,
    fit: &FitOutcome,
    noise: &HashMap<[u64; 3], f64>,
) -> Option<Vec<Option<f64>>> {
    let opts = FitOptions::default();
    let r = noise_residuals(data, noise)?;
    let free = opts.layout.free();
    let v = fit.params.to_file_units();
    let u = DVector::from_iterator(
        free.len(),
        free.iter().map(|id| reparam::to_u(*id, v[id.index()])),
    );
    let jac = LogResidualProblem::new(data, opts.layout.clone(), opts.far).jacobian_at(&u);
    let pts = &data.points.pts;
    crate::fit::uncertainty::robust(&opts.layout, &u, &jac, &r, pts, &fit.uncertainty)
        .map(|rb| rb.se)
}

/// The median (sorts `v`).
fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        f64::NAN
    } else if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// The study's rows, and per noise model ([`NOISES`]) the replicates whose fit failed.
pub struct Study {
    /// One row per noise model and parameter.
    pub rows: Vec<Row>,
    /// Replicates whose fit failed, per noise model.
    pub failed: [usize; NOISES.len()],
}

/// Run `reps` replicates per noise model; `log` gets a line per replicate.
pub fn study(reps: usize, log: &mut dyn FnMut(&str)) -> Result<Study> {
    let truth = FurParams::preset("red-fox").expect("shipped preset");
    let t = truth.to_file_units();
    let (ti, tr, phi) = grid();
    let base = synthesize(
        &truth.into(),
        &ti,
        &tr,
        &phi,
        Integral::Far,
        LobeSet::ALL,
        1.0,
        &FarOptions::default(),
    );
    let angles: Vec<(f64, f64, f64)> = base
        .samples
        .iter()
        .map(|s| (s.theta_i, s.theta_r, s.phi))
        .collect();
    let mut rows = Vec::new();
    let mut failed = [0usize; NOISES.len()];
    for (c, nz) in NOISES.iter().enumerate() {
        let mut runs: Vec<[Estimate; N_PARAMS]> = Vec::new();
        for rep in 0..reps {
            let mut rng = Xoshiro256PlusPlus::seed_from_u64(((c as u64) << 32) | rep as u64);
            let e = noise_for(&angles, nz, &mut rng);
            let mut prof = base.clone();
            let noise = apply_noise(&mut prof, &e);
            let data = channel_data(&prof, 0, false, crate::fit::DEFAULT_FLOOR)?;
            // A failed replicate is counted, not fatal: minutes of others stay.
            let fit = match fit_data(&data, &FitOptions::default(), None) {
                Ok(f) => f,
                Err(e) => {
                    log(&format!("{}: replicate {} failed: {e}", nz.name, rep + 1));
                    failed[c] += 1;
                    continue;
                }
            };
            let f = fit.params.to_file_units();
            let unc = &fit.uncertainty;
            let rb = unc.robust.as_ref().map(|r| r.se.clone());
            let fed = noise_fed_robust(&data, &fit, &noise);
            let mut run = [(0.0, None, None, None); N_PARAMS];
            for id in ParamId::ALL {
                let k = id.index();
                let flagged = unc.unconstrained.iter().any(|(p, _)| *p == id.into());
                run[k] = (
                    f[k],
                    unc.se[k].filter(|_| !flagged),
                    rb.as_ref().and_then(|r| r[k]).filter(|_| !flagged),
                    fed.as_ref().and_then(|r| r[k]).filter(|_| !flagged),
                );
            }
            log(&format!(
                "{}: replicate {}/{reps}: NRMSE {:.3}% in {:.1} s",
                nz.name,
                rep + 1,
                100.0 * fit.nrmse,
                fit.wall_time_s
            ));
            runs.push(run);
        }
        for id in ParamId::ALL {
            let k = id.index();
            let used: Vec<_> = runs
                .iter()
                .map(|r| r[k])
                .filter(|(_, se, rse, fed)| se.is_some() && rse.is_some() && fed.is_some())
                .collect();
            let n = used.len();
            if n < 2 {
                continue;
            }
            let nf = n as f64;
            let mean = used.iter().map(|u| u.0).sum::<f64>() / nf;
            let sd = (used.iter().map(|u| (u.0 - mean).powi(2)).sum::<f64>() / (nf - 1.0)).sqrt();
            let mut est: Vec<f64> = used.iter().map(|u| u.0).collect();
            let med = median(&mut est);
            let mut dev: Vec<f64> = est.iter().map(|v| (v - med).abs()).collect();
            let sd_mad = 1.4826 * median(&mut dev);
            // Per kind of SE (read from a replicate by `se`): its mean, and the share of
            // replicates whose +-1.96 SE covers the truth.
            let mean = |se: fn(&Estimate) -> Option<f64>| {
                used.iter().map(|u| se(u).unwrap_or(0.0)).sum::<f64>() / nf
            };
            let cover = |se: fn(&Estimate) -> Option<f64>| {
                let hit = |u: &Estimate| (u.0 - t[k]).abs() <= 1.96 * se(u).unwrap_or(0.0);
                used.iter().filter(|u| hit(u)).count() as f64 / nf
            };
            rows.push(Row {
                noise: nz.name,
                param: id,
                n,
                sd,
                sd_mad,
                mean_se: mean(|u| u.1),
                mean_se_robust: mean(|u| u.2),
                mean_se_noise_fed: mean(|u| u.3),
                cover: cover(|u| u.1),
                cover_robust: cover(|u| u.2),
                cover_noise_fed: cover(|u| u.3),
            });
        }
    }
    Ok(Study { rows, failed })
}

/// `se_calibration.md` for the study.
pub fn markdown(study: &Study, reps: usize, secs: f64) -> String {
    let rows = &study.rows;
    let (ti, tr, phi) = grid();
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Standard-error calibration\n\nWritten by `furfit se-calibration` ({}) in {secs:.0} s.\n\n\
         Data: SYNTHETIC. {reps} noisy replicates per noise model of one far-field profile \
         at the red fox preset (seed Table 4), {} theta_i x {} theta_r x {} phi = {} samples \
         in {} rows, each fitted with `furfit fit`'s defaults (automatic starts, tolerance \
         mode). The model is the data's own, so there is no model error: this checks only \
         the errors' scale. SD is the standard deviation of the estimates, MAD-SD 1.4826 x their \
         median absolute deviation (the SD if they were normal, not inflated by a few \
         replicates far out: another basin, a curved valley); SE and robust SE \
         are the fits' mean independent-residual and sweep-robust standard errors; cover is \
         the share of replicates whose +-1.96 SE covers the truth (95 % if calibrated; with \
         {reps} replicates a share is known to about +-{:.0} points, less well where n is \
         smaller). A replicate where a parameter is flagged unconstrained (on a bound, no \
         information, or an SE spanning most of its range) is left out of that parameter's \
         row: n counts the others, so rows with n below {reps} describe the better-determined \
         replicates only.\n\n\
         Noise-fed: the robust estimator given each replicate's own noise in place of the \
         fit's residuals, which only a simulation can do. The fit removes the part of a \
         smooth noise that looks like a parameter's effect (the residuals are orthogonal to \
         the Jacobian), so a long-run variance from residuals comes out low: the gap between \
         the robust and noise-fed columns is that loss, and what stays between the noise-fed \
         SE and the spread is the estimator's own (a Bartlett window truncated within sweeps \
         of {} rows).\n",
        crate::TOOL_VERSION,
        ti.len(),
        tr.len(),
        phi.len(),
        ti.len() * tr.len() * phi.len(),
        ti.len() * tr.len(),
        100.0 * 2.0 * (0.95 * 0.05 / reps as f64).sqrt(),
        tr.len(),
    );
    for (c, nz) in NOISES.iter().enumerate() {
        let failed = match study.failed[c] {
            0 => String::new(),
            k => format!(" {k} of {reps} replicates failed to fit and are left out."),
        };
        let _ = writeln!(
            s,
            "## Noise: {}\n\nlog-space noise per sample: {} x AR(1) along phi (rho {}) + {} x row effect, AR(1) in theta_r (rho {}) + {} x independent.{failed}\n\n\
             | parameter | n | SD | MAD-SD | SE | SE / SD | cover | robust SE | robust / SD | robust / MAD-SD | cover | noise-fed / SD | cover |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
            nz.name, nz.sd_phi, nz.rho_phi, nz.sd_row, nz.rho_row, nz.sd_white
        );
        for r in rows.iter().filter(|r| r.noise == nz.name) {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {} | {} | {} | {:.0}% | {} | {} | {} | {:.0}% | {} | {:.0}% |",
                r.param.spec().name,
                r.n,
                super::sig(r.sd, 2),
                super::sig(r.sd_mad, 2),
                super::sig(r.mean_se, 2),
                ratio(r.mean_se, r.sd),
                100.0 * r.cover,
                super::sig(r.mean_se_robust, 2),
                ratio(r.mean_se_robust, r.sd),
                ratio(r.mean_se_robust, r.sd_mad),
                100.0 * r.cover_robust,
                ratio(r.mean_se_noise_fed, r.sd),
                100.0 * r.cover_noise_fed
            );
        }
        let missing: Vec<&str> = ParamId::ALL
            .iter()
            .filter(|id| !rows.iter().any(|r| r.noise == nz.name && r.param == **id))
            .map(|id| id.spec().name)
            .collect();
        if !missing.is_empty() {
            let _ = writeln!(
                s,
                "\nNot shown: {} (flagged unconstrained, or failed, in all but at most one replicate).",
                missing.join(", ")
            );
        }
        s.push('\n');
    }
    s
}

/// `a / b` to two decimals, `-` when `b` is zero (estimates all equal).
fn ratio(a: f64, b: f64) -> String {
    if b > 0.0 && (a / b).is_finite() {
        format!("{:.2}", a / b)
    } else {
        "-".into()
    }
}

/// `se_calibration.csv` for the study's rows.
pub fn csv(rows: &[Row]) -> String {
    let mut s = String::from("noise,param,n,sd,sd_mad,mean_se,mean_se_robust,mean_se_noise_fed,cover,cover_robust,cover_noise_fed\n");
    for r in rows {
        let _ = writeln!(
            s,
            "{},{},{},{:e},{:e},{:e},{:e},{:e},{},{},{}",
            r.noise,
            r.param.spec().name,
            r.n,
            r.sd,
            r.sd_mad,
            r.mean_se,
            r.mean_se_robust,
            r.mean_se_noise_fed,
            r.cover,
            r.cover_robust,
            r.cover_noise_fed
        );
    }
    s
}

/// A spread needs two replicates.
pub fn check_reps(reps: usize) -> Result<()> {
    if reps < 2 {
        return Err(Error::Invalid(format!(
            "--reps must be at least 2, got {reps}"
        )));
    }
    Ok(())
}

/// Run the study and write `se_calibration.{md,csv}` into `out` (together, atomically).
pub fn run(out: &Path, reps: usize, log: &mut dyn FnMut(&str)) -> Result<Vec<PathBuf>> {
    check_reps(reps)?;
    let t = std::time::Instant::now();
    let st = study(reps, log)?;
    let md = markdown(&st, reps, t.elapsed().as_secs_f64());
    let files = vec![
        (out.join("se_calibration.md"), md.into_bytes()),
        (out.join("se_calibration.csv"), csv(&st.rows).into_bytes()),
    ];
    crate::io::write_outputs(&files)?;
    Ok(files.into_iter().map(|(p, _)| p).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The generated noise has the structure it claims: the stated total variance and
    /// lag-1 covariance along phi (the AR part's and the row effect's), within 10 % and
    /// 0.05 of the variance (30 000 values, correlated: a few % sampling error).
    #[test]
    fn noise_has_the_stated_structure() {
        let nz = NOISES[1];
        let mut pts = Vec::new();
        for ti in 0..4 {
            for tr in 0..50 {
                for ph in 0..150 {
                    pts.push((ti as f64, tr as f64, ph as f64));
                }
            }
        }
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(3);
        let e = noise_for(&pts, &nz, &mut rng);
        let var = e.iter().map(|v| v * v).sum::<f64>() / e.len() as f64;
        let want = nz.sd_phi.powi(2) + nz.sd_row.powi(2) + nz.sd_white.powi(2);
        assert!((var / want - 1.0).abs() < 0.1, "{var} vs {want}");
        // Neighbours along phi share the row effect and the AR part.
        let lag: f64 = (1..e.len())
            .filter(|&i| i % 150 != 0)
            .map(|i| e[i] * e[i - 1])
            .sum::<f64>()
            / (e.len() - 200) as f64;
        let want_lag = nz.sd_phi.powi(2) * nz.rho_phi + nz.sd_row.powi(2);
        assert!(
            (lag / var - want_lag / want).abs() < 0.05,
            "{lag} {want_lag}"
        );
    }

    #[test]
    fn noise_residuals_are_the_residuals_at_the_truth() {
        // Residuals at the true parameters of a noisy profile are its noise alone, so the
        // noise-fed residuals must equal them (keyed through channel_data's angle sort,
        // centred by the exposure, scaled by the log range). 1e-12: the model values
        // cancel in ln m - ln(m e^noise) to a few ulps of the logs (|ln m| < ~30).
        let truth = FurParams::preset("red-fox").expect("preset");
        let mut prof = synthesize(
            &truth.into(),
            &[0.0, 30.0],
            &[-40.0, 0.0, 20.0],
            &[-170.0, -60.0, 0.0, 90.0],
            Integral::Far,
            LobeSet::ALL,
            1.0,
            &FarOptions::default(),
        );
        // Shuffle the file order, so that the map (not the order) must pair them.
        prof.samples.reverse();
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(7);
        let e: Vec<f64> = prof
            .samples
            .iter()
            .map(|_| 0.1 * normal(&mut rng))
            .collect();
        let noise = apply_noise(&mut prof, &e);
        let data = channel_data(&prof, 0, false, crate::fit::DEFAULT_FLOOR).expect("data");
        let fed = noise_residuals(&data, &noise).expect("every sample has noise");
        let opts = FitOptions::default();
        let v = truth.to_file_units();
        let u: Vec<f64> = opts
            .layout
            .free()
            .iter()
            .map(|id| reparam::to_u(*id, v[id.index()]))
            .collect();
        let r = LogResidualProblem::new(&data, opts.layout.clone(), opts.far).residuals(&u);
        assert_eq!(r.len(), fed.len());
        for (a, b) in r.iter().zip(fed.iter()) {
            assert!((a - b).abs() < 1e-12, "{a} vs {b}");
        }
        // A sample the map does not know gives none.
        let mut short = noise.clone();
        short.remove(&angle_key(&data.points.pts[0]));
        assert!(noise_residuals(&data, &short).is_none());
    }

    /// The table says which replicates failed and prints no ratio over a zero spread
    /// (all estimates equal), instead of inf or NaN.
    #[test]
    fn markdown_counts_failures_and_survives_a_zero_spread() {
        let row = Row {
            noise: NOISES[0].name,
            param: ParamId::Eta,
            n: 2,
            sd: 0.0,
            sd_mad: 0.0,
            mean_se: 0.01,
            mean_se_robust: 0.02,
            mean_se_noise_fed: 0.03,
            cover: 1.0,
            cover_robust: 1.0,
            cover_noise_fed: 1.0,
        };
        let st = Study {
            rows: vec![row],
            failed: [1, 0],
        };
        let md = markdown(&st, 3, 1.0);
        assert!(md.contains("1 of 3 replicates failed to fit"), "{md}");
        assert!(md.contains("Not shown: kappa, alpha,"), "{md}");
        let line = md.lines().find(|l| l.starts_with("| eta |")).unwrap();
        assert!(
            line.contains("| - |") && !line.contains("inf") && !line.contains("NaN"),
            "{line}"
        );
    }
}

//! `furfit stability`: an adversarial sweep of the far field. Every stiff case of MODEL.md
//! (tiny / huge `beta_n`, the TRT caustic, huge absorption, grazing `theta_d`, `kappa -> 0`
//! and `-> 1`, `eta -> 1` and `eta = 3`, cuticle layers at their bounds) is crossed with
//! other parameters at or near their hard bounds, evaluated over a `theta_d x phi` grid in
//! the default (tolerance) mode and the paper's fixed 8/5 mode, and checked for NaN, Inf
//! and negative values. On a subset the result is compared with the reference integrator:
//! the error of a sample is `|far - ref| / (peak over phi of ref)` for that `theta_d` and
//! lobe. Writes `stability.md` and `stability.csv`.
#![allow(clippy::needless_range_loop)] // fixed-size per-lobe arrays read clearer indexed

use crate::model::far::FarOptions;
use crate::model::{FurModel, LobeSet};
use crate::params::FurParams;
use rayon::prelude::*;
use std::f64::consts::PI;
use std::fmt::Write as _;
use std::path::Path;

/// Totals of a stability run.
#[derive(Clone, Debug, Default)]
pub struct StabilitySummary {
    pub n_evaluations: usize,
    pub n_nonfinite: usize,
    /// Values below zero before the documented clamp of rounding dips.
    pub n_negative_raw: usize,
    /// Values below zero after it (what users get).
    pub n_negative: usize,
}

/// One stiff case: a name and the base parameter vector (file units).
struct Case {
    name: &'static str,
    base: [f64; 10],
}

// eta, kappa, alpha, beta_m, beta_n, sigma_c_a, sigma_m_s, sigma_m_a, g, l
const MID: [f64; 10] = [1.55, 0.6, 2.0, 8.0, 10.0, 0.3, 1.5, 0.1, 0.3, 1.0];

fn with(mut v: [f64; 10], changes: &[(usize, f64)]) -> [f64; 10] {
    for &(i, x) in changes {
        v[i] = x;
    }
    v
}

fn cases() -> Vec<Case> {
    vec![
        Case {
            name: "tiny beta_n (0.1 deg)",
            base: with(MID, &[(4, 0.1)]),
        },
        Case {
            name: "huge beta_n (90 deg)",
            base: with(MID, &[(4, 90.0)]),
        },
        Case {
            name: "TRT caustic (eta 1.3, beta_n 1 deg)",
            base: with(MID, &[(0, 1.3), (4, 1.0)]),
        },
        Case {
            name: "absorption 1e3 (cortex and medulla)",
            base: with(MID, &[(5, 1e3), (6, 1e3), (7, 1e3)]),
        },
        Case {
            name: "kappa -> 0 (1e-6)",
            base: with(MID, &[(1, 1e-6)]),
        },
        Case {
            name: "kappa -> 1 (0.999)",
            base: with(MID, &[(1, 0.999)]),
        },
        Case {
            name: "eta -> 1 (1 + 1e-9)",
            base: with(MID, &[(0, 1.0 + 1e-9)]),
        },
        Case {
            name: "eta = 3",
            base: with(MID, &[(0, 3.0)]),
        },
        Case {
            name: "cuticle layers l at bounds (1e-6)",
            base: with(MID, &[(9, 1e-6)]),
        },
        Case {
            name: "cuticle layers l = 10, g -> +-1",
            base: with(MID, &[(9, 10.0), (8, 0.999_999)]),
        },
        Case {
            name: "no absorption, kappa = 0 (human-like clear fiber)",
            base: with(MID, &[(1, 0.0), (5, 0.0), (6, 0.0), (7, 0.0)]),
        },
    ]
}

/// Variations crossed with every case: other parameters at/near their hard bounds.
/// (`alpha` and `beta_m` only enter `M_p`, not the far-field `N_p`, so they are not varied.)
fn variations(base: [f64; 10]) -> Vec<[f64; 10]> {
    let mut out = Vec::new();
    for &bn in &[None, Some(0.1), Some(90.0)] {
        for &eta in &[None, Some(1.0 + 1e-9), Some(3.0)] {
            for &l in &[None] {
                for &sca in &[None, Some(1e3)] {
                    let mut v = base;
                    if let Some(b) = bn {
                        v[4] = b;
                    }
                    if let Some(e) = eta {
                        v[0] = e;
                    }
                    if let Some(l) = l {
                        v[9] = l;
                    }
                    if let Some(x) = sca {
                        v[5] = x;
                    }
                    out.push(v);
                }
            }
        }
    }
    out.dedup();
    out
}

/// theta_d values (degrees) of the sweep, including grazing.
const THETA_D: [f64; 5] = [-89.0, 0.0, 20.0, 60.0, 89.0];
const N_PHI: usize = 73;
/// Reference subset: first variations per case, theta_d values, phi per pair.
const REF_VARIATIONS: usize = 1;
const REF_THETA_D: [f64; 2] = [0.0, 89.0];
const REF_PHI: usize = 16;

#[derive(Default, Clone)]
struct CaseResult {
    evals: usize,
    nonfinite: usize,
    neg_raw: usize,
    neg: usize,
    worst_dip: f64,
    errs_tol: Vec<f64>,
    errs_paper: Vec<f64>,
    seconds: f64,
}

fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn run_case(case: &Case) -> CaseResult {
    let t0 = std::time::Instant::now();
    let vars = variations(case.base);
    let modes = [FarOptions::default(), FarOptions::paper()];
    let phis: Vec<f64> = (0..N_PHI)
        .map(|k| -PI + 2.0 * PI * k as f64 / (N_PHI - 1) as f64)
        .collect();
    // NaN / Inf / negative sweep over all variations x theta_d x phi x both modes.
    let parts: Vec<CaseResult> = vars
        .par_iter()
        .map(|v| {
            let mut r = CaseResult::default();
            let p = match FurParams::from_file_units(*v) {
                Ok(p) => p,
                Err(_) => return r,
            };
            let m = FurModel::new(&p);
            for td in THETA_D {
                let az = m.azimuthal(td.to_radians());
                for opts in &modes {
                    let fs = az.far_slice(LobeSet::ALL, opts);
                    let mut peak = [0.0f64; 5];
                    let mut dips = [0.0f64; 5];
                    for &phi in &phis {
                        let raw = fs.eval_raw(phi);
                        let val = fs.eval(phi);
                        for i in 0..5 {
                            r.evals += 1;
                            if !raw.0[i].is_finite() || !val.0[i].is_finite() {
                                r.nonfinite += 1;
                                continue;
                            }
                            if raw.0[i] < 0.0 {
                                r.neg_raw += 1;
                                dips[i] = dips[i].max(-raw.0[i]);
                            }
                            if val.0[i] < 0.0 {
                                r.neg += 1;
                            }
                            peak[i] = peak[i].max(val.0[i]);
                        }
                    }
                    for i in 0..5 {
                        if dips[i] > 0.0 {
                            let rel = if peak[i] > 0.0 {
                                dips[i] / peak[i]
                            } else {
                                1.0
                            };
                            r.worst_dip = r.worst_dip.max(rel);
                        }
                    }
                }
            }
            r
        })
        .collect();
    let mut res = CaseResult::default();
    for p in parts {
        res.evals += p.evals;
        res.nonfinite += p.nonfinite;
        res.neg_raw += p.neg_raw;
        res.neg += p.neg;
        res.worst_dip = res.worst_dip.max(p.worst_dip);
    }
    // Accuracy against the reference on a subset.
    let subset: Vec<(usize, f64)> = vars
        .iter()
        .take(REF_VARIATIONS)
        .enumerate()
        .flat_map(|(k, _)| REF_THETA_D.iter().map(move |&td| (k, td)))
        .collect();
    let errs: Vec<(Vec<f64>, Vec<f64>)> = subset
        .par_iter()
        .map(|&(k, td)| {
            let (mut et, mut ep) = (Vec::new(), Vec::new());
            let p = match FurParams::from_file_units(vars[k]) {
                Ok(p) => p,
                Err(_) => return (et, ep),
            };
            let m = FurModel::new(&p);
            let az = m.azimuthal(td.to_radians());
            let fs_t = az.far_slice(LobeSet::ALL, &modes[0]);
            let fs_p = az.far_slice(LobeSet::ALL, &modes[1]);
            let mut rows = Vec::new();
            for j in 0..REF_PHI {
                let phi = -PI + 2.0 * PI * (j as f64 + 0.37) / REF_PHI as f64;
                rows.push((
                    az.far_reference(phi, LobeSet::ALL),
                    fs_t.eval(phi),
                    fs_p.eval(phi),
                ));
            }
            for i in 0..5 {
                let peak = rows.iter().map(|r| r.0 .0[i]).fold(0.0, f64::max);
                if peak <= 0.0 {
                    continue;
                }
                for r in &rows {
                    et.push((r.1 .0[i] - r.0 .0[i]).abs() / peak);
                    ep.push((r.2 .0[i] - r.0 .0[i]).abs() / peak);
                }
            }
            (et, ep)
        })
        .collect();
    for (a, b) in errs {
        res.errs_tol.extend(a);
        res.errs_paper.extend(b);
    }
    res.seconds = t0.elapsed().as_secs_f64();
    res
}

/// Run the adversarial sweep and write `stability.md` / `stability.csv` into `out`.
pub fn run(out: &Path, log: &mut dyn FnMut(&str)) -> crate::Result<StabilitySummary> {
    let t0 = std::time::Instant::now();
    let mut csv = String::from(
        "case,evaluations,nan_inf,negative,negative_before_clamp,worst_dip_rel_peak,\
         ref_samples,tol_max_err,tol_median_err,paper_max_err,paper_median_err,seconds\n",
    );
    let mut md = String::new();
    let mut sum = StabilitySummary::default();
    let mut rows = Vec::new();
    for case in cases() {
        let mut r = run_case(&case);
        let n_ref = r.errs_tol.len();
        let tmax = r.errs_tol.iter().cloned().fold(0.0, f64::max);
        let tmed = median(&mut r.errs_tol);
        let pmax = r.errs_paper.iter().cloned().fold(0.0, f64::max);
        let pmed = median(&mut r.errs_paper);
        log(&format!(
            "{:<48} evals {:>8}  NaN/Inf {}  neg {} (raw {})  tol max {:.2e} med {:.2e}  paper max {:.2e} med {:.2e}  ({:.1} s)",
            case.name, r.evals, r.nonfinite, r.neg, r.neg_raw, tmax, tmed, pmax, pmed, r.seconds
        ));
        let _ = writeln!(
            csv,
            "\"{}\",{},{},{},{},{:.3e},{},{:.3e},{:.3e},{:.3e},{:.3e},{:.2}",
            case.name,
            r.evals,
            r.nonfinite,
            r.neg,
            r.neg_raw,
            r.worst_dip,
            n_ref,
            tmax,
            tmed,
            pmax,
            pmed,
            r.seconds
        );
        sum.n_evaluations += r.evals;
        sum.n_nonfinite += r.nonfinite;
        sum.n_negative += r.neg;
        sum.n_negative_raw += r.neg_raw;
        rows.push((case.name, r, n_ref, tmax, tmed, pmax, pmed));
    }
    let secs = t0.elapsed().as_secs_f64();
    let _ = writeln!(md, "# Far-field stability report\n");
    let _ = writeln!(
        md,
        "Generated by `furfit stability --out {}` (furfit {}) in {:.0} s on {} threads.\n",
        out.display(),
        env!("CARGO_PKG_VERSION"),
        secs,
        rayon::current_num_threads()
    );
    let _ = writeln!(
        md,
        "Each stiff case is crossed with {} variations of the other parameters at or near \
         their hard bounds (beta_n in {{case, 0.1, 90}} deg, eta in {{case, 1 + 1e-9, 3}}, \
         sigma_c_a in {{case, 1e3}}; alpha and beta_m do not enter N_p), \
         theta_d in {:?} deg and {} phi in [-180, 180] deg, in both the default mode \
         (tol 1e-4, initial 8/5 segments) and the paper's fixed 8/5 mode; every lobe value \
         counts as one evaluation.\n",
        variations(MID).len(),
        THETA_D,
        N_PHI
    );
    let _ = writeln!(
        md,
        "Accuracy is measured against the adaptive Gauss-Kronrod reference (~1e-10) on the \
         first {} variations x theta_d {:?} x {} phi per case; the error of a sample is \
         |far - ref| / (peak over phi of ref) for that theta_d and lobe.\n",
        REF_VARIATIONS, REF_THETA_D, REF_PHI
    );
    let _ = writeln!(
        md,
        "**Totals: {} evaluations, {} NaN/Inf, {} negative returned values** \
         ({} negative before clamping rounding-level dips of the quadratic fits to 0; \
         the worst such dip per case is listed relative to the lobe's peak).\n",
        sum.n_evaluations, sum.n_nonfinite, sum.n_negative, sum.n_negative_raw
    );
    let _ = writeln!(
        md,
        "| case | evaluations | NaN/Inf | negative (raw) | worst dip / peak | ref samples | tol max err | tol median | paper 8/5 max err | paper median |"
    );
    let _ = writeln!(md, "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for (name, r, n_ref, tmax, tmed, pmax, pmed) in &rows {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} ({}) | {:.1e} | {} | {:.2e} | {:.2e} | {:.2e} | {:.2e} |",
            name,
            r.evals,
            r.nonfinite,
            r.neg,
            r.neg_raw,
            r.worst_dip,
            n_ref,
            tmax,
            tmed,
            pmax,
            pmed
        );
    }
    std::fs::create_dir_all(out).map_err(|e| crate::Error::io(out, e))?;
    crate::io::write_atomic(&out.join("stability.csv"), csv.as_bytes())?;
    crate::io::write_atomic(&out.join("stability.md"), md.as_bytes())?;
    log(&format!(
        "total: {} evaluations, {} NaN/Inf, {} negative ({} before clamp) in {:.1} s; wrote {}",
        sum.n_evaluations,
        sum.n_nonfinite,
        sum.n_negative,
        sum.n_negative_raw,
        secs,
        out.join("stability.md").display()
    ));
    Ok(sum)
}

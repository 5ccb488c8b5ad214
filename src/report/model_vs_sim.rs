//! `reports/model_vs_simulation.md`: how well the far-field model describes the virtual
//! goniometer's output. Per species folder with a `metadata.json` holding the TRUE
//! parameters (`params`), the NRMSE of the far-field model at those parameters against the
//! simulated profile (with its optimal exposure), the NRMSE of our fit, and fitted vs true
//! parameters side by side. The simulator is an independent 3-D Monte Carlo, so a large
//! NRMSE at the true parameters measures model error, not a bug in either; the table
//! reports it as it comes out.

use super::nrmse::FitFile;
use crate::error::Result;
use crate::fit::forward::{predict_points, Points};
use crate::fit::problem::nrmse;
use crate::model::far::FarOptions;
use crate::model::LobeSet;
use crate::params::{FurParams, ParamId};
use crate::profile::Profile;
use std::fmt::Write as _;
use std::path::Path;

/// True parameters from `measurements/<species>/metadata.json` (`params` object).
pub fn true_params(species_dir: &Path) -> Result<Option<FurParams>> {
    let p = species_dir.join("metadata.json");
    if !p.exists() {
        return Ok(None);
    }
    let v = crate::io::read_json(&p)?;
    match v.get("params") {
        Some(obj) => Ok(Some(FurParams::from_json_value(obj)?.0)),
        None => Ok(None),
    }
}

/// NRMSE (MODEL.md, optimal exposure) of the far-field model at `params` on channel
/// `channel` of `profile`. Returns `(nrmse, exposure, n_valid)`.
pub fn nrmse_at(
    params: &FurParams,
    profile: &Profile,
    channel: usize,
) -> Option<(f64, f64, usize)> {
    let mut pts = Points::default();
    let mut ln_y = Vec::new();
    for s in profile
        .samples
        .iter()
        .filter(|s| s.channel == channel && s.is_valid())
    {
        let (a, b, c) = s.angles_rad();
        pts.push(a, b, c);
        ln_y.push(s.value.ln());
    }
    if ln_y.is_empty() {
        return None;
    }
    let lo = ln_y.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = ln_y.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let range = if hi > lo { hi - lo } else { 1.0 };
    let mut m = vec![0.0; pts.len()];
    predict_points(params, &pts, &FarOptions::default(), LobeSet::ALL, &mut m);
    let (e, k) = nrmse(&m, &ln_y, range);
    Some((e, k, ln_y.len()))
}

/// One species' entry.
pub struct Entry {
    pub species: String,
    pub truth: FurParams,
    pub nrmse_truth: f64,
    pub exposure_truth: f64,
    pub n_valid: usize,
    pub fit: Option<FitFile>,
}

/// The Markdown report.
pub fn markdown(entries: &[Entry]) -> String {
    let mut s = String::from("# Far-field model vs the virtual goniometer\n\n");
    let _ = writeln!(
        s,
        "Data: SYNTHETIC profiles from the independent Monte Carlo virtual goniometer \
         (`measurements/<species>/`, true parameters in its `metadata.json`). \
         \"NRMSE at truth\" evaluates the far-field model (tolerance mode, 1e-4 of each \
         lobe's peak, as `furfit fit` uses by default) at the TRUE \
         parameters with the optimal exposure: it is the model's own error against this \
         simulation. A fit usually does better by moving parameters away from the truth to \
         absorb that error, which is why fitted and true values differ. \
         \"NRMSE of fit\" is from `fits/<species>.json` when that fit was made from this \
         folder. SE is the fit's linearised standard error, s^2 (J^T J)^-1: it assumes \
         independent residuals, but here they are mostly model error, correlated between \
         neighbouring samples, so it understates the real spread, most on shallow \
         directions (equally good fits can differ by more than one SE there).\n"
    );
    if entries.is_empty() {
        s.push_str("No species folder with a metadata.json `params` object was found.\n");
        return s;
    }
    s.push_str(
        "| species | valid samples | NRMSE at truth | NRMSE of fit |\n|---|---:|---:|---:|\n",
    );
    for e in entries {
        let _ = writeln!(
            s,
            "| {} | {} | {:.2}% | {} |",
            e.species,
            e.n_valid,
            100.0 * e.nrmse_truth,
            e.fit
                .as_ref()
                .map(|f| format!("{:.2}%", 100.0 * f.nrmse))
                .unwrap_or_else(|| "(no fit of this data)".into())
        );
    }
    for e in entries {
        let _ = writeln!(s, "\n## {}\n", e.species);
        s.push_str("| parameter | unit | true | fitted | SE | fitted - true |\n|---|---|---:|---:|---:|---:|\n");
        let t = e.truth.to_file_units();
        for id in ParamId::ALL {
            let k = id.index();
            let (fv, se, d) = match &e.fit {
                Some(f) => {
                    let v = f.params.to_file_units()[k];
                    let flag = if f.unconstrained.iter().any(|u| u == id.spec().name) {
                        " (unconstrained)"
                    } else {
                        ""
                    };
                    (
                        format!("{v:.4}"),
                        f.se[k]
                            .map(|x| format!("{x:.3}{flag}"))
                            .unwrap_or_else(|| format!("-{flag}")),
                        format!("{:+.4}", v - t[k]),
                    )
                }
                None => ("-".into(), "-".into(), "-".into()),
            };
            let _ = writeln!(
                s,
                "| {} | {} | {:.4} | {fv} | {se} | {d} |",
                id.spec().name,
                id.spec().unit,
                t[k]
            );
        }
        let _ = writeln!(s, "\nExposure at truth: {:.4e}.", e.exposure_truth);
    }
    s
}

//! The stability sweep for every registered model other than the fur model (whose own,
//! deeper sweep is [`super::stability`]): each parameter in turn at the two ends the fitter
//! can reach (its map at `u = -U_MAX` and `+U_MAX`: roughness -> 0 and its maximum, eta ->
//! 1, absorption ~1e-13 and ~1e13, ...), all parameters at their low ends and at their high
//! ends together, from each of the model's presets, evaluated by
//! [`crate::models::FiberModel::predict`] on a `theta_i x theta_r x phi` grid with grazing
//! inclinations (+-89.9 deg) in the tolerance mode and the fixed rule, and checked for NaN,
//! Inf and negative values.

use crate::model::far::FarOptions;
use crate::model::LobeSet;
use crate::models::{FiberModel, Integral, ModelParams, Points, U_MAX};
use std::fmt::Write as _;

/// Inclinations of the sweep (degrees): grazing at both ends.
const THETA: [f64; 9] = [-89.9, -75.0, -45.0, -15.0, 0.0, 15.0, 45.0, 75.0, 89.9];
/// `phi` points over [-180, 180] degrees.
const N_PHI: usize = 73;

/// One case's counts.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Counts {
    /// Model evaluations made.
    pub evaluations: usize,
    /// Evaluations that were not finite.
    pub nonfinite: usize,
    /// Evaluations below zero.
    pub negative: usize,
}

/// A named parameter vector (file units) of `model`.
pub struct Case {
    /// The case's name in the report.
    pub name: String,
    /// The parameters, file units, in the model's order.
    pub file: Vec<f64>,
}

/// The stiff cases of `model` (see the module doc).
pub fn cases(model: &'static dyn FiberModel) -> Vec<Case> {
    let n = model.specs().len();
    let end = |i: usize, u: f64| model.map(i).to_value(u);
    let mut out = Vec::new();
    for p in model.presets() {
        for i in 0..n {
            for (side, u) in [("low", -U_MAX), ("high", U_MAX)] {
                let mut file = p.values.to_vec();
                file[i] = end(i, u);
                out.push(Case {
                    name: format!(
                        "{}: {} {side} ({})",
                        p.name,
                        model.specs()[i].name,
                        crate::error::Num(file[i])
                    ),
                    file,
                });
            }
        }
        for (side, u) in [("low", -U_MAX), ("high", U_MAX)] {
            out.push(Case {
                name: format!("{}: every parameter {side}", p.name),
                file: (0..n).map(|i| end(i, u)).collect(),
            });
        }
    }
    out
}

/// Evaluate one case in both far-field modes on the sweep's grid.
pub fn sweep(model: &'static dyn FiberModel, case: &Case) -> crate::Result<Counts> {
    let p = ModelParams::from_file_units(model, &case.file)?;
    let phi: Vec<f64> = (0..N_PHI)
        .map(|k| -180.0 + 360.0 * k as f64 / (N_PHI - 1) as f64)
        .collect();
    let pts = Points::grid_degrees(&THETA, &THETA, &phi);
    let mut c = Counts::default();
    for far in [FarOptions::default(), FarOptions::paper()] {
        let pred = model.predict(&p.values, &pts, &far, LobeSet::ALL, Integral::Far);
        for l in &pred.lobes {
            for &v in &l.0[..model.lobe_names().len()] {
                c.evaluations += 1;
                if !v.is_finite() {
                    c.nonfinite += 1;
                } else if v < 0.0 {
                    c.negative += 1;
                }
            }
        }
    }
    Ok(c)
}

/// Sweep every registered model but the default; returns the Markdown section, the CSV
/// rows (`model,case,evaluations,nan_inf,negative`) and the totals.
pub fn run(log: &mut dyn FnMut(&str)) -> crate::Result<(String, String, Counts)> {
    let mut md = String::new();
    let mut csv = String::from("model,case,evaluations,nan_inf,negative\n");
    let mut total = Counts::default();
    let others: Vec<_> = crate::models::MODELS
        .iter()
        .copied()
        .filter(|m| m.name() != crate::models::default_model().name())
        .collect();
    if others.is_empty() {
        return Ok((md, csv, total));
    }
    let _ = writeln!(md, "## Other models\n");
    let _ = writeln!(
        md,
        "Each parameter in turn at the two ends the fitter can reach (its solver map at \
         u = -{U_MAX} and +{U_MAX}), and every parameter at its low and at its high end \
         together, from each preset of the model; evaluated on theta_i x theta_r in {THETA:?} \
         deg x {N_PHI} phi in [-180, 180] deg, in the tolerance mode (1e-4) and the fixed \
         rule, every lobe value one evaluation.\n"
    );
    let _ = writeln!(
        md,
        "| model | cases | evaluations | NaN/Inf | negative | seconds |"
    );
    let _ = writeln!(md, "|---|---:|---:|---:|---:|---:|");
    for m in others {
        let t = std::time::Instant::now();
        let mut sum = Counts::default();
        let cases = cases(m);
        for case in &cases {
            let c = sweep(m, case)?;
            let _ = writeln!(
                csv,
                "{},\"{}\",{},{},{}",
                m.name(),
                case.name.replace('"', "'"),
                c.evaluations,
                c.nonfinite,
                c.negative
            );
            if c.nonfinite + c.negative > 0 {
                log(&format!(
                    "{}: {}: {} NaN/Inf, {} negative",
                    m.name(),
                    case.name,
                    c.nonfinite,
                    c.negative
                ));
            }
            sum.evaluations += c.evaluations;
            sum.nonfinite += c.nonfinite;
            sum.negative += c.negative;
        }
        let secs = t.elapsed().as_secs_f64();
        log(&format!(
            "{}: {} cases, {} evaluations, {} NaN/Inf, {} negative ({secs:.1} s)",
            m.name(),
            cases.len(),
            sum.evaluations,
            sum.nonfinite,
            sum.negative
        ));
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {secs:.1} |",
            m.name(),
            cases.len(),
            sum.evaluations,
            sum.nonfinite,
            sum.negative
        );
        total.evaluations += sum.evaluations;
        total.nonfinite += sum.nonfinite;
        total.negative += sum.negative;
    }
    md.push('\n');
    Ok((md, csv, total))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The cases reach each parameter's ends and stay valid parameter sets.
    #[test]
    fn cases_are_valid_and_reach_the_ends() {
        for m in crate::models::MODELS {
            let cases = cases(m);
            assert_eq!(
                cases.len(),
                m.presets().len() * (2 * m.specs().len() + 2),
                "{}",
                m.name()
            );
            for c in &cases {
                ModelParams::from_file_units(m, &c.file).unwrap();
            }
        }
    }
}

//! `reports/model_vs_simulation.md`: how well the far-field model describes the data (for
//! the shipped species, the virtual goniometer's output). Per species folder with a
//! `metadata.json` holding the TRUE parameters (`params`), the NRMSE of the far-field model
//! at those parameters against the simulated profile (with its optimal exposure, on the
//! samples the fit used and with the far field it used: [`truth_settings`]), the NRMSE of
//! our fit, and fitted vs true parameters side by side. The simulator is an independent
//! 3-D Monte Carlo, so a large NRMSE at the true parameters measures model error, not a bug
//! in either; the table reports it as it comes out.

use super::sig;
use crate::error::{Error, Result};
use crate::fit::file::FitFile;

use crate::params::{FurParams, ParamId};

use std::fmt::Write as _;
use std::path::Path;

/// True parameters from `measurements/<species>/metadata.json` (`params`: a parameter
/// object or a preset name), with the file's description of the data (`what`, else
/// `source`), or `None` when the file or its `params` is absent. Errors name the file and
/// the key.
pub fn true_params(species_dir: &Path) -> Result<Option<(FurParams, Option<String>)>> {
    let p = species_dir.join(crate::profile::provenance::FOLDER_METADATA);
    if !p.exists() {
        return Ok(None);
    }
    let v = crate::io::read_json(&p)?;
    let truth = match v.get("params") {
        None => return Ok(None),
        // A preset name, or a parameter/fit file (relative to the folder), as --params.
        Some(serde_json::Value::String(name)) => match FurParams::preset(name) {
            Some(t) => t,
            None if species_dir.join(name).is_file() => {
                let file = species_dir.join(name);
                FurParams::load(&file.to_string_lossy())
                    .map_err(|e| Error::file(&p, format!("key 'params': {e}")))?
                    .0
            }
            None => {
                return Err(Error::file(
                    &p,
                    format!(
                        "key 'params': '{name}' is neither a preset ({}) nor a parameter or \
                         fit file in {}",
                        crate::params::preset_names().join(", "),
                        species_dir.display()
                    ),
                ))
            }
        },
        Some(obj) => {
            FurParams::from_json_value(obj)
                .map_err(|e| Error::file(&p, format!("key 'params': {e}")))?
                .0
        }
    };
    let what = ["what", "source"]
        .iter()
        .find_map(|k| v.get(*k).and_then(|w| w.as_str()))
        .map(str::to_string);
    Ok(Some((truth, what)))
}

pub use crate::fit::file::{nrmse_at, truth_settings, TruthNrmse};

/// One species' entry.
pub struct Entry {
    /// The species (its `measurements/` folder name).
    pub species: String,
    /// The channel compared, for a profile with named channels.
    pub channel: Option<String>,
    /// Whether the data are labelled synthetic (the profile or its folder's metadata.json).
    pub synthetic: bool,
    /// What the data are (metadata.json `what`/`source`, else the data's label).
    pub data: String,
    /// The parameters the data were simulated at.
    pub truth: FurParams,
    /// At the truth, on the fit's samples with its far field ([`truth_settings`]).
    pub at_truth: TruthNrmse,
    /// The species' fit, if there is one.
    pub fit: Option<FitFile>,
    /// Why the species' fit is not shown (its data changed since), if so.
    pub fit_note: Option<String>,
}

impl Entry {
    /// The species, with the channel compared when the data name channels.
    fn name(&self) -> String {
        match &self.channel {
            Some(c) => format!("{} [channel {c}]", self.species),
            None => self.species.clone(),
        }
    }
}

/// What the compared data are, from the rows' own labels (a folder of lab data read by
/// `report` is not simulated); empty when nothing was compared.
fn data_clause(entries: &[Entry]) -> &'static str {
    let n_syn = entries.iter().filter(|e| e.synthetic).count();
    if entries.is_empty() {
        ""
    } else if n_syn == entries.len() {
        "; the data compared here are SYNTHETIC (simulated profiles, labelled synthetic in \
         their files or their folder's `metadata.json`), not measurements"
    } else if n_syn == 0 {
        "; the data compared here are not marked synthetic (treated as measured: none is \
         labelled synthetic, which does not show that they were measured)"
    } else {
        "; the data compared here are a MIX of SYNTHETIC (simulated) profiles and profiles \
         not marked synthetic (treated as measured; the `data` column says which)"
    }
}

/// How many fitted parameters with a standard error lie within two of them of the truth,
/// for the plain and the robust errors (measured on the entries shown, not assumed).
fn coverage_line(entries: &[Entry]) -> String {
    let (mut n, mut plain, mut n_rob, mut rob) = (0, 0, 0, 0);
    for e in entries {
        let Some(f) = &e.fit else { continue };
        let (v, t) = (f.params.typed_file_units(), e.truth.typed_file_units());
        for id in ParamId::ALL {
            let k = id.index();
            if f.unconstrained.iter().any(|u| u == id.spec().name) {
                continue;
            }
            let d = (v[k] - t[k]).abs();
            if let Some(se) = f.se[k] {
                n += 1;
                plain += usize::from(d <= 2.0 * se);
            }
            if let Some(se) = f.se_robust[k] {
                n_rob += 1;
                rob += usize::from(d <= 2.0 * se);
            }
        }
    }
    format!(
        "Truth within two standard errors of the fit (parameters not flagged unconstrained): \
         {plain} of {n} with SE, {rob} of {n_rob} with robust SE. With no model error about \
         95 % would be."
    )
}

/// [`sig`] with a sign (`+` for positive differences).
fn sig_signed(x: f64, digits: usize) -> String {
    let s = sig(x, digits);
    if x > 0.0 && x.is_finite() {
        format!("+{s}")
    } else {
        s
    }
}

/// The Markdown report; `unusable` lists the species folders whose true parameters or data
/// could not be read, with why.
pub fn markdown(entries: &[Entry], unusable: &[(String, String)]) -> String {
    let mut s = format!(
        "# Far-field model at the true parameters vs the data\n\nWritten by `furfit report` \
         ({}).\n\n",
        crate::TOOL_VERSION
    );
    let _ = writeln!(
        s,
        "Data: each species folder whose `metadata.json` records the true parameters \
         (`params`){}, and each row says what its data are. \
         \"NRMSE at truth\" evaluates the far-field model at the TRUE parameters with the \
         optimal exposure, on the samples the fit used (valid and at least its `data.floor` \
         x the channel's largest valid value, normalised by their log range) with the far \
         field the fit recorded (`solver.tol`, `solver.segments`, `solver.scattered_step`), \
         so both NRMSE columns cover the same samples with the same model; without a fit of \
         this data, with `furfit fit`'s defaults (floor {}, tolerance mode at 1e-4 of each \
         lobe's peak). It is the model's own error against these data. A fit usually does better by moving parameters away from the truth to \
         absorb that error, which is why fitted and true values differ. \
         \"NRMSE of fit\" is from `fits/<species>.json` when that fit was made from this \
         folder's current data. SE is the fit's linearised standard error, s^2 (J^T J)^-1: it assumes \
         independent residuals, but here they are mostly model error, correlated between \
         neighbouring samples, so it understates the real spread, most on shallow \
         directions (equally good fits can differ by more than one SE there). \
         \"robust SE\" (`uncertainty.robust` of the fit) allows residuals correlated along \
         phi and between neighbouring theta_r rows (a row-clustered Newey-West sandwich), \
         so it is the one to read when residuals are correlated; it is local too, and says \
         nothing of shallow valleys or other optima. Neither covers the \
         model's error, which is a bias: fitted - true can exceed both by far, as the \
         count below shows.\n",
        data_clause(entries),
        crate::error::Num(crate::fit::DEFAULT_FLOOR)
    );
    for (species, why) in unusable {
        let _ = writeln!(s, "- {species}: not compared: {why}");
    }
    if !unusable.is_empty() {
        s.push('\n');
    }
    if entries.is_empty() {
        s.push_str(if unusable.is_empty() {
            "No species folder with a metadata.json `params` entry was found.\n"
        } else {
            "No species folder could be compared (see above).\n"
        });
        return s;
    }
    s.push_str(
        "| species | data | samples used | NRMSE at truth | NRMSE of fit |\n|---|---|---:|---:|---:|\n",
    );
    for e in entries {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.2}% | {} |",
            e.name(),
            if e.synthetic {
                "SYNTHETIC"
            } else {
                "not marked synthetic"
            },
            match e.at_truth.n_below_floor {
                0 => e.at_truth.n_used.to_string(),
                b => format!("{} ({b} below the floor left out)", e.at_truth.n_used),
            },
            100.0 * e.at_truth.nrmse,
            match (&e.fit, &e.fit_note) {
                (Some(f), _) => format!("{:.2}%", 100.0 * f.nrmse),
                (None, Some(_)) => "(the data changed since the fit: refit)".into(),
                (None, None) => "(no fit of this data)".into(),
            }
        );
    }
    // A fit whose file recorded another NRMSE than its parameters give (nrmse.md says so
    // too): the column shows the recomputed one.
    for note in entries
        .iter()
        .filter_map(|e| e.fit.as_ref().and_then(|f| f.nrmse_note()))
    {
        let _ = writeln!(s, "\nNote: {note}.");
    }
    let _ = writeln!(s, "\n{}", coverage_line(entries));
    for e in entries {
        let _ = writeln!(
            s,
            "\n## {}\n\nData: {} ({})\n",
            e.name(),
            if e.synthetic {
                "SYNTHETIC"
            } else {
                "not marked synthetic, treated as measured"
            },
            e.data
        );
        if let Some(n) = &e.fit_note {
            let _ = writeln!(s, "Fit not shown: {n}\n");
        }
        s.push_str("| parameter | unit | true | fitted | SE | robust SE | fitted - true |\n|---|---|---:|---:|---:|---:|---:|\n");
        let t = e.truth.typed_file_units();
        for id in ParamId::ALL {
            let k = id.index();
            let (fv, se, rse, d) = match &e.fit {
                Some(f) => {
                    let v = f.params.typed_file_units()[k];
                    let flag = if f.unconstrained.iter().any(|u| u == id.spec().name) {
                        " (unconstrained)"
                    } else {
                        ""
                    };
                    (
                        id.spec().fixed_text(v, 4),
                        f.se[k]
                            .map(|x| format!("{}{flag}", sig(x, 2)))
                            .unwrap_or_else(|| format!("-{flag}")),
                        f.se_robust[k].map_or_else(|| "-".into(), |x| sig(x, 2)),
                        sig_signed(v - t[k], 2),
                    )
                }
                None => ("-".into(), "-".into(), "-".into(), "-".into()),
            };
            let _ = writeln!(
                s,
                "| {} | {} | {:.4} | {fv} | {se} | {rse} | {d} |",
                id.spec().name,
                id.spec().unit,
                t[k]
            );
        }
        let _ = writeln!(s, "\nExposure at truth: {:.4e}.", e.at_truth.exposure);
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::forward::predict_points;
    use crate::model::far::FarOptions;
    use crate::model::LobeSet;

    fn coverage_line_of(md: &str) -> &str {
        md.lines()
            .find(|l| l.starts_with("Truth within"))
            .unwrap_or("")
    }

    /// NRMSE `nrmse` at truth on 10 samples, none below the floor, exposure 1.
    fn at_truth(nrmse: f64) -> TruthNrmse {
        TruthNrmse {
            nrmse,
            exposure: 1.0,
            n_used: 10,
            n_below_floor: 0,
        }
    }

    /// `params` may name a preset (as `--params` does); a bad entry is an error naming
    /// the metadata file and the key; the data's description comes from `what`/`source`.
    #[test]
    fn true_params_from_preset_names_objects_and_errors() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = tmp.path();
        let write = |text: &str| std::fs::write(dir.join("metadata.json"), text).unwrap();
        assert!(true_params(dir).unwrap().is_none());
        write(r#"{"params": "deer", "source": "synthetic: furfit synth + 3 % noise"}"#);
        let (p, what) = true_params(dir).unwrap().unwrap();
        assert_eq!(p, FurParams::preset("deer").unwrap());
        assert_eq!(what.as_deref(), Some("synthetic: furfit synth + 3 % noise"));
        let obj = FurParams::preset("mouse").unwrap().to_json_value();
        write(&serde_json::json!({"params": obj, "what": "lab data"}).to_string());
        let (p, what) = true_params(dir).unwrap().unwrap();
        assert_eq!(p, FurParams::preset("mouse").unwrap());
        assert_eq!(what.as_deref(), Some("lab data"));
        // A parameter file beside it, named relative to the folder.
        std::fs::write(dir.join("truth.json"), obj.to_string()).unwrap();
        write(r#"{"params": "truth.json"}"#);
        assert_eq!(
            true_params(dir).unwrap().unwrap().0,
            FurParams::preset("mouse").unwrap()
        );
        write(r#"{"params": "unicorn"}"#);
        let e = true_params(dir).unwrap_err().to_string();
        assert!(
            e.contains("metadata.json") && e.contains("'params'") && e.contains("unicorn"),
            "{e}"
        );
        write(r#"{"params": [1, 2]}"#);
        let e = true_params(dir).unwrap_err().to_string();
        assert!(e.contains("metadata.json") && e.contains("'params'"), "{e}");
        write(r#"{"what": "no truth here"}"#);
        assert!(true_params(dir).unwrap().is_none());
    }

    /// A folder whose truth could not be read is listed as such, not as "none found";
    /// the compared channel is named.
    #[test]
    fn markdown_lists_unusable_folders_and_names_the_channel() {
        let md = markdown(&[], &[("deer".into(), "bad params".into())]);
        assert!(md.contains("- deer: not compared: bad params"), "{md}");
        assert!(!md.contains("was found"), "{md}");
        assert!(markdown(&[], &[]).contains("No species folder with a metadata.json"));
        let e = Entry {
            species: "fur".into(),
            channel: Some("g".into()),
            synthetic: true,
            data: "synthetic, noisy".into(),
            truth: FurParams::preset("cat").unwrap(),
            at_truth: at_truth(0.01),
            fit: None,
            fit_note: Some("changed".into()),
        };
        let md = markdown(&[e], &[]);
        assert!(
            md.contains("| fur [channel g] | SYNTHETIC | 10 | 1.00% | (the data changed since the fit: refit) |"),
            "{md}"
        );
        assert!(md.contains("Fit not shown: changed"), "{md}");
        assert!(md.contains("Data: SYNTHETIC (synthetic, noisy)"), "{md}");
    }

    /// The introduction says what the rows' data are: lab data are not called the
    /// virtual goniometer's synthetic profiles (the wording was fixed).
    #[test]
    fn markdown_describes_the_data_it_read() {
        let entry = |species: &str, synthetic: bool| Entry {
            species: species.into(),
            channel: None,
            synthetic,
            data: "x".into(),
            truth: FurParams::preset("cat").unwrap(),
            at_truth: at_truth(0.01),
            fit: None,
            fit_note: None,
        };
        let intro = |entries: &[Entry]| {
            let md = markdown(entries, &[]);
            assert!(!md.contains("goniometer"), "{md}");
            md.lines()
                .find(|l| l.starts_with("Data:"))
                .unwrap()
                .to_string()
        };
        let lab = intro(&[entry("lab", false)]);
        assert!(
            lab.contains(
                "(`params`); the data compared here are not marked synthetic (treated as measured: \
                 none is labelled synthetic, which does not show that they were measured), and"
            ),
            "{lab}"
        );
        assert!(!lab.contains("SYNTHETIC"), "{lab}");
        // Rows and sections of unlabelled data do not call them measured either.
        let md = markdown(&[entry("lab", false)], &[]);
        assert!(
            md.contains("| lab | not marked synthetic | 10 | 1.00% |"),
            "{md}"
        );
        assert!(
            md.contains("Data: not marked synthetic, treated as measured (x)"),
            "{md}"
        );
        let sim = intro(&[entry("a", true), entry("b", true)]);
        assert!(
            sim.contains("the data compared here are SYNTHETIC (simulated profiles"),
            "{sim}"
        );
        let mix = intro(&[entry("a", true), entry("lab", false)]);
        assert!(
            mix.contains(
                "a MIX of SYNTHETIC (simulated) profiles and profiles not marked synthetic \
                 (treated as measured;"
            ),
            "{mix}"
        );
        let none = intro(&[]);
        assert!(none.contains("(`params`), and each row"), "{none}");
    }

    /// "NRMSE at truth" takes the fit's floor and far field, so it covers what the fit's
    /// NRMSE covers; without a fit, `furfit fit`'s defaults; a fit file from before the
    /// floor, every valid sample.
    #[test]
    fn truth_settings_follow_the_fit() {
        let tmp = tempfile::tempdir().unwrap();
        let read = |name: &str, extra: serde_json::Value| {
            let mut v = serde_json::json!({
                "params": FurParams::preset("cat").unwrap().to_json_value(),
                "exposure": 1.0,
                "nrmse": 0.02,
            });
            v.as_object_mut()
                .unwrap()
                .extend(extra.as_object().unwrap().clone());
            let p = tmp.path().join(format!("{name}.json"));
            std::fs::write(&p, v.to_string()).unwrap();
            FitFile::read(&p).unwrap().remove(0)
        };
        let f = read(
            "fixed",
            serde_json::json!({
                "data": {"floor": 1e-3},
                "solver": {"tol": null, "segments": {"unscattered": 16, "scattered": 7}},
            }),
        );
        let (floor, far) = truth_settings(Some(&f));
        assert_eq!(floor, 1e-3);
        assert_eq!(
            far,
            FarOptions {
                n_unscattered: 16,
                n_scattered: 7,
                tol: None,
                ..FarOptions::default()
            }
        );
        assert_eq!(
            truth_settings(None),
            (crate::fit::DEFAULT_FLOOR, FarOptions::default())
        );
        let old = read("old", serde_json::json!({}));
        assert_eq!(truth_settings(Some(&old)).0, 0.0);
    }

    /// On data made by the far field it is evaluated with, over the samples above the
    /// floor, the NRMSE at truth is zero to rounding; the samples below the floor (here
    /// wildly off the model) are left out and counted, as the fitter leaves them out.
    #[test]
    fn nrmse_at_uses_the_floor_and_the_far_field_given() {
        let truth = FurParams::preset("cat").unwrap();
        let fixed = FarOptions::paper();
        let mut pts = crate::fit::forward::Points::default();
        let mut angles = Vec::new();
        for ti in [-20.0f64, 20.0] {
            for tr in (-3..=3).map(|k| 20.0 * k as f64) {
                for ph in (-11..=12).map(|k| 15.0 * k as f64) {
                    pts.push(ti.to_radians(), tr.to_radians(), ph.to_radians());
                    angles.push((ti, tr, ph));
                }
            }
        }
        let mut m = vec![0.0; pts.len()];
        predict_points(&truth, &pts, &fixed, LobeSet::ALL, &mut m);
        let peak = m.iter().copied().fold(0.0, f64::max);
        let mut prof = crate::Profile::default();
        for (k, (&(ti, tr, ph), &v)) in angles.iter().zip(&m).enumerate() {
            // Five samples twelve decades below the peak: under the default floor.
            let v = if k % 67 == 1 { 1e-12 * peak } else { v };
            prof.samples
                .push(crate::profile::Sample::new(ti, tr, ph, v));
        }
        let n = prof.n_valid();
        let t = nrmse_at(&truth.into(), &prof, 0, 1e-8, &fixed).unwrap();
        assert_eq!((t.n_used, t.n_below_floor), (n - 5, 5));
        // The model's own values: only the rounding of ln and of the closed-form exposure
        // is left (~1e-16); 1e-12 is far below any model difference.
        assert!(t.nrmse < 1e-12, "{}", t.nrmse);
        assert!((t.exposure - 1.0).abs() < 1e-12, "{}", t.exposure);
        // Without the floor the five outliers, 27 nats off, dominate.
        let all = nrmse_at(&truth.into(), &prof, 0, 0.0, &fixed).unwrap();
        assert_eq!((all.n_used, all.n_below_floor), (n, 0));
        assert!(all.nrmse > 0.05, "{}", all.nrmse);
        // Another far field is another model: the tolerance mode is 1.5e-3 off the fixed
        // segmentation's values here; 1e-6 tells it from rounding with room either side.
        let tol = nrmse_at(&truth.into(), &prof, 0, 1e-8, &FarOptions::default()).unwrap();
        assert!(tol.nrmse > 1e-6, "{}", tol.nrmse);
    }

    /// No nonzero standard error or difference prints as zero: two significant digits at
    /// every magnitude (the exact strings, so no tolerance is involved).
    #[test]
    fn se_and_differences_keep_significant_digits() {
        for (x, want) in [
            (0.00034, "0.00034"),
            (0.17425, "0.17"),
            (0.0995, "0.10"),
            (1.0, "1.0"),
            (1234.0, "1200"),
            (3.4e-7, "3.4e-7"),
            (0.0, "0"),
            (f64::NAN, "-"),
        ] {
            assert_eq!(sig(x, 2), want, "{x}");
        }
        assert_eq!(sig_signed(0.0003, 2), "+0.00030");
        assert_eq!(sig_signed(-0.0123, 2), "-0.012");
        // In the report: the audit's eta row, an SE of 0.00034 beside a +0.0003 difference.
        let tmp = tempfile::tempdir().unwrap();
        let truth = FurParams::preset("cat").unwrap();
        let mut params = truth.to_json_value();
        let eta = params["eta"].as_f64().unwrap();
        params["eta"] = serde_json::json!(eta + 0.0003);
        let v = serde_json::json!({
            "params": params,
            "exposure": 1.0,
            "nrmse": 0.02,
            "uncertainty": {
                "standard_error": {"eta": 0.00034, "kappa": 0.0123},
                "robust": {"standard_error": {"eta": 0.0041}},
            },
        });
        let p = tmp.path().join("cat.json");
        std::fs::write(&p, v.to_string()).unwrap();
        let fit = FitFile::read(&p).unwrap().remove(0);
        let e = Entry {
            species: "cat".into(),
            channel: None,
            synthetic: true,
            data: "x".into(),
            truth,
            at_truth: at_truth(0.03),
            fit: Some(fit),
            fit_note: None,
        };
        let md = markdown(&[e], &[]);
        let row = md.lines().find(|l| l.starts_with("| eta |")).unwrap();
        assert!(row.ends_with("| 0.00034 | 0.0041 | +0.00030 |"), "{row}");
        let row = md.lines().find(|l| l.starts_with("| kappa |")).unwrap();
        assert!(row.ends_with("| 0.012 | - | 0 |"), "{row}");
        // eta lies within two of either SE of the truth, kappa (difference 0) too.
        assert!(
            md.contains("2 of 2 with SE, 1 of 1 with robust SE"),
            "{}",
            coverage_line_of(&md)
        );
    }
}

//! `reports/model_vs_simulation.md`: how well the far-field model describes the data (for
//! the shipped species, the virtual goniometer's output). Per species folder with a `metadata.json` holding the TRUE
//! parameters (`params`), the NRMSE of the far-field model at those parameters against the
//! simulated profile (with its optimal exposure), the NRMSE of our fit, and fitted vs true
//! parameters side by side. The simulator is an independent 3-D Monte Carlo, so a large
//! NRMSE at the true parameters measures model error, not a bug in either; the table
//! reports it as it comes out.

use super::nrmse::FitFile;
use crate::error::{Error, Result};
use crate::fit::forward::{predict_points, Points};
use crate::fit::problem::nrmse;
use crate::model::far::FarOptions;
use crate::model::LobeSet;
use crate::params::{FurParams, ParamId};
use crate::profile::Profile;
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
    /// The channel compared, for a profile with named channels.
    pub channel: Option<String>,
    /// Whether the data are labelled synthetic (the profile or its folder's metadata.json).
    pub synthetic: bool,
    /// What the data are (metadata.json `what`/`source`, else the data's label).
    pub data: String,
    pub truth: FurParams,
    pub nrmse_truth: f64,
    pub exposure_truth: f64,
    pub n_valid: usize,
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
        "; the data compared here are measured (none is labelled synthetic)"
    } else {
        "; the data compared here are a MIX of SYNTHETIC (simulated) and measured profiles \
         (the `data` column says which)"
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
         \"NRMSE at truth\" evaluates the far-field model (tolerance mode, 1e-4 of each \
         lobe's peak, as `furfit fit` uses by default) at the TRUE \
         parameters with the optimal exposure: it is the model's own error against these \
         data. A fit usually does better by moving parameters away from the truth to \
         absorb that error, which is why fitted and true values differ. \
         \"NRMSE of fit\" is from `fits/<species>.json` when that fit was made from this \
         folder's current data. SE is the fit's linearised standard error, s^2 (J^T J)^-1: it assumes \
         independent residuals, but here they are mostly model error, correlated between \
         neighbouring samples, so it understates the real spread, most on shallow \
         directions (equally good fits can differ by more than one SE there).\n",
        data_clause(entries)
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
        "| species | data | valid samples | NRMSE at truth | NRMSE of fit |\n|---|---|---:|---:|---:|\n",
    );
    for e in entries {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.2}% | {} |",
            e.name(),
            if e.synthetic { "SYNTHETIC" } else { "measured" },
            e.n_valid,
            100.0 * e.nrmse_truth,
            match (&e.fit, &e.fit_note) {
                (Some(f), _) => format!("{:.2}%", 100.0 * f.nrmse),
                (None, Some(_)) => "(the data changed since the fit: refit)".into(),
                (None, None) => "(no fit of this data)".into(),
            }
        );
    }
    for e in entries {
        let _ = writeln!(
            s,
            "\n## {}\n\nData: {} ({})\n",
            e.name(),
            if e.synthetic { "SYNTHETIC" } else { "measured" },
            e.data
        );
        if let Some(n) = &e.fit_note {
            let _ = writeln!(s, "Fit not shown: {n}\n");
        }
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

#[cfg(test)]
mod tests {
    use super::*;

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
            nrmse_truth: 0.01,
            exposure_truth: 1.0,
            n_valid: 10,
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
            nrmse_truth: 0.01,
            exposure_truth: 1.0,
            n_valid: 10,
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
                "(`params`); the data compared here are measured (none is labelled synthetic), and"
            ),
            "{lab}"
        );
        assert!(!lab.contains("SYNTHETIC"), "{lab}");
        let sim = intro(&[entry("a", true), entry("b", true)]);
        assert!(
            sim.contains("the data compared here are SYNTHETIC (simulated profiles"),
            "{sim}"
        );
        let mix = intro(&[entry("a", true), entry("lab", false)]);
        assert!(
            mix.contains("a MIX of SYNTHETIC (simulated) and measured"),
            "{mix}"
        );
        let none = intro(&[]);
        assert!(none.contains("(`params`), and each row"), "{none}");
    }
}

//! `reports/nrmse.{md,csv}`: a seed-Table-4-style table of the fits, one column per
//! species (ten parameters, exposure, our NRMSE), with the paper's reported NRMSE (its own
//! and Yan et al. 2015's, from [`crate::params::PRESETS`]) beside ours, headed with what
//! data the fits ran on (from each fit file's `data.synthetic`).
//!
//! The fit files are read by [`crate::fit::file`].

use crate::error::{Num, Result};
use crate::fit::file::{FitFile, Skipped};
use crate::params::{preset_record, ParamId};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// What data the fits ran on, for the table heading.
pub fn data_label(fits: &[FitFile]) -> &'static str {
    let n_syn = fits.iter().filter(|f| f.synthetic).count();
    if n_syn == fits.len() {
        "SYNTHETIC data (simulated profiles labelled synthetic in their files), not measurements"
    } else if n_syn == 0 {
        // furfit cannot know data are measured, only that nothing marks them synthetic.
        "data not marked synthetic (treated as measured: no fit file or data folder marks \
         them synthetic, which does not show that they were measured)"
    } else {
        "a MIX of synthetic data and data not marked synthetic (treated as measured; see the \
         `data` row)"
    }
}

fn pct(x: f64) -> String {
    if x.is_finite() {
        format!("{:.1}%", 100.0 * x)
    } else {
        "-".into()
    }
}

/// How many samples a fit used, and how many valid ones it left out below its floor.
fn samples_used(f: &FitFile) -> String {
    match (f.n_valid, f.n_below_floor) {
        (Some(v), Some(0)) => format!("all {v}"),
        (Some(v), Some(b)) => format!(
            "{} of {v} ({b} below {} x peak left out)",
            v.saturating_sub(b),
            f.floor
                .map_or("the floor".to_string(), |x| Num(x).to_string())
        ),
        _ => "-".into(),
    }
}

/// Rows of the table: `(label, unit, value per species)`.
fn rows(fits: &[FitFile]) -> Vec<(String, String, Vec<String>)> {
    let mut rows = Vec::new();
    for id in ParamId::ALL {
        let vals = fits
            .iter()
            .map(|f| {
                let v = f.params.typed_file_units()[id.index()];
                let name = id.spec().name;
                let mark = if f.fixed.iter().any(|u| u == name) {
                    " (fixed)"
                } else if f.unconstrained.iter().any(|u| u == name) {
                    "*"
                } else {
                    ""
                };
                format!("{}{mark}", id.spec().fixed_text(v, 2))
            })
            .collect();
        rows.push((id.spec().name.to_string(), id.spec().unit.to_string(), vals));
    }
    rows.push((
        "exposure".into(),
        "-".into(),
        fits.iter().map(|f| format!("{:.4e}", f.exposure)).collect(),
    ));
    rows.push((
        "data".into(),
        "-".into(),
        fits.iter()
            .map(|f| {
                if f.synthetic {
                    "synthetic"
                } else {
                    "not marked synthetic"
                }
                .to_string()
            })
            .collect(),
    ));
    // Only when some fit left samples out: its NRMSE does not cover them.
    if fits.iter().any(|f| f.n_below_floor.is_some_and(|n| n > 0)) {
        rows.push((
            "samples used (valid, >= floor x peak)".into(),
            "-".into(),
            fits.iter().map(samples_used).collect(),
        ));
    }
    rows.push((
        "NRMSE (this fit)".into(),
        "%".into(),
        fits.iter().map(|f| pct(f.nrmse)).collect(),
    ));
    let paper = |f: &FitFile, yan: bool| {
        preset_record(&f.species)
            .map(|p| {
                pct(if yan {
                    p.paper_nrmse_yan2015
                } else {
                    p.paper_nrmse
                })
            })
            .unwrap_or_else(|| "-".into())
    };
    rows.push((
        "NRMSE (paper, ours)".into(),
        "%".into(),
        fits.iter().map(|f| paper(f, false)).collect(),
    ));
    rows.push((
        "NRMSE (paper, Yan et al. 2015)".into(),
        "%".into(),
        fits.iter().map(|f| paper(f, true)).collect(),
    ));
    rows
}

/// Fit files whose name is not the species they record (`cat.json` holding a red fox
/// fit): the column and figure take the file's name, the paper's figures beside it the
/// recorded species'.
pub fn species_notes(fits: &[FitFile]) -> Vec<String> {
    fits.iter()
        .filter(|f| f.primary)
        .filter_map(|f| {
            let stem = f.path.file_stem()?.to_string_lossy().into_owned();
            (stem != f.species).then(|| {
                let paper = if preset_record(&f.species).is_some() {
                    format!("the paper's NRMSE beside it is {}'s", f.species)
                } else {
                    "the paper has no NRMSE for that species".to_string()
                };
                format!(
                    "{} records species '{}': its column and figure are named '{stem}', {paper}",
                    f.path.display(),
                    f.species,
                )
            })
        })
        .chain(fits.iter().filter_map(FitFile::nrmse_note))
        .collect()
}

/// The Markdown table, followed by the introduction of `fit_error_vs_time.*`.
pub fn markdown(fits: &[FitFile]) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Fitted parameters and NRMSE (seed Table 4 layout)\n");
    let _ = writeln!(s, "Written by `furfit report` ({}).\n", crate::TOOL_VERSION);
    let _ = writeln!(s, "These fits ran on {}.\n", data_label(fits));
    let _ = writeln!(
        s,
        "NRMSE = RMS of (ln model - ln measured) / (max - min ln measured), both over the samples \
         the fit used: the valid samples of at least floor x the channel's largest valid value \
         (the fit file's `data.floor`, default {}; the others are left out of the fit and of \
         its NRMSE), after the optimal exposure (MODEL.md). The paper's rows are the values it reports for \
         ITS measured data; they are context, not a target this data can be compared with \
         sample for sample. `*` marks a parameter the data does not constrain (see the fit \
         file's `uncertainty.unconstrained`), `(fixed)` one held at its value by `--fix`. A fit \
         of several channels has a column per channel (`<fit>-<channel>`).\n",
        Num(crate::fit::DEFAULT_FLOOR)
    );
    let _ = write!(s, "| parameter | unit |");
    for f in fits {
        let _ = write!(s, " {} |", f.label());
    }
    let _ = write!(s, "\n|---|---|");
    for _ in fits {
        let _ = write!(s, "---:|");
    }
    s.push('\n');
    for (label, unit, vals) in rows(fits) {
        let _ = write!(s, "| {label} | {unit} |");
        for v in vals {
            let _ = write!(s, " {v} |");
        }
        s.push('\n');
    }
    let notes = species_notes(fits);
    if !notes.is_empty() {
        s.push_str("\nNotes:\n\n");
        for n in notes {
            let _ = writeln!(s, "- {n}");
        }
    }
    // The convergence figure is introduced here, with what its values are.
    s.push('\n');
    s.push_str(&super::fit_time::description(fits));
    s
}

/// `text` as one CSV field: quoted (quotes doubled) when it holds a comma, a quote or a
/// line break (a fit file's stem may).
fn csv_field(text: &str) -> String {
    if text.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", text.replace('"', "\"\""))
    } else {
        text.to_string()
    }
}

/// The CSV table (same rows; NRMSE as fractions for machines).
pub fn csv(fits: &[FitFile]) -> String {
    let mut s = String::from("row,unit");
    for f in fits {
        s.push(',');
        s.push_str(&csv_field(&f.label()));
    }
    s.push('\n');
    for id in ParamId::ALL {
        let _ = write!(s, "{},{}", id.spec().name, id.spec().unit);
        for f in fits {
            let _ = write!(s, ",{}", f.params.typed_file_units()[id.index()]);
        }
        s.push('\n');
    }
    let _ = write!(s, "fixed,-");
    for f in fits {
        let _ = write!(s, ",{}", f.fixed.join(";"));
    }
    let _ = write!(s, "\nexposure,-");
    for f in fits {
        let _ = write!(s, ",{}", f.exposure);
    }
    let _ = write!(s, "\nsynthetic,-");
    for f in fits {
        let _ = write!(s, ",{}", f.synthetic);
    }
    // What the NRMSE covers: the valid samples less those below floor x peak.
    let _ = write!(s, "\nfloor,fraction of peak");
    for f in fits {
        let _ = write!(s, ",{}", f.floor.map(|x| x.to_string()).unwrap_or_default());
    }
    for (name, n) in [
        (
            "n_valid",
            (|f: &FitFile| f.n_valid) as fn(&FitFile) -> Option<u64>,
        ),
        ("n_below_floor", |f: &FitFile| f.n_below_floor),
    ] {
        let _ = write!(s, "\n{name},samples");
        for f in fits {
            let _ = write!(s, ",{}", n(f).map(|x| x.to_string()).unwrap_or_default());
        }
    }
    let _ = write!(s, "\nnrmse,fraction");
    for f in fits {
        let _ = write!(s, ",{}", f.nrmse);
    }
    for (name, yan) in [("paper_nrmse_ours", false), ("paper_nrmse_yan2015", true)] {
        let _ = write!(s, "\n{name},fraction");
        for f in fits {
            match preset_record(&f.species) {
                Some(p) => {
                    let _ = write!(
                        s,
                        ",{}",
                        if yan {
                            p.paper_nrmse_yan2015
                        } else {
                            p.paper_nrmse
                        }
                    );
                }
                None => s.push(','),
            }
        }
    }
    s.push('\n');
    s
}

/// Write `nrmse.md` and `nrmse.csv` into `out`; `unverified` lists `(fit label, why)` for
/// fits whose data could not be read back as the fit recorded it (changed or missing):
/// their columns are the fit files' own figures, and `nrmse.md` says so.
/// `unread` lists `(file name, why)` for fit files in the folder that could not be read.
pub fn write(
    fits: &[FitFile],
    unverified: &[(String, String)],
    unread: &[Skipped],
    out: &Path,
) -> Result<()> {
    let mut md = markdown(fits);
    if !unread.is_empty() {
        md.push_str("\n## Fit files not read\n\nNot in the table:\n\n");
        for (name, why) in unread {
            md.push_str(&format!("- {name}: {why}\n"));
        }
    }
    if !unverified.is_empty() {
        md.push_str(
            "\n## Not checked against their data\n\nThese columns are the fit files' own \
             figures: the data they were fitted to could not be read back as recorded, so \
             no figure was drawn for them (refit, or restore the data):\n\n",
        );
        for (label, why) in unverified {
            md.push_str(&format!("- {label}: {why}\n"));
        }
    }
    crate::io::write_output(&out.join("nrmse.md"), md.as_bytes())?;
    crate::io::write_output(&out.join("nrmse.csv"), csv(fits).as_bytes())
}

/// What [`write_fit_reports`] wrote and what it had to skip.
#[derive(Debug, Default)]
pub struct ReportSummary {
    /// Files written.
    pub written: Vec<PathBuf>,
    /// `(species, reason)` for figures or entries that could not be made.
    pub skipped: Vec<(String, String)>,
    /// An earlier run's figures removed, with why: of a fit whose figure could not be
    /// made now, or of a fit no longer there (no stale figure stands beside the reports).
    pub removed: Vec<(PathBuf, &'static str)>,
    /// Things the reader should know that do not stop a part (a fit file named for
    /// another species than the one it records).
    pub notes: Vec<String>,
}

/// The entry point of the fit reports: `nrmse.{md,csv}`, `fig11_<species>.{png,svg}`,
/// `fit_error_vs_time.{csv,png,svg}` and `model_vs_simulation.md` from the fits
/// [`crate::fit::file::read_fits`] read (`unread`: the fit files it could not) and the
/// profiles in `measurements` (a fit's Fig-11 data is read from the first place holding the data it
/// recorded, see [`FitFile::load_data`]).
pub fn write_fit_reports(
    fits: &[FitFile],
    unread: &[Skipped],
    measurements: &Path,
    out: &Path,
    force: bool,
) -> Result<ReportSummary> {
    let figures: Vec<PathBuf> = fits
        .iter()
        .flat_map(|f| super::fig11::outputs(f, out))
        .collect();
    // Every file this run may write, checked before any is ([`crate::io::LEDGER`]).
    let mut planned: Vec<PathBuf> = ["nrmse.md", "nrmse.csv", "model_vs_simulation.md"]
        .iter()
        .chain(&[
            "fit_error_vs_time.csv",
            "fit_error_vs_time.png",
            "fit_error_vs_time.svg",
        ])
        .map(|n| out.join(n))
        .collect();
    planned.extend(figures.iter().cloned());
    crate::io::check_replaceable(&planned, force)?;
    let mut sum = ReportSummary {
        skipped: unread.to_vec(),
        notes: species_notes(fits),
        ..Default::default()
    };
    remove_stale_figures(out, &figures, unread, &mut sum);
    write_planned(fits, unread, measurements, out, &mut sum)?;
    Ok(sum)
}

/// Figures of fits no longer in the folder: an earlier report's, still recorded unchanged
/// in the ledger (so furfit's own), would stand beside tables that do not list them. Only
/// the figures of the fits the earlier `nrmse.csv` lists (itself unchanged) are candidates:
/// another command's output named `fig11_*` (a render) is not report's to remove (review,
/// 2026-11-28). Those of a fit file in `unread` (still there, only not readable this time)
/// stay; `figures` are this run's.
fn remove_stale_figures(
    out: &Path,
    figures: &[PathBuf],
    unread: &[Skipped],
    sum: &mut ReportSummary,
) {
    let of_unread = |label: &str| {
        unread.iter().any(|(file, _)| {
            let stem = file.strip_suffix(".json").unwrap_or(file);
            label == stem || label.strip_prefix(stem).is_some_and(|r| r.starts_with('-'))
        })
    };
    let table = out.join("nrmse.csv");
    if crate::io::check_replaceable(std::slice::from_ref(&table), false).is_err() {
        return;
    }
    let Ok(text) = std::fs::read_to_string(&table) else {
        return;
    };
    let mut header = ::csv::StringRecord::new();
    let read = ::csv::ReaderBuilder::new()
        .has_headers(false)
        .flexible(true)
        .from_reader(text.as_bytes())
        .read_record(&mut header);
    if !read.is_ok_and(|got| got) {
        return;
    }
    let mut stale: Vec<PathBuf> = header
        .iter()
        .skip(2)
        .filter(|label| !label.is_empty() && !of_unread(label))
        .flat_map(|label| super::fig11::outputs_of(label, out))
        .filter(|p| {
            p.is_file()
                && !figures.contains(p)
                && crate::io::check_replaceable(std::slice::from_ref(p), false).is_ok()
        })
        .collect();
    stale.sort();
    stale.dedup();
    for p in stale {
        if std::fs::remove_file(&p).is_ok() {
            sum.removed
                .push((p, "a figure of a fit no longer in the fits folder"));
        }
    }
}

/// Write the planned reports, listing each file in `sum.written` once it is written. Each
/// is already in its folder's ledger then ([`crate::io::write_output`]), so a run stopped
/// part-way leaves every file it wrote recorded as furfit's.
fn write_planned(
    fits: &[FitFile],
    unread: &[Skipped],
    measurements: &Path,
    out: &Path,
    sum: &mut ReportSummary,
) -> Result<()> {
    use super::{fig11, fit_time, model_vs_sim};
    // Each fit's data first: data labelled synthetic (in the file or its folder's
    // metadata.json, also when the label came after the fit) are reported as synthetic
    // everywhere, not only where the fit file recorded it.
    let mut fits = fits.to_vec();
    let mut data: Vec<Result<crate::Profile>> = Vec::with_capacity(fits.len());
    for f in fits.iter_mut() {
        match f.load_data(measurements) {
            Ok((p, place)) => {
                // Where the data were verified, for model_vs_simulation's pairing too.
                f.verified = place;
                f.synthetic |= p.is_synthetic();
                f.check_nrmse(&p);
                sum.notes.extend(f.nrmse_note());
                data.push(Ok(p));
            }
            Err(e) => data.push(Err(e)),
        }
    }
    let fits = fits.as_slice();
    let unverified: Vec<(String, String)> = fits
        .iter()
        .zip(&data)
        .filter_map(|(f, d)| d.as_ref().err().map(|e| (f.label(), e.to_string())))
        .collect();
    write(fits, &unverified, unread, out)?;
    sum.written
        .extend(["nrmse.md", "nrmse.csv"].map(|n| out.join(n)));
    fit_time::write(fits, out)?;
    sum.written
        .extend(["csv", "png", "svg"].map(|e| out.join(format!("fit_error_vs_time.{e}"))));
    for (f, d) in fits.iter().zip(data) {
        match d.and_then(|p| fig11::write(f, &p, out)) {
            Ok(paths) => sum.written.extend(paths),
            Err(e) => {
                // An earlier run's figure of this fit would stand for data it no longer
                // shows: remove it (the ledger check at the start let this run replace it).
                for p in fig11::outputs(f, out) {
                    if p.is_file() && std::fs::remove_file(&p).is_ok() {
                        sum.removed
                            .push((p, "an earlier report's figure of data that no longer match"));
                    }
                }
                sum.skipped.push((f.label(), format!("fig11: {e}")));
            }
        }
    }
    // Model vs simulation: every species folder with true parameters.
    let mut entries = Vec::new();
    let mut unusable = Vec::new();
    if let Ok(rd) = std::fs::read_dir(measurements) {
        let mut dirs: Vec<PathBuf> = rd
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.is_dir())
            .collect();
        dirs.sort();
        for d in dirs {
            let species = crate::fit::job::species_name(&d);
            let mut skip = |why: String| {
                sum.skipped
                    .push((species.clone(), format!("model_vs_simulation: {why}")));
                unusable.push((species.clone(), why));
            };
            let (truth, what) = match model_vs_sim::true_params(&d) {
                Ok(Some(t)) => t,
                Ok(None) => continue,
                Err(e) => {
                    skip(e.to_string());
                    continue;
                }
            };
            // A fit of other data (its own files) has other loader options and an NRMSE
            // that is not comparable: listed without it.
            // `<species>.json` first, then any other fit of this data (file-name order
            // picked a hand-edited copy over it: audit, 2026-11-28).
            let of_data = |f: &&FitFile| f.primary && f.species == species && f.fitted_from(&d);
            let mut fit = fits
                .iter()
                .filter(of_data)
                .find(|f| f.label == species)
                .or_else(|| fits.iter().find(of_data))
                .cloned();
            let load = fit.as_ref().map(|f| f.load.clone()).unwrap_or_default();
            let inputs = [d.clone()];
            let loaded = match crate::fit::job::load_inputs_full(&inputs, &load) {
                Ok(p) => p,
                Err(e) => {
                    skip(e.to_string());
                    continue;
                }
            };
            // As for fig11: a fit made before the data changed is not this data's fit.
            let mut fit_note = None;
            if let Some(f) = &fit {
                if let Err(e) = f.check_digests(&inputs, &loaded.files) {
                    fit_note = Some(e.to_string());
                    fit = None;
                }
            }
            let prof = loaded.profile;
            let ch = fit
                .as_ref()
                .and_then(|f| prof.channels.iter().position(|c| *c == f.channel))
                .unwrap_or(0);
            // On the fit's samples with its far field: like with like beside its NRMSE.
            let (floor, far) = model_vs_sim::truth_settings(fit.as_ref());
            if let Some(at_truth) = model_vs_sim::nrmse_at(&truth.into(), &prof, ch, floor, &far) {
                entries.push(model_vs_sim::Entry {
                    species,
                    channel: prof.channels.get(ch).cloned(),
                    synthetic: prof.is_synthetic(),
                    data: what.unwrap_or_else(|| {
                        if prof.is_synthetic() {
                            "synthetic (labelled so in the data)".into()
                        } else if let Some(label) =
                            crate::profile::provenance::measured_label(&prof, &d)
                        {
                            format!("labelled measured ({label})")
                        } else {
                            "no synthetic label in the data or its folder's metadata.json".into()
                        }
                    }),
                    truth,
                    at_truth,
                    fit,
                    fit_note,
                });
            }
        }
    }
    let p = out.join("model_vs_simulation.md");
    crate::io::write_output(&p, model_vs_sim::markdown(&entries, &unusable).as_bytes())?;
    sum.written.push(p);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fit::file::read_fits;
    use crate::FurParams;

    /// A fit file `<name>.json` in `dir` whose `data` holds `data`.
    fn fit(dir: &Path, name: &str, data: serde_json::Value) -> FitFile {
        let v = serde_json::json!({
            "params": FurParams::preset("cat").unwrap().to_json_value(),
            "exposure": 1.0,
            "nrmse": 0.02,
            "data": data,
        });
        let p = dir.join(format!("{name}.json"));
        std::fs::write(&p, v.to_string()).unwrap();
        FitFile::read(&p).unwrap().remove(0)
    }

    /// Two channels of one file whose names clean to one label are refused naming the
    /// channels (the message named the same file twice); a label with a comma stays one
    /// field of nrmse.csv's header.
    #[test]
    fn channel_twins_are_refused_and_commas_are_quoted() {
        let tmp = tempfile::tempdir().unwrap();
        let params = FurParams::preset("cat").unwrap().to_json_value();
        let ch = |name: &str| {
            serde_json::json!({"params": params, "exposure": 1.0, "nrmse": 0.02,
                "data": {"channel": name}})
        };
        let v = serde_json::json!({
            "params": params, "exposure": 1.0, "nrmse": 0.02, "data": {"channel": "r."},
            "channels": [ch("r."), ch("r,")],
        });
        std::fs::write(tmp.path().join("fox.json"), v.to_string()).unwrap();
        let e = read_fits(tmp.path()).unwrap_err().to_string();
        assert!(
            e.contains("its channels 'r.' and 'r,' would both be named 'fox-r_'"),
            "{e}"
        );
        std::fs::remove_file(tmp.path().join("fox.json")).unwrap();
        let odd = fit(tmp.path(), "fox,v2", serde_json::json!({}));
        let head = csv(&[odd]).lines().next().unwrap().to_string();
        assert_eq!(head, "row,unit,\"fox,v2\"");
    }

    /// furfit cannot know that data are measured: data without a synthetic mark are
    /// called what they are, in the heading and the `data` row.
    #[test]
    fn unmarked_data_are_not_called_measured() {
        let tmp = tempfile::tempdir().unwrap();
        let lab = fit(tmp.path(), "lab", serde_json::json!({}));
        let sim = fit(tmp.path(), "sim", serde_json::json!({"synthetic": true}));
        let md = markdown(std::slice::from_ref(&lab));
        assert!(
            md.contains("These fits ran on data not marked synthetic (treated as measured:"),
            "{md}"
        );
        assert!(md.contains("| data | - | not marked synthetic |"), "{md}");
        assert!(!md.contains("| measured"), "{md}");
        let md = markdown(&[sim, lab]);
        assert!(
            md.contains("a MIX of synthetic data and data not marked synthetic"),
            "{md}"
        );
        assert!(
            md.contains("| data | - | synthetic | not marked synthetic |"),
            "{md}"
        );
    }

    /// The NRMSE is said to cover the samples the fit used, and a fit that left samples
    /// out below its floor says how many (shipped fits leave none out: no row then).
    #[test]
    fn markdown_counts_the_samples_left_out_below_the_floor() {
        let tmp = tempfile::tempdir().unwrap();
        let all = fit(
            tmp.path(),
            "all",
            serde_json::json!({"floor": 1e-8, "n_valid": 1000, "n_used": 1000, "n_below_floor": 0}),
        );
        let cut = fit(
            tmp.path(),
            "cut",
            serde_json::json!({"floor": 1e-3, "n_valid": 1000, "n_used": 950, "n_below_floor": 50}),
        );
        let md = markdown(std::slice::from_ref(&all));
        assert!(
            md.contains(
                "both over the samples the fit used: the valid samples of at least floor x \
                 the channel's largest valid value (the fit file's `data.floor`, default 1e-8;"
            ),
            "{md}"
        );
        assert!(!md.contains("over the valid samples"), "{md}");
        assert!(!md.contains("| samples used"), "{md}");
        let md = markdown(&[all.clone(), cut.clone()]);
        assert!(
            md.contains(
                "| samples used (valid, >= floor x peak) | - | all 1000 | 950 of 1000 (50 below 0.001 x peak left out) |"
            ),
            "{md}"
        );
        let csv = csv(&[all, cut]);
        for row in [
            "floor,fraction of peak,0.00000001,0.001",
            "n_valid,samples,1000,1000",
            "n_below_floor,samples,0,50",
        ] {
            assert!(csv.lines().any(|l| l == row), "no '{row}' in\n{csv}");
        }
    }
}

//! The model comparison of `furfit report`: every registered model fitted to the same
//! species' data, side by side.
//!
//! - `model_comparison.csv`: one row per species and model (`species,model,nrmse,n_params,
//!   samples,wall_time_s,evaluations,synthetic,paper_nrmse_yan2017`);
//! - `model_comparison.md`: the species x model NRMSE table, the best per row in bold, with
//!   the paper's own NRMSE (seed Table 4, its measured data) as context;
//! - `fig11_models_<species>.{png,svg}`: seed-Fig.-11-style profiles along `phi` at a few
//!   `(theta_i, theta_r)`, the data as dots and one curve per model (each at its own
//!   exposure);
//! - `fit_error_vs_time_models.{csv,png,svg}`: each fit's convergence trace (NRMSE against
//!   wall time), one panel per species, one line per model.
//!
//! The fits are the default model's in the fits folder and each other model's in
//! `<fits>/<model>/` ([`crate::fit::batch::model_dir`]).

use super::fig11::ensure_font;
use crate::error::{Error, Result};
use crate::fit::file::{read_fits, FitFile};
use crate::fit::forward::Points;
use crate::model::LobeSet;
use crate::models::{FiberModel, Integral, MODELS};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Each model's fits, in registry order.
pub type ByModel = Vec<(&'static dyn FiberModel, Vec<FitFile>)>;
/// `(name, why)` of a fit file or figure left out.
pub type Skips = Vec<(String, String)>;

/// The fits of each model that has a folder of them, in registry order: `(model, fits)`;
/// the fit files of a folder that could not be read, or are of another model, are listed
/// as `(file, why)`.
pub fn read_all(fits_dir: &Path) -> (ByModel, Skips) {
    let mut out = Vec::new();
    let mut skipped = Vec::new();
    for m in MODELS {
        let dir = crate::fit::batch::model_dir(fits_dir, m);
        let Ok((fits, bad)) = read_fits(&dir) else {
            continue;
        };
        skipped.extend(bad);
        let (mine, other): (Vec<FitFile>, Vec<FitFile>) = fits
            .into_iter()
            .filter(|f| f.primary)
            .partition(|f| f.params.model.name() == m.name());
        for f in other {
            skipped.push((
                f.path.display().to_string(),
                format!(
                    "a fit of {} in the folder of {}; left out of the comparison",
                    f.params.model.name(),
                    m.name()
                ),
            ));
        }
        if !mine.is_empty() {
            out.push((m, mine));
        }
    }
    (out, skipped)
}

/// The species of the comparison, in order (the union of the models' fit labels).
fn species(by_model: &[(&'static dyn FiberModel, Vec<FitFile>)]) -> Vec<String> {
    let mut s: Vec<String> = by_model
        .iter()
        .flat_map(|(_, fs)| fs.iter().map(|f| f.label()))
        .collect();
    s.sort();
    s.dedup();
    s
}

fn find<'a>(fits: &'a [FitFile], label: &str) -> Option<&'a FitFile> {
    fits.iter().find(|f| f.label() == label)
}

/// Free parameters of a fit: its model's, less those it fixed.
fn n_free(f: &FitFile) -> usize {
    f.params.model.specs().len() - f.fixed.len()
}

/// The CSV (one row per species and model).
pub fn csv(by_model: &[(&'static dyn FiberModel, Vec<FitFile>)]) -> String {
    let mut s = String::from(
        "species,model,nrmse,n_params,samples,wall_time_s,evaluations,synthetic,paper_nrmse_yan2017\n",
    );
    for sp in species(by_model) {
        for (m, fits) in by_model {
            let Some(f) = find(fits, &sp) else { continue };
            let paper = crate::params::preset_record(&f.species)
                .map(|p| p.paper_nrmse.to_string())
                .unwrap_or_default();
            let _ = writeln!(
                s,
                "{sp},{},{},{},{},{},{},{},{paper}",
                m.name(),
                f.nrmse,
                n_free(f),
                f.n_used.map(|n| n.to_string()).unwrap_or_default(),
                f.wall_time_s,
                f.evaluations.map(|n| n.to_string()).unwrap_or_default(),
                f.synthetic
            );
        }
    }
    s
}

/// The Markdown report.
pub fn markdown(by_model: &[(&'static dyn FiberModel, Vec<FitFile>)], fits_dir: &Path) -> String {
    let all: Vec<FitFile> = by_model
        .iter()
        .flat_map(|(_, f)| f.iter().cloned())
        .collect();
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Model comparison: NRMSE of every model on the same data\n"
    );
    let _ = writeln!(s, "Written by `furfit report` ({}).\n", crate::TOOL_VERSION);
    let _ = writeln!(s, "These fits ran on {}.\n", super::nrmse::data_label(&all));
    let _ = writeln!(
        s,
        "Each model was fitted to each species' profile by `furfit fit --model <name>` (the \
         same multi-start, bounds and closed-form exposure; fits in `{}` and `{}/<model>/`). \
         NRMSE as MODEL.md defines it, on the samples each fit used; the best model per \
         species in bold. Where the data are the project's virtual goniometer's (an explicit \
         ray tracer of a double-cylinder fiber with a medulla: `measurements/`), the fur \
         model's medulla lobes have light to explain that the hair models have no lobe for. The paper's column is the \
         NRMSE seed 000 reports for its own model on ITS measured data: context, not a \
         figure this data can be compared with sample for sample.\n",
        fits_dir.display(),
        fits_dir.display()
    );
    let _ = write!(s, "| species |");
    for (m, _) in by_model {
        let _ = write!(s, " {} |", m.name());
    }
    let _ = writeln!(s, " paper (yan2017, its data) |");
    let _ = write!(s, "|---|");
    for _ in by_model {
        let _ = write!(s, "---:|");
    }
    let _ = writeln!(s, "---:|");
    for sp in species(by_model) {
        let vals: Vec<Option<&FitFile>> = by_model.iter().map(|(_, f)| find(f, &sp)).collect();
        let best = vals
            .iter()
            .flatten()
            .map(|f| f.nrmse)
            .fold(f64::INFINITY, f64::min);
        let _ = write!(s, "| {sp} |");
        for v in &vals {
            let cell = match v {
                Some(f) if f.nrmse == best && vals.iter().flatten().count() > 1 => {
                    format!("**{:.2}%**", 100.0 * f.nrmse)
                }
                Some(f) => format!("{:.2}%", 100.0 * f.nrmse),
                None => "-".into(),
            };
            let _ = write!(s, " {cell} |");
        }
        let paper = vals
            .iter()
            .flatten()
            .next()
            .and_then(|f| crate::params::preset_record(&f.species))
            .map(|p| format!("{:.1}%", 100.0 * p.paper_nrmse))
            .unwrap_or_else(|| "-".into());
        let _ = writeln!(s, " {paper} |");
    }
    let _ = writeln!(s, "\n## Cost of each fit\n");
    let _ = writeln!(
        s,
        "Free parameters, wall time and model evaluations of each fit (the exposure is \
         solved in closed form and not counted). Times are of the machine that ran the fit.\n"
    );
    let _ = write!(s, "| species |");
    for (m, _) in by_model {
        let _ = write!(s, " {} (params, s, evaluations) |", m.name());
    }
    s.push('\n');
    let _ = write!(s, "|---|");
    for _ in by_model {
        let _ = write!(s, "---:|");
    }
    s.push('\n');
    for sp in species(by_model) {
        let _ = write!(s, "| {sp} |");
        for (_, fits) in by_model {
            let cell = find(fits, &sp).map_or("-".to_string(), |f| {
                format!(
                    "{}, {:.1}, {}",
                    n_free(f),
                    f.wall_time_s,
                    f.evaluations.map_or("-".into(), |n| n.to_string())
                )
            });
            let _ = write!(s, " {cell} |");
        }
        s.push('\n');
    }
    let _ = writeln!(
        s,
        "\nFigures: `fig11_models_<species>.png` (profiles along phi, one curve per model) \
         and `fit_error_vs_time_models.png` (convergence traces)."
    );
    s
}

/// The outputs of the comparison for these species.
pub fn outputs(species: &[String], out: &Path) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = ["model_comparison.csv", "model_comparison.md"]
        .iter()
        .chain(&[
            "fit_error_vs_time_models.csv",
            "fit_error_vs_time_models.png",
            "fit_error_vs_time_models.svg",
        ])
        .map(|n| out.join(n))
        .collect();
    for sp in species {
        for e in ["png", "svg"] {
            v.push(out.join(format!("fig11_models_{sp}.{e}")));
        }
    }
    v
}

/// Panels of the overlay figure: `(theta_i, theta_r)` nearest the specular cone and 30
/// degrees off it, for up to four incident angles of the data.
fn panels(data: &crate::Profile) -> Vec<(f64, f64)> {
    let mut ti: Vec<f64> = data.samples.iter().map(|s| s.theta_i).collect();
    ti.sort_by(f64::total_cmp);
    ti.dedup();
    let step = ti.len().div_ceil(4).max(1);
    let mut out = Vec::new();
    for &t in ti.iter().step_by(step) {
        let mut tr: Vec<f64> = data
            .samples
            .iter()
            .filter(|s| s.theta_i == t)
            .map(|s| s.theta_r)
            .collect();
        tr.sort_by(f64::total_cmp);
        tr.dedup();
        for target in [-t, -t + 30.0] {
            if let Some(&r) = tr
                .iter()
                .min_by(|a, b| (*a - target).abs().total_cmp(&(*b - target).abs()))
            {
                if !out.contains(&(t, r)) {
                    out.push((t, r));
                }
            }
        }
    }
    out
}

/// One panel's series: the data `(phi, value)` and each model's `(phi, prediction)`.
struct Panel {
    theta_i: f64,
    theta_r: f64,
    data: Vec<(f64, f64)>,
    models: Vec<(String, Vec<(f64, f64)>)>,
}

fn panel_data(data: &crate::Profile, fits: &[&FitFile]) -> Vec<Panel> {
    panels(data)
        .into_iter()
        .map(|(ti, tr)| {
            let mut row: Vec<(f64, f64)> = data
                .samples
                .iter()
                .filter(|s| s.theta_i == ti && s.theta_r == tr && s.channel == 0)
                .map(|s| (s.phi, if s.is_valid() { s.value } else { f64::NAN }))
                .collect();
            row.sort_by(|a, b| a.0.total_cmp(&b.0));
            let phis: Vec<f64> = (0..=180).map(|k| -180.0 + 2.0 * k as f64).collect();
            let pts = Points::grid_degrees(&[ti], &[tr], &phis);
            let models = fits
                .iter()
                .map(|f| {
                    let p = &f.params;
                    let v = p
                        .model
                        .predict(&p.values, &pts, &f.far, LobeSet::ALL, Integral::Far)
                        .lobes;
                    let curve = phis
                        .iter()
                        .zip(&v)
                        .map(|(&ph, l)| (ph, f.exposure * l.sum()))
                        .collect();
                    (
                        format!("{} ({:.2}%)", p.model.name(), 100.0 * f.nrmse),
                        curve,
                    )
                })
                .collect();
            Panel {
                theta_i: ti,
                theta_r: tr,
                data: row,
                models,
            }
        })
        .collect()
}

const COLORS: [RGBColor; 4] = [
    RGBColor(214, 39, 40),
    RGBColor(31, 119, 180),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
];

fn draw_overlay<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    species: &str,
    panels: &[Panel],
    synthetic: bool,
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    root.fill(&WHITE)?;
    let (top, body) = root.split_vertically(36);
    top.draw(&Text::new(
        format!(
            "{species}: {} data (dots) and each model's fit along phi",
            if synthetic {
                "SYNTHETIC"
            } else {
                "not marked synthetic"
            }
        ),
        (10, 10),
        (super::fig11::FONT, 16),
    ))?;
    let cols = 2;
    let rows = panels.len().div_ceil(cols).max(1);
    let areas = body.split_evenly((rows, cols));
    for (p, area) in panels.iter().zip(&areas) {
        let log = |v: f64| if v > 0.0 { v.log10() } else { f64::NAN };
        let ys = p
            .data
            .iter()
            .map(|d| log(d.1))
            .chain(
                p.models
                    .iter()
                    .flat_map(|(_, c)| c.iter().map(|d| log(d.1))),
            )
            .filter(|y| y.is_finite());
        let (lo, hi) = ys.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), y| {
            (a.min(y), b.max(y))
        });
        let (lo, hi) = if lo.is_finite() {
            (lo.max(hi - 8.0) - 0.2, hi + 0.2)
        } else {
            (-1.0, 1.0)
        };
        let mut ch = ChartBuilder::on(area)
            .caption(
                format!("theta_i {:.0}, theta_r {:.0} deg", p.theta_i, p.theta_r),
                (super::fig11::FONT, 13),
            )
            .margin(6)
            .x_label_area_size(28)
            .y_label_area_size(40)
            .build_cartesian_2d(-180.0..180.0, lo..hi)?;
        ch.configure_mesh()
            .x_desc("phi (deg)")
            .y_desc("log10 value")
            .label_style((super::fig11::FONT, 10))
            .x_labels(5)
            .y_labels(5)
            .draw()?;
        for (k, (name, curve)) in p.models.iter().enumerate() {
            let c = COLORS[k % COLORS.len()];
            let pts: Vec<(f64, f64)> = curve
                .iter()
                .map(|&(x, y)| (x, log(y)))
                .filter(|(_, y)| y.is_finite() && *y >= lo)
                .collect();
            ch.draw_series(LineSeries::new(pts, c.stroke_width(2)))?
                .label(name.clone())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 14, y)], c));
        }
        ch.draw_series(
            p.data
                .iter()
                .filter(|d| log(d.1) >= lo)
                .map(|d| Circle::new((d.0, log(d.1)), 2, BLACK.filled())),
        )?;
        ch.configure_series_labels()
            .position(SeriesLabelPosition::LowerLeft)
            .label_font((super::fig11::FONT, 10))
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()?;
    }
    root.present()?;
    Ok(())
}

fn draw_traces<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    by_model: &[(&'static dyn FiberModel, Vec<FitFile>)],
    species: &[String],
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    root.fill(&WHITE)?;
    let cols = 5.min(species.len().max(1));
    let rows = species.len().div_ceil(cols).max(1);
    let areas = root.split_evenly((rows, cols));
    for (sp, area) in species.iter().zip(&areas) {
        let traces: Vec<(&str, Vec<(f64, f64)>)> = by_model
            .iter()
            .filter_map(|(m, fits)| {
                let f = find(fits, sp)?;
                let pts: Vec<(f64, f64)> = f
                    .trace
                    .iter()
                    .map(|t| (t.2, t.3))
                    .filter(|(t, e)| *t > 0.0 && *e > 0.0 && t.is_finite() && e.is_finite())
                    .collect();
                Some((m.name(), pts))
            })
            .collect();
        let all = traces.iter().flat_map(|(_, p)| p.iter());
        let (mut x0, mut x1, mut y0, mut y1) = (f64::INFINITY, 0.0f64, f64::INFINITY, 0.0f64);
        for &(x, y) in all {
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
        if !x0.is_finite() {
            (x0, x1, y0, y1) = (1e-2, 1.0, 1e-3, 1.0);
        }
        let mut ch = ChartBuilder::on(area)
            .caption(sp.as_str(), (super::fig11::FONT, 13))
            .margin(6)
            .x_label_area_size(28)
            .y_label_area_size(44)
            .build_cartesian_2d(
                ((x0 / 1.5)..(x1 * 1.5)).log_scale(),
                ((y0 / 1.3)..(y1 * 1.3)).log_scale(),
            )?;
        ch.configure_mesh()
            .x_desc("wall time (s)")
            .y_desc("NRMSE")
            .label_style((super::fig11::FONT, 9))
            .x_label_formatter(&super::plot::tick)
            .y_label_formatter(&super::plot::tick)
            .draw()?;
        for (k, (name, pts)) in traces.into_iter().enumerate() {
            let c = COLORS[k % COLORS.len()];
            ch.draw_series(LineSeries::new(pts, c.stroke_width(2)))?
                .label(name)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 14, y)], c));
        }
        ch.configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .label_font((super::fig11::FONT, 9))
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()?;
    }
    root.present()?;
    Ok(())
}

/// The traces CSV: `species,model,stage,iter,time_s,nrmse`.
fn traces_csv(by_model: &[(&'static dyn FiberModel, Vec<FitFile>)]) -> String {
    let mut s = String::from("species,model,stage,iter,time_s,nrmse\n");
    for (m, fits) in by_model {
        for f in fits {
            for (stage, it, t, e) in &f.trace {
                let _ = writeln!(s, "{},{},{stage},{it},{t},{e}", f.label(), m.name());
            }
        }
    }
    s
}

/// Render `draw` into PNG and SVG bytes at `size`.
fn figure(
    base: &Path,
    size: (u32, u32),
    draw: impl Fn(DrawingArea<SVGBackend<'_>, Shift>) -> std::result::Result<(), String>,
    draw_png: impl FnOnce(DrawingArea<BitMapBackend<'_>, Shift>) -> std::result::Result<(), String>,
) -> Result<Vec<(PathBuf, Vec<u8>)>> {
    let png = base.with_extension("png");
    let svg = base.with_extension("svg");
    let bytes = super::plot::png_bytes(size, &png, |root| {
        draw_png(root).map_err(|e| Error::file(&png, format!("plot: {e}")))
    })?;
    let mut text = String::new();
    {
        let root = SVGBackend::with_string(&mut text, size).into_drawing_area();
        draw(root).map_err(|e| Error::file(&svg, format!("plot: {e}")))?;
    }
    Ok(vec![(png, bytes), (svg, text.into_bytes())])
}

/// Write the comparison (see the module doc) into `out`; `measurements` as for the fit
/// reports. Returns the files written and `(species, why)` for overlays that could not be
/// drawn (their data not found as recorded).
pub fn write(
    by_model: &[(&'static dyn FiberModel, Vec<FitFile>)],
    fits_dir: &Path,
    measurements: &Path,
    out: &Path,
) -> Result<(Vec<PathBuf>, Skips)> {
    ensure_font();
    let mut written = Vec::new();
    let mut skipped = Vec::new();
    let species = species(by_model);
    for (name, text) in [
        ("model_comparison.csv", csv(by_model)),
        ("model_comparison.md", markdown(by_model, fits_dir)),
        ("fit_error_vs_time_models.csv", traces_csv(by_model)),
    ] {
        crate::io::write_output(&out.join(name), text.as_bytes())?;
        written.push(out.join(name));
    }
    let cols = 5.min(species.len().max(1)) as u32;
    let rows = species.len().div_ceil(cols as usize).max(1) as u32;
    let size = (300 * cols, 260 * rows);
    let files = figure(
        &out.join("fit_error_vs_time_models"),
        size,
        |r| draw_traces(r, by_model, &species).map_err(|e| e.to_string()),
        |r| draw_traces(r, by_model, &species).map_err(|e| e.to_string()),
    )?;
    crate::io::write_outputs(&files)?;
    written.extend(files.into_iter().map(|f| f.0));
    for sp in &species {
        let fits: Vec<&FitFile> = by_model.iter().filter_map(|(_, f)| find(f, sp)).collect();
        let data = fits
            .iter()
            .find_map(|f| f.load_data(measurements).ok().map(|d| (d.0, f.synthetic)));
        let Some((data, synthetic)) = data else {
            skipped.push((
                sp.clone(),
                "fig11_models: no fit's recorded data were found".into(),
            ));
            continue;
        };
        let synthetic = synthetic || data.is_synthetic();
        let panels = panel_data(&data, &fits);
        let rows = panels.len().div_ceil(2).max(1) as u32;
        let size = (1100, 40 + 300 * rows);
        let files = figure(
            &out.join(format!("fig11_models_{sp}")),
            size,
            |r| draw_overlay(r, sp, &panels, synthetic).map_err(|e| e.to_string()),
            |r| draw_overlay(r, sp, &panels, synthetic).map_err(|e| e.to_string()),
        )?;
        crate::io::write_outputs(&files)?;
        written.extend(files.into_iter().map(|f| f.0));
    }
    Ok((written, skipped))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Best per row is bolded only among several models, and the CSV has a row per
    /// species and model.
    #[test]
    fn tables_mark_the_best_model_per_species() {
        let dir = tempfile::tempdir().unwrap();
        let write_fit = |folder: &Path, name: &str, nrmse: f64| {
            std::fs::create_dir_all(folder).unwrap();
            let p = crate::params::FurParams::preset("red-fox").unwrap();
            let v = serde_json::json!({"params": p.to_json_value(), "exposure": 1.0,
                "nrmse": nrmse, "solver": {"wall_time_s": 1.5, "evaluations": 10},
                "data": {"n_used": 100, "synthetic": true}, "species": name});
            std::fs::write(folder.join(format!("{name}.json")), v.to_string()).unwrap();
        };
        write_fit(dir.path(), "red-fox", 0.03);
        write_fit(dir.path(), "cat", 0.05);
        let (by_model, skipped) = read_all(dir.path());
        assert!(skipped.is_empty(), "{skipped:?}");
        assert_eq!(by_model.len(), 1);
        let md = markdown(&by_model, dir.path());
        // One model: nothing to mark.
        assert!(!md.contains("**"), "{md}");
        assert!(md.contains("| red-fox | 3.00% | 6.2% |"), "{md}");
        let c = csv(&by_model);
        assert_eq!(c.lines().count(), 3, "{c}");
        assert!(
            c.contains("fox,yan2017,0.03,10,100,1.5,10,true,0.062"),
            "{c}"
        );
    }
}

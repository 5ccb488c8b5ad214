//! `reports/fit_error_vs_time.{csv,png,svg}`: each fit's error against wall time and
//! against LM iterations, from the `trace` of its fit file. The stages: `global` (the
//! best score among the global stage's starts), `subsample` (LM on the subsample from
//! the start that ended best there), `full` (LM polish on all samples used), `retry` (a
//! second polish from another start, kept when it ended lower); the subsample stages'
//! values are measured on the subsample.
//!
//! The fitter records every trace value under `nrmse`, but for a fit made with
//! `--weighted` they are the RMS of the *weighted* normalised log residuals, not the
//! NRMSE (often several times smaller): those fits get the metric `weighted_rms` in the
//! CSV and their own row of panels in the figure, never an NRMSE axis.

use super::fig11::{ensure_font, FONT};
use super::plot::plot_err;
use crate::error::Result;
use crate::fit::file::FitFile;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::fmt::Write as _;
use std::path::Path;

/// What a fit's trace values are (the CSV's `metric`).
fn metric(f: &FitFile) -> &'static str {
    if f.weighted {
        "weighted_rms"
    } else {
        "nrmse"
    }
}

/// The CSV: one row per trace point, `metric` saying what `value` is (`nrmse`, or
/// `weighted_rms` for a weighted fit).
pub fn csv(fits: &[FitFile]) -> String {
    let mut s = String::from("species,stage,iter,time_s,metric,value\n");
    for f in fits {
        let m = metric(f);
        for (stage, it, t, e) in &f.trace {
            let _ = writeln!(s, "{},{stage},{it},{t},{m},{e}", f.label());
        }
    }
    s
}

/// The paragraph of `nrmse.md` that introduces the figure: what the stages are and, when
/// any fit was weighted, that its values are no NRMSE.
pub fn description(fits: &[FitFile]) -> String {
    let mut s = String::from(
        "## Fit error vs time\n\n\
         `fit_error_vs_time.{png,svg,csv}`: each fit's convergence trace against wall time \
         and LM iterations. Stages: `global` (a cross, not joined to the line) is the best \
         score among the global stage's starts on the subsample; the line is the LM path of \
         the start that ended best on the subsample (`subsample`, measured on the \
         subsample; it may have begun from another scored start than the best, so above \
         the cross), then its polish on all samples used (`full`, from the same parameters: \
         the step between the two is the change of samples), and a second polish from \
         another start when it ended lower (`retry`, a line of its own).",
    );
    let weighted: Vec<String> = fits
        .iter()
        .filter(|f| f.weighted)
        .map(|f| f.label())
        .collect();
    if weighted.is_empty() {
        s.push_str(" Every value is an NRMSE (`metric` = `nrmse` in the CSV).\n");
    } else {
        let _ = writeln!(
            s,
            " The fits made with `--weighted` ({}) trace the RMS of the WEIGHTED normalised \
             log residuals, which is NOT an NRMSE and not comparable with one: they have \
             their own row of panels, their legend says \"(weighted RMS, not NRMSE)\", the \
             CSV gives them `metric` = `weighted_rms`; their NRMSE is the table's.",
            weighted.join(", ")
        );
    }
    s
}

/// A fit's trace as drawn against `x`: the global stage's points (markers only) and the
/// LM paths (one line each). The global point is not joined to the LM path, which is
/// that of the start that ended best, not of the best scored start. A new path begins at
/// the first `retry` point and wherever the value rises within a stage: an LM run
/// records only accepted steps, which never raise its cost, so a rise is another run's
/// first point.
#[allow(clippy::type_complexity)]
fn paths(
    trace: &[(String, u64, f64, f64)],
    x: impl Fn(&(String, u64, f64, f64)) -> f64,
) -> (Vec<(f64, f64)>, Vec<Vec<(f64, f64)>>) {
    let plottable = |p: (f64, f64)| p.0.is_finite() && p.1.is_finite() && p.1 > 0.0;
    let mut global = Vec::new();
    let mut runs: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut prev: Option<&(String, u64, f64, f64)> = None;
    for t in trace {
        let p = (x(t), t.3);
        if t.0 == "global" {
            if plottable(p) {
                global.push(p);
            }
            prev = None;
            continue;
        }
        let new_run = match prev {
            None => true,
            Some(q) => (t.0 == "retry" && q.0 != "retry") || (t.0 == q.0 && t.3 > q.3),
        };
        if new_run {
            runs.push(Vec::new());
        }
        if plottable(p) {
            if let Some(r) = runs.last_mut() {
                r.push(p);
            }
        }
        prev = Some(t);
    }
    runs.retain(|r| !r.is_empty());
    (global, runs)
}

/// One row of two panels (against wall time, against iterations) for `fits`, all of
/// whose traces are of one metric (`weighted`: weighted RMS residuals, else NRMSE).
fn draw_row<DB: DrawingBackend>(
    row: &DrawingArea<DB, Shift>,
    fits: &[&FitFile],
    weighted: bool,
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let panels = row.split_evenly((1, 2));
    let all: Vec<&(String, u64, f64, f64)> = fits.iter().flat_map(|f| f.trace.iter()).collect();
    let good = |x: f64| x.is_finite() && x > 0.0;
    let emin = all
        .iter()
        .map(|t| t.3)
        .filter(|x| good(*x))
        .fold(f64::INFINITY, f64::min);
    let emax = all
        .iter()
        .map(|t| t.3)
        .filter(|x| good(*x))
        .fold(0.0, f64::max);
    let (emin, emax) = if emax > 0.0 {
        (emin * 0.8, emax * 1.25)
    } else {
        (1e-3, 1.0)
    };
    let tmax = all
        .iter()
        .map(|t| t.2)
        .filter(|x| x.is_finite())
        .fold(0.0, f64::max)
        .max(1e-3)
        * 1.05;
    let imax = all.iter().map(|t| t.1).max().unwrap_or(1).max(1) as f64 * 1.05;
    let (what, y_desc) = if weighted {
        (
            "weighted RMS (NOT NRMSE)",
            "weighted RMS of normalised ln residuals",
        )
    } else {
        ("NRMSE", "NRMSE")
    };
    for (k, (xdesc, xmax)) in [
        ("wall time since fit start (s)", tmax),
        ("LM iteration", imax),
    ]
    .into_iter()
    .enumerate()
    {
        let mut ch = ChartBuilder::on(&panels[k])
            .caption(format!("{what} vs {xdesc}"), (FONT, 16))
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(56)
            .build_cartesian_2d(0.0..xmax, emin..emax)?;
        // Linear: a fit's NRMSE spans well under a decade, where a log axis gets no labels.
        ch.configure_mesh()
            .x_desc(xdesc)
            .y_desc(y_desc)
            .y_labels(8)
            .y_label_formatter(&|v| format!("{:.2}%", 100.0 * v))
            .label_style((FONT, 12))
            .draw()?;
        for (i, f) in fits.iter().enumerate() {
            let c = Palette99::pick(i).to_rgba();
            let (global, runs) = paths(&f.trace, |t| if k == 0 { t.2 } else { t.1 as f64 });
            let label = if weighted {
                format!("{} (weighted RMS, not NRMSE)", f.label())
            } else {
                f.label()
            };
            for (r, pts) in runs.into_iter().enumerate() {
                let s = ch.draw_series(LineSeries::new(pts.clone(), c.stroke_width(2)))?;
                if r == 0 {
                    s.label(label.clone())
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 14, y)], c));
                }
                ch.draw_series(pts.into_iter().map(|p| Circle::new(p, 2, c.filled())))?;
            }
            ch.draw_series(
                global
                    .into_iter()
                    .map(|p| Cross::new(p, 5, c.stroke_width(2))),
            )?;
        }
        ch.draw_series(std::iter::empty::<Cross<(f64, f64), i32>>())?
            .label("global stage: best scored start")
            .legend(|(x, y)| Cross::new((x + 7, y), 5, BLACK.stroke_width(2)));
        ch.configure_series_labels()
            .label_font((FONT, 12))
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()?;
    }
    Ok(())
}

/// The fits in rows of one metric each: NRMSE first, then weighted RMS.
fn rows(fits: &[FitFile]) -> Vec<(bool, Vec<&FitFile>)> {
    [false, true]
        .into_iter()
        .map(|w| {
            (
                w,
                fits.iter().filter(|f| f.weighted == w).collect::<Vec<_>>(),
            )
        })
        .filter(|(_, fs)| !fs.is_empty())
        .collect()
}

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    fits: &[FitFile],
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    root.fill(&WHITE)?;
    let rows = rows(fits);
    let areas = root.split_evenly((rows.len().max(1), 1));
    for ((weighted, fs), area) in rows.iter().zip(&areas) {
        draw_row(area, fs, *weighted)?;
    }
    root.present()?;
    Ok(())
}

/// Figure size: 560 pixels of height per row of panels.
fn size(fits: &[FitFile]) -> (u32, u32) {
    (1400, 560 * rows(fits).len().max(1) as u32)
}

/// Write the CSV, PNG and SVG into `out`.
pub fn write(fits: &[FitFile], out: &Path) -> Result<()> {
    ensure_font();
    crate::io::write_output(&out.join("fit_error_vs_time.csv"), csv(fits).as_bytes())?;
    let size = size(fits);
    let png = out.join("fit_error_vs_time.png");
    let bytes =
        super::plot::png_bytes(size, &png, |root| draw(root, fits).map_err(plot_err(&png)))?;
    crate::io::write_output(&png, &bytes)?;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        draw(root, fits).map_err(plot_err(out))?;
    }
    crate::io::write_output(&out.join("fit_error_vs_time.svg"), svg.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fit file `<name>.json` in `dir` with the given trace (values as the fitter
    /// records them, under `nrmse`) and `solver.weighted`.
    fn fit(dir: &Path, name: &str, weighted: bool, trace: &[(&str, u64, f64)]) -> FitFile {
        let trace: Vec<_> = trace
            .iter()
            .map(|(s, i, e)| serde_json::json!({"stage": s, "iter": i, "time_s": *i as f64 * 0.1, "nrmse": e}))
            .collect();
        let v = serde_json::json!({
            "params": crate::FurParams::preset("cat").unwrap().to_json_value(),
            "exposure": 1.0,
            "nrmse": 0.0107,
            "solver": {"weighted": weighted},
            "trace": trace,
        });
        let p = dir.join(format!("{name}.json"));
        std::fs::write(&p, v.to_string()).unwrap();
        FitFile::read(&p).unwrap().remove(0)
    }

    /// The trace shape of the audit: the global stage's best score, then the LM path of
    /// another start (beginning higher), its polish, and a retry from a third start.
    const TRACE: &[(&str, u64, f64)] = &[
        ("global", 0, 0.0085),
        ("subsample", 0, 0.044),
        ("subsample", 3, 0.02),
        ("full", 3, 0.012),
        ("full", 9, 0.0107),
        ("retry", 20, 0.03),
        ("retry", 25, 0.0106),
    ];

    /// A weighted fit's trace is written as `weighted_rms`, never as `nrmse`.
    #[test]
    fn csv_names_the_metric_of_each_fit() {
        let tmp = tempfile::tempdir().unwrap();
        let fits = [
            fit(tmp.path(), "plain", false, TRACE),
            fit(tmp.path(), "weighted", true, TRACE),
        ];
        let text = csv(&fits);
        let mut lines = text.lines();
        assert_eq!(lines.next(), Some("species,stage,iter,time_s,metric,value"));
        for l in lines {
            let metric = l.split(',').nth(4).unwrap();
            let want = if l.starts_with("weighted,") {
                "weighted_rms"
            } else {
                "nrmse"
            };
            assert_eq!(metric, want, "{l}");
        }
        assert!(
            text.contains("weighted,global,0,0,weighted_rms,0.0085"),
            "{text}"
        );
    }

    /// The global point stands alone, and each LM run is its own line: joining them drew
    /// a jump (0.85 % to 4.4 %) that no iterate made.
    #[test]
    fn global_point_and_each_run_are_drawn_apart() {
        let trace: Vec<(String, u64, f64, f64)> = TRACE
            .iter()
            .map(|(s, i, e)| (s.to_string(), *i, f64::NAN, *e))
            .collect();
        let (global, runs) = paths(&trace, |t| t.1 as f64);
        assert_eq!(global, vec![(0.0, 0.0085)]);
        let ys: Vec<Vec<f64>> = runs
            .iter()
            .map(|r| r.iter().map(|p| p.1).collect())
            .collect();
        assert_eq!(
            ys,
            vec![vec![0.044, 0.02, 0.012, 0.0107], vec![0.03, 0.0106]]
        );
        // A rise within a stage is another run's first point.
        let trace: Vec<(String, u64, f64, f64)> = [(0, 0.05), (4, 0.02), (5, 0.04), (8, 0.01)]
            .iter()
            .map(|(i, e)| ("retry".to_string(), *i, 0.0, *e))
            .collect();
        assert_eq!(paths(&trace, |t| t.1 as f64).1.len(), 2);
    }

    /// A weighted fit never sits on an NRMSE axis: it gets its own row of panels, its
    /// legend says what it is, and the Markdown names it.
    #[test]
    fn weighted_fits_are_not_plotted_as_nrmse() {
        let tmp = tempfile::tempdir().unwrap();
        let fits = [
            fit(tmp.path(), "plain", false, TRACE),
            fit(tmp.path(), "wfit", true, TRACE),
        ];
        assert_eq!(size(&fits), (1400, 1120));
        let mut svg = String::new();
        {
            let root = SVGBackend::with_string(&mut svg, size(&fits)).into_drawing_area();
            ensure_font();
            draw(root, &fits).unwrap();
        }
        for want in [
            "NRMSE vs LM iteration",
            "weighted RMS (NOT NRMSE) vs LM iteration",
            "wfit (weighted RMS, not NRMSE)",
            "global stage: best scored start",
        ] {
            assert!(svg.contains(want), "no '{want}' in the SVG");
        }
        // Alone, the weighted fit has no NRMSE panel at all.
        let mut svg = String::new();
        {
            let one = &fits[1..];
            let root = SVGBackend::with_string(&mut svg, size(one)).into_drawing_area();
            draw(root, one).unwrap();
        }
        assert!(!svg.contains(">NRMSE"), "an NRMSE axis for a weighted fit");
        let md = description(&fits);
        assert!(md.contains("(wfit) trace the RMS of the WEIGHTED"), "{md}");
        assert!(description(&fits[..1]).contains("Every value is an NRMSE"));
    }
}

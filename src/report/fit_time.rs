//! `reports/fit_error_vs_time.{csv,png,svg}`: NRMSE against wall time and against LM
//! iterations per species, from the `trace` of each fit file (the best start's path:
//! after the global stage, LM on the subsample, then LM on all samples; the subsample
//! stages' NRMSE is measured on the subsample).

use super::fig11::{ensure_font, FONT};
use super::nrmse::FitFile;
use crate::error::{Error, Result};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::fmt::Write as _;
use std::path::Path;

/// The CSV: one row per trace point.
pub fn csv(fits: &[FitFile]) -> String {
    let mut s = String::from("species,stage,iter,time_s,nrmse\n");
    for f in fits {
        for (stage, it, t, e) in &f.trace {
            let _ = writeln!(s, "{},{stage},{it},{t},{e}", f.label());
        }
    }
    s
}

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, Shift>,
    fits: &[FitFile],
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    root.fill(&WHITE)?;
    let panels = root.split_evenly((1, 2));
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
    for (k, (xdesc, xmax)) in [
        ("wall time since fit start (s)", tmax),
        ("LM iteration", imax),
    ]
    .into_iter()
    .enumerate()
    {
        let mut ch = ChartBuilder::on(&panels[k])
            .caption(format!("NRMSE vs {xdesc}"), (FONT, 16))
            .margin(10)
            .x_label_area_size(36)
            .y_label_area_size(56)
            .build_cartesian_2d(0.0..xmax, emin..emax)?;
        // Linear: a fit's NRMSE spans well under a decade, where a log axis gets no labels.
        ch.configure_mesh()
            .x_desc(xdesc)
            .y_desc("NRMSE")
            .y_labels(8)
            .y_label_formatter(&|v| format!("{:.2}%", 100.0 * v))
            .label_style((FONT, 12))
            .draw()?;
        for (i, f) in fits.iter().enumerate() {
            let c = Palette99::pick(i).to_rgba();
            let pts: Vec<(f64, f64)> = f
                .trace
                .iter()
                .map(|t| (if k == 0 { t.2 } else { t.1 as f64 }, t.3))
                .filter(|(x, y)| x.is_finite() && good(*y))
                .collect();
            ch.draw_series(LineSeries::new(pts.clone(), c.stroke_width(2)))?
                .label(f.label())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 14, y)], c));
            ch.draw_series(pts.into_iter().map(|p| Circle::new(p, 2, c.filled())))?;
        }
        ch.configure_series_labels()
            .label_font((FONT, 12))
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()?;
    }
    root.present()?;
    Ok(())
}

/// Write the CSV, PNG and SVG into `out`.
pub fn write(fits: &[FitFile], out: &Path) -> Result<()> {
    ensure_font();
    crate::io::write_output(&out.join("fit_error_vs_time.csv"), csv(fits).as_bytes())?;
    let size = (1400u32, 560u32);
    let png = out.join("fit_error_vs_time.png");
    let tmp = out.join(".fit_error_vs_time.tmp.png");
    {
        let root = BitMapBackend::new(&tmp, size).into_drawing_area();
        draw(root, fits).map_err(|e| Error::file(&png, format!("plotting failed: {e:?}")))?;
    }
    let bytes = std::fs::read(&tmp).map_err(|e| Error::io(&tmp, e))?;
    let _ = std::fs::remove_file(&tmp);
    crate::io::write_output(&png, &bytes)?;
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, size).into_drawing_area();
        draw(root, fits).map_err(|e| Error::file(out, format!("plotting failed: {e:?}")))?;
    }
    crate::io::write_output(&out.join("fit_error_vs_time.svg"), svg.as_bytes())
}

//! Shared plotting helpers for reports: the shipped DejaVu Sans font (no system fonts) and
//! a log-log line chart written to PNG and SVG atomically.

use crate::error::{Error, Result};
use plotters::prelude::*;
use plotters::style::FontStyle;
use std::path::{Path, PathBuf};
use std::sync::Once;

/// The font shipped with the crate (`assets/fonts/DejaVuSans.ttf`).
pub static FONT_BYTES: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");

/// Font family name under which [`FONT_BYTES`] is registered.
pub const FONT: &str = "sans-serif";

/// Register the shipped font with plotters (once per process; every style maps to it).
pub fn register_fonts() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        for style in [
            FontStyle::Normal,
            FontStyle::Bold,
            FontStyle::Italic,
            FontStyle::Oblique,
        ] {
            // The bytes are a valid TrueType font shipped with the crate.
            let _ = plotters::style::register_font(FONT, style, FONT_BYTES);
        }
    });
}

/// The error for a plotting failure while drawing `path` (plotters' errors name no file).
pub(super) fn plot_err<E: std::fmt::Debug>(path: &Path) -> impl Fn(E) -> Error + '_ {
    move |e| Error::file(path, format!("plotting failed: {e:?}"))
}

/// One line of a chart.
#[derive(Clone, Debug)]
pub struct Series {
    /// Legend label.
    pub name: String,
    /// `(x, y)` points; non-positive or non-finite points are skipped on log axes.
    pub points: Vec<(f64, f64)>,
    /// Draw markers at the points as well as the line.
    pub markers: bool,
}

/// Labels of a chart.
#[derive(Clone, Debug)]
pub struct ChartSpec<'a> {
    /// Title above the chart.
    pub title: &'a str,
    /// Label of the x axis.
    pub x_label: &'a str,
    /// Label of the y axis.
    pub y_label: &'a str,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
}

const PALETTE: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(23, 190, 207),
];

fn log_range(series: &[Series], pick: impl Fn(&(f64, f64)) -> f64) -> (f64, f64) {
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for s in series {
        for p in &s.points {
            let v = pick(p);
            if v.is_finite() && v > 0.0 && pick(&(p.0, p.0)).is_finite() {
                lo = lo.min(v);
                hi = hi.max(v);
            }
        }
    }
    if !lo.is_finite() {
        return (1e-3, 1.0);
    }
    let (lo, hi) = (lo / 1.5, hi * 1.5);
    if hi <= lo {
        (lo / 10.0, lo * 10.0)
    } else {
        (lo, hi)
    }
}

fn draw<DB: DrawingBackend>(
    root: DrawingArea<DB, plotters::coord::Shift>,
    spec: &ChartSpec,
    series: &[Series],
) -> std::result::Result<(), String> {
    root.fill(&WHITE).map_err(|e| e.to_string())?;
    let (x0, x1) = log_range(series, |p| p.0);
    let (y0, y1) = log_range(series, |p| p.1);
    let mut chart = ChartBuilder::on(&root)
        .caption(spec.title, (FONT, 20))
        .margin(12)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
        .map_err(|e| e.to_string())?;
    chart
        .configure_mesh()
        .x_desc(spec.x_label)
        .y_desc(spec.y_label)
        .label_style((FONT, 13))
        .axis_desc_style((FONT, 15))
        .x_label_formatter(&|v| format!("{v:.0e}"))
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .draw()
        .map_err(|e| e.to_string())?;
    for (k, s) in series.iter().enumerate() {
        let color = PALETTE[k % PALETTE.len()];
        let pts: Vec<(f64, f64)> = s
            .points
            .iter()
            .copied()
            .filter(|p| p.0.is_finite() && p.1.is_finite() && p.0 > 0.0 && p.1 > 0.0)
            .collect();
        chart
            .draw_series(LineSeries::new(pts.clone(), color.stroke_width(2)))
            .map_err(|e| e.to_string())?
            .label(s.name.clone())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(2))
            });
        if s.markers {
            chart
                .draw_series(pts.iter().map(|&p| Circle::new(p, 3, color.filled())))
                .map_err(|e| e.to_string())?;
        }
    }
    chart
        .configure_series_labels()
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .label_font((FONT, 13))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(|e| e.to_string())?;
    root.present().map_err(|e| e.to_string())?;
    Ok(())
}

/// A log-log line chart as the bytes of `png` and `svg` (either may be `None`), for the
/// caller to write with the rest of its report.
pub fn loglog_chart(
    png: Option<&Path>,
    svg: Option<&Path>,
    spec: &ChartSpec,
    series: &[Series],
) -> Result<Vec<(PathBuf, Vec<u8>)>> {
    register_fonts();
    let mut files = Vec::new();
    if let Some(path) = svg {
        let mut text = String::new();
        {
            let root =
                SVGBackend::with_string(&mut text, (spec.width, spec.height)).into_drawing_area();
            draw(root, spec, series).map_err(|e| Error::file(path, format!("plot: {e}")))?;
        }
        files.push((path.to_path_buf(), text.into_bytes()));
    }
    if let Some(path) = png {
        let bytes = png_bytes((spec.width, spec.height), path, |root| {
            draw(root, spec, series).map_err(|e| Error::file(path, format!("plot: {e}")))
        })?;
        files.push((path.to_path_buf(), bytes));
    }
    Ok(files)
}

/// The PNG bytes of a plot of `size` drawn by `draw` into memory (no temporary file to
/// leave behind if the run is stopped); `path` names the plot in errors.
pub fn png_bytes(
    size: (u32, u32),
    path: &Path,
    draw: impl FnOnce(DrawingArea<BitMapBackend<'_>, plotters::coord::Shift>) -> Result<()>,
) -> Result<Vec<u8>> {
    let (w, h) = size;
    let mut buf = vec![0u8; (w as usize) * (h as usize) * 3];
    draw(BitMapBackend::with_buffer(&mut buf, size).into_drawing_area())?;
    let img = image::RgbImage::from_raw(w, h, buf)
        .ok_or_else(|| Error::file(path, "plot buffer has the wrong size"))?;
    let mut bytes = Vec::new();
    img.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .map_err(|e| Error::file(path, format!("PNG encoding: {e}")))?;
    Ok(bytes)
}

/// A tick label for a log axis: three significant digits without binary noise (plotters'
/// default printed 0.30000000000000004), scientific outside 1e-3..1e4.
pub fn tick(v: &f64) -> String {
    let a = v.abs();
    if a == 0.0 || !a.is_finite() {
        return format!("{v}");
    }
    let mag = a.log10().floor();
    if !(-3.0..4.0).contains(&mag) {
        return format!("{v:.1e}");
    }
    let s = format!("{:.*}", (2.0 - mag).max(0.0) as usize, v);
    if s.contains('.') {
        s.trim_end_matches('0').trim_end_matches('.').to_string()
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn ticks_have_no_binary_noise() {
        assert_eq!(super::tick(&0.30000000000000004), "0.3");
        assert_eq!(super::tick(&0.6000000000000001), "0.6");
        assert_eq!(super::tick(&12.5), "12.5");
        assert_eq!(super::tick(&2e-5), "2.0e-5");
    }

    use super::*;

    #[test]
    fn writes_png_and_svg_with_the_shipped_font() {
        let dir = tempfile::tempdir().unwrap();
        let (png, svg) = (dir.path().join("a.png"), dir.path().join("a.svg"));
        let s = vec![Series {
            name: "x^-2".into(),
            points: (1..20).map(|i| (i as f64, 1.0 / (i * i) as f64)).collect(),
            markers: true,
        }];
        let spec = ChartSpec {
            title: "test",
            x_label: "x",
            y_label: "y",
            width: 320,
            height: 240,
        };
        crate::io::write_atomic_all(&loglog_chart(Some(&png), Some(&svg), &spec, &s).unwrap())
            .unwrap();
        let bytes = std::fs::read(&png).unwrap();
        assert_eq!(&bytes[1..4], b"PNG");
        let text = std::fs::read_to_string(&svg).unwrap();
        assert!(text.contains("<svg") && text.contains("x^-2"));
    }
}

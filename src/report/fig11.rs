//! Per-species seed-Fig.-11-style figure (`reports/fig11_<fit file stem>.{png,svg}`): for each
//! incident angle (rows) the measured profile, the fitted profile and the log residual as
//! `theta_r x phi` heat maps, measured and fitted on ONE log colour scale, plus the
//! per-lobe contributions of the fit (R, TT, TRT, TTs, TRTs, times the exposure) along
//! `phi` at the outgoing angle nearest the specular cone `theta_r = -theta_i`, with the
//! measured samples there as dots.
//!
//! Plotters with the shipped DejaVuSans font only (registered from `assets/fonts`).

use super::plot::plot_err;
use crate::error::{Error, Result};
use crate::fit::file::FitFile;
use crate::fit::forward::Points;
use crate::model::far::FarOptions;
use crate::profile::Profile;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::collections::BTreeMap;
use std::path::Path;

/// Font family name under which the shipped font is registered.
pub const FONT: &str = "DejaVuSans";

/// Register `assets/fonts/DejaVuSans.ttf` with plotters (idempotent).
pub fn ensure_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let bytes: &'static [u8] = include_bytes!("../../assets/fonts/DejaVuSans.ttf");
        // The shipped font is a valid TTF; a failure would only lose text, never data.
        let _ = plotters::style::register_font(FONT, FontStyle::Normal, bytes);
    });
}

/// Perceptual-ish sequential map (viridis control points, linear in between), t in [0, 1].
pub fn viridis(t: f64) -> RGBColor {
    const C: [(f64, f64, f64); 5] = [
        (68.0, 1.0, 84.0),
        (59.0, 82.0, 139.0),
        (33.0, 145.0, 140.0),
        (94.0, 201.0, 98.0),
        (253.0, 231.0, 37.0),
    ];
    let t = if t.is_finite() {
        t.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let x = t * 4.0;
    let i = (x.floor() as usize).min(3);
    let f = x - i as f64;
    let (a, b) = (C[i], C[i + 1]);
    RGBColor(
        (a.0 + f * (b.0 - a.0)) as u8,
        (a.1 + f * (b.1 - a.1)) as u8,
        (a.2 + f * (b.2 - a.2)) as u8,
    )
}

/// Diverging blue-white-red map, t in [-1, 1].
pub fn diverging(t: f64) -> RGBColor {
    let t = if t.is_finite() {
        t.clamp(-1.0, 1.0)
    } else {
        0.0
    };
    if t < 0.0 {
        let f = -t;
        RGBColor(
            (255.0 * (1.0 - f) + 33.0 * f) as u8,
            (255.0 * (1.0 - f) + 102.0 * f) as u8,
            (255.0 * (1.0 - f) + 172.0 * f) as u8,
        )
    } else {
        RGBColor(
            (255.0 * (1.0 - t) + 178.0 * t) as u8,
            (255.0 * (1.0 - t) + 24.0 * t) as u8,
            (255.0 * (1.0 - t) + 43.0 * t) as u8,
        )
    }
}

/// One incident angle's data on its grid.
struct Slice {
    theta_i: f64,
    theta_r: Vec<f64>,
    phi: Vec<f64>,
    /// `(theta_r, phi)` -> (measured or NaN, per-lobe fitted incl. exposure).
    cells: BTreeMap<(i64, i64), (f64, [f64; 5])>,
    /// The fit's model's lobe names, in the slots of `cells`.
    names: &'static [&'static str],
}

fn key(x: f64) -> i64 {
    (x * 1e6).round() as i64
}

fn half_widths(v: &[f64]) -> Vec<(f64, f64)> {
    (0..v.len())
        .map(|i| {
            let lo = if i > 0 {
                0.5 * (v[i] - v[i - 1])
            } else if v.len() > 1 {
                0.5 * (v[1] - v[0])
            } else {
                1.0
            };
            let hi = if i + 1 < v.len() {
                0.5 * (v[i + 1] - v[i])
            } else {
                lo
            };
            (v[i] - lo, v[i] + hi)
        })
        .collect()
}

fn slices(profile: &Profile, channel: usize, fit: &FitFile, far: &FarOptions) -> Vec<Slice> {
    let samples: Vec<_> = profile
        .samples
        .iter()
        .filter(|s| s.channel == channel)
        .collect();
    let mut pts = Points::default();
    for s in &samples {
        let (a, b, c) = s.angles_rad();
        pts.push(a, b, c);
    }
    let p = &fit.params;
    let lobes = p
        .model
        .predict(
            &p.values,
            &pts,
            far,
            crate::model::LobeSet::ALL,
            crate::models::Integral::Far,
        )
        .lobes;
    let mut by_ti: BTreeMap<i64, Slice> = BTreeMap::new();
    for (s, l) in samples.iter().zip(&lobes) {
        let sl = by_ti.entry(key(s.theta_i)).or_insert_with(|| Slice {
            theta_i: s.theta_i,
            theta_r: Vec::new(),
            phi: Vec::new(),
            cells: BTreeMap::new(),
            names: p.model.lobe_names(),
        });
        let meas = if s.is_valid() { s.value } else { f64::NAN };
        let mut v = l.0;
        v.iter_mut().for_each(|x| *x *= fit.exposure);
        sl.cells.insert((key(s.theta_r), key(s.phi)), (meas, v));
        sl.theta_r.push(s.theta_r);
        sl.phi.push(s.phi);
    }
    let mut out: Vec<Slice> = by_ti.into_values().collect();
    for s in &mut out {
        for v in [&mut s.theta_r, &mut s.phi] {
            v.sort_by(f64::total_cmp);
            v.dedup_by(|a, b| key(*a) == key(*b));
        }
    }
    // At most four incident angles, spread over the range.
    if out.len() > 4 {
        let n = out.len();
        let pick: Vec<usize> = (0..4).map(|i| i * (n - 1) / 3).collect();
        out = out
            .into_iter()
            .enumerate()
            .filter(|(i, _)| pick.contains(i))
            .map(|(_, s)| s)
            .collect();
    }
    out
}

type Area<'a, DB> = DrawingArea<DB, Shift>;

#[allow(clippy::too_many_arguments)]
fn heat<DB: DrawingBackend>(
    area: &Area<'_, DB>,
    title: &str,
    sl: &Slice,
    value: &dyn Fn(f64, [f64; 5]) -> f64,
    color: &dyn Fn(f64) -> RGBColor,
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let (r0, r1) = (sl.theta_r[0], *sl.theta_r.last().unwrap_or(&sl.theta_r[0]));
    let mut ch = ChartBuilder::on(area)
        .caption(title, (FONT, 14))
        .margin(4)
        .x_label_area_size(28)
        .y_label_area_size(36)
        .build_cartesian_2d(-180.0..180.0, (r0 - 1.0)..(r1 + 1.0))?;
    ch.configure_mesh()
        .disable_mesh()
        .x_desc("phi (deg)")
        .y_desc("theta_r (deg)")
        .label_style((FONT, 11))
        .x_labels(5)
        .y_labels(5)
        .draw()?;
    let hr = half_widths(&sl.theta_r);
    let hp = half_widths(&sl.phi);
    let mut rects = Vec::new();
    for (i, tr) in sl.theta_r.iter().enumerate() {
        for (j, ph) in sl.phi.iter().enumerate() {
            let c = match sl.cells.get(&(key(*tr), key(*ph))) {
                Some(&(m, l)) => {
                    let v = value(m, l);
                    if v.is_finite() {
                        color(v)
                    } else {
                        RGBColor(160, 160, 160)
                    }
                }
                None => RGBColor(230, 230, 230),
            };
            rects.push(Rectangle::new(
                [(hp[j].0, hr[i].0), (hp[j].1, hr[i].1)],
                c.filled(),
            ));
        }
    }
    ch.draw_series(rects)?;
    Ok(())
}

/// What the figure calls the profile the fit was made to: never "measured" for
/// simulated data (the project's rule: synthetic data is always labelled so).
fn data_word(synthetic: bool) -> &'static str {
    if synthetic {
        "synthetic data"
    } else {
        "data"
    }
}

fn lobe_panel<DB: DrawingBackend>(
    area: &Area<'_, DB>,
    sl: &Slice,
    word: &str,
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    let tr = *sl
        .theta_r
        .iter()
        .min_by(|a, b| (*a + sl.theta_i).abs().total_cmp(&(*b + sl.theta_i).abs()))
        .unwrap_or(&0.0);
    let row: Vec<(f64, f64, [f64; 5])> = sl
        .phi
        .iter()
        .filter_map(|ph| {
            sl.cells
                .get(&(key(tr), key(*ph)))
                .map(|&(m, l)| (*ph, m, l))
        })
        .collect();
    let logs = row.iter().flat_map(|(_, m, l)| {
        let mut v: Vec<f64> = l.iter().map(|x| x.log10()).collect();
        v.push(m.log10());
        v.push(l.iter().sum::<f64>().log10());
        v
    });
    let vals: Vec<f64> = logs.filter(|x| x.is_finite()).collect();
    let hi = vals.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let lo = vals
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min)
        .max(hi - 6.0);
    let (lo, hi) = if hi.is_finite() {
        (lo - 0.1, hi + 0.1)
    } else {
        (-1.0, 1.0)
    };
    let mut ch = ChartBuilder::on(area)
        .caption(format!("lobes at theta_r = {tr:.0} deg"), (FONT, 14))
        .margin(4)
        .x_label_area_size(28)
        .y_label_area_size(36)
        .build_cartesian_2d(-180.0..180.0, lo..hi)?;
    ch.configure_mesh()
        .x_desc("phi (deg)")
        .y_desc("log10 value")
        .label_style((FONT, 11))
        .x_labels(5)
        .y_labels(5)
        .draw()?;
    let colors = [RED, BLUE, GREEN, MAGENTA, CYAN];
    for (li, lobe) in sl.names.iter().enumerate() {
        let runs = visible_runs(row.iter().map(|(p, _, l)| (*p, l[li].log10())), lo);
        let c = colors[li];
        for (k, pts) in runs.into_iter().enumerate() {
            let s = ch.draw_series(LineSeries::new(pts, c.stroke_width(1)))?;
            if k == 0 {
                s.label(*lobe)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 14, y)], c));
            }
        }
    }
    let total: Vec<(f64, f64)> = row
        .iter()
        .map(|(p, _, l)| (*p, l.iter().sum::<f64>().log10()))
        .filter(|(_, y)| y.is_finite())
        .collect();
    ch.draw_series(LineSeries::new(total, BLACK.stroke_width(2)))?
        .label("fit")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 14, y)], BLACK));
    ch.draw_series(
        row.iter()
            .filter(|(_, m, _)| m.is_finite() && m.log10() >= lo)
            .map(|(p, m, _)| Circle::new((*p, m.log10()), 2, BLACK.filled())),
    )?
    .label(word)
    .legend(|(x, y)| Circle::new((x + 7, y), 2, BLACK.filled()));
    ch.configure_series_labels()
        .position(SeriesLabelPosition::LowerLeft)
        .label_font((FONT, 10))
        .background_style(WHITE.mix(0.8))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}

fn draw<DB: DrawingBackend>(
    root: Area<'_, DB>,
    species: &str,
    sls: &[Slice],
    nrmse: f64,
    synthetic: bool,
) -> std::result::Result<(), DrawingAreaErrorKind<DB::ErrorType>> {
    root.fill(&WHITE)?;
    let word = data_word(synthetic);
    let (top, body) = root.split_vertically(40);
    top.draw(&Text::new(
        format!(
            "{species}: {word} | fitted | ln(fit/data), one log10 scale for both profiles; NRMSE {:.2}% ({})",
            100.0 * nrmse,
            if synthetic {
                "SYNTHETIC data"
            } else {
                "data not marked synthetic"
            }
        ),
        (10, 12),
        (FONT, 16),
    ))?;
    // One log scale for measured and fitted, over all incident angles.
    let mut lo = f64::INFINITY;
    let mut hi = f64::NEG_INFINITY;
    let mut rmax: f64 = 0.0;
    for sl in sls {
        for &(m, l) in sl.cells.values() {
            if m.is_finite() && m > 0.0 {
                lo = lo.min(m.log10());
                hi = hi.max(m.log10());
                let f: f64 = l.iter().sum();
                if f > 0.0 {
                    rmax = rmax.max((f.ln() - m.ln()).abs());
                }
            }
        }
    }
    if !lo.is_finite() {
        lo = -1.0;
        hi = 0.0;
    }
    let span = (hi - lo).max(1e-9);
    let rmax = rmax.max(0.05);
    let rows = body.split_evenly((sls.len().max(1), 4));
    for (r, sl) in sls.iter().enumerate() {
        let t = format!("theta_i = {:.0}", sl.theta_i);
        let logc = |v: f64| viridis((v - lo) / span);
        heat(
            &rows[4 * r],
            &format!("{word}, {t}"),
            sl,
            &|m, _| m.log10(),
            &logc,
        )?;
        heat(
            &rows[4 * r + 1],
            &format!("fitted, {t}"),
            sl,
            &|_, l| l.iter().sum::<f64>().log10(),
            &logc,
        )?;
        heat(
            &rows[4 * r + 2],
            &format!("ln(fit/data), scale +/-{rmax:.2}, {t}"),
            sl,
            &|m, l| l.iter().sum::<f64>().ln() - m.ln(),
            &|v| diverging(v / rmax),
        )?;
        lobe_panel(&rows[4 * r + 3], sl, word)?;
    }
    root.present()?;
    Ok(())
}

/// The files [`write()`] writes for `fit` into `out` ([`outputs_of`] its label).
pub fn outputs(fit: &FitFile, out: &Path) -> [std::path::PathBuf; 2] {
    outputs_of(&fit.label(), out)
}

/// `fig11_<label>.png` and `.svg` in `out`: the figures of the fit labelled `label`
/// ([`FitFile::label`]).
pub fn outputs_of(label: &str, out: &Path) -> [std::path::PathBuf; 2] {
    ["png", "svg"].map(|e| out.join(format!("fig11_{label}.{e}")))
}

/// The runs of consecutive points a log plot can show (finite, at least `lo`): a lobe that
/// is exactly 0 over a range of `phi` (TT in front of a thick fiber) leaves a gap, where
/// one line through all shown points drew a flat segment at the axis floor instead.
fn visible_runs(pts: impl Iterator<Item = (f64, f64)>, lo: f64) -> Vec<Vec<(f64, f64)>> {
    let mut runs: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
    for (x, y) in pts {
        if y.is_finite() && y >= lo {
            runs.last_mut().expect("never empty").push((x, y));
        } else if !runs.last().expect("never empty").is_empty() {
            runs.push(Vec::new());
        }
    }
    runs.retain(|r| !r.is_empty());
    runs
}

/// Draw `fit`'s figure against `profile` into folder `out`: `fig11_<fit file stem>.png` and
/// `.svg`; returns the paths written.
pub fn write(fit: &FitFile, profile: &Profile, out: &Path) -> Result<Vec<std::path::PathBuf>> {
    ensure_font();
    let channel = profile
        .channels
        .iter()
        .position(|c| *c == fit.channel)
        .unwrap_or(0);
    // The far field the fit was made with, so the figure shows what was fitted.
    let sls = slices(profile, channel, fit, &fit.far);
    if sls.is_empty() {
        return Err(Error::Invalid(format!(
            "{}: profile has no samples to plot",
            fit.species
        )));
    }
    let h = 40 + 300 * sls.len() as u32;
    let size = (1600u32, h);
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let name = fit.label();
    let [png, svg] = outputs(fit, out);
    // Rendered in memory, then written atomically.
    let bytes = super::plot::png_bytes(size, &png, |root| {
        draw(root, &name, &sls, fit.nrmse, fit.synthetic).map_err(plot_err(&png))
    })?;
    crate::io::write_output(&png, &bytes)?;
    let mut svg_text = String::new();
    {
        let root = SVGBackend::with_string(&mut svg_text, size).into_drawing_area();
        draw(root, &name, &sls, fit.nrmse, fit.synthetic).map_err(plot_err(&svg))?;
    }
    crate::io::write_output(&svg, svg_text.as_bytes())?;
    Ok(vec![png, svg])
}

#[cfg(test)]
mod tests {
    use super::visible_runs;

    /// Zeros (log10 = -inf) and values under the floor split a lobe's line instead of being
    /// bridged by a segment along the floor.
    #[test]
    fn runs_break_at_zeros_and_under_the_floor() {
        let ys = [
            0.0,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
            -1.0,
            -9.0,
            -2.0,
            -3.0,
        ];
        let runs = visible_runs(ys.iter().enumerate().map(|(i, y)| (i as f64, *y)), -5.0);
        assert_eq!(
            runs,
            vec![
                vec![(0.0, 0.0)],
                vec![(3.0, -1.0)],
                vec![(5.0, -2.0), (6.0, -3.0)]
            ]
        );
        assert!(visible_runs(std::iter::once((0.0, f64::NAN)), -5.0).is_empty());
    }
}

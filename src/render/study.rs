//! Studies printed by `furfit render-convergence`: RMSE versus samples per pixel and time
//! for each BCSDF scale against a high-spp reference of the same scale (seed Fig. 15), the
//! equal-quality speedup of multi-scale over near field, and a culling study.

use super::bsdf::Mode;
use super::{render_scene, Image, RenderSettings, Scene};
use crate::params::FurParams;

/// Resamples and seed of the bootstrap interval of the speedup in the report.
const BOOTSTRAP_RESAMPLES: usize = 2000;
const BOOTSTRAP_SEED: u64 = 0x5eed_b007;

/// One point of a convergence curve.
#[derive(Clone, Debug)]
pub struct ConvergencePoint {
    /// The render mode of this point.
    pub mode: Mode,
    /// Which independent render (seed) of this spp, from 0.
    pub repeat: usize,
    /// Samples per pixel.
    pub spp: usize,
    /// Path-tracing seconds of the render.
    pub seconds: f64,
    /// RMSE of the render against the reference.
    pub rmse: f64,
}

/// Result of [`convergence`].
#[derive(Clone, Debug)]
pub struct Convergence {
    /// Every render of the curve.
    pub points: Vec<ConvergencePoint>,
    /// Reference render time per mode.
    pub reference_seconds: Vec<(Mode, f64)>,
    /// One-off far-field table build per mode (before the first render; not in `seconds`).
    pub setup_seconds: Vec<(Mode, f64)>,
}

impl Convergence {
    /// The curve of a mode: per spp, the mean over the repeats in `which` (all when
    /// `None`) of the squared RMSE and of the seconds, as `(spp, seconds, rmse)`.
    pub fn curve(&self, mode: Mode, which: Option<usize>) -> Vec<(usize, f64, f64)> {
        self.curve_weighted(mode, |r| which.map_or(1.0, |w| f64::from(u8::from(w == r))))
    }

    /// [`Self::curve`] with repeat `r` counted `weight(r)` times (a bootstrap resample).
    fn curve_weighted(&self, mode: Mode, weight: impl Fn(usize) -> f64) -> Vec<(usize, f64, f64)> {
        let mut out: Vec<(usize, f64, f64, f64)> = Vec::new();
        for p in self
            .points
            .iter()
            .filter(|p| p.mode == mode && p.rmse > 0.0)
        {
            let w = weight(p.repeat);
            if w <= 0.0 {
                continue;
            }
            match out.iter_mut().find(|c| c.0 == p.spp) {
                Some(c) => {
                    c.1 += w * p.seconds;
                    c.2 += w * p.rmse * p.rmse;
                    c.3 += w;
                }
                None => out.push((p.spp, w * p.seconds, w * p.rmse * p.rmse, w)),
            }
        }
        out.sort_by_key(|c| c.0);
        out.iter()
            .map(|&(spp, t, e2, n)| (spp, t / n, (e2 / n).sqrt()))
            .collect()
    }

    /// Inefficiency `RMSE^2 * time` of a mode (Monte Carlo error falls as 1/sqrt(time), so
    /// this is constant once in the asymptotic regime): the median over the spp >= `min_spp`
    /// of the [`Self::curve`] pooled over all repeats.
    pub fn inefficiency(&self, mode: Mode, min_spp: usize) -> Option<f64> {
        self.inefficiency_weighted(mode, min_spp, |_| 1.0)
    }

    fn inefficiency_weighted(
        &self,
        mode: Mode,
        min_spp: usize,
        weight: impl Fn(usize) -> f64,
    ) -> Option<f64> {
        let mut v: Vec<f64> = self
            .curve_weighted(mode, weight)
            .into_iter()
            .filter(|c| c.0 >= min_spp)
            .map(|(_, t, e)| e * e * t)
            .collect();
        if v.is_empty() {
            return None;
        }
        v.sort_by(f64::total_cmp);
        Some(v[v.len() / 2])
    }

    /// Equal-quality speedup of `fast` over `slow`: ratio of their pooled inefficiencies
    /// (time needed to reach the same RMSE).
    pub fn speedup(&self, slow: Mode, fast: Mode, min_spp: usize) -> Option<f64> {
        self.speedup_weighted(slow, fast, min_spp, |_| 1.0)
    }

    fn speedup_weighted(
        &self,
        slow: Mode,
        fast: Mode,
        min_spp: usize,
        weight: impl Fn(usize) -> f64 + Copy,
    ) -> Option<f64> {
        Some(
            self.inefficiency_weighted(slow, min_spp, weight)?
                / self.inefficiency_weighted(fast, min_spp, weight)?,
        )
    }

    fn repeats(&self) -> usize {
        self.points.iter().map(|p| p.repeat + 1).max().unwrap_or(0)
    }

    /// The speedup of each repeat on its own: its spread is the measurement's noise.
    pub fn speedup_per_repeat(&self, slow: Mode, fast: Mode, min_spp: usize) -> Vec<f64> {
        (0..self.repeats())
            .filter_map(|r| {
                self.speedup_weighted(slow, fast, min_spp, |q| f64::from(u8::from(q == r)))
            })
            .collect()
    }

    /// Percentile bootstrap interval of the pooled [`Self::speedup`] at `level` (e.g. 0.9):
    /// the repeats are resampled with replacement, `resamples` times from a fixed seed,
    /// each resample weighting both modes' repeats alike (repeat `r` of each mode shares
    /// its seed). `None` with fewer than two repeats.
    pub fn speedup_interval(
        &self,
        slow: Mode,
        fast: Mode,
        min_spp: usize,
        level: f64,
        resamples: usize,
    ) -> Option<(f64, f64)> {
        use rand::{Rng, SeedableRng};
        let n = self.repeats();
        if n < 2 || resamples == 0 {
            return None;
        }
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(BOOTSTRAP_SEED);
        let mut stats = Vec::with_capacity(resamples);
        let mut counts = vec![0.0f64; n];
        for _ in 0..resamples {
            counts.iter_mut().for_each(|c| *c = 0.0);
            for _ in 0..n {
                counts[rng.random_range(0..n)] += 1.0;
            }
            if let Some(x) = self.speedup_weighted(slow, fast, min_spp, |r| counts[r]) {
                stats.push(x);
            }
        }
        if stats.is_empty() {
            return None;
        }
        stats.sort_by(f64::total_cmp);
        let q =
            |f: f64| stats[((f * (stats.len() - 1) as f64).round() as usize).min(stats.len() - 1)];
        let tail = 0.5 * (1.0 - level);
        Some((q(tail), q(1.0 - tail)))
    }

    /// Markdown report: the points, the per-mode inefficiency and the speedups; `threads`
    /// is the renders' thread count.
    pub fn to_markdown(&self, command: &str, min_spp: usize, threads: usize) -> String {
        let version = crate::TOOL_VERSION;
        let mut s = format!(
            "# Render convergence\n\nCommand: `{command}` ({version})\n\nRMSE of the linear image \
             against a high-spp reference of the SAME mode (another seed). `seconds` is \
             path-tracing wall time on {threads} thread(s): absolute figures depend on the \
             machine and its load; the ratios are what matter (the modes take turns at each \
             spp and repeat, so a change of load hits them alike). With several repeats (independent seeds) the table shows the mean \
             seconds and the root-mean-square RMSE per spp.\n\n\
             | mode | spp | seconds | RMSE |\n|---|---|---|---|\n"
        );
        for (m, _) in &self.reference_seconds {
            for (spp, t, e) in self.curve(*m, None) {
                s += &format!("| {} | {spp} | {t:.3} | {e:.3e} |\n", m.name());
            }
        }
        s += "\n| mode | reference seconds | far-field table build (s, once) | RMSE^2 x seconds |\n|---|---|---|---|\n";
        for (m, t) in &self.reference_seconds {
            let setup = self
                .setup_seconds
                .iter()
                .find(|(q, _)| q == m)
                .map_or(0.0, |x| x.1);
            let ineff = self
                .inefficiency(*m, min_spp)
                .map_or("n/a".to_string(), |v| format!("{v:.3e}"));
            s += &format!("| {} | {t:.2} | {setup:.2} | {ineff} |\n", m.name());
        }
        s += &format!(
            "\nInefficiency = median of RMSE^2 x seconds over spp >= {min_spp} (constant in \
             the Monte Carlo regime); equal-quality speedup = ratio of inefficiencies.\n\n"
        );
        for (slow, fast) in [(Mode::Near, Mode::Multiscale), (Mode::Near, Mode::Far)] {
            if let Some(x) = self.speedup(slow, fast, min_spp) {
                let each = self.speedup_per_repeat(slow, fast, min_spp);
                let interval = self
                    .speedup_interval(slow, fast, min_spp, 0.9, BOOTSTRAP_RESAMPLES)
                    .map_or(String::new(), |(a, b)| {
                        format!(" (90 % bootstrap interval over the repeats {a:.2}-{b:.2}x)")
                    });
                s += &format!(
                    "- equal-quality speedup of {} over {}: **{x:.2}x** pooled over {} \
                     repeats{interval}; per repeat {}\n",
                    fast.name(),
                    slow.name(),
                    each.len(),
                    each.iter()
                        .map(|v| format!("{v:.2}x"))
                        .collect::<Vec<_>>()
                        .join(", ")
                );
            }
        }
        s += "\nPaper (seed Sec. 7, Fig. 15, the central 32 x 32 patch of a hair lock with the \
              human-hair fit): its near field converges about 2x faster than Yan et al. 2015 and \
              its multi-scale model about an order of magnitude faster, so multi-scale is about \
              5x its own near field there. Its 3.5x (Fig. 16) and 6-8x (Figs. 1, 17) compare \
              with Yan et al. 2015, not with its own near field.\n";
        s
    }

    /// The points as CSV (`mode,repeat,spp,seconds,rmse`).
    pub fn to_csv(&self) -> String {
        let mut s = String::from("mode,repeat,spp,seconds,rmse\n");
        for p in &self.points {
            s += &format!(
                "{},{},{},{:.6},{:.6e}\n",
                p.mode.name(),
                p.repeat,
                p.spp,
                p.seconds,
                p.rmse
            );
        }
        s
    }
}

/// Render each mode at spp 1, 2, 4, ... `max_spp`, `repeats` times with independent seeds,
/// and a `ref_spp` reference with yet another seed; RMSE against the reference of the same
/// mode; the modes take turns at each `(repeat, spp)`. `progress` is called per render.
pub fn convergence(
    scene: &Scene,
    params: &FurParams,
    base: &RenderSettings,
    modes: &[Mode],
    (max_spp, ref_spp): (usize, usize),
    repeats: usize,
    mut progress: impl FnMut(&str),
) -> crate::Result<Convergence> {
    let mut points = Vec::new();
    let mut reference_seconds = Vec::new();
    let mut setup_seconds = Vec::new();
    // The shadow-ray tree is shared by every mode: build it before the per-mode setups.
    if let Some(l) = base.light {
        scene.light_tree(l.dir);
    }
    let mut references = Vec::new();
    for &mode in modes {
        let mut s = base.clone();
        s.mode = mode;
        s.spp = ref_spp;
        s.seed = base.seed.wrapping_add(1_000_003);
        let r = render_scene(scene, params, &s)?;
        progress(&format!(
            "{} reference {} spp: {:.2} s",
            mode.name(),
            ref_spp,
            r.seconds
        ));
        reference_seconds.push((mode, r.seconds));
        setup_seconds.push((mode, r.setup_seconds));
        references.push(r.beauty);
    }
    // The modes take turns at each (repeat, spp), so a change of the machine's load during
    // the run (it is shared) lands on all modes alike instead of on whichever ran then.
    for repeat in 0..repeats {
        let mut spp = 1;
        while spp <= max_spp {
            for (&mode, reference) in modes.iter().zip(&references) {
                let mut s = base.clone();
                s.mode = mode;
                s.spp = spp;
                s.seed = base.seed.wrapping_add(7919 * repeat as u64);
                let r = render_scene(scene, params, &s)?;
                let rmse = r.beauty.rmse(reference);
                progress(&format!(
                    "{} {spp} spp (repeat {repeat}): {:.3} s, RMSE {rmse:.4e}",
                    mode.name(),
                    r.seconds
                ));
                points.push(ConvergencePoint {
                    mode,
                    repeat,
                    spp,
                    seconds: r.seconds,
                    rmse,
                });
            }
            spp *= 2;
        }
    }
    // Listed mode by mode (the order of `modes`), as the CSV reads best.
    let rank = |m: Mode| modes.iter().position(|&q| q == m).unwrap_or(usize::MAX);
    points.sort_by_key(|p| (rank(p.mode), p.repeat, p.spp));
    Ok(Convergence {
        points,
        reference_seconds,
        setup_seconds,
    })
}

/// The lighting of one row of [`noise_budget`]: what reaches the camera.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BudgetLighting {
    /// The default scene: key light and environment, multiple scattering.
    Full,
    /// Key light only (black environment), multiple scattering.
    Key,
    /// Key light only, first fiber vertex only (`max_depth` 1): the one estimator where
    /// multi-scale replaces the near field's `h` by its analytic average and nothing
    /// else differs.
    KeyDirect,
}

impl BudgetLighting {
    /// Every lighting, in report order.
    pub const ALL: [BudgetLighting; 3] = [Self::Full, Self::Key, Self::KeyDirect];

    /// One line for the report.
    pub fn describe(self) -> &'static str {
        match self {
            Self::Full => "key light + environment, multiple scattering (the default scene)",
            Self::Key => "key light only, multiple scattering",
            Self::KeyDirect => "key light only, direct (first fiber vertex)",
        }
    }

    /// `base` with this lighting.
    pub fn apply(self, base: &RenderSettings) -> RenderSettings {
        let mut s = base.clone();
        if self != Self::Full {
            s.env = super::scene::Environment::constant(0.0);
        }
        if self == Self::KeyDirect {
            s.max_depth = 1;
        }
        s
    }
}

/// The modes of a [`noise_budget`]: the far field integrates `h` over the whole fiber, so
/// its speedup is what removing all of the `h` noise gives.
pub const BUDGET_MODES: [Mode; 3] = [Mode::Near, Mode::Multiscale, Mode::Far];

/// Where the noise that multi-scale does not remove comes from: the [`convergence`] of
/// [`BUDGET_MODES`] on the same patch under each [`BudgetLighting`]. Multi-scale and far
/// field only integrate over the offset `h` (within the pixel footprint, or over the whole
/// fiber); the noise of which fiber a camera sample hits, of its shadow ray and of the
/// paths beyond is the same in every mode, so the far field's speedup under `KeyDirect`
/// bounds what any `h` integration can gain there.
pub fn noise_budget(
    scene: &Scene,
    params: &FurParams,
    base: &RenderSettings,
    spp: (usize, usize),
    repeats: usize,
    mut progress: impl FnMut(&str),
) -> crate::Result<Vec<(BudgetLighting, Convergence)>> {
    BudgetLighting::ALL
        .iter()
        .map(|&l| {
            let c = convergence(
                scene,
                params,
                &l.apply(base),
                &BUDGET_MODES,
                spp,
                repeats,
                |m| progress(&format!("{}: {m}", l.describe())),
            )?;
            Ok((l, c))
        })
        .collect()
}

/// Markdown table of a [`noise_budget`]: per lighting the inefficiencies and the speedups
/// over near field with their bootstrap intervals.
pub fn noise_budget_markdown(
    rows: &[(BudgetLighting, Convergence)],
    command: &str,
    min_spp: usize,
    threads: usize,
) -> String {
    let mut s = format!(
        "# Render noise budget\n\nCommand: `{command}` ({})\n\nThe equal-quality speedup \
         over near field (as in `render_convergence.md`: RMSE^2 x seconds, median over spp \
         >= {min_spp}, each mode against its own reference, 90 % bootstrap interval over the \
         repeats) under three lightings of the same patch, {threads} thread(s). Multi-scale \
         integrates the offset `h` over the pixel footprint (seed Eq. 26-27), the far field \
         over the whole fiber, and neither changes anything else. With the key light direct \
         (the estimator where both replace `h` by its analytic average) the far field's \
         speedup is what removing all of the `h` noise gives; the rest (which fiber or the \
         background a camera sample hits, shadow rays, the paths beyond) is common to the \
         modes.\n\n\
         | lighting | RMSE^2 x s: near | multi-scale | far | multi-scale speedup | far speedup |\n\
         |---|---|---|---|---|---|\n",
        crate::TOOL_VERSION
    );
    for (l, c) in rows {
        let ineff = |m: Mode| {
            c.inefficiency(m, min_spp)
                .map_or("n/a".to_string(), |v| format!("{v:.3e}"))
        };
        let speedup = |m: Mode| {
            let Some(x) = c.speedup(Mode::Near, m, min_spp) else {
                return "n/a".to_string();
            };
            match c.speedup_interval(Mode::Near, m, min_spp, 0.9, BOOTSTRAP_RESAMPLES) {
                Some((a, b)) => format!("{x:.2}x ({a:.2}-{b:.2}x)"),
                None => format!("{x:.2}x"),
            }
        };
        s += &format!(
            "| {} | {} | {} | {} | {} | {} |\n",
            l.describe(),
            ineff(Mode::Near),
            ineff(Mode::Multiscale),
            ineff(Mode::Far),
            speedup(Mode::Multiscale),
            speedup(Mode::Far)
        );
    }
    s
}

/// Plot RMSE versus time (log-log) per mode; `svg` chooses the backend.
pub fn plot_convergence(c: &Convergence, path: &std::path::Path, svg: bool) -> crate::Result<()> {
    crate::io::write_atomic(path, &plot_convergence_bytes(c, path, svg)?)
}

/// The bytes of [`plot_convergence`]'s file, for [`crate::io::write_atomic_all`] (`path`
/// only names the target in errors).
pub fn plot_convergence_bytes(
    c: &Convergence,
    path: &std::path::Path,
    svg: bool,
) -> crate::Result<Vec<u8>> {
    use plotters::prelude::*;
    super::output::register_font();
    let err = |e: String| crate::Error::file(path, format!("plotting failed: {e}"));
    // Pooled curves (mean seconds, RMS of the RMSE over the repeats) per mode.
    let curves: Vec<(Mode, Vec<(f64, f64)>)> = [Mode::Near, Mode::Far, Mode::Multiscale]
        .into_iter()
        .map(|m| {
            (
                m,
                c.curve(m, None).iter().map(|&(_, t, e)| (t, e)).collect(),
            )
        })
        .collect();
    let pts: Vec<(f64, f64)> = curves.iter().flat_map(|c| c.1.iter().copied()).collect();
    if pts.is_empty() {
        return Err(crate::Error::file(path, "no convergence points to plot"));
    }
    let (tmin, tmax) = pts
        .iter()
        .fold((f64::MAX, 0.0f64), |a, p| (a.0.min(p.0), a.1.max(p.0)));
    let (emin, emax) = pts
        .iter()
        .fold((f64::MAX, 0.0f64), |a, p| (a.0.min(p.1), a.1.max(p.1)));
    #[allow(clippy::type_complexity)]
    fn draw_chart<DB: DrawingBackend>(
        root: DrawingArea<DB, plotters::coord::Shift>,
        curves: &[(Mode, Vec<(f64, f64)>)],
        (tmin, tmax, emin, emax): (f64, f64, f64, f64),
    ) -> Result<(), String> {
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let font = super::output::FONT;
        let mut chart = ChartBuilder::on(&root)
            .caption("RMSE vs render time (same-mode reference)", (font, 20))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(64)
            .build_cartesian_2d(
                (tmin * 0.8..tmax * 1.25).log_scale(),
                (emin * 0.8..emax * 1.25).log_scale(),
            )
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .x_desc("seconds")
            .y_desc("RMSE")
            .label_style((font, 13))
            .x_label_formatter(&crate::report::plot::tick)
            .y_label_formatter(&crate::report::plot::tick)
            .draw()
            .map_err(|e| e.to_string())?;
        for (mode, color) in [
            (Mode::Near, RED),
            (Mode::Far, BLUE),
            (Mode::Multiscale, GREEN),
        ] {
            let series: Vec<(f64, f64)> = curves
                .iter()
                .find(|c| c.0 == mode)
                .map_or(Vec::new(), |c| c.1.clone());
            if series.is_empty() {
                continue;
            }
            chart
                .draw_series(LineSeries::new(series.clone(), color.stroke_width(2)))
                .map_err(|e| e.to_string())?
                .label(mode.name())
                .legend(move |(x, y)| PathElement::new([(x, y), (x + 18, y)], color));
            chart
                .draw_series(series.iter().map(|&p| Circle::new(p, 3, color.filled())))
                .map_err(|e| e.to_string())?;
        }
        chart
            .configure_series_labels()
            .label_font((font, 14))
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| e.to_string())?;
        root.present().map_err(|e| e.to_string())
    }
    let bounds = (tmin, tmax, emin, emax);
    if svg {
        let mut s = String::new();
        draw_chart(
            SVGBackend::with_string(&mut s, (720, 480)).into_drawing_area(),
            &curves,
            bounds,
        )
        .map_err(err)?;
        Ok(s.into_bytes())
    } else {
        crate::report::plot::png_bytes((720, 480), path, |root| {
            draw_chart(root, &curves, bounds).map_err(err)
        })
    }
}

/// One variant of the culling study.
#[derive(Clone, Debug)]
pub struct CullingRow {
    /// The variant's name in the report.
    pub name: String,
    /// Path-tracing seconds.
    pub seconds: f64,
    /// Far-field table build seconds (where segment culling acts).
    pub setup_seconds: f64,
    /// RMSE against the variant without any culling, same seed.
    pub rmse_vs_full: f64,
    /// RMSE between two seeds of the full variant: the noise floor.
    pub noise_rmse: f64,
}

/// Time and image difference of far-field segment culling (multi-scale mode), off / on.
/// Each variant gets a fresh [`Scene`] so its table is built (and timed) once. Same seed,
/// so differences beyond the noise floor would be bias.
pub fn culling_study(
    strand: &super::scene::StrandSpec,
    params: &FurParams,
    base: &RenderSettings,
) -> crate::Result<Vec<CullingRow>> {
    let run = |scene: &Scene, cull: bool, seed: u64| -> crate::Result<(Image, f64, f64)> {
        let mut s = base.clone();
        s.seed = seed;
        s.far_cull = cull;
        let r = render_scene(scene, params, &s)?;
        Ok((r.beauty, r.seconds, r.setup_seconds))
    };
    // A fresh scene whose shadow-ray tree is built outside the timed setup, which then
    // times the far-field table alone.
    let fresh = || {
        let scene = Scene::build(strand);
        if let Some(l) = base.light {
            scene.light_tree(l.dir);
        }
        scene
    };
    let scene = fresh();
    let (full, t_full, s_full) = run(&scene, false, base.seed)?;
    let (full2, _, _) = run(&scene, false, base.seed.wrapping_add(17))?;
    let noise = full.rmse(&full2);
    let scene = fresh();
    let (cull, t_cull, s_cull) = run(&scene, true, base.seed)?;
    Ok(vec![
        CullingRow {
            name: "no culling".into(),
            seconds: t_full,
            setup_seconds: s_full,
            rmse_vs_full: 0.0,
            noise_rmse: noise,
        },
        CullingRow {
            name: "far-field segment culling".into(),
            seconds: t_cull,
            setup_seconds: s_cull,
            rmse_vs_full: cull.rmse(&full),
            noise_rmse: noise,
        },
    ])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn budget_lightings_change_only_what_they_name() {
        let base = RenderSettings::default();
        let full = BudgetLighting::Full.apply(&base);
        assert_eq!(full.max_depth, base.max_depth);
        assert_eq!(full.env.top, base.env.top);
        assert!(!full.env.is_black() && full.light.is_some());
        let key = BudgetLighting::Key.apply(&base);
        assert!(key.env.is_black() && key.light.is_some());
        assert_eq!(key.max_depth, base.max_depth);
        let direct = BudgetLighting::KeyDirect.apply(&base);
        assert!(direct.env.is_black() && direct.light.is_some());
        assert_eq!(direct.max_depth, 1);
        assert_eq!(direct.spp, base.spp);
    }

    fn point(mode: Mode, repeat: usize, spp: usize, seconds: f64, rmse: f64) -> ConvergencePoint {
        ConvergencePoint {
            mode,
            repeat,
            spp,
            seconds,
            rmse,
        }
    }

    /// Pooling averages the squared RMSE and the seconds per spp over the repeats; the
    /// per-repeat speedups use each repeat alone. Values chosen so every number is exact.
    #[test]
    fn curves_pool_repeats_and_speedups_split_them() {
        let mut points = Vec::new();
        for (r, (near_e, ms_e)) in [(0.2f64, 0.1f64), (0.4, 0.1)].into_iter().enumerate() {
            for spp in [4, 8] {
                points.push(point(Mode::Near, r, spp, 1.0, near_e));
                points.push(point(Mode::Multiscale, r, spp, 1.0, ms_e));
            }
        }
        let c = Convergence {
            points,
            reference_seconds: vec![(Mode::Near, 1.0), (Mode::Multiscale, 1.0)],
            setup_seconds: vec![],
        };
        let near = c.curve(Mode::Near, None);
        assert_eq!(near.len(), 2);
        // RMS of 0.2 and 0.4: sqrt(0.1).
        assert!((near[0].2 - 0.1f64.sqrt()).abs() < 1e-15 && near[0].1 == 1.0);
        // Pooled: 0.1 / 0.01 = 10; per repeat: 0.04 / 0.01 = 4 and 0.16 / 0.01 = 16.
        let s = c.speedup(Mode::Near, Mode::Multiscale, 4).unwrap();
        assert!((s - 10.0).abs() < 1e-9, "{s}");
        let each = c.speedup_per_repeat(Mode::Near, Mode::Multiscale, 4);
        assert_eq!(each.len(), 2);
        assert!((each[0] - 4.0).abs() < 1e-9 && (each[1] - 16.0).abs() < 1e-9);
        // spp below the threshold are ignored.
        assert!(c.speedup(Mode::Near, Mode::Multiscale, 16).is_none());
        // Bootstrap: a resample holds repeat 0 k times and repeat 1 (2 - k) times, so the
        // pooled speedup is 4 (k = 2), 10 (k = 1) or 16 (k = 0), with probabilities 1/4,
        // 1/2, 1/4: the 90 % interval spans 4..16, the 40 % interval is 10..10.
        let (a, b) = c
            .speedup_interval(Mode::Near, Mode::Multiscale, 4, 0.9, 2000)
            .unwrap();
        assert!((a - 4.0).abs() < 1e-9 && (b - 16.0).abs() < 1e-9, "{a} {b}");
        let (a, b) = c
            .speedup_interval(Mode::Near, Mode::Multiscale, 4, 0.4, 2000)
            .unwrap();
        assert!(
            (a - 10.0).abs() < 1e-9 && (b - 10.0).abs() < 1e-9,
            "{a} {b}"
        );
    }
}

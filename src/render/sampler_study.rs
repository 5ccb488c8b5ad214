//! Equal-quality comparison of the BCSDF samplers ([`Sampling`]) in each BCSDF scale, and
//! the cost of a preview render relative to the same render in near-field mode
//! (`furfit render-convergence --samplings ...`, `--preview`).
//!
//! Method as [`super::study::convergence`]: RMSE of the linear patch against a high-spp
//! reference, inefficiency = median over spp >= 4 of `RMSE^2 x seconds`, equal-quality
//! ratio = ratio of inefficiencies. Every (sampler, mode) has its own reference (each is
//! unbiased, so all converge to the same image; a reference's own noise inflates every
//! RMSE of its curve by the same fraction, `ref_spp` being the same). The (sampler, mode)
//! pairs take turns at each (repeat, spp), so a change of the shared machine's load lands
//! on all of them alike.

use super::bsdf::Mode;
use super::ishair::Sampling;
use super::study::{Convergence, ConvergencePoint};
use super::{render_scene, RenderSettings, Scene};
use crate::params::FurParams;

/// One [`Convergence`] per sampler.
#[derive(Clone, Debug)]
pub struct SamplerStudy {
    /// Each sampler with its convergence curve.
    pub runs: Vec<(Sampling, Convergence)>,
}

/// Run the comparison (module doc).
#[allow(clippy::too_many_arguments)]
pub fn sampler_study(
    scene: &Scene,
    params: &FurParams,
    base: &RenderSettings,
    modes: &[Mode],
    samplings: &[Sampling],
    (max_spp, ref_spp): (usize, usize),
    repeats: usize,
    mut progress: impl FnMut(&str),
) -> crate::Result<SamplerStudy> {
    if let Some(l) = base.light {
        scene.light_tree(l.dir);
    }
    let settings = |sm: Sampling, mode: Mode, spp: usize, seed: u64| {
        let mut s = base.clone();
        s.sampling = sm;
        s.mode = mode;
        s.spp = spp;
        s.seed = seed;
        s
    };
    let mut runs: Vec<(Sampling, Convergence)> = Vec::new();
    let mut refs = Vec::new();
    for &sm in samplings {
        let mut c = Convergence {
            points: Vec::new(),
            reference_seconds: Vec::new(),
            setup_seconds: Vec::new(),
        };
        for &mode in modes {
            let s = settings(sm, mode, ref_spp, base.seed.wrapping_add(1_000_003));
            let r = render_scene(scene, params, &s)?;
            progress(&format!(
                "{} {} reference {ref_spp} spp: {:.2} s",
                sm.name(),
                mode.name(),
                r.seconds
            ));
            c.reference_seconds.push((mode, r.seconds));
            c.setup_seconds.push((mode, r.setup_seconds));
            refs.push(((sm, mode), r.beauty));
        }
        runs.push((sm, c));
    }
    for repeat in 0..repeats {
        let mut spp = 1;
        while spp <= max_spp {
            for (k, &sm) in samplings.iter().enumerate() {
                for &mode in modes {
                    let seed = base.seed.wrapping_add(7919 * repeat as u64);
                    let r = render_scene(scene, params, &settings(sm, mode, spp, seed))?;
                    let reference = &refs.iter().find(|(key, _)| *key == (sm, mode)).unwrap().1;
                    let rmse = r.beauty.rmse(reference);
                    progress(&format!(
                        "{} {} {spp} spp (repeat {repeat}): {:.3} s, RMSE {rmse:.4e}",
                        sm.name(),
                        mode.name(),
                        r.seconds
                    ));
                    runs[k].1.points.push(ConvergencePoint {
                        mode,
                        repeat,
                        spp,
                        seconds: r.seconds,
                        rmse,
                    });
                }
            }
            spp *= 2;
        }
    }
    Ok(SamplerStudy { runs })
}

impl SamplerStudy {
    fn run(&self, sm: Sampling) -> Option<&Convergence> {
        self.runs.iter().find(|(s, _)| *s == sm).map(|(_, c)| c)
    }

    /// Equal-quality speedup of sampler `fast` over `slow` in `mode` (pooled repeats).
    pub fn ratio(&self, slow: Sampling, fast: Sampling, mode: Mode) -> Option<f64> {
        Some(self.run(slow)?.inefficiency(mode, 4)? / self.run(fast)?.inefficiency(mode, 4)?)
    }

    /// [`Self::ratio`] of each repeat alone (its spread is the measurement's noise).
    pub fn ratio_per_repeat(&self, slow: Sampling, fast: Sampling, mode: Mode) -> Vec<f64> {
        let (Some(a), Some(b)) = (self.run(slow), self.run(fast)) else {
            return Vec::new();
        };
        let reps = a.points.iter().map(|p| p.repeat + 1).max().unwrap_or(0);
        let ineff = |c: &Convergence, r: usize| {
            let mut v: Vec<f64> = c
                .curve(mode, Some(r))
                .into_iter()
                .filter(|x| x.0 >= 4)
                .map(|(_, t, e)| e * e * t)
                .collect();
            v.sort_by(f64::total_cmp);
            v.get(v.len() / 2).copied()
        };
        (0..reps)
            .filter_map(|r| Some(ineff(a, r)? / ineff(b, r)?))
            .collect()
    }

    /// Multi-scale (and far) over near field with each sampler.
    pub fn mode_speedup(&self, sm: Sampling, fast: Mode) -> Option<f64> {
        self.run(sm)?.speedup(Mode::Near, fast, 4)
    }

    /// The comparison as Markdown.
    pub fn markdown(&self, modes: &[Mode]) -> String {
        let mut s = String::from("## Samplers\n\nInefficiency `RMSE^2 x seconds` (median over spp >= 4, pooled repeats) per sampler and mode; `uniform` is the sphere (ISHair's Fig. 1 baseline), `lobes` the truncated / wrapped Gaussians of the lobes, `ishair` the Cauchy proposals (`render::ishair`).\n\n| sampler |");
        for m in modes {
            s += &format!(" {} |", m.name());
        }
        s += "\n|---|";
        s += &"---|".repeat(modes.len());
        s += "\n";
        for (sm, c) in &self.runs {
            s += &format!("| {} |", sm.name());
            for m in modes {
                match c.inefficiency(*m, 4) {
                    Some(v) => s += &format!(" {v:.3e} |"),
                    None => s += " - |",
                }
            }
            s += "\n";
        }
        s += "\nEqual-quality speedups (ratio of inefficiencies; in brackets the range over the repeats):\n\n";
        let pairs = [
            (Sampling::Uniform, Sampling::Ishair),
            (Sampling::Lobes, Sampling::Ishair),
            (Sampling::Uniform, Sampling::Lobes),
        ];
        for (slow, fast) in pairs {
            for m in modes {
                if let Some(x) = self.ratio(slow, fast, *m) {
                    let per = self.ratio_per_repeat(slow, fast, *m);
                    let (lo, hi) = per
                        .iter()
                        .fold((f64::INFINITY, 0.0f64), |(l, h), v| (l.min(*v), h.max(*v)));
                    s += &format!(
                        "- {} over {}, {}: **{x:.2}x** [{lo:.2}-{hi:.2}]\n",
                        fast.name(),
                        slow.name(),
                        m.name()
                    );
                }
            }
        }
        s += "\nMulti-scale and far field over near field, per sampler:\n\n";
        for (sm, _) in &self.runs {
            for fast in [Mode::Multiscale, Mode::Far] {
                if let Some(x) = self.mode_speedup(*sm, fast) {
                    s += &format!("- {}: {} over near **{x:.2}x**\n", sm.name(), fast.name());
                }
            }
        }
        s
    }

    /// Every point as CSV.
    pub fn csv(&self) -> String {
        let mut s = String::from("sampling,mode,repeat,spp,seconds,rmse\n");
        for (sm, c) in &self.runs {
            for p in &c.points {
                s += &format!(
                    "{},{},{},{},{:.6},{:.6e}\n",
                    sm.name(),
                    p.mode.name(),
                    p.repeat,
                    p.spp,
                    p.seconds,
                    p.rmse
                );
            }
        }
        s
    }
}

/// Wall seconds (setup + tracing) of the full-frame preview `base` (its size and spp) in
/// `mode` and in near field, in that order: the preview's cost as a ratio to a reference
/// workload of the same run (absolute seconds vary 2-3x between days on shared machines).
pub fn preview_ratio(
    scene: &Scene,
    params: &FurParams,
    base: &RenderSettings,
    mode: Mode,
) -> crate::Result<(f64, f64)> {
    let mut s = base.clone();
    s.region = None;
    let mut time = |m: Mode| -> crate::Result<f64> {
        s.mode = m;
        let r = render_scene(scene, params, &s)?;
        Ok(r.seconds + r.setup_seconds)
    };
    let near = time(Mode::Near)?;
    let t = time(mode)?;
    Ok((t, near))
}

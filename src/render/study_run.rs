//! One `furfit render-convergence` run from parsed options: the output files checked, then
//! the convergence curves ([`super::study::convergence`], with several samplers
//! [`super::sampler_study::sampler_study`]), the culling study or the noise budget, and
//! their report files. The command line only parses and prints.

use super::bsdf::Mode;
use super::ishair::Sampling;
use super::qmc::PixelSampling;
use super::sampler_study::{preview_ratio, sampler_study, SamplerStudy};
use super::study::{
    convergence, culling_study, noise_budget, noise_budget_markdown, plot_convergence_bytes,
    Convergence, CullingRow,
};
use super::{RenderSettings, Scene};
use crate::error::Result;
use crate::params::FurParams;
use std::path::PathBuf;

/// Which study a run makes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StudyKind {
    /// RMSE against spp and time per mode, and the equal-quality speedups
    /// (`render_convergence.{csv,png,svg,md}`).
    Convergence,
    /// The time saved by far-field culling and its image difference (`render_culling.md`).
    Culling,
    /// The speedups under lightings that isolate the noise of `h`
    /// (`render_noise_budget.md`).
    NoiseBudget,
}

/// The options of a run, parsed and checked.
#[derive(Clone, Debug)]
pub struct StudyOptions {
    /// Which study.
    pub kind: StudyKind,
    /// `--params` as given (the culling report names it).
    pub params_spec: String,
    /// Size of the central patch rendered (width, height), inside `frame`.
    pub patch: (usize, usize),
    /// The full frame the patch is cut from (sets the pixel footprint).
    pub frame: (usize, usize),
    /// Largest spp of the curves, or the spp of the culling study's renders.
    pub max_spp: usize,
    /// spp of each mode's reference image.
    pub ref_spp: usize,
    /// The modes compared.
    pub modes: Vec<Mode>,
    /// The BCSDF samplers compared (the first one's curves are the report's).
    pub samplings: Vec<Sampling>,
    /// Where the pixel position and the first BCSDF uniforms come from.
    pub pixel_sampling: PixelSampling,
    /// Seed of the first repeat's renders.
    pub seed: u64,
    /// Independent renders (seeds) per spp.
    pub repeats: usize,
    /// Worker threads of each render (0 = all cores).
    pub threads: usize,
    /// Next-event estimation of the environment.
    pub env_nee: bool,
    /// Also time the full frame at 64 spp (multi-scale against near field).
    pub preview: bool,
    /// Output directory.
    pub out: PathBuf,
    /// Replace existing output files that furfit did not write.
    pub force: bool,
    /// The command line the convergence report and noise budget record.
    pub command: String,
}

impl StudyOptions {
    /// The files the run writes, in `out`.
    pub fn output_paths(&self) -> Vec<PathBuf> {
        let names: &[&str] = match self.kind {
            StudyKind::Culling => &["render_culling.md"],
            StudyKind::NoiseBudget => &["render_noise_budget.md"],
            StudyKind::Convergence => &[
                "render_convergence.csv",
                "render_convergence.png",
                "render_convergence.svg",
                "render_convergence.md",
            ],
        };
        let mut paths: Vec<PathBuf> = names.iter().map(|n| self.out.join(n)).collect();
        if self.samplings.len() > 1 && names.len() == 4 {
            paths.push(self.out.join("render_samplers.csv"));
        }
        paths
    }
}

/// Check the output files (the folder prepared by the caller), make the study of `o` with
/// `params` and write its report. `say` gets the lines for the user (progress, results,
/// the files written).
pub fn run(o: &StudyOptions, params: &FurParams, mut say: impl FnMut(&str)) -> Result<()> {
    let paths = o.output_paths();
    for p in &paths {
        crate::io::check_out_file(p)?;
    }
    crate::io::check_replaceable(&paths, o.force)?;
    let ((pw, ph), (fw, fh)) = (o.patch, o.frame);
    let base = RenderSettings {
        width: fw,
        height: fh,
        seed: o.seed,
        threads: o.threads,
        region: Some(((fw - pw) / 2, (fh - ph) / 2, pw, ph)),
        env_nee: o.env_nee,
        sampling: o.samplings[0],
        pixel_sampling: o.pixel_sampling,
        ..RenderSettings::default()
    };
    if o.kind == StudyKind::Culling {
        return culling(o, params, &base, &paths, &mut say);
    }
    let scene = Scene::build(&base.strand);
    let spp = (o.max_spp, o.ref_spp);
    if o.kind == StudyKind::NoiseBudget {
        let rows = noise_budget(&scene, params, &base, spp, o.repeats, &mut say)?;
        for (l, c) in &rows {
            for m in [Mode::Multiscale, Mode::Far] {
                if let Some(x) = c.speedup(Mode::Near, m, 4) {
                    say(&format!(
                        "{}: equal-quality speedup of {} over near {x:.2}x",
                        l.describe(),
                        m.name()
                    ));
                }
            }
        }
        let p = &paths[0];
        crate::io::write_output(
            p,
            noise_budget_markdown(&rows, &o.command, 4, threads(o)).as_bytes(),
        )?;
        say(&format!("wrote {}", p.display()));
        return Ok(());
    }
    curves(o, params, &scene, &base, &paths, &mut say)
}

/// What each render's pool gets: `--threads 0` is rayon's default, the global pool's size.
fn threads(o: &StudyOptions) -> usize {
    match o.threads {
        0 => rayon::current_num_threads(),
        t => t,
    }
}

/// The culling study (multi-scale, one seed, at `max_spp`) and `render_culling.md`.
fn culling(
    o: &StudyOptions,
    params: &FurParams,
    base: &RenderSettings,
    paths: &[PathBuf],
    say: &mut impl FnMut(&str),
) -> Result<()> {
    let ((pw, ph), (fw, fh)) = (o.patch, o.frame);
    let mut s = base.clone();
    s.spp = o.max_spp;
    s.mode = Mode::Multiscale;
    let rows = culling_study(&s.strand, params, &s)?;
    let mut md = format!(
        "# Render culling study\n\n`furfit render-convergence --culling-study --params {} \
         --size {pw}x{ph} --frame {fw}x{fh} --max-spp {}` ({}): multi-scale mode, same seed; \
         RMSE against the unculled image, noise floor = RMSE between two seeds. Culling \
         acts where the far field / multi-scale term is computed: in the per-render \
         table build (`render::ntable`); tracing reads the table either way.\n\n\
         | variant | table build s | tracing s | total s | RMSE vs unculled | noise floor |\n\
         |---|---|---|---|---|---|\n",
        o.params_spec,
        o.max_spp,
        crate::TOOL_VERSION
    );
    for r in &rows {
        say(&format!(
            "{:28} table {:6.2} s + tracing {:7.2} s  RMSE vs unculled {:.3e}  (noise floor {:.3e})",
            r.name, r.setup_seconds, r.seconds, r.rmse_vs_full, r.noise_rmse
        ));
        md += &format!(
            "| {} | {:.2} | {:.2} | {:.2} | {:.3e} | {:.3e} |\n",
            r.name,
            r.setup_seconds,
            r.seconds,
            r.setup_seconds + r.seconds,
            r.rmse_vs_full,
            r.noise_rmse
        );
    }
    let total = |r: &CullingRow| r.setup_seconds + r.seconds;
    let saved = 1.0 - total(&rows[1]) / total(&rows[0]);
    let saved_table = 1.0 - rows[1].setup_seconds / rows[0].setup_seconds.max(1e-9);
    say(&format!(
        "time saved by culling: {:.1} % of the total, {:.1} % of the table build",
        100.0 * saved,
        100.0 * saved_table
    ));
    md += &format!(
        "\nTime saved by culling: {:.1} % of the total ({:.1} % of the table build; \
         {} thread(s), wall times: noisy under load). Scattered lobes are skipped whenever \
         kappa = 0 or sigma_m_s = 0 (`FurModel::active_lobes`) and footprints covering \
         the whole fiber use the far field directly; both are always on.\n",
        100.0 * saved,
        100.0 * saved_table,
        threads(o)
    );
    let p = &paths[0];
    crate::io::write_output(p, md.as_bytes())?;
    say(&format!("wrote {}", p.display()));
    Ok(())
}

/// The convergence curves (and with several samplers their comparison, with `preview`
/// the preview's cost) and their report files, written together.
fn curves(
    o: &StudyOptions,
    params: &FurParams,
    scene: &Scene,
    base: &RenderSettings,
    paths: &[PathBuf],
    say: &mut impl FnMut(&str),
) -> Result<()> {
    let spp = (o.max_spp, o.ref_spp);
    let (modes, samplings) = (&o.modes[..], &o.samplings[..]);
    let study: Option<SamplerStudy> = if samplings.len() > 1 {
        Some(sampler_study(
            scene, params, base, modes, samplings, spp, o.repeats, &mut *say,
        )?)
    } else {
        None
    };
    let c: Convergence = match &study {
        Some(st) => st.runs[0].1.clone(),
        None => convergence(scene, params, base, modes, spp, o.repeats, &mut *say)?,
    };
    let mut extra = String::new();
    if let Some(st) = &study {
        extra += &format!(
            "\nThe curves above are sampler `{}`'s.\n\n{}",
            samplings[0].name(),
            st.markdown(modes)
        );
        for line in st.markdown(modes).lines().filter(|l| l.starts_with("- ")) {
            say(&line.trim_start_matches("- ").replace("**", ""));
        }
    }
    if o.preview {
        let (fw, fh) = o.frame;
        let mut s = base.clone();
        s.spp = 64;
        let (t, near) = preview_ratio(scene, params, &s, Mode::Multiscale)?;
        let line = format!(
            "preview {fw}x{fh} at 64 spp, multiscale, sampler {}: {:.2}x the time of the same render in near-field mode ({t:.1} s against {near:.1} s on this run)",
            samplings[0].name(),
            t / near
        );
        say(&line);
        extra += &format!("\n## Preview\n\n{line}.\n");
    }
    for m in modes {
        if let Some(v) = c.inefficiency(*m, 4) {
            say(&format!(
                "{:10} RMSE^2 x seconds (median, spp >= 4): {v:.3e}",
                m.name()
            ));
        }
    }
    // The report's files land together or not at all.
    let [csv, png, svg, md] = [0, 1, 2, 3].map(|i| paths[i].clone());
    let mut files = vec![
        (csv.clone(), c.to_csv().into_bytes()),
        (png.clone(), plot_convergence_bytes(&c, &png, false)?),
        (svg.clone(), plot_convergence_bytes(&c, &svg, true)?),
        (
            md.clone(),
            (c.to_markdown(&o.command, 4, threads(o)) + &extra).into_bytes(),
        ),
    ];
    if let Some(st) = &study {
        files.push((o.out.join("render_samplers.csv"), st.csv().into_bytes()));
    }
    crate::io::write_outputs(&files)?;
    say(&format!("wrote {} (+ .png, .svg, .md)", csv.display()));
    for fast in [Mode::Multiscale, Mode::Far] {
        if let Some(s) = c.speedup(Mode::Near, fast, 4) {
            say(&format!(
                "equal-quality speedup {} over near: {s:.2}x pooled, per repeat {} (paper, hair lock: multi-scale ~5x its near field)",
                fast.name(),
                c.speedup_per_repeat(Mode::Near, fast, 4)
                    .iter()
                    .map(|x| format!("{x:.2}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            ));
        }
    }
    Ok(())
}

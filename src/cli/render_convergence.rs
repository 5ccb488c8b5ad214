//! `furfit render-convergence`: RMSE vs spp/time per BCSDF scale on a patch of the test
//! lock, the equal-quality speedup of multi-scale over near field, and (with
//! `--culling-study`) the time saved by far-field culling with its image difference.

use crate::params::FurParams;
use crate::render::bsdf::Mode;
use crate::render::study::{convergence, culling_study, plot_convergence};
use crate::render::{RenderSettings, Scene};
use anyhow::{bail, Context};
use std::path::PathBuf;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Parameter file, fit file or preset.
    #[arg(long, default_value = "red-fox")]
    pub params: String,
    /// Size of the central patch rendered (WxH).
    #[arg(long, default_value = "48x48")]
    pub size: String,
    /// Full frame the patch is cut from (sets the pixel footprint).
    #[arg(long, default_value = "512x512")]
    pub frame: String,
    /// Largest spp of the curves (powers of two from 1).
    #[arg(long, default_value_t = 64)]
    pub max_spp: usize,
    /// spp of each mode's reference image.
    #[arg(long, default_value_t = 512)]
    pub ref_spp: usize,
    /// Modes to compare.
    #[arg(long, default_value = "near,far,multiscale")]
    pub modes: String,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Independent renders (seeds) per spp: the speedup is reported pooled over them and
    /// per repeat, since one 48x48 patch gives a ratio that swings by tens of percent.
    #[arg(long, default_value_t = 4)]
    pub repeats: usize,
    #[arg(long, default_value_t = 0)]
    pub threads: usize,
    /// Render with next-event estimation of the environment (MIS with BCSDF sampling).
    #[arg(long)]
    pub env_nee: bool,
    /// Run the culling study instead (writes reports/render_culling.md).
    #[arg(long)]
    pub culling_study: bool,
    /// Output directory.
    #[arg(long, default_value = "reports")]
    pub out: PathBuf,
}

fn size(s: &str) -> anyhow::Result<(usize, usize)> {
    let (w, h) = s
        .split_once('x')
        .with_context(|| format!("'{s}': expected WxH"))?;
    Ok((w.parse()?, h.parse()?))
}

pub fn run(a: Args) -> anyhow::Result<()> {
    let (params, _) = FurParams::load(&a.params)?;
    let (pw, ph) = size(&a.size)?;
    let (fw, fh) = size(&a.frame)?;
    if pw == 0 || ph == 0 || pw > fw || ph > fh {
        bail!("--size {pw}x{ph} must be non-empty and fit in --frame {fw}x{fh}");
    }
    let base = RenderSettings {
        width: fw,
        height: fh,
        seed: a.seed,
        threads: a.threads,
        region: Some(((fw - pw) / 2, (fh - ph) / 2, pw, ph)),
        env_nee: a.env_nee,
        ..RenderSettings::default()
    };
    let scene = Scene::build(&base.strand);
    if a.culling_study {
        let mut s = base.clone();
        s.spp = a.max_spp;
        s.mode = Mode::Multiscale;
        let rows = culling_study(&s.strand, &params, &s)?;
        let mut md = format!(
            "# Render culling study\n\n`furfit render-convergence --culling-study --params {} \
             --size {pw}x{ph} --frame {fw}x{fh} --max-spp {}`: multi-scale mode, same seed; \
             RMSE against the unculled image, noise floor = RMSE between two seeds. Culling \
             acts where the far field / multi-scale term is computed: in the per-render \
             table build (`render::ntable`); tracing reads the table either way.\n\n\
             | variant | table build s | tracing s | total s | RMSE vs unculled | noise floor |\n\
             |---|---|---|---|---|---|\n",
            a.params, a.max_spp
        );
        for r in &rows {
            outln!(
                "{:28} table {:6.2} s + tracing {:7.2} s  RMSE vs unculled {:.3e}  (noise floor {:.3e})",
                r.name, r.setup_seconds, r.seconds, r.rmse_vs_full, r.noise_rmse
            );
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
        let total = |r: &crate::render::study::CullingRow| r.setup_seconds + r.seconds;
        let saved = 1.0 - total(&rows[1]) / total(&rows[0]);
        let saved_table = 1.0 - rows[1].setup_seconds / rows[0].setup_seconds.max(1e-9);
        outln!(
            "time saved by culling: {:.1} % of the total, {:.1} % of the table build",
            100.0 * saved,
            100.0 * saved_table
        );
        md += &format!(
            "\nTime saved by culling: {:.1} % of the total ({:.1} % of the table build; \
             machine shared, timings noisy). Scattered lobes are skipped whenever \
             kappa = 0 or sigma_m_s = 0 (`FurModel::active_lobes`) and footprints covering \
             the whole fiber use the far field directly; both are always on.\n",
            100.0 * saved,
            100.0 * saved_table
        );
        let p = a.out.join("render_culling.md");
        crate::io::write_atomic(&p, md.as_bytes())?;
        outln!("wrote {}", p.display());
        return Ok(());
    }
    let modes: Vec<Mode> = a
        .modes
        .split(',')
        .map(Mode::parse)
        .collect::<crate::Result<_>>()?;
    if a.repeats == 0 {
        anyhow::bail!("--repeats must be at least 1");
    }
    let spp = (a.max_spp, a.ref_spp);
    let c = convergence(&scene, &params, &base, &modes, spp, a.repeats, |m| {
        outln!("{m}")
    })?;
    let csv = a.out.join("render_convergence.csv");
    crate::io::write_atomic(&csv, c.to_csv().as_bytes())?;
    plot_convergence(&c, &a.out.join("render_convergence.png"), false)?;
    plot_convergence(&c, &a.out.join("render_convergence.svg"), true)?;
    outln!("wrote {} (+ .png, .svg)", csv.display());
    for m in &modes {
        if let Some(v) = c.inefficiency(*m, 4) {
            outln!(
                "{:10} RMSE^2 x seconds (median, spp >= 4): {v:.3e}",
                m.name()
            );
        }
    }
    let command = format!(
        "furfit render-convergence --params {} --size {pw}x{ph} --frame {fw}x{fh} \
         --max-spp {} --ref-spp {} --modes {} --seed {} --repeats {} --threads {}{}",
        a.params,
        a.max_spp,
        a.ref_spp,
        a.modes,
        a.seed,
        a.repeats,
        a.threads,
        if a.env_nee { " --env-nee" } else { "" }
    );
    let md = a.out.join("render_convergence.md");
    crate::io::write_atomic(&md, c.to_markdown(&command, 4).as_bytes())?;
    outln!("wrote {}", md.display());
    for fast in [Mode::Multiscale, Mode::Far] {
        if let Some(s) = c.speedup(Mode::Near, fast, 4) {
            outln!(
                "equal-quality speedup {} over near: {s:.2}x pooled, per repeat {} (paper, multiscale: 3.5-8x)",
                fast.name(),
                c.speedup_per_repeat(Mode::Near, fast, 4)
                    .iter()
                    .map(|x| format!("{x:.2}"))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
    }
    Ok(())
}

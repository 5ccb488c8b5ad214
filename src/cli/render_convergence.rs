//! `furfit render-convergence`: RMSE vs spp/time per BCSDF scale on a patch of the test
//! lock, the equal-quality speedup of multi-scale over near field, and (with
//! `--culling-study`) the time saved by far-field culling with its image difference, or
//! (with `--noise-budget`) the speedup under lightings that isolate the noise of `h`.

use crate::render::bsdf::Mode;
use crate::render::sampler_study::{preview_ratio, sampler_study};
use crate::render::study::{
    convergence, culling_study, noise_budget, noise_budget_markdown, plot_convergence_bytes,
};
use crate::render::{RenderSettings, Scene, MAX_PIXELS, MAX_SIDE, MAX_SPP};
use anyhow::{bail, Context};
use clap::builder::RangedU64ValueParser;
use std::path::PathBuf;

/// Largest `--repeats`: each repeat renders the whole curve again.
const MAX_REPEATS: usize = 1000;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Parameter file, fit file or preset.
    #[arg(long, default_value = "red-fox")]
    pub params: String,
    /// Size of the central patch rendered (WxH or WXH), inside --frame.
    #[arg(long, default_value = "48x48")]
    pub size: String,
    /// Full frame the patch is cut from (sets the pixel footprint), each side 1..=8192.
    #[arg(long, default_value = "512x512")]
    pub frame: String,
    /// Largest spp of the curves (powers of two, below --ref-spp), at most 1048576.
    #[arg(long, allow_negative_numbers = true, default_value_t = 64, value_parser = RangedU64ValueParser::<usize>::new().range(1..=MAX_SPP as u64))]
    pub max_spp: usize,
    /// spp of each mode's reference image, above --max-spp, at most 1048576.
    #[arg(long, allow_negative_numbers = true, default_value_t = 512, value_parser = RangedU64ValueParser::<usize>::new().range(2..=MAX_SPP as u64))]
    pub ref_spp: usize,
    /// Modes to compare, each once: near, far, multiscale.
    #[arg(long, default_value = "near,far,multiscale")]
    pub modes: String,
    /// Seed of the first repeat's renders (each repeat and reference takes the next).
    #[arg(long, allow_negative_numbers = true, default_value_t = 1)]
    pub seed: u64,
    /// Replace existing output files that furfit did not write (or that changed since).
    #[arg(long)]
    pub force: bool,
    /// Independent renders (seeds) per spp, pooled in the speedup, 1..=1000.
    #[arg(long, allow_negative_numbers = true, default_value_t = 4, value_parser = RangedU64ValueParser::<usize>::new().range(1..=MAX_REPEATS as u64))]
    pub repeats: usize,
    /// Worker threads (0 = all cores), at most 1024.
    #[arg(long, allow_negative_numbers = true, default_value_t = 0, value_parser = super::threads_parser())]
    pub threads: usize,
    /// Render with next-event estimation of the environment (MIS with BCSDF sampling).
    #[arg(long)]
    pub env_nee: bool,
    /// Run the culling study instead (render_culling.md).
    #[arg(long, conflicts_with_all = ["modes", "ref_spp", "repeats"])]
    pub culling_study: bool,
    /// Run the noise budget instead (render_noise_budget.md): three lightings, near/multiscale/far.
    #[arg(long, conflicts_with_all = ["modes", "culling_study", "env_nee"])]
    pub noise_budget: bool,
    /// Output directory.
    #[arg(long, default_value = "reports")]
    pub out: PathBuf,
    /// BCSDF samplers to compare (ishair, lobes, uniform); the first one's curves are the report's.
    #[arg(long, default_value = "ishair")]
    pub samplings: String,
    /// Also time the full --frame at 64 spp, multiscale against near field.
    #[arg(long, conflicts_with_all = ["culling_study", "noise_budget"])]
    pub preview: bool,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    // Every option and the output paths are checked before the first render.
    let (pw, ph) = super::parse_size("--size", &a.size, MAX_SIDE, MAX_PIXELS)?;
    // Only the --size patch is rendered: the frame only sets the pixel footprint.
    let (fw, fh) = super::parse_size("--frame", &a.frame, MAX_SIDE, usize::MAX)?;
    if pw > fw || ph > fh {
        bail!("--size {pw}x{ph} must fit in --frame {fw}x{fh}");
    }
    let mut samplings = Vec::new();
    for m in a.samplings.split(',') {
        let m = crate::render::ishair::Sampling::parse(m)
            .with_context(|| format!("--samplings '{}'", a.samplings))?;
        if samplings.contains(&m) {
            bail!("--samplings '{}': {} given twice", a.samplings, m.name());
        }
        samplings.push(m);
    }
    let mut modes: Vec<Mode> = Vec::new();
    for m in a.modes.split(',') {
        let m = Mode::parse(m.trim()).with_context(|| format!("--modes '{}'", a.modes))?;
        if modes.contains(&m) {
            bail!("--modes '{}': {} given twice", a.modes, m.name());
        }
        modes.push(m);
    }
    if !a.culling_study && a.ref_spp <= a.max_spp {
        bail!(
            "--ref-spp {} must be more than --max-spp {} (the reference must be better than \
             every point of the curve)",
            a.ref_spp,
            a.max_spp
        );
    }
    if !a.culling_study && !a.max_spp.is_power_of_two() {
        eprintln!(
            "note: --max-spp {} is not a power of two: the curves stop at {} spp",
            a.max_spp,
            1usize << a.max_spp.ilog2()
        );
    }
    let names: &[&str] = if a.culling_study {
        &["render_culling.md"]
    } else if a.noise_budget {
        &["render_noise_budget.md"]
    } else {
        &[
            "render_convergence.csv",
            "render_convergence.png",
            "render_convergence.svg",
            "render_convergence.md",
        ]
    };
    let mut paths: Vec<PathBuf> = names.iter().map(|n| a.out.join(n)).collect();
    if samplings.len() > 1 && names.len() == 4 {
        paths.push(a.out.join("render_samplers.csv"));
    }
    let (params, _, _) = super::load_params(&a.params)?;
    super::prepare_out_dir(&a.out)?;
    for p in &paths {
        crate::io::check_out_file(p)?;
    }
    crate::io::check_replaceable(&paths, a.force)?;
    // What each render's pool gets: --threads 0 is rayon's default, the global pool's size.
    let threads = match a.threads {
        0 => rayon::current_num_threads(),
        t => t,
    };
    let base = RenderSettings {
        width: fw,
        height: fh,
        seed: a.seed,
        threads: a.threads,
        region: Some(((fw - pw) / 2, (fh - ph) / 2, pw, ph)),
        env_nee: a.env_nee,
        sampling: samplings[0],
        ..RenderSettings::default()
    };
    if a.culling_study {
        let mut s = base.clone();
        s.spp = a.max_spp;
        s.mode = Mode::Multiscale;
        let rows = culling_study(&s.strand, &params, &s)?;
        let mut md = format!(
            "# Render culling study\n\n`furfit render-convergence --culling-study --params {} \
             --size {pw}x{ph} --frame {fw}x{fh} --max-spp {}` ({}): multi-scale mode, same seed; \
             RMSE against the unculled image, noise floor = RMSE between two seeds. Culling \
             acts where the far field / multi-scale term is computed: in the per-render \
             table build (`render::ntable`); tracing reads the table either way.\n\n\
             | variant | table build s | tracing s | total s | RMSE vs unculled | noise floor |\n\
             |---|---|---|---|---|---|\n",
            a.params,
            a.max_spp,
            crate::TOOL_VERSION
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
             {threads} thread(s), wall times: noisy under load). Scattered lobes are skipped whenever \
             kappa = 0 or sigma_m_s = 0 (`FurModel::active_lobes`) and footprints covering \
             the whole fiber use the far field directly; both are always on.\n",
            100.0 * saved,
            100.0 * saved_table
        );
        let p = &paths[0];
        crate::io::write_output(p, md.as_bytes())?;
        outln!("wrote {}", p.display());
        return Ok(());
    }
    let scene = Scene::build(&base.strand);
    let spp = (a.max_spp, a.ref_spp);
    if a.noise_budget {
        let rows = noise_budget(&scene, &params, &base, spp, a.repeats, |m| outln!("{m}"))?;
        let command = command_line(&a, (pw, ph), (fw, fh));
        for (l, c) in &rows {
            for m in [Mode::Multiscale, Mode::Far] {
                if let Some(x) = c.speedup(Mode::Near, m, 4) {
                    outln!(
                        "{}: equal-quality speedup of {} over near {x:.2}x",
                        l.describe(),
                        m.name()
                    );
                }
            }
        }
        let p = &paths[0];
        crate::io::write_output(
            p,
            noise_budget_markdown(&rows, &command, 4, threads).as_bytes(),
        )?;
        outln!("wrote {}", p.display());
        return Ok(());
    }
    let study = if samplings.len() > 1 {
        Some(sampler_study(
            &scene,
            &params,
            &base,
            &modes,
            &samplings,
            spp,
            a.repeats,
            |m| outln!("{m}"),
        )?)
    } else {
        None
    };
    let c = match &study {
        Some(st) => st.runs[0].1.clone(),
        None => convergence(&scene, &params, &base, &modes, spp, a.repeats, |m| {
            outln!("{m}")
        })?,
    };
    let mut extra = String::new();
    if let Some(st) = &study {
        extra += &format!(
            "\nThe curves above are sampler `{}`'s.\n\n{}",
            samplings[0].name(),
            st.markdown(&modes)
        );
        for line in st.markdown(&modes).lines().filter(|l| l.starts_with("- ")) {
            outln!("{}", line.trim_start_matches("- ").replace("**", ""));
        }
    }
    if a.preview {
        let mut s = base.clone();
        s.spp = 64;
        let (t, near) = preview_ratio(&scene, &params, &s, Mode::Multiscale)?;
        let line = format!(
            "preview {fw}x{fh} at 64 spp, multiscale, sampler {}: {:.2}x the time of the same render in near-field mode ({t:.1} s against {near:.1} s on this run)",
            samplings[0].name(),
            t / near
        );
        outln!("{line}");
        extra += &format!("\n## Preview\n\n{line}.\n");
    }
    for m in &modes {
        if let Some(v) = c.inefficiency(*m, 4) {
            outln!(
                "{:10} RMSE^2 x seconds (median, spp >= 4): {v:.3e}",
                m.name()
            );
        }
    }
    let command = command_line(&a, (pw, ph), (fw, fh));
    // The report's files land together or not at all.
    let [csv, png, svg, md] = [0, 1, 2, 3].map(|i| paths[i].clone());
    let files = vec![
        (csv.clone(), c.to_csv().into_bytes()),
        (png.clone(), plot_convergence_bytes(&c, &png, false)?),
        (svg.clone(), plot_convergence_bytes(&c, &svg, true)?),
        (
            md.clone(),
            (c.to_markdown(&command, 4, threads) + &extra).into_bytes(),
        ),
    ];
    let mut files = files;
    if let Some(st) = &study {
        files.push((a.out.join("render_samplers.csv"), st.csv().into_bytes()));
    }
    crate::io::write_outputs(&files)?;
    outln!("wrote {} (+ .png, .svg, .md)", csv.display());
    for fast in [Mode::Multiscale, Mode::Far] {
        if let Some(s) = c.speedup(Mode::Near, fast, 4) {
            outln!(
                "equal-quality speedup {} over near: {s:.2}x pooled, per repeat {} (paper, hair lock: multi-scale ~5x its near field)",
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

/// The command line a convergence report or noise budget records: every option it ran
/// with (`--modes` and `--env-nee` only where they apply; the noise budget takes neither).
fn command_line(a: &Args, (pw, ph): (usize, usize), (fw, fh): (usize, usize)) -> String {
    let variant = if a.noise_budget {
        " --noise-budget".to_string()
    } else {
        String::new()
    };
    let modes = if a.noise_budget {
        String::new()
    } else {
        format!(" --modes {}", super::shell_quote(&a.modes))
    };
    format!(
        "furfit render-convergence{variant} --params {} --size {pw}x{ph} --frame {fw}x{fh} \
         --max-spp {} --ref-spp {}{modes} --seed {} --repeats {} --threads {}{} --samplings {}{} --out {}",
        super::shell_quote(&a.params),
        a.max_spp,
        a.ref_spp,
        a.seed,
        a.repeats,
        a.threads,
        if a.env_nee { " --env-nee" } else { "" },
        super::shell_quote(&a.samplings),
        if a.preview { " --preview" } else { "" },
        super::shell_quote(&a.out.display().to_string())
    )
}

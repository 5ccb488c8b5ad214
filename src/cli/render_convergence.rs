//! `furfit render-convergence`: RMSE vs spp/time per BCSDF scale on a patch of the test
//! lock, the equal-quality speedup of multi-scale over near field, and (with
//! `--culling-study`) the time saved by far-field culling with its image difference, or
//! (with `--noise-budget`) the speedup under lightings that isolate the noise of `h`.

use crate::render::bsdf::Mode;
use crate::render::study_run::{self, StudyKind, StudyOptions};
use crate::render::{MAX_PIXELS, MAX_SIDE, MAX_SPP};
use anyhow::{bail, Context};
use clap::builder::RangedU64ValueParser;
use std::path::PathBuf;

/// Largest `--repeats`: each repeat renders the whole curve again.
const MAX_REPEATS: usize = 1000;

#[derive(clap::Args, Debug)]
/// Arguments of `furfit render-convergence` (its `--help` text is the [`super::Command`]
/// variant's).
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
    /// BCSDF samplers to compare (lobes, ishair, uniform); the first one's curves are the report's.
    #[arg(long, default_value = "lobes")]
    pub samplings: String,
    /// Pixel position and first vertices' BCSDF uniforms: stratified, sobol or independent (as `furfit render`).
    #[arg(long, default_value = "stratified")]
    pub pixel_sampling: String,
    /// Also time the full --frame at 64 spp, multiscale against near field.
    #[arg(long, conflicts_with_all = ["culling_study", "noise_budget"])]
    pub preview: bool,
}

/// Run `furfit render-convergence`: parse and check every option, load the parameters,
/// prepare the output folder, then make the study ([`study_run::run`]).
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
    let pixel_sampling =
        crate::render::qmc::PixelSampling::parse(&a.pixel_sampling).context("--pixel-sampling")?;
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
    let kind = if a.culling_study {
        StudyKind::Culling
    } else if a.noise_budget {
        StudyKind::NoiseBudget
    } else {
        StudyKind::Convergence
    };
    let opts = StudyOptions {
        kind,
        params_spec: a.params.clone(),
        patch: (pw, ph),
        frame: (fw, fh),
        max_spp: a.max_spp,
        ref_spp: a.ref_spp,
        modes,
        samplings,
        pixel_sampling,
        seed: a.seed,
        repeats: a.repeats,
        threads: a.threads,
        env_nee: a.env_nee,
        preview: a.preview,
        out: a.out.clone(),
        force: a.force,
        command: command_line(&a, (pw, ph), (fw, fh)),
    };
    let (params, _, _) = super::load_params(&a.params)?;
    super::prepare_out_dir(&a.out)?;
    study_run::run(&opts, &params, |m| outln!("{m}"))?;
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
         --max-spp {} --ref-spp {}{modes} --seed {} --repeats {} --threads {}{} --samplings {} --pixel-sampling {}{} --out {}",
        super::shell_quote(&a.params),
        a.max_spp,
        a.ref_spp,
        a.seed,
        a.repeats,
        a.threads,
        if a.env_nee { " --env-nee" } else { "" },
        super::shell_quote(&a.samplings),
        super::shell_quote(&a.pixel_sampling),
        if a.preview { " --preview" } else { "" },
        super::shell_quote(&a.out.display().to_string())
    )
}

//! `furfit fit <profile-file-or-species-folder>... [--out fits/<species>.json] ...`

use crate::fit::batch::{outcome_lines, Batch};
use crate::fit::job::{jobs_for_all, species_name, Job};
use crate::fit::FitOptions;
use crate::models::{FiberModel, Param};
use anyhow::Context;
use std::io::IsTerminal;
use std::path::PathBuf;

/// Largest `--starts`: the global stage keeps every scored start (about 0.25 KB each,
/// 0.25 GB at the cap; each costs one evaluation on the subsample, milliseconds).
const MAX_STARTS: u64 = 1_000_000;
/// Largest `--lm-starts`: each is a full Levenberg-Marquardt run on the subsample.
const MAX_LM_STARTS: u64 = 1024;

#[derive(clap::Args, Debug)]
/// Arguments of `furfit fit` (its `--help` text is the [`super::Command`] variant's).
pub struct Args {
    /// Profile files (.csv, .npz, .npy, Yan .txt) and/or species folders; all are merged
    /// into one species.
    pub inputs: Vec<PathBuf>,
    /// Output fit file (default fits/<species>.json; with --all, the folder is --fits).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Folder for fit files with --all or when --out is not given.
    #[arg(long, default_value = "fits", conflicts_with = "out")]
    pub fits: PathBuf,
    /// Seed of the subsample and the Halton scrambling (same seed, same fit).
    #[arg(long, allow_negative_numbers = true, default_value_t = 0)]
    pub seed: u64,
    /// Worker threads (default or 0: all cores), at most 1024.
    #[arg(long, allow_negative_numbers = true, value_parser = super::threads_parser())]
    pub threads: Option<usize>,
    /// Fit every species folder under --measurements, one after another.
    #[arg(long)]
    pub all: bool,
    /// Replace a fit file made from other data (a refit of the same data needs no --force).
    #[arg(long)]
    pub force: bool,
    /// With --all: the folder of species folders to fit.
    #[arg(long, default_value = "measurements", requires = "all")]
    pub measurements: PathBuf,
    /// Model: yan2017, marschner2003, chiang2016, or all; non-default models go to --fits/<model>/.
    #[arg(long, default_value = "yan2017")]
    pub model: String,
    #[command(flatten)]
    /// Far-field accuracy options.
    pub far: super::FarArgs,
    /// An extra start: a preset of the model, a parameter JSON or a fit JSON.
    #[arg(long)]
    pub init: Option<String>,
    /// Fix a parameter, `name=value` in file units (e.g. `kappa=0`); repeatable.
    #[arg(long = "fix", value_name = "NAME=VALUE")]
    pub fix: Vec<String>,
    /// Halton starts in the global stage (scored with the model's presets and --init), at
    /// most 1000000.
    #[arg(long, allow_negative_numbers = true, default_value_t = 128)]
    pub starts: usize,
    /// Best-scored starts that run Levenberg-Marquardt, 1..=1024 (--init runs in addition);
    /// default: the model's (4; marschner2003 8).
    #[arg(long, allow_negative_numbers = true)]
    pub lm_starts: Option<usize>,
    /// Samples in the subsample of the global stage, 10..=10000000 (more than the data
    /// holds: all of it).
    #[arg(long, allow_negative_numbers = true, default_value_t = 1500)]
    pub subsample: usize,
    /// Iteration cap per LM run (at least 1).
    #[arg(long, allow_negative_numbers = true, default_value_t = 100)]
    pub max_iters: u64,
    /// Profile-likelihood intervals (68 %) of these parameters after the fit: names or `all` (costly).
    #[arg(long, value_name = "NAMES")]
    pub profile: Option<String>,
    /// Leave out samples below this fraction of the channel's peak, in [0, 1) (0 keeps all).
    #[arg(long, allow_negative_numbers = true, default_value_t = crate::fit::DEFAULT_FLOOR, value_parser = super::unit_fraction)]
    pub floor: f64,
    /// Weight residuals by sigma/value (every valid sample needs a sigma > 0).
    #[arg(long)]
    pub weighted: bool,
    /// Fit the full model only: skip the nested model tried first (yan2017: kappa = 0).
    #[arg(long)]
    pub full_model: bool,
    /// Print timing figures (evaluations/s, share of time in the model).
    #[arg(long)]
    pub bench: bool,
    #[command(flatten)]
    /// How profile files are read.
    pub load: super::LoadArgs,
}

/// Run `furfit fit`.
pub fn run(a: Args) -> anyhow::Result<()> {
    check_counts(&a)?;
    if a.all && (!a.inputs.is_empty() || a.out.is_some()) {
        anyhow::bail!(
            "--all fits every folder under --measurements into --fits: give no input files and no --out with it"
        );
    }
    let models: Vec<&'static dyn FiberModel> = if a.model.trim().eq_ignore_ascii_case("all") {
        crate::models::MODELS.to_vec()
    } else {
        vec![crate::models::by_name(&a.model)?]
    };
    if models.len() > 1 && a.out.is_some() {
        anyhow::bail!("--model all writes one fit per model: give --fits, not --out");
    }
    // 0 = all cores, as for render.
    if let Some(t) = a.threads.filter(|&t| t > 0) {
        rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build_global()
            .context("setting up the thread pool")?;
    }
    let load = a.load.to_options()?;
    let mut failures = Vec::new();
    let mut n_jobs = 0;
    for model in models {
        let opts = options(&a, model)?;
        let batch = Batch::prepare(jobs(&a, model)?, &load, &opts)?;
        n_jobs += batch.jobs.len();
        failures.extend(fit_batch(&a, &batch, &opts, &load));
    }
    match failures.len() {
        0 => Ok(()),
        // One job (no --all, or --all over one species): its error as it is.
        1 if n_jobs == 1 => Err(failures.pop().expect("one failure")),
        n => {
            // Every failure once more at the end, where a long batch's log is read; the
            // exit status must not pass the missing fits as success.
            let list: Vec<String> = failures.iter().map(|e| format!("  {e:#}")).collect();
            anyhow::bail!(
                "{n} of {n_jobs} species not fitted{}:\n{}",
                if n < n_jobs {
                    " (the others' fit files are written)"
                } else {
                    ""
                },
                list.join("\n")
            )
        }
    }
}

/// The numeric options within their ranges.
fn check_counts(a: &Args) -> anyhow::Result<()> {
    // A subsample above the grid limit would not be a subsample of any profile.
    let max_sub = crate::grid::MAX_GRID_SAMPLES as u64;
    for (name, v, min, max) in [
        ("--starts", a.starts as u64, 0, MAX_STARTS),
        (
            "--lm-starts",
            a.lm_starts.unwrap_or(1) as u64,
            1,
            MAX_LM_STARTS,
        ),
        ("--subsample", a.subsample as u64, 10, max_sub),
        ("--max-iters", a.max_iters, 1, u64::MAX),
    ] {
        if v < min {
            anyhow::bail!("{name} {v}: must be at least {min}");
        }
        if v > max {
            anyhow::bail!("{name} {v}: must be at most {max}");
        }
    }
    Ok(())
}

/// The fit options of the command line for `model`.
fn options(a: &Args, model: &'static dyn FiberModel) -> anyhow::Result<FitOptions> {
    let mut opts = FitOptions {
        seed: a.seed,
        n_global: a.starts,
        n_sub: a.subsample,
        max_iters: a.max_iters,
        weighted: a.weighted,
        floor: a.floor,
        nested: !a.full_model,
        ..FitOptions::for_model(model)
    };
    if let Some(n) = a.lm_starts {
        opts.n_best = n;
    }
    opts.far = a.far.options()?;
    for w in a.far.ignored(&opts.far, None) {
        eprintln!("warning: {w}");
    }
    if let Some(init) = &a.init {
        let (p, _, json) = super::load_model_params(init, Some(model))?;
        if let Some(chs) = json
            .as_ref()
            .and_then(|v| v["channels"].as_array())
            .filter(|c| c.len() > 1)
        {
            let primary = json.as_ref().and_then(|v| v["data"]["channel"].as_str());
            eprintln!(
                "note: --init {init} is a fit of {} channels: every channel fitted here \
                 starts from its top-level channel{}",
                chs.len(),
                primary.map_or(String::new(), |c| format!(" '{c}'"))
            );
        }
        opts.init = Some(p.to_file_units());
    }
    for f in &a.fix {
        let (k, v) = f
            .split_once('=')
            .with_context(|| format!("--fix '{f}': expected NAME=VALUE"))?;
        let v = super::number(v).map_err(|m| anyhow::anyhow!("--fix '{f}': {m}"))?;
        opts.fix(k.trim(), v)?;
    }
    if let Some(names) = &a.profile {
        opts.profile = profile_params(names, &opts)?;
    }
    Ok(opts)
}

/// The species to fit for `model`: every folder of --measurements, or the inputs given.
fn jobs(a: &Args, model: &'static dyn FiberModel) -> anyhow::Result<Vec<Job>> {
    let fits = crate::fit::batch::model_dir(&a.fits, model);
    if a.all {
        let (jobs, passed) = jobs_for_all(&a.measurements, &fits, a.force)?;
        for d in passed {
            eprintln!(
                "note: {}: not a species folder (no profile file, or a result kept from a \
                 refused run: *.kept-<pid>)",
                d.display()
            );
        }
        return Ok(jobs);
    }
    if a.inputs.is_empty() {
        anyhow::bail!("give profile files or species folders, or --all");
    }
    let species = species_name(&a.inputs[0]);
    Ok(vec![Job {
        out: a
            .out
            .clone()
            .unwrap_or_else(|| crate::fit::batch::default_out(&a.fits, &species, model)),
        species,
        inputs: a.inputs.clone(),
        force: a.force,
    }])
}

/// Fit every job of `batch` in turn, printing each; returns the species not fitted, each
/// error naming it. With several species a failure is said when it happens too.
fn fit_batch(
    a: &Args,
    batch: &Batch,
    opts: &FitOptions,
    load: &crate::profile::LoadOptions,
) -> Vec<anyhow::Error> {
    let jobs = &batch.jobs;
    let several = jobs.len() > 1;
    let mut not_fitted = Vec::new();
    let mut give_up = |j: usize, e: anyhow::Error| {
        if several {
            eprintln!("{}: not fitted: {e:#}", jobs[j].species);
        }
        not_fitted.push(e.context(format!("fitting {}", jobs[j].species)));
    };
    let mut skip = vec![false; jobs.len()];
    for (j, why) in batch.unfit.iter().enumerate() {
        if let Some(e) = why {
            skip[j] = true;
            give_up(j, anyhow::anyhow!("{e}"));
        }
    }
    // Folders the fits will create (said when they are, as the other commands do).
    let mut missing: Vec<PathBuf> = jobs
        .iter()
        .map(|j| crate::io::parent_dir(&j.out))
        .filter(|d| !d.exists())
        .collect();
    missing.sort();
    missing.dedup();
    for (j, job) in jobs.iter().enumerate() {
        if skip[j] {
            continue;
        }
        // What inspect would say about the data (duplicates, a radians warning) is said
        // before the fit, which may take long or fail because of it.
        for n in batch.loaded[j].notes.iter().chain(&batch.notes[j]) {
            outln!("{}: note: {n}", job.species);
        }
        let res = with_progress(&job.species, |say| batch.fit(j, opts, load, Some(say)));
        let sums = match res {
            Ok((_, sums)) => sums,
            Err(e) => {
                give_up(j, e.into());
                continue;
            }
        };
        for s in &sums {
            for l in outcome_lines(&job.species, s, opts, a.bench) {
                outln!("{l}");
            }
        }
        let dir = crate::io::parent_dir(&job.out);
        if let Some(k) = missing.iter().position(|d| *d == dir) {
            super::note_created_folder(&missing.remove(k));
        }
        outln!("  wrote {}", job.out.display());
    }
    not_fitted
}

/// Run `f` with a progress callback: a spinner on a terminal; in a log (stderr not a
/// terminal, where indicatif draws nothing) one line per stage, so a long fit shows where
/// it is.
fn with_progress<T>(prefix: &str, f: impl FnOnce(&(dyn Fn(&str) + Sync)) -> T) -> T {
    let bar = indicatif::ProgressBar::new_spinner();
    bar.set_prefix(prefix.to_string());
    bar.set_style(
        indicatif::ProgressStyle::with_template("{spinner} {prefix}: {msg} [{elapsed}]")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
    );
    let tty = std::io::stderr().is_terminal();
    if tty {
        bar.enable_steady_tick(std::time::Duration::from_millis(200));
    }
    let started = std::time::Instant::now();
    let say = |m: &str| {
        if tty {
            bar.set_message(m.to_string());
        } else {
            eprintln!("{prefix}: {m} [{:.1} s]", started.elapsed().as_secs_f64());
        }
    };
    let out = f(&say);
    bar.finish_and_clear();
    out
}

/// The parameters of `--profile NAMES` (`all`: every free one), each free and named once.
fn profile_params(names: &str, opts: &FitOptions) -> anyhow::Result<Vec<Param>> {
    let free = opts.layout.free();
    if names.trim().eq_ignore_ascii_case("all") {
        return Ok(free);
    }
    let mut out = Vec::new();
    for name in names.split(',').map(|n| n.trim().to_ascii_lowercase()) {
        let name = name.as_str();
        let id = Param::by_name(opts.model(), name).with_context(|| {
            format!(
                "--profile: unknown parameter '{name}' of model {} (expected `all` or names among: {})",
                opts.model().name(),
                opts.layout.all().map(|p| p.name()).collect::<Vec<_>>().join(", ")
            )
        })?;
        if !free.contains(&id) {
            anyhow::bail!("--profile: {name} is fixed (--fix), so it has no interval");
        }
        if out.contains(&id) {
            anyhow::bail!("--profile: {name} is named twice");
        }
        out.push(id);
    }
    Ok(out)
}

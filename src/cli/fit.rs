//! `furfit fit <profile-file-or-species-folder>... [--out fits/<species>.json] ...`

use crate::fit::job::{fit_loaded, jobs_for_all, load_inputs_full, species_name, Job};
use crate::fit::FitOptions;
use anyhow::Context;
use std::io::IsTerminal;
use std::path::PathBuf;

/// Largest `--starts`: the global stage keeps every scored start (about 0.25 KB each,
/// 0.25 GB at the cap; each costs one evaluation on the subsample, milliseconds).
const MAX_STARTS: u64 = 1_000_000;
/// Largest `--lm-starts`: each is a full Levenberg-Marquardt run on the subsample.
const MAX_LM_STARTS: u64 = 1024;

#[derive(clap::Args, Debug)]
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
    /// Fit every species folder under --measurements (one species after another, each
    /// using all --threads, so the total thread count stays --threads). Unreadable data,
    /// options the data cannot serve (e.g. --weighted without sigmas) and outputs in the
    /// way stop the run before any fit; a species that cannot be fitted (no valid sample,
    /// a solver error) is listed at the end, after the others are fitted, and the exit
    /// status is non-zero.
    #[arg(long)]
    pub all: bool,
    /// Replace an existing fit file that was made from other data (a refit of the same
    /// data replaces it without this).
    #[arg(long)]
    pub force: bool,
    /// With --all: the folder of species folders to fit.
    #[arg(long, default_value = "measurements", requires = "all")]
    pub measurements: PathBuf,
    #[command(flatten)]
    pub far: super::FarArgs,
    /// Start point: a preset name, a parameter JSON or a fit JSON (used as one of the starts).
    #[arg(long)]
    pub init: Option<String>,
    /// Fix a parameter, `name=value` in file units (e.g. `kappa=0`); repeatable.
    #[arg(long = "fix", value_name = "NAME=VALUE")]
    pub fix: Vec<String>,
    /// Halton starts in the global stage (scored with the ten presets and --init), at
    /// most 1000000.
    #[arg(long, allow_negative_numbers = true, default_value_t = 128)]
    pub starts: usize,
    /// Best-scored starts that run Levenberg-Marquardt, 1..=1024 (--init runs in addition).
    #[arg(long, allow_negative_numbers = true, default_value_t = 4)]
    pub lm_starts: usize,
    /// Samples in the subsample of the global stage, 10..=10000000 (more than the data
    /// holds: all of it).
    #[arg(long, allow_negative_numbers = true, default_value_t = 1500)]
    pub subsample: usize,
    /// Iteration cap per LM run (at least 1).
    #[arg(long, allow_negative_numbers = true, default_value_t = 100)]
    pub max_iters: u64,
    /// Profile-likelihood intervals (68 %, Delta RSS = s^2) of these free parameters after
    /// the fit: a comma list of names or `all`. Each re-solves the other parameters at
    /// typically under ten values per side (more when its linearised SE is far below the
    /// step cap, as the steps then double out to the same reach), so it costs several fits;
    /// recorded as uncertainty.profile.
    #[arg(long, value_name = "NAMES")]
    pub profile: Option<String>,
    /// Leave out samples below this fraction of the channel's largest value, in [0, 1)
    /// (0 keeps all). No goniometer resolves eight decades, while the tails of noise-free
    /// model profiles (down to 1e-44) would outweigh the lobes in log space.
    #[arg(long, allow_negative_numbers = true, default_value_t = crate::fit::DEFAULT_FLOOR, value_parser = super::unit_fraction)]
    pub floor: f64,
    /// Weight residuals by sigma/value (every valid sample needs a sigma > 0, and none may
    /// lie more than 1000 times below the channel's median sigma/value)
    #[arg(long)]
    pub weighted: bool,
    /// Print timing figures (evaluations/s, share of time in the model).
    #[arg(long)]
    pub bench: bool,
    #[command(flatten)]
    pub load: super::LoadArgs,
}

pub fn run(a: Args) -> anyhow::Result<()> {
    // A subsample above the grid limit would not be a subsample of any profile.
    let max_sub = crate::grid::MAX_GRID_SAMPLES as u64;
    for (name, v, min, max) in [
        ("--starts", a.starts as u64, 0, MAX_STARTS),
        ("--lm-starts", a.lm_starts as u64, 1, MAX_LM_STARTS),
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
    if a.all && (!a.inputs.is_empty() || a.out.is_some()) {
        anyhow::bail!(
            "--all fits every folder under --measurements into --fits: give no input files and no --out with it"
        );
    }
    // 0 = all cores, as for render.
    if let Some(t) = a.threads.filter(|&t| t > 0) {
        rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build_global()
            .context("setting up the thread pool")?;
    }
    let mut opts = FitOptions {
        seed: a.seed,
        n_global: a.starts,
        n_sub: a.subsample,
        n_best: a.lm_starts,
        max_iters: a.max_iters,
        weighted: a.weighted,
        floor: a.floor,
        ..FitOptions::default()
    };
    opts.far = a.far.options()?;
    for w in a.far.ignored(&opts.far, None) {
        eprintln!("warning: {w}");
    }
    if let Some(init) = &a.init {
        let (p, _, json) = super::load_params(init)?;
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
    let load = a.load.to_options()?;
    let jobs = if a.all {
        let (jobs, passed) = jobs_for_all(&a.measurements, &a.fits, a.force)?;
        for d in passed {
            eprintln!(
                "note: {}: not a species folder (no profile file, or a result kept from a \
                 refused run: *.kept-<pid>)",
                d.display()
            );
        }
        jobs
    } else {
        if a.inputs.is_empty() {
            anyhow::bail!("give profile files or species folders, or --all");
        }
        let species = species_name(&a.inputs[0]);
        vec![Job {
            out: a
                .out
                .clone()
                .unwrap_or_else(|| a.fits.join(format!("{species}.json"))),
            species,
            inputs: a.inputs.clone(),
            force: a.force,
        }]
    };
    // Every job's data is read before any fit, so an unreadable file or an axis option no
    // input reads (e.g. --theta-i for CSV files) fails at once, not after earlier fits.
    // Every failing species is named at once (not one per run).
    let mut loaded = Vec::new();
    let mut failed = Vec::new();
    for job in &jobs {
        match load_inputs_full(&job.inputs, &load) {
            Ok(l) => loaded.push(l),
            Err(e) => failed.push(format!("fitting {}: {e}", job.species)),
        }
    }
    if !failed.is_empty() {
        anyhow::bail!("{}", failed.join("\n"));
    }
    let formats: Vec<_> = loaded.iter().flat_map(|l| l.formats()).collect();
    load.check_used(&formats)?;
    // And every channel's fit data (e.g. --weighted without sigmas), so a bad species fails
    // before any fit; fit_loaded would also prefix the species the context below names.
    // A channel without a valid sample only keeps its own species from being fitted
    // (`unfit`): no option can fit it, and the other species still can be.
    let mut floor_notes = Vec::new();
    let mut unfit: Vec<Option<anyhow::Error>> = Vec::new();
    for (job, inputs) in jobs.iter().zip(&loaded) {
        let mut notes = Vec::new();
        let mut why = None;
        for c in 0..inputs.profile.n_channels() {
            let d = match crate::fit::channel_data(&inputs.profile, c, opts.weighted, opts.floor) {
                Ok(d) => d,
                Err(e) => {
                    let any_valid = inputs
                        .profile
                        .samples
                        .iter()
                        .any(|s| s.channel == c && s.is_valid());
                    if any_valid {
                        return Err(
                            anyhow::Error::new(e).context(format!("fitting {}", job.species))
                        );
                    }
                    why.get_or_insert(anyhow::Error::new(e));
                    continue;
                }
            };
            let ch = inputs
                .profile
                .channels
                .get(c)
                .map_or(String::new(), |n| format!(" of channel {n}"));
            let left: Vec<f64> = inputs
                .profile
                .samples
                .iter()
                .filter(|s| s.channel == c && !s.is_valid())
                .map(|s| s.value)
                .collect();
            if !left.is_empty() {
                let neg = left.iter().filter(|v| **v < 0.0).count();
                let zero = left.iter().filter(|v| **v == 0.0).count();
                let mut note = format!(
                    "{} sample(s){ch} without a positive value left out ({neg} negative, {zero} \
                     zero, {} missing or not finite): the fit works in log space",
                    left.len(),
                    left.len() - neg - zero
                );
                if neg > 0 {
                    note.push_str(
                        "; leaving out negative values (background subtraction) biases the \
                         low-signal regions upward",
                    );
                }
                notes.push(note);
            }
            if d.n_below_floor > 0 {
                notes.push(format!(
                    "{} valid sample(s){ch} below {:e} of the channel's largest value left out (--floor; 0 keeps them)",
                    d.n_below_floor, opts.floor
                ));
            }
        }
        floor_notes.push(notes);
        unfit.push(why);
    }
    // Every output too, so `--all` cannot stop at the n-th species after n - 1 fits, nor
    // write two species' fits to one file (folders `fox` and `.fox` are both species fox).
    let outs: Vec<PathBuf> = jobs
        .iter()
        .map(|j| crate::io::resolve_path(&j.out))
        .collect();
    for (j, (job, inputs)) in jobs.iter().zip(&loaded).enumerate() {
        crate::fit::job::check_out(&job.out)?;
        crate::fit::job::check_replace_fit(&job.out, &inputs.files, job.force)?;
        if let Some(other) = (0..j).find(|&o| outs[o] == outs[j]).map(|o| &jobs[o]) {
            anyhow::bail!(
                "{} and {} would both be fitted into {}; fit them one at a time with --out",
                other.inputs[0].display(),
                job.inputs[0].display(),
                job.out.display()
            );
        }
    }
    // Species that could not be fitted, with the reason; the others go on. With several
    // species (`--all`) a failure is said when it happens and listed again at the end.
    let batch = jobs.len() > 1;
    let mut not_fitted: Vec<(usize, anyhow::Error)> = Vec::new();
    let mut give_up = |j: usize, e: anyhow::Error| {
        if batch {
            eprintln!("{}: not fitted: {e:#}", jobs[j].species);
        }
        not_fitted.push((j, e));
    };
    let mut skip = Vec::new();
    for (j, why) in unfit.into_iter().enumerate() {
        skip.push(why.is_some());
        if let Some(e) = why {
            give_up(j, e);
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
    for (j, ((job, inputs), floor_notes)) in jobs.iter().zip(&loaded).zip(&floor_notes).enumerate()
    {
        if skip[j] {
            continue;
        }
        // What inspect would say about the data (duplicates, a radians warning) is said
        // before the fit, which may take long or fail because of it.
        for n in inputs.notes.iter().chain(floor_notes) {
            outln!("{}: note: {n}", job.species);
        }
        let bar = indicatif::ProgressBar::new_spinner();
        bar.set_prefix(job.species.clone());
        bar.set_style(
            indicatif::ProgressStyle::with_template("{spinner} {prefix}: {msg} [{elapsed}]")
                .unwrap_or_else(|_| indicatif::ProgressStyle::default_spinner()),
        );
        // A spinner on a terminal; in a log (stderr not a terminal, where indicatif draws
        // nothing) one line per stage, so a long fit shows where it is.
        let tty = std::io::stderr().is_terminal();
        if tty {
            bar.enable_steady_tick(std::time::Duration::from_millis(200));
        }
        let started = std::time::Instant::now();
        let say = |m: &str| {
            if tty {
                bar.set_message(m.to_string());
            } else {
                eprintln!(
                    "{}: {m} [{:.1} s]",
                    job.species,
                    started.elapsed().as_secs_f64()
                );
            }
        };
        let res = fit_loaded(job, inputs, &opts, &load, Some(&say));
        bar.finish_and_clear();
        let sums = match res {
            Ok((_, sums)) => sums,
            Err(e) => {
                give_up(j, e.into());
                continue;
            }
        };
        for s in &sums {
            let o = &s.outcome;
            let ch = if s.channel.is_empty() {
                String::new()
            } else {
                format!(" [{}]", s.channel)
            };
            outln!(
                "{}{ch}: NRMSE {} exposure {:.4e} ({} samples, {} LM iterations over all runs, {} evaluations, {:.2} s; {})",
                job.species,
                // Small values in scientific notation: "0.00%" hid a failed noise-free fit.
                if o.nrmse >= 1e-4 {
                    format!("{:.2}%", 100.0 * o.nrmse)
                } else {
                    format!("{:.1e}%", 100.0 * o.nrmse)
                },
                o.exposure,
                o.n_used,
                o.iterations,
                o.evaluations,
                o.wall_time_s,
                o.termination
            );
            let file = o.params.typed_file_units();
            let line: Vec<String> = crate::ParamId::ALL
                .iter()
                .map(|id| {
                    let spec = id.spec();
                    format!("{}={}", spec.name, spec.value_text(file[id.index()]))
                })
                .collect();
            outln!("  {}", line.join(" "));
            for l in se_lines(&o.uncertainty) {
                outln!("  {l}");
            }
            let fixed: Vec<&str> = crate::ParamId::ALL
                .iter()
                .filter(|id| opts.layout.fixed[id.index()].is_some())
                .map(|id| id.spec().name)
                .collect();
            if !fixed.is_empty() {
                outln!("  fixed (--fix): {}", fixed.join(", "));
            }
            if o.termination.starts_with("Maximum number of iterations") {
                outln!(
                    "  warning: the last LM run stopped at --max-iters {} before a convergence test passed: the result may not be the optimum (raise --max-iters)",
                    opts.max_iters
                );
            } else if o.uncertainty.s2.sqrt() < crate::fit::uncertainty::ROUNDING_RMS {
                // Noise-free data the model reproduces (a synth round trip): the standard
                // errors are ~0, so a step measured in them is rounding over rounding.
                outln!(
                    "  note: the residuals are at rounding level (NRMSE {:.1e}%): the model reproduces the data exactly, and the standard errors (about 0) say nothing",
                    100.0 * o.nrmse
                );
            } else if o.uncertainty.step_se > opts.step_se.unwrap_or(f64::INFINITY) {
                outln!(
                    "  warning: the local optimum is {:.2} standard errors from the result (converged fits: below {}); the solver ended with \"{}\"",
                    o.uncertainty.step_se,
                    opts.step_se.unwrap_or(f64::INFINITY),
                    o.termination
                );
            }
            if o.capped_slices.0 > 0 {
                outln!(
                    "  note: {} of {} theta_d slices hit the far field's refinement limit at the result; their model values are not guaranteed to the tolerance",
                    o.capped_slices.0,
                    o.capped_slices.1
                );
            }
            // As synth and render say it: a tau or g beyond the tables is evaluated at
            // their edge (a fit can reach it through --fix or the local solve).
            for n in crate::model::FurModel::model_notes(&o.params) {
                outln!("  note: {n}");
            }
            for iv in &o.profile {
                outln!("  {}", crate::fit::likelihood::describe(iv));
            }
            if o.profile_failed > 0 {
                outln!(
                    "  warning: {} profile re-solve(s) failed in the solver and were scored at their start: an interval end beside them may lie too far out",
                    o.profile_failed
                );
            }
            for (id, why) in &o.uncertainty.unconstrained {
                outln!("  unconstrained: {} ({why})", id.spec().name);
            }
            // Parameters the linearisation leaves out (on a bound, or on a singular
            // direction): every other standard error is conditional on their value.
            let held = o.uncertainty.held();
            if !held.is_empty() {
                let names: Vec<&str> = held.iter().map(|id| id.spec().name).collect();
                outln!(
                    "  note: the other standard errors hold {} fixed at the fitted value (far too small if the data favour another value); --profile gives intervals that re-solve {}",
                    names.join(", "),
                    if names.len() == 1 { "it" } else { "them" }
                );
            }
            if a.bench {
                outln!(
                    "  bench: {:.3e} sample evaluations/s, {:.1} model evaluations/s, estimated model time / wall {:.0}% ({:.2} s model in {:.2} s wall, {} threads; above 100 % where evaluations overlapped on several threads)",
                    o.sample_evaluations as f64 / o.wall_time_s,
                    o.evaluations as f64 / o.wall_time_s,
                    100.0 * o.model_time_s / o.wall_time_s,
                    o.model_time_s,
                    o.wall_time_s,
                    rayon::current_num_threads()
                );
            }
        }
        let dir = crate::io::parent_dir(&job.out);
        if let Some(k) = missing.iter().position(|d| *d == dir) {
            super::note_created_folder(&missing.remove(k));
        }
        outln!("  wrote {}", job.out.display());
    }
    let mut not_fitted = not_fitted
        .into_iter()
        .map(|(j, e)| e.context(format!("fitting {}", jobs[j].species)));
    match not_fitted.len() {
        0 => Ok(()),
        // One job (no --all, or --all over one species): its error as it is.
        _ if !batch => Err(not_fitted.next().expect("one failure")),
        n => {
            // Every failure once more at the end, where a long batch's log is read; the
            // exit status must not pass the missing fits as success.
            let list: Vec<String> = not_fitted.map(|e| format!("  {e:#}")).collect();
            anyhow::bail!(
                "{n} of {} species not fitted{}:\n{}",
                jobs.len(),
                if n < jobs.len() {
                    " (the others' fit files are written)"
                } else {
                    ""
                },
                list.join("\n")
            )
        }
    }
}

/// The parameters of `--profile NAMES` (`all`: every free one), each free and named once.
fn profile_params(names: &str, opts: &FitOptions) -> anyhow::Result<Vec<crate::ParamId>> {
    let free = opts.layout.free();
    if names.trim().eq_ignore_ascii_case("all") {
        return Ok(free);
    }
    let mut out = Vec::new();
    for name in names.split(',').map(|n| n.trim().to_ascii_lowercase()) {
        let name = name.as_str();
        let id = crate::ParamId::from_name(name).with_context(|| {
            format!(
                "--profile: unknown parameter '{name}' (expected `all` or names among: {})",
                crate::ParamId::ALL.map(|p| p.spec().name).join(", ")
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

/// The standard errors as the fit prints them: independent-residual and, when there are
/// enough rows, sweep-robust, per free parameter with one.
fn se_lines(unc: &crate::fit::uncertainty::Uncertainty) -> Vec<String> {
    let sig = |x: f64| crate::report::sig(x, 2);
    let mut out = Vec::new();
    let rb = unc.robust.as_ref();
    let cells: Vec<String> = crate::ParamId::ALL
        .iter()
        .filter_map(|id| {
            let se = unc.se[id.index()]?;
            let r = rb.and_then(|r| r.se[id.index()]);
            Some(match r {
                Some(r) => format!("{} {} | {}", id.spec().name, sig(se), sig(r)),
                None => format!("{} {}", id.spec().name, sig(se)),
            })
        })
        .collect();
    if cells.is_empty() {
        return out;
    }
    out.push(match rb {
        Some(r) => format!(
            "standard errors, independent residuals | robust to correlation along the sweeps (residuals' lag-1 autocorrelation along phi {:.2}; {} rows, up to {} theta_r lags):",
            r.phi_lag1,
            r.rows,
            r.bandwidth.iter().flatten().max().copied().unwrap_or(0)
        ),
        None => "standard errors (independent residuals; the sweep-robust ones need at least 4 (theta_i, theta_r) rows per free parameter and 2 samples per row on average):".into(),
    });
    out.push(format!("  {}", cells.join(", ")));
    if let Some(r) = rb.filter(|r| !r.spans_most.is_empty()) {
        let names: Vec<&str> = r.spans_most.iter().map(|id| id.spec().name).collect();
        out.push(format!(
            "note: by the sweep-robust errors {} also span most of {} range (the unconstrained flags follow the independent-residual ones)",
            names.join(", "),
            if names.len() == 1 { "its" } else { "their" }
        ));
    }
    out
}

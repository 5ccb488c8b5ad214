//! A batch of species fits as `furfit fit` runs it: every job's data read, its fit data
//! built and its output checked before the first fit ([`Batch::prepare`]), so a bad
//! species or an output in the way fails at once, not after earlier fits; then the fits one
//! after another ([`Batch::fit`]), and what a fit prints ([`outcome_lines`]).
//!
//! Where the fits go: the default model's (`yan2017`) to `<fits>/<species>.json`, as
//! before the model zoo; any other model's to `<fits>/<model>/<species>.json`
//! ([`default_out`]), so a folder of fits holds one model and reports read it whole.

use super::job::{fit_loaded, load_inputs_full, ChannelSummary, Job, LoadedInputs};
use super::{channel_data, FitOptions, Progress};
use crate::error::{Error, Result};
use crate::models::FiberModel;
use crate::profile::LoadOptions;
use serde_json::Value;
use std::path::{Path, PathBuf};

/// The fit file of `species` for `model` under the folder `fits` (see the module doc).
pub fn default_out(fits: &Path, species: &str, model: &dyn FiberModel) -> PathBuf {
    model_dir(fits, model).join(format!("{species}.json"))
}

/// The folder of `model`'s fits under `fits`: `fits` itself for the default model.
pub fn model_dir(fits: &Path, model: &dyn FiberModel) -> PathBuf {
    if model.name() == crate::models::default_model().name() {
        fits.to_path_buf()
    } else {
        fits.join(model.name())
    }
}

/// The jobs of a batch, each with its data loaded and checked.
pub struct Batch {
    /// The jobs, in the order given.
    pub jobs: Vec<Job>,
    /// Per job: its inputs, loaded and merged.
    pub loaded: Vec<LoadedInputs>,
    /// Per job: notes on samples left out (non-positive, below the floor), to print
    /// before its fit beside the loaders' notes.
    pub notes: Vec<Vec<String>>,
    /// Per job: why it cannot be fitted at all (a channel with no valid sample), if so.
    /// Such a job only keeps its own species from being fitted.
    pub unfit: Vec<Option<Error>>,
}

impl Batch {
    /// Read every job's data (with `load`), build every channel's fit data under `opts`
    /// and check every output, before any fit. Every species whose data cannot be read is
    /// named at once.
    pub fn prepare(jobs: Vec<Job>, load: &LoadOptions, opts: &FitOptions) -> Result<Batch> {
        let mut loaded = Vec::new();
        let mut failed = Vec::new();
        for job in &jobs {
            match load_inputs_full(&job.inputs, load) {
                Ok(l) => loaded.push(l),
                Err(e) => failed.push(format!("fitting {}: {e}", job.species)),
            }
        }
        if !failed.is_empty() {
            return Err(Error::Invalid(failed.join("\n")));
        }
        let formats: Vec<_> = loaded.iter().flat_map(|l| l.formats()).collect();
        load.check_used(&formats)?;
        let mut notes = Vec::new();
        let mut unfit = Vec::new();
        for (job, inputs) in jobs.iter().zip(&loaded) {
            let (n, why) = data_notes(job, inputs, opts)?;
            notes.push(n);
            unfit.push(why);
        }
        check_outputs(&jobs, &loaded)?;
        Ok(Batch {
            jobs,
            loaded,
            notes,
            unfit,
        })
    }

    /// Fit job `j` and write its fit file.
    pub fn fit(
        &self,
        j: usize,
        opts: &FitOptions,
        load: &LoadOptions,
        progress: Option<Progress>,
    ) -> Result<(Value, Vec<ChannelSummary>)> {
        fit_loaded(&self.jobs[j], &self.loaded[j], opts, load, progress)
    }
}

/// The notes on the samples of `inputs` a fit leaves out, and the reason it cannot be
/// fitted (a channel without any valid sample: no option can fit it). Any other error of
/// the fit data (e.g. `--weighted` without sigmas) is the batch's error.
pub fn data_notes(
    job: &Job,
    inputs: &LoadedInputs,
    opts: &FitOptions,
) -> Result<(Vec<String>, Option<Error>)> {
    let prof = &inputs.profile;
    let mut notes = Vec::new();
    let mut why = None;
    for c in 0..prof.n_channels() {
        let d = match channel_data(prof, c, opts.weighted, opts.floor) {
            Ok(d) => d,
            Err(e) => {
                let any_valid = prof.samples.iter().any(|s| s.channel == c && s.is_valid());
                if any_valid {
                    return Err(Error::Invalid(format!("fitting {}: {e}", job.species)));
                }
                why.get_or_insert(e);
                continue;
            }
        };
        let ch = prof
            .channels
            .get(c)
            .map_or(String::new(), |n| format!(" of channel {n}"));
        let left: Vec<f64> = prof
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
    Ok((notes, why))
}

/// Every output is a fit file furfit may replace, and no two jobs write one file (folders
/// `fox` and `.fox` are both species fox): checked before the first fit, so `--all`
/// cannot stop at the n-th species after n - 1 fits.
fn check_outputs(jobs: &[Job], loaded: &[LoadedInputs]) -> Result<()> {
    let outs: Vec<PathBuf> = jobs
        .iter()
        .map(|j| crate::io::resolve_path(&j.out))
        .collect();
    for (j, (job, inputs)) in jobs.iter().zip(loaded).enumerate() {
        super::job::check_out(&job.out)?;
        super::job::check_replace_fit(&job.out, &inputs.files, job.force)?;
        if let Some(other) = (0..j).find(|&o| outs[o] == outs[j]).map(|o| &jobs[o]) {
            return Err(Error::Invalid(format!(
                "{} and {} would both be fitted into {}; fit them one at a time with --out",
                other.inputs[0].display(),
                job.inputs[0].display(),
                job.out.display()
            )));
        }
    }
    Ok(())
}

/// What `furfit fit` prints of one channel's fit of `species` under the options `opts`,
/// line by line (the CLI adds nothing but the output path). `bench` adds the timing line.
pub fn outcome_lines(
    species: &str,
    s: &ChannelSummary,
    opts: &FitOptions,
    bench: bool,
) -> Vec<String> {
    let o = &s.outcome;
    let model = opts.model();
    let mut out = Vec::new();
    let ch = if s.channel.is_empty() {
        String::new()
    } else {
        format!(" [{}]", s.channel)
    };
    let tag = if model.name() == crate::models::default_model().name() {
        String::new()
    } else {
        format!(" ({})", model.name())
    };
    out.push(format!(
        "{species}{ch}{tag}: NRMSE {} exposure {:.4e} ({} samples, {} LM iterations over all runs, {} evaluations, {:.2} s; {})",
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
    ));
    let file = o.params.typed_file_units();
    let line: Vec<String> = opts
        .layout
        .all()
        .map(|id| format!("{}={}", id.name(), id.spec().value_text(file[id.index()])))
        .collect();
    out.push(format!("  {}", line.join(" ")));
    out.extend(
        se_lines(&o.uncertainty, opts)
            .into_iter()
            .map(|l| format!("  {l}")),
    );
    let fixed: Vec<&str> = opts
        .layout
        .all()
        .filter(|id| opts.layout.fixed[id.index()].is_some())
        .map(|id| id.name())
        .collect();
    if !fixed.is_empty() {
        out.push(format!("  fixed (--fix): {}", fixed.join(", ")));
    }
    out.extend(convergence_lines(o, opts));
    for iv in &o.profile {
        out.push(format!("  {}", super::likelihood::describe(iv)));
    }
    if o.profile_failed > 0 {
        out.push(format!(
            "  warning: {} profile re-solve(s) failed in the solver and were scored at their start: an interval end beside them may lie too far out",
            o.profile_failed
        ));
    }
    for (id, why) in &o.uncertainty.unconstrained {
        out.push(format!("  unconstrained: {} ({why})", id.name()));
    }
    // Parameters the linearisation leaves out (on a bound, or on a singular direction):
    // every other standard error is conditional on their value.
    let held = o.uncertainty.held();
    if !held.is_empty() {
        let names: Vec<&str> = held.iter().map(|id| id.name()).collect();
        out.push(format!(
            "  note: the other standard errors hold {} fixed at the fitted value (far too small if the data favour another value); --profile gives intervals that re-solve {}",
            names.join(", "),
            if names.len() == 1 { "it" } else { "them" }
        ));
    }
    if bench {
        out.push(format!(
            "  bench: {:.3e} sample evaluations/s, {:.1} model evaluations/s, estimated model time / wall {:.0}% ({:.2} s model in {:.2} s wall, {} threads; above 100 % where evaluations overlapped on several threads)",
            o.sample_evaluations as f64 / o.wall_time_s,
            o.evaluations as f64 / o.wall_time_s,
            100.0 * o.model_time_s / o.wall_time_s,
            o.model_time_s,
            o.wall_time_s,
            rayon::current_num_threads()
        ));
    }
    out
}

/// Warnings on how the solve ended, the far field's capped slices and the model's notes.
fn convergence_lines(o: &super::FitOutcome, opts: &FitOptions) -> Vec<String> {
    let mut out = Vec::new();
    if o.termination.starts_with("Maximum number of iterations") {
        out.push(format!(
            "  warning: the last LM run stopped at --max-iters {} before a convergence test passed: the result may not be the optimum (raise --max-iters)",
            opts.max_iters
        ));
    } else if o.uncertainty.s2.sqrt() < super::uncertainty::ROUNDING_RMS {
        // Noise-free data the model reproduces (a synth round trip): the standard errors
        // are ~0, so a step measured in them is rounding over rounding.
        out.push(format!(
            "  note: the residuals are at rounding level (NRMSE {:.1e}%): the model reproduces the data exactly, and the standard errors (about 0) say nothing",
            100.0 * o.nrmse
        ));
    } else if o.uncertainty.step_se > opts.step_se.unwrap_or(f64::INFINITY) {
        out.push(format!(
            "  warning: the local optimum is {:.2} standard errors from the result (converged fits: below {}); the solver ended with \"{}\"",
            o.uncertainty.step_se,
            opts.step_se.unwrap_or(f64::INFINITY),
            o.termination
        ));
    }
    if o.capped_slices.0 > 0 {
        out.push(format!(
            "  note: {} of {} far-field slices hit the refinement limit at the result; their model values are not guaranteed to the tolerance",
            o.capped_slices.0, o.capped_slices.1
        ));
    }
    // As synth and render say it: a tau or g beyond the tables is evaluated at their edge
    // (a fit can reach it through --fix or the local solve).
    for n in opts.model().notes(&o.params.values) {
        out.push(format!("  note: {n}"));
    }
    out
}

/// The standard errors as the fit prints them: independent-residual and, when there are
/// enough rows, sweep-robust, per free parameter with one.
fn se_lines(unc: &super::uncertainty::Uncertainty, opts: &FitOptions) -> Vec<String> {
    let sig = |x: f64| crate::error::sig(x, 2);
    let mut out = Vec::new();
    let rb = unc.robust.as_ref();
    let cells: Vec<String> = opts
        .layout
        .all()
        .filter_map(|id| {
            let se = unc.se[id.index()]?;
            let r = rb.and_then(|r| r.se[id.index()]);
            Some(match r {
                Some(r) => format!("{} {} | {}", id.name(), sig(se), sig(r)),
                None => format!("{} {}", id.name(), sig(se)),
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
        let names: Vec<&str> = r.spans_most.iter().map(|id| id.name()).collect();
        out.push(format!(
            "note: by the sweep-robust errors {} also span most of {} range (the unconstrained flags follow the independent-residual ones)",
            names.join(", "),
            if names.len() == 1 { "its" } else { "their" }
        ));
    }
    out
}

//! The fitter: ten BCSDF parameters from a goniometric profile, in log space, with the
//! exposure in closed form (seed Sec. 5.1 "Validation"; MODEL.md "Error metric").
//!
//! Pipeline of [`fit_data`]:
//! 1. **Global stage**: a seeded, scrambled Halton design of `n_global` points over a
//!    plausible box ([`crate::models::FiberModel::plausible_box`], drawn by [`starts`]),
//!    the ten seed Table 4 presets and an optional user start, each scored on a seeded
//!    subsample of `n_sub` samples.
//! 2. **Multi-start LM**: the best `n_best` starts run Levenberg-Marquardt ([`lm`]) on the
//!    subsample in parallel (rayon); the best result is polished by LM on all samples.
//!    (When the profile is not much larger than the subsample, step 2 runs directly on all
//!    samples.)
//! 3. **Uncertainty** from the Jacobian at the optimum ([`uncertainty`]).
//!
//! Before these, when the model has a nested reduction (the fur model without a medulla),
//! [`nested`] decides whether to run them for the reduced model first: it is fitted when
//! the global stage's first starts do not show the full model's signal plainly, and kept
//! unless an F-test says the full model lowers the cost by more than noise.
//!
//! Cost: Jacobians are forward differences, one column per free parameter in parallel,
//! each recomputing only the model terms its parameter can change
//! ([`crate::models::ModelTerms::with_change`]: `alpha` and `beta_m` touch only `M_p`,
//! `g` only the scattered lobes). Between accepted steps the LM runs update the Jacobian by
//! Broyden's secant formula ([`FitOptions::broyden`]); a run stops only on a step taken with
//! a freshly differenced Jacobian, and the uncertainty always uses one.
//!
//! Parameters are bounded by smooth maps ([`reparam`]); fixed parameters (`--fix`) are
//! removed from the solve. Everything is deterministic for a given seed: parallel work
//! writes to disjoint slots and every reduction runs in a fixed order.
//!
//! **Multi-channel profiles** are fitted one channel at a time (all ten parameters and the
//! exposure per channel): the seed fits one profile per species and its Table 4 has one
//! column per species, and a per-channel fit keeps the ten-key `params` object of DATA.md
//! meaningful for every channel. See [`job::fit_loaded`] and [`channel_data`].

pub mod batch;
pub mod file;
pub mod forward;
pub mod job;
pub mod likelihood;
pub mod lm;
pub mod nested;
mod options;
pub mod output;
mod polish;
pub mod problem;
pub mod reparam;
mod run;
mod stages;
pub mod starts;
pub mod uncertainty;

use crate::error::{Error, Num, Result};
use crate::model::far::FarOptions;
use crate::profile::Profile;
use forward::Points;
use nalgebra::DVector;
use problem::{FitData, LogResidualProblem};
use std::sync::atomic::Ordering;
use std::time::Instant;

pub use options::{FitOptions, FitOutcome, NestedTest, TraceEntry, DEFAULT_FLOOR, STEP_SE};
use run::Solved;

/// Progress callback: a short stage message.
pub type Progress<'a> = &'a (dyn Fn(&str) + Sync);

/// Fit the ten parameters to one channel's valid samples.
pub fn fit_data(
    data: &FitData,
    opts: &FitOptions,
    progress: Option<Progress>,
) -> Result<FitOutcome> {
    let say = |m: &str| {
        if let Some(p) = progress {
            p(m)
        }
    };
    if data.is_empty() {
        return Err(Error::Invalid(
            "no valid sample to fit (every value is <= 0 or missing)".into(),
        ));
    }
    let clock = Instant::now();
    let n_free = opts.layout.free().len();
    // The free parameters and the exposure are the unknowns: with no more samples than
    // that the fit interpolates the data and its NRMSE (0) and uncertainty mean nothing.
    if data.len() <= n_free + 1 {
        return Err(Error::Invalid(format!(
            "{} valid sample(s) for {n_free} free parameter(s) + the exposure: a fit needs more samples than unknowns",
            data.len()
        )));
    }
    // The NRMSE (MODEL.md) divides by the log range of the data, 0 for a flat profile:
    // no fit quality can be stated, and a goniometric profile never is flat.
    if data.ln_y.iter().all(|&v| v == data.ln_y[0]) {
        return Err(Error::Invalid(format!(
            "all {} valid samples have the same value: the NRMSE is normalised by the \
             range of ln(value), which is 0, so the fit could not be judged",
            data.len()
        )));
    }
    let Some(red) = nested::applicable(opts) else {
        return fit_layout(data, opts, clock, &say);
    };
    // The nested model first, unless the global stage shows the full model's signal
    // plainly; the full model only when the data ask for it.
    let sub_data = subsample(data, opts);
    let coarse = FarOptions {
        tol: None,
        ..opts.far
    };
    let sub = LogResidualProblem::new(&sub_data, opts.layout.clone(), coarse)
        .with_cancel(opts.cancel.clone());
    let pre = nested::precheck(&sub, opts, red)?;
    let done = |mut out: FitOutcome, test: NestedTest, before: u64| {
        out.evaluations += before + test.evaluations;
        out.nested = Some(test);
        out.wall_time_s = clock.elapsed().as_secs_f64();
        out
    };
    if !pre.try_reduced() {
        let test = nested::skipped(red, &pre, sub_data.len());
        say(&test.summary());
        let mut full_opts = opts.clone();
        full_opts.design_costs = Some(pre.costs_full.clone());
        return Ok(done(fit_layout(data, &full_opts, clock, &say)?, test, 0));
    }
    say(&format!("nested model first: {}", red.name));
    let r_opts = nested::reduced_design(opts, red, &pre);
    let reduced = fit_layout(data, &r_opts, clock, &say)?;
    let (mut test, best) = nested::probe(&sub_data, opts, &reduced, &pre, red, clock)?;
    test.evaluations += pre.evaluations;
    say(&test.summary());
    if test.kept_reduced {
        return Ok(done(reduced, test, 0));
    }
    let mut full_opts = opts.clone();
    full_opts.extra_starts.push(best);
    full_opts.design_costs = Some(pre.costs_full.clone());
    let full = fit_layout(data, &full_opts, clock, &say)?;
    // The full model contains the reduced one, so its fit ending worse is a basin the
    // multi-start missed: the reduced fit is then the better answer.
    if full.nrmse > reduced.nrmse {
        test.kept_reduced = true;
        test.decided_by = "F-test, then the full fit ended above the nested one";
        return Ok(done(reduced, test, full.evaluations));
    }
    Ok(done(full, test, reduced.evaluations))
}

/// The global and multi-start stages only choose the basin (the polish on all samples
/// settles the optimum), so they run on a subsample of whole far-field slices (all
/// samples when that would not save much).
fn subsample(data: &FitData, opts: &FitOptions) -> FitData {
    if data.len() > opts.n_sub * 3 / 2 {
        let model = opts.layout.model;
        data.subset(&starts::subsample_grouped(
            &data.points.pts,
            opts.n_sub,
            opts.seed,
            |ti, tr| model.slice_of(ti, tr),
        ))
    } else {
        data.clone()
    }
}

/// [`fit_data`] of one parameter layout (the stages of the module doc), on checked data.
fn fit_layout(
    data: &FitData,
    opts: &FitOptions,
    clock: Instant,
    say: &dyn Fn(&str),
) -> Result<FitOutcome> {
    let layout = &opts.layout;
    let n_free = layout.free().len();
    let full =
        LogResidualProblem::new(data, layout.clone(), opts.far).with_cancel(opts.cancel.clone());
    if n_free == 0 {
        let fixed = Solved {
            u: DVector::zeros(0),
            iters: 0,
            termination: "all parameters fixed".into(),
            trace: Vec::new(),
        };
        return finish(data, opts, &full, &full, fixed, (0, 0), clock);
    }
    // The subsample's stages run on the fixed initial segmentation: smooth in the
    // parameters and several times cheaper than the tolerance mode.
    let sub_data = subsample(data, opts);
    let sub_far = FarOptions {
        tol: None,
        ..opts.far
    };
    let sub = LogResidualProblem::new(&sub_data, layout.clone(), sub_far)
        .with_cancel(opts.cancel.clone());
    let stage = if sub_data.len() < data.len() {
        "subsample"
    } else {
        "coarse"
    };
    // 1. Global stage.
    let starts = stages::global(&sub, opts, clock, say)?;
    // 2. Multi-start LM (parallel over starts).
    let (best_run, runs) = stages::multi_start(&sub, &starts, opts, clock, say)?;
    let mut trace = vec![starts.entry(sub_data.len())];
    trace.extend(stages::entries(stage, 0, &best_run, sub_data.len()));
    let iters = best_run.iters + runs.iter().map(|r| r.iters).sum::<u64>();
    // 3. Polish on all samples; 4. second polishes.
    say(&format!("polishing on all {} samples", data.len()));
    let first = polish::polish(&full, best_run.u, opts, clock)?;
    trace.extend(stages::entries("full", best_run.iters, &first, data.len()));
    let mut solved = Solved {
        iters: iters + first.iters,
        termination: first.termination,
        u: first.u,
        trace,
    };
    let cost = polish::second_polishes(
        &full,
        &mut solved,
        first.cost,
        &runs,
        &starts,
        opts,
        clock,
        say,
    )?;
    let counts = (starts.scored.len(), starts.chosen.len());
    let out = finish(data, opts, &full, &sub, solved.clone(), counts, clock)?;
    if opts.profile.is_empty() {
        return Ok(out);
    }
    polish::with_profile(out, &full, solved, cost, opts, clock, say, |s| {
        finish(data, opts, &full, &sub, s, counts, clock)
    })
}

/// The outcome at `solved`: residuals, uncertainty and timing at the full tolerance.
/// `starts` counts the global and LM starts.
fn finish(
    data: &FitData,
    opts: &FitOptions,
    full: &LogResidualProblem,
    sub: &LogResidualProblem,
    solved: Solved,
    starts: (usize, usize),
    clock: Instant,
) -> Result<FitOutcome> {
    let Solved {
        u,
        iters: iterations,
        termination,
        trace,
    } = solved;
    let (starts_global, starts_lm) = starts;
    opts.cancel.check()?;
    // The solve's evaluations; those below (residuals, Jacobian for the uncertainty,
    // timing) are not part of it.
    let counts = |p: &LogResidualProblem| {
        (
            p.evals.load(Ordering::Relaxed),
            p.fd_columns.load(Ordering::Relaxed),
            p.jacobians.load(Ordering::Relaxed),
        )
    };
    let (full_evals, full_cols, full_jacs) = counts(full);
    let (sub_evals, sub_cols, sub_jacs) = if std::ptr::eq(full, sub) {
        (0, 0, 0)
    } else {
        counts(sub)
    };
    // Evaluated through the cache, so the Jacobian below reuses this evaluation.
    let (r, lk, terms) = full.evaluate_terms_at(&u);
    let capped_slices = terms.capped_slices();
    let t_jac = Instant::now();
    let jac = if u.is_empty() {
        nalgebra::DMatrix::zeros(data.len(), 0)
    } else {
        full.jacobian_at(&u)
    };
    let t_jac = t_jac.elapsed().as_secs_f64();
    let analytic = full.jacobians.load(Ordering::Relaxed) > full_jacs;
    let mut unc = uncertainty::estimate(&opts.layout, &u, &jac, &r);
    let held = uncertainty::bound_effects(full, &u, &r, &unc);
    uncertainty::flag_coupled(&mut unc, &jac, &held);
    unc.robust = uncertainty::robust(&opts.layout, &u, &jac, &r, &data.points.pts, &unc);
    let params = opts.layout.params(u.as_slice());
    params.validate()?;
    // Time of one evaluation alone: the fastest of three, since a single timing of a
    // millisecond-scale call (cold caches, a busy machine) overstated it enough to report
    // a model time share above 100 %.
    let time_min3 = |p: &LogResidualProblem| {
        (0..3)
            .map(|_| {
                let t = Instant::now();
                let m = p.model_values(u.as_slice());
                (t.elapsed().as_secs_f64(), m)
            })
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .expect("three timings")
    };
    let (t_full, m) = time_min3(full);
    let (nrmse, nrmse_exposure) = problem::nrmse(&m, &data.ln_y, data.range);
    let sample_evaluations = full_evals * data.len() as u64 + sub_evals * sub.data.len() as u64;
    // Time in the model, estimated as evaluations x the time of one evaluation measured
    // alone (concurrent evaluations during the solve make per-call timers overlap). A
    // finite-difference column recomputes only the terms its parameter changes: it costs
    // the Jacobian's time above per column, a share `col_cost` of a full evaluation
    // (taken as the same share on the subsample).
    let t_sub = if sub_evals > 0 { time_min3(sub).0 } else { 0.0 };
    // An analytic Jacobian: the final one's time, in evaluations.
    let (col_cost, jac_cost) = if u.is_empty() || t_full <= 0.0 {
        (1.0, 1.0)
    } else if analytic {
        (1.0, t_jac / t_full)
    } else {
        ((t_jac / u.len() as f64 / t_full).min(1.0), 0.0)
    };
    let cost = |evals: u64, cols: u64, jacs: u64| {
        (evals - cols) as f64 + cols as f64 * col_cost + jacs as f64 * jac_cost
    };
    let model_time_s = cost(full_evals, full_cols, full_jacs) * t_full
        + cost(sub_evals, sub_cols, sub_jacs) * t_sub;
    Ok(FitOutcome {
        params,
        exposure: lk.exp(),
        nrmse,
        nrmse_exposure,
        uncertainty: unc,
        iterations,
        evaluations: full_evals + sub_evals,
        jacobians: full_jacs + sub_jacs,
        jacobian: if analytic || full_jacs + sub_jacs > 0 {
            "analytic"
        } else {
            "finite differences"
        },
        sample_evaluations,
        model_time_s,
        starts_global,
        starts_lm,
        wall_time_s: clock.elapsed().as_secs_f64(),
        termination,
        trace,
        n_used: data.len(),
        capped_slices,
        profile: Vec::new(),
        profile_time_s: 0.0,
        profile_failed: 0,
        nested: None,
    })
}

/// The valid samples of channel `channel` of `profile` as fit data, without those below
/// `floor` times the channel's largest valid value (counted in
/// [`FitData::n_below_floor`]). Errors when there is none.
pub fn channel_data(
    profile: &Profile,
    channel: usize,
    weighted: bool,
    floor: f64,
) -> Result<FitData> {
    let mut pts = Points::default();
    let mut vals = Vec::new();
    let mut rel = Vec::new();
    // In angle order, not file order: the subsample, the starts' scores and every sum
    // then do not depend on how the file's rows happen to be ordered (a shuffled file
    // gave another optimum, eta 1.588 vs 1.618 on the red fox).
    let mut samples: Vec<_> = profile
        .samples
        .iter()
        .filter(|s| s.channel == channel && s.is_valid())
        .collect();
    samples.sort_by(|a, b| {
        (a.theta_i.total_cmp(&b.theta_i))
            .then(a.theta_r.total_cmp(&b.theta_r))
            .then(a.phi.total_cmp(&b.phi))
    });
    let peak = samples.iter().map(|s| s.value).fold(0.0f64, f64::max);
    let n_before = samples.len();
    samples.retain(|s| s.value >= floor * peak);
    let n_below_floor = n_before - samples.len();
    // The first sample (in angle order) that --weighted cannot weight, named by its
    // coordinates and, when it was read from a file, its file and line.
    let mut first_unweighted = None;
    let mut used = Vec::with_capacity(samples.len());
    for s in samples {
        used.push(s);
        let (ti, tr, ph) = s.angles_rad();
        pts.push(ti, tr, ph);
        vals.push(s.value);
        let r = s.sigma.map(|sg| sg / s.value).unwrap_or(f64::NAN);
        if first_unweighted.is_none() && !(r.is_finite() && r > 0.0) {
            first_unweighted = Some(s);
        }
        rel.push(r);
    }
    let what = profile
        .source
        .as_ref()
        .map(|p| p.display().to_string())
        .unwrap_or_else(|| "profile".into());
    // The channel as the file names it (an index would mean nothing to the reader); the
    // one channel of a profile without names is just "the profile".
    let channel_text = match profile.channels.get(channel) {
        Some(name) => format!("channel {name}"),
        None if profile.channels.is_empty() => "the profile".to_string(),
        None => format!("channel {channel}"),
    };
    if vals.is_empty() {
        return Err(Error::Invalid(format!(
            "{what}: {channel_text} has no valid sample (all {} samples are <= 0, NaN or missing)",
            profile
                .samples
                .iter()
                .filter(|s| s.channel == channel)
                .count()
        )));
    }
    if weighted {
        // Weights 1/(sigma/value)^2 need a positive, finite sigma on every sample used;
        // falling back to an unweighted fit would contradict the fit file's "weighted".
        if let Some(s) = first_unweighted {
            let bad = rel.iter().filter(|r| !(r.is_finite() && **r > 0.0)).count();
            let sigma = s
                .sigma
                .map_or("no sigma".to_string(), |sg| format!("sigma {}", Num(sg)));
            let at = profile
                .origin_of(s)
                .map(|o| format!(", {o}"))
                .unwrap_or_default();
            return Err(Error::Invalid(format!(
                "{what}: --weighted needs a sigma > 0 on every valid sample; {bad} of {} valid samples of {channel_text} have none (or 0), \
                 the first (in angle order) at theta_i {}, theta_r {}, phi {} ({sigma}{at})",
                rel.len(),
                s.theta_i,
                s.theta_r,
                s.phi
            )));
        }
    }
    if weighted {
        // One sample whose relative sigma is orders of magnitude below the others' takes a
        // weight that decides the fit alone (a sigma of 1e-20 froze the solver at its
        // start): a typing or unit slip in the sigma column, not a measurement.
        let mut sorted = rel.clone();
        sorted.sort_by(f64::total_cmp);
        let median = sorted[sorted.len() / 2];
        let (k, &least) = rel
            .iter()
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(b.1))
            .expect("at least one sample");
        if least * MAX_SIGMA_SPREAD < median {
            let s = used[k];
            let at = profile
                .origin_of(s)
                .map(|o| format!(" ({o})"))
                .unwrap_or_default();
            return Err(Error::Invalid(format!(
                "{what}: --weighted: the sample at theta_i {}, theta_r {}, phi {}{at} has sigma/value {least:.3e}, {:.3e} times below the median {median:.3e} of {channel_text}; its weight 1/(sigma/value)^2 would decide the fit alone (allowed: up to {} times below). Check its sigma, or fit without --weighted",
                s.theta_i,
                s.theta_r,
                s.phi,
                median / least,
                Num(MAX_SIGMA_SPREAD)
            )));
        }
    }
    let mut data = FitData::new(pts, &vals, if weighted { Some(&rel) } else { None });
    data.n_below_floor = n_below_floor;
    Ok(data)
}

/// How far below the median relative sigma (`sigma / value`) of a channel a sample's may
/// lie under `--weighted`: its weight is then at most 1e6 times the median's. Photon noise
/// spans about 0.1 % at a lobe's peak to tens of per cent in the tails, a few hundred; an
/// audit's sample at 7e3 times below the median dragged eta and beta_n off the optimum
/// of the rest.
pub const MAX_SIGMA_SPREAD: f64 = 1e3;

#[cfg(test)]
mod tests;

//! Stages 1 and 2 of [`super::fit_data`] (the global design scored on the subsample, and
//! the multi-start LM runs there), and the trace entries of a run.

use super::options::{FitOptions, TraceEntry};
use super::problem::LogResidualProblem;
use super::run::{run_lm, RunResult, SUBSAMPLE_FTOL};
use super::starts;
use crate::error::Result;
use nalgebra::DVector;
use rayon::prelude::*;
use std::sync::atomic::Ordering;
use std::time::Instant;

/// The scored starts of the global stage.
pub(super) struct Starts {
    /// `(candidate index, subsample cost, start in solver coordinates)` per candidate; the
    /// `--init` start, when given, is candidate 0, the extra starts follow.
    pub scored: Vec<(usize, f64, DVector<f64>)>,
    /// Candidates by cost, best first.
    pub order: Vec<usize>,
    /// The candidates the LM runs start from.
    pub chosen: Vec<usize>,
    /// When the best was scored.
    time_s: f64,
}

impl Starts {
    /// The trace's `global` entry: the best start on `n` samples.
    pub fn entry(&self, n: usize) -> TraceEntry {
        TraceEntry {
            stage: "global",
            iter: 0,
            time_s: self.time_s,
            nrmse: (2.0 * self.scored[self.order[0]].1 / n as f64).sqrt(),
        }
    }
}

/// Step 1: the `--init` start, the model's presets and a Halton design, each scored on `sub`.
pub(super) fn global(
    sub: &LogResidualProblem,
    opts: &FitOptions,
    clock: Instant,
    say: &dyn Fn(&str),
) -> Result<Starts> {
    let layout = &opts.layout;
    let mut cands: Vec<Vec<f64>> = Vec::new();
    if let Some(init) = &opts.init {
        let mut v = init.clone();
        for (k, f) in layout.fixed.iter().enumerate() {
            if let Some(x) = f {
                v[k] = *x;
            }
        }
        cands.push(v);
    }
    let n_extra = opts.extra_starts.len();
    for e in &opts.extra_starts {
        let mut v = e.clone();
        for (k, f) in layout.fixed.iter().enumerate() {
            if let Some(x) = f {
                v[k] = *x;
            }
        }
        cands.push(v);
    }
    let presets = starts::preset_starts(layout);
    let n_presets = presets.len();
    cands.extend(presets);
    cands.extend(starts::halton_starts(layout, opts.n_global, opts.seed));
    say(&format!(
        "global stage: scoring {} starts ({} Halton, {} presets{}{}) on {} samples",
        cands.len(),
        opts.n_global,
        n_presets,
        if opts.init.is_some() { ", --init" } else { "" },
        if n_extra > 0 {
            ", the nested probe's"
        } else {
            ""
        },
        sub.data.len()
    ));
    // The design's costs where the caller scored it already (same subsample, same
    // layout, same points: `fit::nested`; NaN where it did not).
    let first_design = cands.len() - n_presets - opts.n_global;
    let known = opts
        .design_costs
        .as_deref()
        .filter(|c| c.len() == n_presets + opts.n_global);
    let scored: Vec<(usize, f64, DVector<f64>)> = cands
        .par_iter()
        .enumerate()
        .map(|(i, c)| {
            let u = DVector::from_vec(layout.to_u(c));
            // Once cancelled, the remaining starts are not evaluated (checked below).
            let cost = if opts.cancel.is_cancelled() {
                f64::INFINITY
            } else if let Some(k) = known
                .filter(|_| i >= first_design)
                .map(|k| k[i - first_design])
                .filter(|k| !k.is_nan())
            {
                k
            } else {
                sub.cost(u.as_slice())
            };
            (
                i,
                if cost.is_finite() {
                    cost
                } else {
                    f64::INFINITY
                },
                u,
            )
        })
        .collect();
    opts.cancel.check()?;
    let mut order: Vec<usize> = (0..scored.len()).collect();
    order.sort_by(|&a, &b| scored[a].1.total_cmp(&scored[b].1).then(a.cmp(&b)));
    let mut chosen: Vec<usize> = order.iter().copied().take(opts.n_best.max(1)).collect();
    // The --init start always runs LM, in addition to the best scored ones (replacing one
    // of them could drop the best start of all).
    if opts.init.is_some() && !chosen.contains(&0) {
        chosen.insert(0, 0);
    }
    // So do the extra starts, which follow it.
    let first_extra = usize::from(opts.init.is_some());
    for i in first_extra..first_extra + n_extra {
        if !chosen.contains(&i) {
            chosen.push(i);
        }
    }
    Ok(Starts {
        scored,
        order,
        chosen,
        time_s: clock.elapsed().as_secs_f64(),
    })
}

/// Step 2: LM from each chosen start on `sub` in parallel, to the loose [`SUBSAMPLE_FTOL`]
/// (the runs only choose the basin): the best run and the others.
pub(super) fn multi_start(
    sub: &LogResidualProblem,
    starts: &Starts,
    opts: &FitOptions,
    clock: Instant,
    say: &dyn Fn(&str),
) -> Result<(RunResult, Vec<RunResult>)> {
    say(&format!(
        "multi-start LM: {} starts on {} samples",
        starts.chosen.len(),
        sub.data.len()
    ));
    let runs: Vec<Result<RunResult>> = starts
        .chosen
        .par_iter()
        .map(|&i| {
            let u0 = starts.scored[i].2.clone();
            run_lm(
                sub,
                u0,
                opts.max_iters,
                SUBSAMPLE_FTOL,
                None,
                opts.broyden,
                clock,
            )
        })
        .collect();
    let mut runs: Vec<RunResult> = runs.into_iter().collect::<Result<_>>()?;
    sub.evals
        .fetch_add(runs.iter().map(|r| r.evals).sum(), Ordering::Relaxed);
    sub.fd_columns
        .fetch_add(runs.iter().map(|r| r.fd_columns).sum(), Ordering::Relaxed);
    sub.jacobians
        .fetch_add(runs.iter().map(|r| r.jacobians).sum(), Ordering::Relaxed);
    let best = (0..runs.len())
        .min_by(|&a, &b| runs[a].cost.total_cmp(&runs[b].cost).then(a.cmp(&b)))
        .expect("at least one start");
    let best_run = runs.swap_remove(best);
    Ok((best_run, runs))
}

/// The trace entries of `run` as `stage`, its iterations numbered on from `offset`, its
/// cost as the RMS residual over `n` samples.
pub(super) fn entries(
    stage: &'static str,
    offset: u64,
    run: &RunResult,
    n: usize,
) -> Vec<TraceEntry> {
    run.trace
        .iter()
        .map(|t| TraceEntry {
            stage,
            iter: offset + t.iter,
            time_s: t.time_s,
            nrmse: (2.0 * t.cost / n as f64).sqrt(),
        })
        .collect()
}

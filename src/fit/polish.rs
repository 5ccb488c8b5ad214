//! Polishes on all samples (steps 3 and 4 of [`super::fit_data`]), and the
//! profile-likelihood stage after the fit, which may polish again.
//!
//! A second polish (from a start off a bound, see [`super::second_polish_starts`]) is
//! screened first on the far field's fixed initial segmentation (`tol: None`): smooth in
//! the parameters and about four times cheaper per evaluation than the tolerance mode.
//! Its full-tolerance run follows only when that coarse run ends in a basin at least
//! [`RETRY_SCREEN`] (relative) below the coarse optimum next to the first polish's end.
//! The coarse model's error is nearly common to nearby basins, and one basin reached from
//! two starts agrees to the runs' `ftol`. Measured on the red fox (`reports/fit_speed.md`):
//! the retry's full-tolerance run cost as much as the first polish and ended in the same
//! basin.
//!
//! Tried and not kept (the figures are in `reports/fit_speed.md`): a coarse stage before
//! every polish (the coarse optimum lies several standard errors from the fine one, and
//! the fine run then took as many steps as from the subsample's end), and freezing the
//! refinement decisions during the fine run.

use super::options::{FitOptions, FitOutcome};
use super::problem::LogResidualProblem;
use super::run::{run_lm, RunResult, Solved};
use super::stages::{entries, Starts};
use super::{likelihood, reparam};
use crate::error::Result;
use crate::model::far::FarOptions;
use nalgebra::DVector;
use std::sync::atomic::Ordering;
use std::time::Instant;

/// See the module doc.
pub const RETRY_SCREEN: f64 = 1e-5;

/// An LM run on all samples from `start`, to the fit's full stop (`ftol` and the
/// standard-error test), its evaluations counted in `full`.
pub(super) fn polish(
    full: &LogResidualProblem,
    start: DVector<f64>,
    opts: &FitOptions,
    clock: Instant,
) -> Result<RunResult> {
    let run = run_lm(
        full,
        start,
        opts.max_iters,
        opts.ftol,
        opts.step_se,
        opts.broyden,
        clock,
    )?;
    count(full, &run);
    Ok(run)
}

/// The screen of second polishes: the coarse optimum next to the first polish's end,
/// computed on first use.
pub(super) struct Screen<'p, 'a> {
    full: &'p LogResidualProblem<'a>,
    coarse: Option<LogResidualProblem<'a>>,
    reference: Option<f64>,
    first: DVector<f64>,
}

impl<'p, 'a> Screen<'p, 'a> {
    /// A screen against the first polish's end `first` (no screening when `full` has no
    /// tolerance to relax, or its model none to honour).
    pub fn new(full: &'p LogResidualProblem<'a>, first: &DVector<f64>) -> Self {
        let refines = full.far.tol.is_some() && full.layout.model.refines();
        let coarse = refines.then(|| {
            full.with_far(FarOptions {
                tol: None,
                ..full.far
            })
        });
        Screen {
            full,
            coarse,
            reference: None,
            first: first.clone(),
        }
    }

    /// The coarse run from `start` and whether its basin passes the screen (`None`: no
    /// screening, polish from `start`).
    pub fn run(
        &mut self,
        start: &DVector<f64>,
        opts: &FitOptions,
        clock: Instant,
    ) -> Result<Option<(RunResult, bool)>> {
        let Some(coarse) = &self.coarse else {
            return Ok(None);
        };
        let full = self.full;
        let lm = |u: DVector<f64>| -> Result<RunResult> {
            let run = run_lm(
                coarse,
                u,
                opts.max_iters,
                opts.ftol,
                None,
                opts.broyden,
                clock,
            )?;
            count(full, &run);
            Ok(run)
        };
        let reference = match self.reference {
            Some(c) => c,
            None => lm(self.first.clone())?.cost,
        };
        let run = lm(start.clone())?;
        self.reference = Some(reference);
        let passes = run.cost < reference * (1.0 - RETRY_SCREEN);
        Ok(Some((run, passes)))
    }
}

/// Step 4: second polishes of `solved` (the first polish's end, `cost` on all samples) on all
/// samples. A bounded map's derivative vanishes at its bound, so LM cannot leave a bound
/// that the subsample's model led it to, even where all samples favour an interior value
/// (noise-free data, fitted exactly from another start, ended on a bound); and a --init
/// start must never end worse than it began. Each is screened on the coarse model first
/// (module doc). Updates `solved` when one ends lower; returns the final cost.
#[allow(clippy::too_many_arguments)]
pub(super) fn second_polishes(
    full: &LogResidualProblem,
    solved: &mut Solved,
    mut cost: f64,
    runs: &[RunResult],
    starts: &Starts,
    opts: &FitOptions,
    clock: Instant,
    say: &dyn Fn(&str),
) -> Result<f64> {
    let init_u = opts.init.as_ref().map(|_| starts.scored[0].2.clone());
    let retries = second_polish_starts(full, &solved.u, cost, init_u, runs, starts);
    let mut screen = Screen::new(full, &solved.u);
    for (why, start) in retries {
        say(&format!("second polish from {why}"));
        let offset = solved.iters;
        let start = match screen.run(&start, opts, clock)? {
            Some((coarse, false)) => {
                solved.iters += coarse.iters;
                say("  its coarse run ended no lower than the first polish's basin: not polished");
                continue;
            }
            Some((coarse, true)) => {
                solved.iters += coarse.iters;
                coarse.u
            }
            None => start,
        };
        let run = polish(full, start, opts, clock)?;
        solved.iters += run.iters;
        if run.cost < cost {
            solved
                .trace
                .extend(entries("retry", offset, &run, full.data.len()));
            cost = run.cost;
            solved.u = run.u;
            solved.termination = format!("{} (second polish from {why})", run.termination);
        }
    }
    Ok(cost)
}

/// Starts of second polishes on all samples after the first ended at `u` with `cost` (see
/// step 4 of [`super::fit_data`]): the `--init` start `init_u` when it costs less there, and when
/// `u` has parameters on their bounds ([`reparam::at_bound`]), the best other candidate
/// with them inside: another start's LM end (by its subsample cost), else the best
/// scored start.
fn second_polish_starts(
    full: &LogResidualProblem,
    u: &DVector<f64>,
    cost: f64,
    init_u: Option<DVector<f64>>,
    runs: &[RunResult],
    starts: &Starts,
) -> Vec<(&'static str, DVector<f64>)> {
    let (order, scored) = (&starts.order, &starts.scored);
    let mut out = Vec::new();
    if let Some(init) = init_u {
        if full.cost(init.as_slice()) < cost {
            out.push(("--init", init));
        }
    }
    let free = full.layout.free();
    let pinned: Vec<usize> = (0..free.len())
        .filter(|&j| reparam::at_bound(free[j], u[j]))
        .collect();
    if pinned.is_empty() {
        return out;
    }
    let inside = |v: &DVector<f64>| pinned.iter().all(|&j| !reparam::at_bound(free[j], v[j]));
    let cand = runs
        .iter()
        .filter(|r| inside(&r.u))
        .min_by(|a, b| a.cost.total_cmp(&b.cost))
        .map(|r| r.u.clone())
        .or_else(|| {
            order
                .iter()
                .map(|&i| &scored[i].2)
                .find(|v| inside(v))
                .cloned()
        });
    if let Some(c) = cand {
        out.push(("a start off the bound", c));
    }
    out
}

/// Adds `run`'s evaluations to `full`'s counters.
fn count(full: &LogResidualProblem, run: &RunResult) {
    full.evals.fetch_add(run.evals, Ordering::Relaxed);
    full.fd_columns.fetch_add(run.fd_columns, Ordering::Relaxed);
    full.jacobians.fetch_add(run.jacobians, Ordering::Relaxed);
}

/// Profile-likelihood intervals of [`FitOptions::profile`] for the fit `out` at `solved`
/// (cost `cost` on all samples), `finish` making the outcome of another solve. A profile
/// re-solve that fits better than the optimum by more than the data's resolution means
/// the fit stopped short (a valley the polish left on a bound): the fit is polished again
/// from there, and when that wins, the result and its intervals are the new point's
/// (once).
#[allow(clippy::too_many_arguments)]
pub(super) fn with_profile(
    mut out: FitOutcome,
    full: &LogResidualProblem,
    solved: Solved,
    cost: f64,
    opts: &FitOptions,
    clock: Instant,
    say: &dyn Fn(&str),
    finish: impl Fn(Solved) -> Result<FitOutcome>,
) -> Result<FitOutcome> {
    let t = Instant::now();
    // A re-solve with one more parameter fixed: its solution and RSS (2 x its cost). One
    // the solver fails on is scored at its start (an upper bound of its RSS), and counted.
    let failed = std::cell::Cell::new(0usize);
    let mut refit = |p: &LogResidualProblem, start: DVector<f64>| {
        let run = run_lm(
            p,
            start.clone(),
            opts.max_iters,
            opts.ftol,
            opts.step_se,
            opts.broyden,
            clock,
        );
        match run {
            Ok(run) => (run.u, 2.0 * run.cost),
            Err(_) => {
                failed.set(failed.get() + 1);
                let rss = p.residuals(start.as_slice()).norm_squared();
                (start, rss)
            }
        }
    };
    let mut profile_at = |u: &DVector<f64>, out: &FitOutcome| {
        let (r, _) = full.evaluate_at(u);
        likelihood::intervals(
            full,
            u,
            &r,
            &out.uncertainty,
            &opts.profile,
            &mut refit,
            say,
        )
    };
    out.profile = profile_at(&solved.u, &out);
    let better = out
        .profile
        .iter()
        .filter_map(|iv| Some((iv.lowest?.0, iv.better.clone()?)))
        .filter(|(d, _)| *d < likelihood::REPOLISH)
        .min_by(|a, b| a.0.total_cmp(&b.0));
    if let Some((d, start)) = better {
        say("polishing from a better profile point");
        let run = polish(full, start, opts, clock)?;
        if run.cost < cost {
            let mut trace = solved.trace;
            trace.extend(entries("retry", solved.iters, &run, full.data.len()));
            let again = Solved {
                termination: format!(
                    "{} (polished again from a profile re-solve {d:.1} s^2 below the first optimum)",
                    run.termination
                ),
                iters: solved.iters + run.iters,
                u: run.u,
                trace,
            };
            let u = again.u.clone();
            out = finish(again)?;
            out.profile = profile_at(&u, &out);
        }
    }
    out.profile_time_s = t.elapsed().as_secs_f64();
    out.profile_failed = failed.get();
    // A cancelled re-solve counts as failed above; the intervals are then unfinished.
    opts.cancel.check()?;
    Ok(out)
}

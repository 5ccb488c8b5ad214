//! The nested-model stage of [`super::fit_data`]: fit the model's [`Reduction`] first
//! (the fur model without a medulla, six parameters instead of ten), then ask whether the
//! full model lowers the cost by more than noise, and fit the full model only if it does.
//!
//! The test is the F-test of nested least-squares models: with `C0` the reduced model's
//! cost and `C1` the best full-model cost found near it, `q` the parameters the full model
//! adds and `n - p` the full model's residual degrees of freedom,
//! `F = ((C0 - C1) / q) / (C1 / (n - p))`, and the full model is fitted when
//! `P(F_{q, n-p} > F) <` [`ALPHA`]. Two things make the reference distribution
//! approximate: the reduction sits on a bound (`kappa = 0`) and the inert parameters are
//! not identified there. Both make the nominal level optimistic about the full model, so
//! doubtful cases go to the full fit: the cost of an error is time, not accuracy.
//! Residuals correlated along a sweep do the same. Structured misfit (real data that no
//! model fits to the noise) lets the medulla lobes absorb misfit, which the test counts
//! as signal: the full model is then fitted, as before this stage existed.
//!
//! `C1` comes from a probe on the fit's subsample: the reduced optimum with the held
//! parameters taken from each global start (presets and the Halton design: the same
//! candidates the full fit scores), scored, and the best few polished by short LM runs.

use super::options::{FitOptions, FitOutcome, NestedTest};
use super::problem::{FitData, LogResidualProblem};
use super::run::run_lm;
use super::starts;
use crate::error::Result;
use crate::models::Reduction;
use nalgebra::DVector;
use rayon::prelude::*;
use std::sync::Arc;
use std::time::Instant;

/// Significance level of the test: below it the full model is fitted. Small because the
/// nominal level is optimistic about the full model (module doc) and a wrong "keep the
/// reduction" costs accuracy.
pub const ALPHA: f64 = 1e-3;

/// Best full-model starts whose held parameters make the probe's hybrids.
const PROBE_HYBRIDS: usize = 8;

/// How far toward a start's value the faint hybrids put the switch ([`probe`]).
const FAINT: f64 = 0.1;

/// Relative cost change that ends a probe run: well under the cost difference the test
/// needs at `q = 4`, `n = 1500` (~1.2 % for `p = ALPHA`).
const PROBE_FTOL: f64 = 1e-4;

/// Iteration cap of a probe run: the probe asks whether the full model does better near
/// the reduced optimum, not where its own optimum lies (the full fit finds that).
const PROBE_ITERS: u64 = 12;

/// The model's reduction, when this fit may try it: the model has one, it is asked for
/// ([`FitOptions::nested`]), the user fixed none of its parameters, gave no `--init`
/// (which names a start of the full model) and asked no profile interval of them.
pub(super) fn applicable(opts: &FitOptions) -> Option<&'static Reduction> {
    let red = opts.model().reduction()?;
    let touched = red.fixed.iter().any(|&(i, _)| {
        opts.layout.fixed[i].is_some() || opts.profile.iter().any(|p| p.index() == i)
    });
    (opts.nested && opts.init.is_none() && !touched).then_some(red)
}

/// `opts` with the reduction's parameters held.
pub(super) fn reduced_options(opts: &FitOptions, red: &Reduction) -> FitOptions {
    let mut o = opts.clone();
    o.design_costs = None;
    for &(i, v) in red.fixed {
        o.layout.fixed[i] = Some(v);
    }
    o
}

/// The reduced fit's options: the reduction's parameters held, and its global design the
/// one the precheck scored already (the presets and the first [`PRECHECK_HALTON`] Halton
/// points, a prefix of the full design), so its global stage evaluates nothing new. Six
/// free parameters need fewer starts than ten: on the three hair profiles of
/// `bench/fit_speed` the same optimum, 96 fewer evaluations (`reports/fit_speed.md`).
pub(super) fn reduced_design(opts: &FitOptions, red: &Reduction, pre: &Precheck) -> FitOptions {
    let mut o = reduced_options(opts, red);
    o.n_global = opts.n_global.min(PRECHECK_HALTON);
    let n_presets = pre.costs_reduced.len() - opts.n_global;
    o.design_costs = Some(Arc::new(
        pre.costs_reduced[..n_presets + o.n_global].to_vec(),
    ));
    o
}

/// The global stage's view of the two models: the start of the full model's design (its
/// presets and first [`PRECHECK_HALTON`] Halton points) scored on the subsample, and the
/// same points with the reduction applied. When the best full start beats the best
/// reduced one, the data carry the extra lobes' signal plainly (every medullated
/// species: by 116x to 376x in cost) and the reduced model is not fitted; otherwise
/// it is fitted first and the F-test decides. A wrong skip only costs time: the full
/// model is then fitted, as without this stage.
pub(super) struct Precheck {
    /// Best subsample cost of a full-model start, and of a reduced one.
    pub best_full: f64,
    pub best_reduced: f64,
    /// The design's costs in each layout ([`FitOptions::design_costs`], NaN where not
    /// scored).
    pub costs_full: Arc<Vec<f64>>,
    pub costs_reduced: Arc<Vec<f64>>,
    /// The best full-model starts (file units), best first: the probe takes its held
    /// parameters from them.
    pub top_full: Vec<Vec<f64>>,
    /// Model evaluations spent.
    pub evaluations: u64,
}

impl Precheck {
    /// The reduced model is worth fitting first.
    pub fn try_reduced(&self) -> bool {
        self.best_reduced <= self.best_full
    }
}

/// Halton points of each design the precheck scores (besides the presets): enough to
/// see a plain signal and to seed the probe; the chosen fit scores the rest itself.
const PRECHECK_HALTON: usize = 32;

/// Score the full design and its reductions on `sub` (fixed segmentation: a ranking).
pub(super) fn precheck(
    sub: &LogResidualProblem,
    opts: &FitOptions,
    red: &Reduction,
) -> Result<Precheck> {
    let mut cands = starts::preset_starts(&opts.layout);
    cands.extend(starts::halton_starts(
        &opts.layout,
        opts.n_global,
        opts.seed,
    ));
    let small = LogResidualProblem::new(sub.data, reduced_options(opts, red).layout, sub.far);
    // The presets and the first Halton points only: enough to see a plain signal and to
    // seed the probe; the full fit scores the rest itself (NaN: not scored).
    let n_scored = (cands.len() - opts.n_global + PRECHECK_HALTON).min(cands.len());
    let design = |prob: &LogResidualProblem| -> Result<Vec<f64>> {
        let costs = (0..cands.len())
            .into_par_iter()
            .map(|i| {
                if i >= n_scored {
                    f64::NAN
                } else if opts.cancel.is_cancelled() {
                    f64::INFINITY
                } else {
                    let c = prob.cost(&prob.layout.to_u(&cands[i]));
                    if c.is_finite() {
                        c
                    } else {
                        f64::INFINITY
                    }
                }
            })
            .collect();
        opts.cancel.check()?;
        Ok(costs)
    };
    let full = design(sub)?;
    let mut order: Vec<usize> = (0..n_scored).collect();
    order.sort_by(|&a, &b| full[a].total_cmp(&full[b]).then(a.cmp(&b)));
    let best_full = full[order[0]];
    let reduced = design(&small)?;
    let best_reduced = reduced[..n_scored]
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min);
    let evaluations = 2 * n_scored as u64;
    Ok(Precheck {
        best_full,
        best_reduced,
        costs_full: Arc::new(full),
        costs_reduced: Arc::new(reduced),
        top_full: order
            .iter()
            .take(PROBE_HYBRIDS)
            .map(|&i| cands[i].clone())
            .collect(),
        evaluations,
    })
}

/// The F-test probe (module doc) around the reduced fit `reduced` on `sub_data` (the
/// fit's subsample), and the best full-model point it found (file units) as a start for
/// the full fit.
pub(super) fn probe(
    sub_data: &FitData,
    opts: &FitOptions,
    reduced: &FitOutcome,
    pre: &Precheck,
    red: &'static Reduction,
    clock: Instant,
) -> Result<(NestedTest, Vec<f64>)> {
    let t0 = Instant::now();
    // Both costs at the fit's own far field: on the fixed initial segmentation the
    // reduced model carries the segmentation's error, which the full model's wide
    // scattered lobes absorb (kappa = 0 profiles tested "significant" at F ~ 13 there).
    let problem = |layout: &super::problem::ParamLayout| {
        LogResidualProblem::new(sub_data, layout.clone(), opts.far).with_cancel(opts.cancel.clone())
    };
    let full = problem(&opts.layout);
    let r_opts = reduced_options(opts, red);
    let small = problem(&r_opts.layout);
    // C0 and C1 must be optima of the same cost: the reduced fit was solved on all
    // samples, the probe runs on the subsample, whose optimum lies a little away.
    // Re-solved here, so that shift is not counted as the full model's gain.
    let probe_run = |prob: &LogResidualProblem, u: DVector<f64>| {
        run_lm(prob, u, PROBE_ITERS, PROBE_FTOL, None, opts.broyden, clock)
    };
    let polished = probe_run(
        &small,
        DVector::from_vec(r_opts.layout.to_u(&reduced.params.to_file_units())),
    )?;
    let c0 = polished.cost;
    let base = r_opts.layout.file_values(polished.u.as_slice());
    // Hybrids: the reduced optimum with the held parameters of the best full starts, the
    // switch (the first held parameter) at the start's value and, faint, a tenth of the
    // way there: without a signal the faint one starts next to C0 and its run ends in a
    // few steps; with one, the run grows it.
    let (switch, off) = red.fixed[0];
    let hybrids: Vec<DVector<f64>> = pre
        .top_full
        .iter()
        .flat_map(|c| {
            [1.0, FAINT].map(|share| {
                let mut v = base.clone();
                for &(i, _) in red.fixed {
                    v[i] = c[i];
                }
                v[switch] = off + share * (c[switch] - off);
                DVector::from_vec(full.layout.to_u(&v))
            })
        })
        .collect();
    let scores: Vec<f64> = hybrids
        .par_iter()
        .map(|u| {
            let c = full.cost(u.as_slice());
            if c.is_finite() {
                c
            } else {
                f64::INFINITY
            }
        })
        .collect();
    opts.cancel.check()?;
    let first = (0..hybrids.len())
        .min_by(|&a, &b| scores[a].total_cmp(&scores[b]).then(a.cmp(&b)))
        .expect("at least one hybrid");
    let run = probe_run(&full, hybrids[first].clone())?;
    let evaluations = hybrids.len() as u64 + polished.evals + run.evals;
    let c1 = run.cost.min(c0);
    let q = red.fixed.len();
    let n = sub_data.len();
    let p = opts.layout.free().len() + 1;
    let dof = n.saturating_sub(p).max(1);
    let (f, p_value) = f_test(c0, c1, q, dof);
    let test = NestedTest {
        name: red.name,
        held: red.fixed.to_vec(),
        kept_reduced: p_value >= ALPHA,
        decided_by: "F-test",
        n,
        q,
        dof,
        cost_reduced: c0,
        cost_full: c1,
        f,
        p_value,
        evaluations,
        seconds: t0.elapsed().as_secs_f64(),
    };
    Ok((test, opts.layout.file_values(run.u.as_slice())))
}

/// The record of a nested stage the global stage skipped ([`Precheck`]).
pub(super) fn skipped(red: &'static Reduction, pre: &Precheck, n: usize) -> NestedTest {
    NestedTest {
        name: red.name,
        held: red.fixed.to_vec(),
        kept_reduced: false,
        decided_by: "global stage (the best full-model start beat every nested one)",
        n,
        q: red.fixed.len(),
        dof: 0,
        cost_reduced: pre.best_reduced,
        cost_full: pre.best_full,
        f: f64::NAN,
        p_value: f64::NAN,
        evaluations: pre.evaluations,
        seconds: 0.0,
    }
}

/// The F statistic of nested least-squares models and its upper tail probability:
/// costs `c0 >= c1` (`0.5 sum r^2`), `q` added parameters, `dof` residual degrees of
/// freedom of the larger model. `P(F > f) = I_{dof / (dof + q f)}(dof / 2, q / 2)` (the
/// regularised incomplete beta function).
pub fn f_test(c0: f64, c1: f64, q: usize, dof: usize) -> (f64, f64) {
    // NaN costs compare false: no evidence either.
    let improved = c1 > 0.0 && c0 > c1;
    if !improved {
        return (0.0, 1.0);
    }
    let (q, d) = (q as f64, dof as f64);
    let f = ((c0 - c1) / q) / (c1 / d);
    let x = (d / (d + q * f)).clamp(0.0, 1.0);
    (f, puruspe::betai(d / 2.0, q / 2.0, x))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Upper quantiles of F from standard tables (Abramowitz & Stegun 26.6, and R's
    /// `qf`): `P(F_{4, 100} > 3.513) = 0.01`, `P(F_{1, 10} > 4.965) = 0.05`. The tables
    /// give four digits, so the tail probability is checked to 1e-4 absolute.
    #[test]
    fn f_tail_matches_tables() {
        // f = ((c0 - c1) / q) / (c1 / d) with c1 = d: c0 = d + q f.
        let (f, p) = f_test(100.0 + 4.0 * 3.513, 100.0, 4, 100);
        assert!((f - 3.513).abs() < 1e-12);
        assert!((p - 0.01).abs() < 1e-4, "{p}");
        let (_, p) = f_test(10.0 + 4.965, 10.0, 1, 10);
        assert!((p - 0.05).abs() < 1e-4, "{p}");
    }

    /// No improvement, or a "full" cost above the reduced one, is no evidence.
    #[test]
    fn no_improvement_is_p_one() {
        assert_eq!(f_test(5.0, 5.0, 4, 100), (0.0, 1.0));
        assert_eq!(f_test(5.0, 6.0, 4, 100), (0.0, 1.0));
        assert_eq!(f_test(5.0, 0.0, 4, 100), (0.0, 1.0));
    }
}

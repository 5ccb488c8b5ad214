//! One Levenberg-Marquardt run ([`run_lm`]) and what the stages hand on: its result and
//! where the solve ended.

use super::lm::{LevenbergMarquardt, TracePoint};
use super::options::TraceEntry;
use super::problem::LogResidualProblem;
use super::uncertainty;
use crate::error::{Error, Result};
use argmin::core::{Executor, State, TerminationStatus};
use nalgebra::DVector;
use std::sync::atomic::Ordering;
use std::time::Instant;

/// Relative cost change that ends an LM run on the subsample (see [`fit_data`](super::fit_data)).
pub(super) const SUBSAMPLE_FTOL: f64 = 1e-3;

pub(super) struct RunResult {
    pub(super) u: DVector<f64>,
    pub(super) cost: f64,
    pub(super) iters: u64,
    pub(super) termination: String,
    pub(super) trace: Vec<TracePoint>,
    pub(super) evals: u64,
    pub(super) fd_columns: u64,
    pub(super) jacobians: u64,
}

/// One LM run from `u0` on `shared`'s data. The run gets its own problem instance (its own
/// residual cache and counter), so concurrent runs cannot change each other's evaluation
/// counts; the count is added to `shared` afterwards.
pub(super) fn run_lm(
    shared: &LogResidualProblem,
    u0: DVector<f64>,
    max_iters: u64,
    ftol: f64,
    step_se: Option<f64>,
    broyden: bool,
    clock: Instant,
) -> Result<RunResult> {
    let prob = shared.fork();
    let mut lm = LevenbergMarquardt::new(clock);
    lm.ftol = ftol;
    lm.step_se = step_se;
    lm.max_se = uncertainty::MAX_SE_U;
    lm.broyden = broyden;
    let res = Executor::new(&prob, lm)
        .configure(|s| s.param(u0).max_iters(max_iters))
        .run()
        .map_err(|e| {
            // A cancelled run fails at its next evaluation; that is no solver failure.
            if shared.cancel.is_cancelled() {
                Error::Interrupted
            } else {
                Error::Invalid(format!("solver failed: {e}"))
            }
        })?;
    let state = &res.state;
    let u = state
        .get_best_param()
        .cloned()
        .ok_or_else(|| Error::Invalid("solver returned no parameters".into()))?;
    let termination = match state.get_termination_status() {
        TerminationStatus::Terminated(r) => r.text().to_string(),
        TerminationStatus::NotTerminated => "running".into(),
    };
    Ok(RunResult {
        cost: state.get_best_cost(),
        iters: state.get_iter(),
        termination,
        trace: res.solver.trace.clone(),
        u,
        evals: prob.evals.load(Ordering::Relaxed),
        fd_columns: prob.fd_columns.load(Ordering::Relaxed),
        jacobians: prob.jacobians.load(Ordering::Relaxed),
    })
}

impl<'a> argmin::core::Operator for &LogResidualProblem<'a> {
    type Param = DVector<f64>;
    type Output = DVector<f64>;
    fn apply(&self, u: &DVector<f64>) -> std::result::Result<DVector<f64>, argmin::core::Error> {
        (*self).apply(u)
    }
}

impl<'a> argmin::core::Jacobian for &LogResidualProblem<'a> {
    type Param = DVector<f64>;
    type Jacobian = nalgebra::DMatrix<f64>;
    fn jacobian(
        &self,
        u: &DVector<f64>,
    ) -> std::result::Result<nalgebra::DMatrix<f64>, argmin::core::Error> {
        (*self).jacobian(u)
    }
}

/// Where the solve ended: the point, its LM iterations over all runs, why its last run
/// stopped, and the convergence trace.
#[derive(Clone, Debug)]
pub(super) struct Solved {
    pub(super) u: DVector<f64>,
    pub(super) iters: u64,
    pub(super) termination: String,
    pub(super) trace: Vec<TraceEntry>,
}

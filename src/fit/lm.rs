//! Levenberg-Marquardt as an argmin 0.11 [`Solver`] over nalgebra vectors.
//!
//! Each argmin iteration is one trial step: solve `(J^T J + mu D^2) delta = -J^T r` by
//! Cholesky, where `D^2 = diag(J^T J)` kept as the running maximum over iterations (Moré's
//! scale invariance, "The Levenberg-Marquardt algorithm: implementation and theory", 1978);
//! accept when the gain ratio `rho = actual / predicted reduction` is positive and update
//! the damping with Nielsen's rule (`mu *= max(1/3, 1 - (2 rho - 1)^3)`, `nu = 2`;
//! on rejection `mu *= nu`, `nu *= 2`; H. B. Nielsen, "Damping parameter in Marquardt's
//! method", IMM-REP-1999-05). The Jacobian is recomputed only after an accepted step.
//!
//! Termination (besides argmin's `max_iters`): `||J^T r||_inf <= gtol`; an accepted step
//! with `||delta|| <= xtol (||u|| + xtol)`; the damping exceeding `1e16` (no further
//! descent possible; see below); and either an accepted step whose relative cost reduction is
//! `<= ftol` or, with [`LevenbergMarquardt::step_se`] set, such a step (progress has
//! slowed) followed, on a true Jacobian, by a Gauss-Newton step to the local optimum that
//! moves no coordinate by more than that many of its standard errors.
//! The relative-cost test stops wherever progress per step is slow, which on a flat valley
//! of a least-squares fit can be more than one standard error short of the optimum; the
//! standard-error test measures the remaining distance in the statistic a user reads: with
//! `H = J^T J`, `g = J^T r` and the residual variance `s^2 = |r|^2 / (n - p - 1)`, each
//! coordinate's Gauss-Newton step `(-H^+ g)_j` against its standard error
//! `sqrt(s^2 H^+_jj)`. Coordinates the data does not determine (loading on a singular
//! direction of `H`, below `1e-10` of the largest, or with a standard error above
//! [`LevenbergMarquardt::max_se`]) are left out, as the uncertainty estimate flags them:
//! driven towards a bound through a bounded map, such a coordinate keeps a step of a
//! fixed size in its (growing) standard error and would never pass. Where that test keeps
//! failing while ten accepted steps together lower `chi^2 = |r|^2 / s^2` by less than
//! 0.01 ([`STALLED`]), the run stops: what is left is invisible in the data (the cost at
//! that scale is rough, e.g. from the far field's tolerance-mode refinement). A run whose
//! damping runs out on a true Jacobian stops converged if the standard-error test passes
//! there, else with [`DAMPING_EXHAUSTED`]; [`LevenbergMarquardt::last_step_se`] keeps the
//! last test's value.
//!
//! With [`LevenbergMarquardt::broyden`] on, an accepted step updates the Jacobian by
//! Broyden's rank-one secant formula `J += (r_new - r - J delta) delta^T / |delta|^2`
//! (one residual evaluation) instead of recomputing it (one evaluation per parameter by
//! finite differences), as in MINPACK's `hybrd`. The true Jacobian is recomputed whenever
//! a step with an updated one is rejected, and before any convergence test is believed:
//! the solver only stops on a step computed from a freshly differentiated Jacobian, so
//! the secant updates change the cost of the path, not where it may end.

use super::uncertainty::{gauss_newton_step_se, residual_variance};
use argmin::core::{
    Error, IterState, Jacobian, Operator, Problem, Solver, State, TerminationReason,
    TerminationStatus, KV,
};
use nalgebra::{DMatrix, DVector};
use std::time::Instant;

type LmState = IterState<DVector<f64>, DVector<f64>, DMatrix<f64>, (), DVector<f64>, f64>;

/// The state at a point: parameters, residuals, Jacobian, gradient and cost together.
fn with_point(
    state: LmState,
    u: DVector<f64>,
    r: DVector<f64>,
    jac: DMatrix<f64>,
    grad: DVector<f64>,
    cost: f64,
) -> LmState {
    state
        .param(u)
        .residuals(r)
        .jacobian(jac)
        .gradient(grad)
        .cost(cost)
}

/// One point of the convergence trace of a run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TracePoint {
    /// Argmin iteration (trial steps, accepted or not).
    pub iter: u64,
    /// Seconds since the trace clock started (the start of the whole fit).
    pub time_s: f64,
    /// `0.5 sum r^2` after this iteration.
    pub cost: f64,
}

/// Levenberg-Marquardt solver state and settings.
#[derive(Clone, Debug)]
pub struct LevenbergMarquardt {
    /// Stop when `||J^T r||_inf <= gtol`.
    pub gtol: f64,
    /// Stop on an accepted step with `||delta|| <= xtol (||u|| + xtol)`.
    pub xtol: f64,
    /// Stop on an accepted step that reduces the cost by at most this fraction.
    pub ftol: f64,
    /// Stop when the Gauss-Newton step moves no determined coordinate by more than this
    /// many of its standard errors (replaces the `ftol` test; see the module doc).
    pub step_se: Option<f64>,
    /// Coordinates whose standard error exceeds this are not determined by the data and
    /// left out of the `step_se` test (they may crawl towards a bound forever).
    pub max_se: f64,
    /// Initial damping relative to `max diag(J^T J)` (Nielsen's `tau`).
    pub tau: f64,
    mu: f64,
    nu: f64,
    scale: Option<DVector<f64>>,
    converged: Option<&'static str>,
    clock: Instant,
    /// Accepted-step trace (iteration, time, cost), starting with the initial point.
    pub trace: Vec<TracePoint>,
    /// Number of rejected trial steps.
    pub rejected: u64,
    /// Update the Jacobian by Broyden's formula after accepted steps (see the module doc).
    pub broyden: bool,
    /// Is the Jacobian in the state a true (finite-difference) one?
    fresh: bool,
    /// Did the last accepted step reduce the cost by at most `ftol` (relative)?
    stalled: bool,
    /// Accepted steps so far.
    accepted: u64,
    /// Progress between failed standard-error tests.
    stall: StallWatch,
    /// The last standard-error test's Gauss-Newton step, in standard errors.
    last_step_se: Option<f64>,
}

/// Watches the progress of a run whose standard-error test keeps failing.
#[derive(Clone, Debug, Default)]
struct StallWatch {
    /// `(accepted steps, cost)` at the start of the current window.
    from: Option<(u64, f64)>,
}

impl StallWatch {
    /// Called at each failed test with the run's accepted-step count, cost and residual
    /// variance: has a window of [`STALL_STEPS`] accepted steps lowered
    /// `chi^2 = |r|^2 / s^2` by less than [`STALL_CHI2`] in all? Each full window that
    /// gained more starts the next one.
    fn stalled(&mut self, accepted: u64, cost: f64, s2: f64) -> bool {
        match self.from {
            Some((k, c0)) if accepted >= k + STALL_STEPS => {
                if 2.0 * (c0 - cost) < STALL_CHI2 * s2 {
                    return true;
                }
                self.from = Some((accepted, cost));
            }
            None => self.from = Some((accepted, cost)),
            Some(_) => {}
        }
        false
    }
}

/// Damping beyond which no step is tried.
const MAX_DAMPING: f64 = 1e16;
/// Termination reason when the damping grew past [`MAX_DAMPING`] and the standard-error
/// test (if set) did not pass.
pub const DAMPING_EXHAUSTED: &str = "damping exhausted (no descent direction left)";
/// Termination reason of the standard-error test.
pub const CONVERGED_SE: &str = "Gauss-Newton step below tolerance (standard errors)";
/// Termination reason of a run the standard-error test could not end: [`STALL_STEPS`]
/// accepted steps lowered chi^2 by less than [`STALL_CHI2`] (see [`LevenbergMarquardt::last_step_se`]
/// for how far the optimum of the local model still was).
pub const STALLED: &str =
    "stalled: 10 accepted steps lowered chi^2 by < 0.01 before the standard-error test passed";
/// Accepted steps over which a stall is judged.
pub const STALL_STEPS: u64 = 10;
/// Total chi^2 gain below which those steps count as stalled (a hundredth of what moves a
/// parameter by one standard error).
pub const STALL_CHI2: f64 = 0.01;

impl LevenbergMarquardt {
    /// A solver whose trace times count from `clock`.
    pub fn new(clock: Instant) -> Self {
        LevenbergMarquardt {
            // Ceres' defaults (function_tolerance 1e-6, parameter_tolerance 1e-8): a
            // relative cost change below 1e-6 moves the NRMSE by < 1e-6 of itself.
            gtol: 1e-10,
            xtol: 1e-8,
            ftol: 1e-6,
            step_se: None,
            max_se: f64::INFINITY,
            tau: 1e-3,
            mu: 0.0,
            nu: 2.0,
            scale: None,
            converged: None,
            clock,
            trace: Vec::new(),
            rejected: 0,
            broyden: false,
            fresh: true,
            stalled: false,
            accepted: 0,
            stall: StallWatch::default(),
            last_step_se: None,
        }
    }

    /// The Gauss-Newton step of the last standard-error test, in standard errors of the
    /// determined coordinates (`None` if the test never ran).
    pub fn last_step_se(&self) -> Option<f64> {
        self.last_step_se
    }

    /// Why the solver stopped on its own, if it did.
    pub fn converged_reason(&self) -> Option<&'static str> {
        self.converged
    }

    /// Replace a secant Jacobian by a finite-difference one at the current point `u`.
    fn refresh<O>(
        &mut self,
        problem: &mut Problem<O>,
        state: LmState,
        u: DVector<f64>,
        r: DVector<f64>,
        cost: f64,
    ) -> Result<(LmState, Option<KV>), Error>
    where
        O: Jacobian<Param = DVector<f64>, Jacobian = DMatrix<f64>>,
    {
        let jac = problem.jacobian(&u)?;
        self.fresh = true;
        let grad = jac.transpose() * &r;
        Ok((with_point(state, u, r, jac, grad, cost), None))
    }

    /// Stop once the damping has grown past any use (no step on a true Jacobian lowers
    /// the cost): converged if the standard-error test (when set) passes there, else
    /// [`DAMPING_EXHAUSTED`]. Called only on a true Jacobian: both callers first replace
    /// a secant one ([`Self::refresh`]).
    fn check_exhausted(&mut self, jtj: &DMatrix<f64>, grad: &DVector<f64>, r: &DVector<f64>) {
        debug_assert!(self.fresh, "damping judged on a secant Jacobian");
        if self.mu <= MAX_DAMPING {
            return;
        }
        self.converged = Some(DAMPING_EXHAUSTED);
        if let Some(tol) = self.step_se {
            let step_se = gauss_newton_step_se(jtj, grad, r, self.max_se);
            self.last_step_se = Some(step_se);
            if step_se <= tol {
                self.converged = Some(CONVERGED_SE);
            }
        }
    }

    fn update_scale(&mut self, jtj: &DMatrix<f64>) -> DVector<f64> {
        let d = jtj.diagonal().map(|x| x.max(1e-12));
        let s = match self.scale.take() {
            Some(old) => old.zip_map(&d, f64::max),
            None => d,
        };
        self.scale = Some(s.clone());
        s
    }
}

impl<O> Solver<O, LmState> for LevenbergMarquardt
where
    O: Operator<Param = DVector<f64>, Output = DVector<f64>>
        + Jacobian<Param = DVector<f64>, Jacobian = DMatrix<f64>>,
{
    fn name(&self) -> &str {
        "Levenberg-Marquardt (Nielsen damping, More scaling)"
    }

    fn init(
        &mut self,
        problem: &mut Problem<O>,
        mut state: LmState,
    ) -> Result<(LmState, Option<KV>), Error> {
        let u = state
            .take_param()
            .ok_or_else(|| argmin::core::ArgminError::NotInitialized {
                text: "Levenberg-Marquardt needs a start point".into(),
            })?;
        let r = problem.apply(&u)?;
        let cost = 0.5 * r.norm_squared();
        let jac = problem.jacobian(&u)?;
        self.fresh = true;
        let jtj = jac.transpose() * &jac;
        let d = self.update_scale(&jtj);
        self.mu = self.tau * jtj.diagonal().max().max(1e-300) / d.max().max(1e-300);
        self.nu = 2.0;
        let grad = jac.transpose() * &r;
        self.trace.push(TracePoint {
            iter: 0,
            time_s: self.clock.elapsed().as_secs_f64(),
            cost,
        });
        Ok((with_point(state, u, r, jac, grad, cost), None))
    }

    fn next_iter(
        &mut self,
        problem: &mut Problem<O>,
        mut state: LmState,
    ) -> Result<(LmState, Option<KV>), Error> {
        let u = state.take_param().expect("LM: param set in init");
        let r = state.take_residuals().expect("LM: residuals set in init");
        let jac = state.take_jacobian().expect("LM: jacobian set in init");
        let grad = state.take_gradient().expect("LM: gradient set in init");
        let cost = state.get_cost();

        if grad.amax() <= self.gtol {
            if self.fresh {
                self.converged = Some("gradient below tolerance");
                return Ok((with_point(state, u, r, jac, grad, cost), None));
            }
            return self.refresh(problem, state, u, r, cost);
        }
        let jtj = jac.transpose() * &jac;
        // Tested once progress has slowed (far from the optimum the residual variance, and
        // with it which coordinates count as determined, is not yet what it will be), on a
        // true Jacobian.
        if let (Some(tol), true, true) = (self.step_se, self.fresh, self.stalled) {
            let step_se = gauss_newton_step_se(&jtj, &grad, &r, self.max_se);
            self.last_step_se = Some(step_se);
            if step_se <= tol {
                self.converged = Some(CONVERGED_SE);
                return Ok((with_point(state, u, r, jac, grad, cost), None));
            }
            let s2 = residual_variance(&r, grad.len());
            if self.stall.stalled(self.accepted, cost, s2) {
                self.converged = Some(STALLED);
                return Ok((with_point(state, u, r, jac, grad, cost), None));
            }
        }
        let d = self.update_scale(&jtj);
        let mut a = jtj.clone();
        for i in 0..a.nrows() {
            a[(i, i)] += self.mu * d[i];
        }
        let step = a.cholesky().map(|c| c.solve(&(-&grad)));
        // The trial step, its point and gain ratio; `None` when there is no finite step
        // (a failed factorisation), which is rejected like a step that does not descend.
        let trial = match step.filter(|s| s.iter().all(|x| x.is_finite())) {
            Some(delta) => {
                let u_new = &u + &delta;
                let r_new = problem.apply(&u_new)?;
                let cost_new = 0.5 * r_new.norm_squared();
                // Predicted reduction of the quadratic model: 0.5 delta^T (mu D delta - g).
                let md = delta.zip_map(&d, |x, s| self.mu * s * x);
                let pred = 0.5 * delta.dot(&(md - &grad));
                let rho = if pred > 0.0 {
                    (cost - cost_new) / pred
                } else {
                    -1.0
                };
                Some((delta, u_new, r_new, cost_new, rho))
            }
            None => None,
        };
        if let Some((delta, u_new, r_new, cost_new, rho)) =
            trial.filter(|t| t.4 > 0.0 && t.3.is_finite())
        {
            self.mu *= (1.0f64 / 3.0).max(1.0 - (2.0 * rho - 1.0).powi(3));
            self.nu = 2.0;
            self.accepted += 1;
            self.stalled = cost - cost_new <= self.ftol * cost;
            let converged = if delta.norm() <= self.xtol * (u.norm() + self.xtol) {
                Some("step below tolerance")
            } else if self.step_se.is_none() && self.stalled {
                Some("relative cost change below tolerance")
            } else {
                None
            };
            // Stop only on a step from a true Jacobian; otherwise differentiate afresh at
            // the new point and go on.
            if self.fresh {
                self.converged = converged;
            }
            // A stalled step under the standard-error test gets a true Jacobian, so the test
            // can run at the next iteration (a secant one never lets it).
            let secant = converged.is_none() && !(self.step_se.is_some() && self.stalled);
            let jac_new = if self.broyden && secant {
                let dd = delta.norm_squared();
                let mut j = jac;
                if dd > 0.0 {
                    let y = &r_new - &r - &j * &delta;
                    j.ger(1.0 / dd, &y, &delta, 1.0);
                }
                self.fresh = false;
                j
            } else {
                self.fresh = true;
                problem.jacobian(&u_new)?
            };
            let grad_new = jac_new.transpose() * &r_new;
            self.trace.push(TracePoint {
                iter: state.get_iter() + 1,
                time_s: self.clock.elapsed().as_secs_f64(),
                cost: cost_new,
            });
            let kv = argmin::kv!("mu" => self.mu; "rho" => rho;);
            Ok((
                with_point(state, u_new, r_new, jac_new, grad_new, cost_new),
                Some(kv),
            ))
        } else {
            self.mu *= self.nu;
            self.nu *= 2.0;
            self.rejected += 1;
            if !self.fresh {
                // The secant Jacobian may be what failed: differentiate at `u` again.
                return self.refresh(problem, state, u, r, cost);
            }
            self.check_exhausted(&jtj, &grad, &r);
            Ok((with_point(state, u, r, jac, grad, cost), None))
        }
    }

    fn terminate(&mut self, state: &LmState) -> TerminationStatus {
        if let Some(reason) = self.converged {
            return TerminationStatus::Terminated(TerminationReason::SolverExit(reason.into()));
        }
        if state.get_cost() == 0.0 {
            return TerminationStatus::Terminated(TerminationReason::TargetCostReached);
        }
        TerminationStatus::NotTerminated
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use argmin::core::Executor;

    /// Rosenbrock as residuals r = (10 (y - x^2), 1 - x): a classic LM test.
    struct Rosen;
    impl Operator for Rosen {
        type Param = DVector<f64>;
        type Output = DVector<f64>;
        fn apply(&self, p: &DVector<f64>) -> Result<DVector<f64>, Error> {
            Ok(DVector::from_vec(vec![
                10.0 * (p[1] - p[0] * p[0]),
                1.0 - p[0],
            ]))
        }
    }
    impl Jacobian for Rosen {
        type Param = DVector<f64>;
        type Jacobian = DMatrix<f64>;
        fn jacobian(&self, p: &DVector<f64>) -> Result<DMatrix<f64>, Error> {
            Ok(DMatrix::from_row_slice(
                2,
                2,
                &[-20.0 * p[0], 10.0, -1.0, 0.0],
            ))
        }
    }

    /// Solve Rosenbrock from the classic start; the minimum (1, 1) is exact and LM
    /// converges quadratically to ~1e-10 or better, with or without the secant updates (a
    /// run may only stop on a fresh Jacobian, so the answer is as tight either way).
    fn check_rosenbrock(broyden: bool) {
        let mut lm = LevenbergMarquardt::new(Instant::now());
        lm.broyden = broyden;
        let res = Executor::new(Rosen, lm)
            .configure(|s| s.param(DVector::from_vec(vec![-1.2, 1.0])).max_iters(500))
            .run()
            .unwrap();
        let p = res.state.get_best_param().unwrap();
        assert!(
            (p[0] - 1.0).abs() < 1e-6 && (p[1] - 1.0).abs() < 1e-6,
            "broyden {broyden}: {p}"
        );
        assert!(res.state.get_iter() < 500, "did not converge");
    }

    #[test]
    fn solves_rosenbrock() {
        check_rosenbrock(false);
    }

    #[test]
    fn solves_rosenbrock_with_broyden_updates() {
        check_rosenbrock(true);
    }

    /// `y = a exp(-b t) + c` with fixed pseudo-noise: residuals and their exact Jacobian.
    struct Decay {
        t: Vec<f64>,
        y: Vec<f64>,
    }
    impl Decay {
        fn new() -> Decay {
            let t: Vec<f64> = (0..60).map(|i| i as f64 * 0.1).collect();
            // Deterministic "noise" of RMS ~0.01.
            let y = t
                .iter()
                .enumerate()
                .map(|(i, &t)| {
                    2.0 * (-0.7 * t).exp() + 0.3 + 0.014 * ((i * 37 % 11) as f64 / 5.0 - 1.0)
                })
                .collect();
            Decay { t, y }
        }
    }
    impl Operator for Decay {
        type Param = DVector<f64>;
        type Output = DVector<f64>;
        fn apply(&self, p: &DVector<f64>) -> Result<DVector<f64>, Error> {
            Ok(DVector::from_iterator(
                self.t.len(),
                self.t
                    .iter()
                    .zip(&self.y)
                    .map(|(&t, &y)| p[0] * (-p[1] * t).exp() + p[2] - y),
            ))
        }
    }
    impl Jacobian for Decay {
        type Param = DVector<f64>;
        type Jacobian = DMatrix<f64>;
        fn jacobian(&self, p: &DVector<f64>) -> Result<DMatrix<f64>, Error> {
            Ok(DMatrix::from_fn(self.t.len(), 3, |i, j| {
                let e = (-p[1] * self.t[i]).exp();
                [e, -p[0] * self.t[i] * e, 1.0][j]
            }))
        }
    }

    /// With Broyden updates on, the standard-error stop still ends the run (it needs a true
    /// Jacobian, which a secant update after every accepted step never gave it), and where
    /// it ends the Gauss-Newton step is within the tolerance of every standard error.
    #[test]
    fn standard_error_stop_ends_a_broyden_run() {
        let mut lm = LevenbergMarquardt::new(Instant::now());
        lm.broyden = true;
        lm.step_se = Some(0.1);
        let res = Executor::new(Decay::new(), lm)
            .configure(|s| {
                s.param(DVector::from_vec(vec![1.0, 0.2, 0.0]))
                    .max_iters(200)
            })
            .run()
            .unwrap();
        assert_eq!(res.solver.converged_reason(), Some(CONVERGED_SE));
        // Accepted steps that barely moved the cost (the ftol test) before the stop: the
        // first gets a true Jacobian and the test; a run that kept secant updates took
        // one after another (23 in a row in a dog fit).
        let stalled = res
            .solver
            .trace
            .windows(2)
            .filter(|w| w[0].cost - w[1].cost <= 1e-6 * w[0].cost)
            .count();
        assert!(stalled <= 2, "{stalled} stalled steps before the stop");
        let p = res.state.get_best_param().unwrap().clone();
        let d = Decay::new();
        let (r, j) = (d.apply(&p).unwrap(), d.jacobian(&p).unwrap());
        let g = j.transpose() * &r;
        let step = gauss_newton_step_se(&(j.transpose() * &j), &g, &r, f64::INFINITY);
        assert!(step <= 0.1, "Gauss-Newton step {step} standard errors");
    }

    /// A problem that records where its Jacobian was evaluated.
    struct Recorded<P> {
        inner: P,
        jac_at: std::cell::RefCell<Vec<DVector<f64>>>,
    }
    impl<P: Operator<Param = DVector<f64>, Output = DVector<f64>>> Operator for Recorded<P> {
        type Param = DVector<f64>;
        type Output = DVector<f64>;
        fn apply(&self, p: &DVector<f64>) -> Result<DVector<f64>, Error> {
            self.inner.apply(p)
        }
    }
    impl<P: Jacobian<Param = DVector<f64>, Jacobian = DMatrix<f64>>> Jacobian for Recorded<P> {
        type Param = DVector<f64>;
        type Jacobian = DMatrix<f64>;
        fn jacobian(&self, p: &DVector<f64>) -> Result<DMatrix<f64>, Error> {
            self.jac_at.borrow_mut().push(p.clone());
            self.inner.jacobian(p)
        }
    }

    /// With Broyden updates a run still ends only on a step computed from a true
    /// Jacobian (module doc): the step that met a tolerance started from a point where
    /// the Jacobian was differentiated, and a gradient that met `gtol` is the true one.
    /// A stop on a secant step would trust a direction built from rank-one guesses.
    /// Points are matched by their cost, recomputed by the same code the solver ran on
    /// the same parameters, so bit for bit.
    #[test]
    fn broyden_runs_stop_only_on_steps_from_a_true_jacobian() {
        fn check<P>(inner: P, start: &[f64], to_gtol: bool)
        where
            P: Operator<Param = DVector<f64>, Output = DVector<f64>>
                + Jacobian<Param = DVector<f64>, Jacobian = DMatrix<f64>>,
        {
            let mut lm = LevenbergMarquardt::new(Instant::now());
            lm.broyden = true;
            if to_gtol {
                // Only the gradient test can end the run, at a gradient round-off lets
                // this decay reach (at the default 1e-10 the damping ran out first).
                (lm.ftol, lm.xtol, lm.gtol) = (0.0, 0.0, 1e-6);
            }
            let problem = Recorded {
                inner,
                jac_at: Default::default(),
            };
            let res = Executor::new(problem, lm)
                .configure(|s| s.param(DVector::from_vec(start.to_vec())).max_iters(500))
                .run()
                .unwrap();
            let reason = res.solver.converged_reason();
            let trace = &res.solver.trace;
            let problem = res.problem.problem.as_ref().unwrap();
            if to_gtol {
                // The gradient that passed is that of the true Jacobian at the end point.
                assert_eq!(reason, Some("gradient below tolerance"));
                let u = res.state.get_param().unwrap();
                let jac = res.state.get_jacobian().unwrap();
                assert_eq!(
                    *jac,
                    problem.jacobian(u).unwrap(),
                    "stopped on a secant gradient"
                );
                return;
            }
            assert!(
                matches!(
                    reason,
                    Some("relative cost change below tolerance" | "step below tolerance")
                ),
                "{reason:?}"
            );
            let from = trace[trace.len() - 2].cost;
            let fresh_costs: Vec<f64> = problem
                .jac_at
                .borrow()
                .iter()
                .map(|u| 0.5 * problem.apply(u).unwrap().norm_squared())
                .collect();
            assert!(
                fresh_costs.contains(&from),
                "the last step started at cost {from}, Jacobians at {fresh_costs:?}"
            );
            // Secant updates did happen (else the test would check nothing).
            assert!(fresh_costs.len() < trace.len(), "no secant step taken");
        }
        check(Decay::new(), &[1.0, 0.2, 0.0], false);
        check(Rosen, &[-1.2, 1.0], false);
        check(Decay::new(), &[1.0, 0.2, 0.0], true);
    }

    /// `Decay` in rescaled coordinates `v = s * u` (per-coordinate factors `s`).
    struct Rescaled {
        s: DVector<f64>,
    }
    impl Operator for Rescaled {
        type Param = DVector<f64>;
        type Output = DVector<f64>;
        fn apply(&self, v: &DVector<f64>) -> Result<DVector<f64>, Error> {
            Decay::new().apply(&v.component_div(&self.s))
        }
    }
    impl Jacobian for Rescaled {
        type Param = DVector<f64>;
        type Jacobian = DMatrix<f64>;
        fn jacobian(&self, v: &DVector<f64>) -> Result<DMatrix<f64>, Error> {
            let j = Decay::new().jacobian(&v.component_div(&self.s))?;
            Ok(DMatrix::from_fn(j.nrows(), j.ncols(), |i, k| {
                j[(i, k)] / self.s[k]
            }))
        }
    }

    /// Moré's scaling `D^2 = diag(J^T J)` makes the damped step covariant with a rescaling
    /// of the parameters, so a run in coordinates scaled by 1e4 and 1e-3 takes the same
    /// path: the same accepted-step costs and the same optimum. The scale-dependent stops
    /// (`gtol`, `xtol`) are off so that both runs end by the same (relative-cost) rule.
    /// Tolerance 1e-9 relative: identical algebra up to the round-off of the scaling, which
    /// the 3x3 solves amplify by their condition number; damping without `D` (a fixed
    /// multiple of the identity) changes the path at the percent level.
    #[test]
    fn damping_is_invariant_to_parameter_scaling() {
        let run = |s: [f64; 3]| {
            let s = DVector::from_vec(s.to_vec());
            let mut lm = LevenbergMarquardt::new(Instant::now());
            (lm.gtol, lm.xtol) = (0.0, 0.0);
            let start = DVector::from_vec(vec![1.0, 0.2, 0.0]).component_mul(&s);
            let res = Executor::new(Rescaled { s: s.clone() }, lm)
                .configure(|st| st.param(start).max_iters(100))
                .run()
                .unwrap();
            let u = res.state.get_best_param().unwrap().component_div(&s);
            let costs: Vec<f64> = res.solver.trace.iter().map(|t| t.cost).collect();
            (u, costs, res.solver.rejected)
        };
        let (u1, c1, rej1) = run([1.0, 1.0, 1.0]);
        let (u2, c2, rej2) = run([1e4, 1e-3, 1.0]);
        assert!(c1.len() > 3, "{} accepted steps", c1.len() - 1);
        assert_eq!(
            (c1.len(), rej1),
            (c2.len(), rej2),
            "paths differ: {c1:?} vs {c2:?}"
        );
        for (a, b) in c1.iter().zip(&c2) {
            assert!((a - b).abs() <= 1e-9 * a, "cost {a} vs {b}");
        }
        for k in 0..3 {
            assert!(
                (u1[k] - u2[k]).abs() <= 1e-9 * u1[k].abs().max(1.0),
                "{u1} vs {u2}"
            );
        }
    }

    /// The stall rule: ten accepted steps worth < 0.01 chi^2 in all end a run; a window
    /// that gained more starts the next one; fewer than ten steps never do.
    #[test]
    fn stall_watch_needs_ten_steps_without_visible_gain() {
        let s2 = 2.0; // chi^2 = 2 cost / s2 = cost here
        let mut w = StallWatch::default();
        assert!(!w.stalled(3, 100.0, s2));
        // Nine more steps gaining 0.001 each: window not full yet.
        assert!(!w.stalled(12, 99.991, s2));
        // The tenth: 0.010 gained... exactly at the limit is progress, below is not.
        assert!(!w.stalled(13, 99.99, s2));
        let mut w = StallWatch::default();
        assert!(!w.stalled(0, 100.0, s2));
        assert!(w.stalled(10, 99.995, s2));
        // A window that gained 0.5 chi^2 restarts from its end.
        let mut w = StallWatch::default();
        assert!(!w.stalled(0, 100.0, s2));
        assert!(!w.stalled(10, 99.5, s2));
        assert!(!w.stalled(15, 99.499, s2));
        assert!(w.stalled(20, 99.498, s2));
    }
}

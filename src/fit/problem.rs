//! The least-squares problem the fitter solves: normalised log residuals with the exposure
//! in closed form (seed Sec. 5.1 "Validation"; MODEL.md "Error metric").
//!
//! For valid samples `y_i` with model values `m_i(x)` and weights `w_i` (mean 1):
//!
//! `r_i = sqrt(w_i) (ln m_i + ln k - ln y_i) / (max ln y - min ln y)`,
//!
//! with `ln k = sum w_i (ln y_i - ln m_i) / sum w_i`, the exact minimiser of `sum r_i^2`
//! over `k` (set the derivative in `ln k` to zero). The exposure is therefore recomputed at
//! every evaluation and never is a solver parameter. With unit weights
//! `sqrt(sum r_i^2 / n)` is MODEL.md's NRMSE.
//!
//! Model values are floored at `f64::MIN_POSITIVE` before the logarithm, so a lobe that
//! underflows to zero gives a large but finite residual instead of `-inf`.

use super::reparam;
use crate::cancel::Cancel;
use crate::model::far::FarOptions;
use crate::models::{FiberModel, ModelParams, ModelTerms, Param, Points};
use argmin::core::{Error as ArgminError, Jacobian, Operator};
use nalgebra::{DMatrix, DVector};
use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

/// One channel's valid samples, ready for the residuals.
#[derive(Clone, Debug)]
pub struct FitData {
    /// The samples' goniometer angles, radians.
    pub points: Points,
    /// `ln y_i`.
    pub ln_y: Vec<f64>,
    /// Weights, normalised to mean 1 (all 1 when unweighted).
    pub w: Vec<f64>,
    /// `max ln y - min ln y` (1 if all samples are equal, to stay finite).
    pub range: f64,
    /// Valid samples left out below the relative floor ([`super::channel_data`]).
    pub n_below_floor: usize,
}

impl FitData {
    /// Build from points, measured values (all `> 0` and finite) and optional relative
    /// standard errors `sigma_i / y_i` (weights `1 / rel^2`, normalised to mean 1).
    pub fn new(points: Points, values: &[f64], rel_sigma: Option<&[f64]>) -> FitData {
        let ln_y: Vec<f64> = values.iter().map(|v| v.ln()).collect();
        let (lo, hi) = ln_y
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| {
                (a.min(v), b.max(v))
            });
        let range = if hi > lo { hi - lo } else { 1.0 };
        let mut w: Vec<f64> = match rel_sigma {
            Some(rs) => {
                // Relative to the geometric mean sigma, so that sigmas scaled as a whole
                // (1e-160 or 1e160 times the values) neither overflow nor underflow.
                let ok: Vec<f64> = rs
                    .iter()
                    .filter(|s| s.is_finite() && **s > 0.0)
                    .map(|s| s.ln())
                    .collect();
                let ln_gm = ok.iter().sum::<f64>() / ok.len().max(1) as f64;
                rs.iter()
                    .map(|&s| {
                        if s.is_finite() && s > 0.0 {
                            (-2.0 * (s.ln() - ln_gm)).exp()
                        } else {
                            1.0
                        }
                    })
                    .collect()
            }
            None => vec![1.0; ln_y.len()],
        };
        let mean = w.iter().sum::<f64>() / w.len().max(1) as f64;
        if mean > 0.0 {
            w.iter_mut().for_each(|x| *x /= mean);
        }
        FitData {
            points,
            ln_y,
            w,
            range,
            n_below_floor: 0,
        }
    }

    /// Number of valid samples.
    pub fn len(&self) -> usize {
        self.ln_y.len()
    }

    /// Whether there are no valid samples.
    pub fn is_empty(&self) -> bool {
        self.ln_y.is_empty()
    }

    /// The samples at `idx` (same normalising range as the whole, so costs are comparable).
    pub fn subset(&self, idx: &[usize]) -> FitData {
        FitData {
            points: self.points.subset(idx),
            ln_y: idx.iter().map(|&i| self.ln_y[i]).collect(),
            w: idx.iter().map(|&i| self.w[i]).collect(),
            range: self.range,
            n_below_floor: self.n_below_floor,
        }
    }
}

/// `ln k` minimising `sum w_i (ln m_i + ln k - ln y_i)^2`: the weighted mean of
/// `ln y_i - ln m_i`.
pub fn optimal_log_exposure(ln_m: &[f64], ln_y: &[f64], w: &[f64]) -> f64 {
    let (mut s, mut sw) = (0.0, 0.0);
    for ((m, y), w) in ln_m.iter().zip(ln_y).zip(w) {
        s += w * (y - m);
        sw += w;
    }
    if sw > 0.0 {
        s / sw
    } else {
        0.0
    }
}

/// `ln` of a model value, floored so that zero never enters a logarithm.
pub fn ln_model(m: f64) -> f64 {
    if m.is_finite() && m > f64::MIN_POSITIVE {
        m.ln()
    } else if m.is_finite() {
        f64::MIN_POSITIVE.ln()
    } else {
        // NaN/inf from the model: a huge residual rather than a poisoned solve.
        1e3
    }
}

/// NRMSE per MODEL.md (unit weights, optimal exposure) of model values `m` against `ln_y`.
/// Returns `(nrmse, exposure)`.
pub fn nrmse(m: &[f64], ln_y: &[f64], range: f64) -> (f64, f64) {
    let ln_m: Vec<f64> = m.iter().map(|&v| ln_model(v)).collect();
    let ones = vec![1.0; ln_m.len()];
    let lk = optimal_log_exposure(&ln_m, ln_y, &ones);
    let ss: f64 = ln_m
        .iter()
        .zip(ln_y)
        .map(|(a, b)| ((a + lk - b) / range).powi(2))
        .sum();
    ((ss / ln_m.len().max(1) as f64).sqrt(), lk.exp())
}

/// The model being fitted, which of its parameters are free (solved for) and the file-unit
/// values of the fixed ones.
#[derive(Clone, Debug)]
pub struct ParamLayout {
    /// The model being fitted.
    pub model: &'static dyn FiberModel,
    /// File-unit value of each fixed parameter, `None` for free ones (model order).
    pub fixed: Vec<Option<f64>>,
}

impl PartialEq for ParamLayout {
    fn eq(&self, o: &Self) -> bool {
        self.model.name() == o.model.name() && self.fixed == o.fixed
    }
}

impl ParamLayout {
    /// All parameters of `model` free.
    pub fn all_free(model: &'static dyn FiberModel) -> ParamLayout {
        ParamLayout {
            model,
            fixed: vec![None; model.specs().len()],
        }
    }

    /// The model's parameters in order.
    pub fn all(&self) -> impl Iterator<Item = Param> {
        Param::all(self.model)
    }

    /// The free parameters in the model's order.
    pub fn free(&self) -> Vec<Param> {
        self.all()
            .filter(|id| self.fixed[id.index()].is_none())
            .collect()
    }

    /// File-unit values at free coordinates `u` (one per free parameter).
    pub fn file_values(&self, u: &[f64]) -> Vec<f64> {
        let mut k = 0;
        self.all()
            .map(|id| match self.fixed[id.index()] {
                Some(v) => v,
                None => {
                    k += 1;
                    reparam::to_value(id, u[k - 1])
                }
            })
            .collect()
    }

    /// Model parameters (internal units) at free coordinates `u`. Always within the hard
    /// bounds: the maps cannot leave them and fixed values are validated at the boundary.
    pub fn internal(&self, u: &[f64]) -> Vec<f64> {
        self.all()
            .zip(self.file_values(u))
            .map(|(id, v)| id.spec().to_internal(v))
            .collect()
    }

    /// [`Self::internal`] as a parameter set of the model.
    pub fn params(&self, u: &[f64]) -> ModelParams {
        ModelParams {
            model: self.model,
            values: self.internal(u),
        }
    }

    /// Free coordinates of a full file-unit vector, as a start point
    /// ([`reparam::to_u_start`]: a value on or beyond a bounded range starts just inside
    /// it, where the solver can still move it).
    pub fn to_u(&self, file: &[f64]) -> Vec<f64> {
        self.free()
            .into_iter()
            .map(|id| reparam::to_u_start(id, file[id.index()]))
            .collect()
    }
}

/// The residual operator handed to the solver (argmin [`Operator`] + [`Jacobian`]).
pub struct LogResidualProblem<'a> {
    /// The samples the residuals are taken against.
    pub data: &'a FitData,
    /// Which parameters are solved for, and the fixed ones' values.
    pub layout: ParamLayout,
    /// Far-field options of every model evaluation.
    pub far: FarOptions,
    /// Model evaluations (one per residual vector), including finite-difference columns.
    pub evals: AtomicU64,
    /// Of those, finite-difference columns (most recompute only part of the model).
    pub fd_columns: AtomicU64,
    /// Analytic Jacobians computed ([`ModelTerms::jacobian`]; not counted in `evals`).
    pub jacobians: AtomicU64,
    /// Use the model's analytic Jacobian where it provides one (default); `false` forces
    /// finite differences (tests, comparisons).
    pub analytic: bool,
    /// Last `(u, r, terms)` computed, so the Jacobian reuses the residuals and model terms
    /// of its base point.
    last: Mutex<Option<Cached>>,
    /// Once set, the solver's evaluations fail (ending its run) instead of evaluating
    /// ([`FitOptions::cancel`](super::FitOptions::cancel)).
    pub cancel: Cancel,
}

/// Residuals and model terms at one point `u`.
type Cached = (DVector<f64>, DVector<f64>, Arc<dyn ModelTerms>);

/// Relative forward-difference step in `u`.
pub const FD_STEP: f64 = 1e-6;

impl<'a> LogResidualProblem<'a> {
    /// The problem of fitting `layout`'s free parameters to `data`, the model evaluated
    /// with `far`.
    pub fn new(data: &'a FitData, layout: ParamLayout, far: FarOptions) -> Self {
        LogResidualProblem {
            data,
            layout,
            far,
            evals: AtomicU64::new(0),
            fd_columns: AtomicU64::new(0),
            jacobians: AtomicU64::new(0),
            analytic: true,
            last: Mutex::new(None),
            cancel: Cancel::default(),
        }
    }

    /// A problem on the same data and parameters with its own counters and cache.
    pub fn fork(&self) -> LogResidualProblem<'a> {
        self.with_far(self.far)
    }

    /// This problem at another far-field setting, with its own counters and cache.
    pub fn with_far(&self, far: FarOptions) -> LogResidualProblem<'a> {
        let mut p = LogResidualProblem::new(self.data, self.layout.clone(), far)
            .with_cancel(self.cancel.clone());
        p.analytic = self.analytic;
        p
    }

    /// This problem, its solver runs ended by `cancel` once it is set.
    pub fn with_cancel(mut self, cancel: Cancel) -> Self {
        self.cancel = cancel;
        self
    }

    /// The solver's error once cancelled: its run ends at the next evaluation.
    fn stop_if_cancelled(&self) -> Result<(), ArgminError> {
        if self.cancel.is_cancelled() {
            return Err(ArgminError::msg("interrupted"));
        }
        Ok(())
    }

    /// Number of free parameters.
    pub fn n_free(&self) -> usize {
        self.layout.free().len()
    }

    /// Model terms at `u` (all lobes; parallel inside).
    fn terms(&self, u: &[f64]) -> Arc<dyn ModelTerms> {
        self.evals.fetch_add(1, Ordering::Relaxed);
        let p = self.layout.internal(u);
        Arc::from(self.layout.model.terms(&p, &self.data.points, &self.far))
    }

    /// Model values (no exposure) of `terms`.
    fn values(&self, terms: &dyn ModelTerms) -> Vec<f64> {
        let mut out = vec![0.0; self.data.len()];
        terms.values(&self.data.points, &mut out);
        out
    }

    /// Model values (no exposure) at `u`.
    pub fn model_values(&self, u: &[f64]) -> Vec<f64> {
        self.values(&*self.terms(u))
    }

    /// Residuals and `ln k` of model values `m`.
    fn residuals_of(&self, m: &[f64]) -> (DVector<f64>, f64) {
        let ln_m: Vec<f64> = m.iter().map(|&v| ln_model(v)).collect();
        let d = self.data;
        let lk = optimal_log_exposure(&ln_m, &d.ln_y, &d.w);
        let inv = 1.0 / d.range;
        let r = DVector::from_iterator(
            d.len(),
            (0..d.len()).map(|i| d.w[i].sqrt() * (ln_m[i] + lk - d.ln_y[i]) * inv),
        );
        (r, lk)
    }

    /// Residuals and `ln k` at `u`.
    pub fn residuals_and_log_exposure(&self, u: &[f64]) -> (DVector<f64>, f64) {
        self.residuals_of(&self.model_values(u))
    }

    /// Residuals at `u`.
    pub fn residuals(&self, u: &[f64]) -> DVector<f64> {
        self.residuals_and_log_exposure(u).0
    }

    /// `0.5 sum r^2` at `u`.
    pub fn cost(&self, u: &[f64]) -> f64 {
        0.5 * self.residuals(u).norm_squared()
    }

    /// Forward-difference Jacobian `d r / d u`, one column per free parameter computed in
    /// parallel; `r0` and `base` are the residuals and model terms at `u`. Step
    /// `FD_STEP * max(1, |u_j|)`. A column recomputes only the model terms its parameter
    /// can change ([`ModelTerms::with_change`]), so `alpha` and `beta_m` cost almost
    /// nothing; the columns equal full re-evaluations (tested).
    pub fn jacobian_forward(
        &self,
        u: &DVector<f64>,
        r0: &DVector<f64>,
        base: &dyn ModelTerms,
    ) -> DMatrix<f64> {
        let free = self.layout.free();
        let cols: Vec<DVector<f64>> = (0..u.len())
            .into_par_iter()
            .map(|j| {
                let h = FD_STEP * u[j].abs().max(1.0);
                let mut up = u.clone();
                up[j] += h;
                let h = up[j] - u[j];
                self.evals.fetch_add(1, Ordering::Relaxed);
                self.fd_columns.fetch_add(1, Ordering::Relaxed);
                let params = self.layout.internal(up.as_slice());
                let terms =
                    base.with_change(&params, free[j].index(), &self.data.points, &self.far);
                (self.residuals_of(&self.values(&*terms)).0 - r0) / h
            })
            .collect();
        DMatrix::from_columns(&cols)
    }

    /// The Jacobian `d r / d u` from the model's analytic derivatives at `base` (the
    /// terms at `u`), `None` when the model provides none. The same matrix as
    /// [`Self::jacobian_forward`] differentiates, exactly rather than to the step's
    /// truncation: with `m_i` the model values and `p_k` the parameters (internal units),
    /// `d ln m_i / d u_j = (d m_i / d p_k) (d p_k / d u_j) / m_i` (zero where
    /// [`ln_model`] floors `m_i`), `d p_k / d u_j` the bounded map's derivative
    /// ([`reparam::derivative`], zero beyond its clamp) in internal units, and the
    /// closed-form exposure's `d ln k / d u_j = -sum w_i (d ln m_i / d u_j) / sum w_i`, so
    /// `d r_i / d u_j = sqrt(w_i) (d ln m_i / d u_j + d ln k / d u_j) / range`.
    pub fn jacobian_analytic(
        &self,
        u: &DVector<f64>,
        base: &dyn ModelTerms,
    ) -> Option<DMatrix<f64>> {
        let vj = base.jacobian(&self.data.points)?;
        self.jacobians.fetch_add(1, Ordering::Relaxed);
        let d = self.data;
        let free = self.layout.free();
        let k = vj.n_params;
        let sw: f64 = d.w.iter().sum();
        let inv = 1.0 / d.range;
        let cols: Vec<DVector<f64>> = free
            .iter()
            .enumerate()
            .map(|(j, id)| {
                let scale = id.spec().to_internal(reparam::derivative(*id, u[j]));
                let (pk, mut s) = (id.index(), 0.0);
                let mut col = DVector::from_iterator(
                    d.len(),
                    vj.values.iter().enumerate().map(|(i, &m)| {
                        let dl = if m.is_finite() && m > f64::MIN_POSITIVE {
                            vj.d[i * k + pk] * scale / m
                        } else {
                            0.0
                        };
                        s += d.w[i] * dl;
                        dl
                    }),
                );
                let mean = if sw > 0.0 { s / sw } else { 0.0 };
                for (i, c) in col.iter_mut().enumerate() {
                    *c = d.w[i].sqrt() * (*c - mean) * inv;
                }
                col
            })
            .collect();
        Some(DMatrix::from_columns(&cols))
    }

    /// Residuals, `ln k` and model terms at `u`, remembered for the Jacobian at the same
    /// point.
    fn evaluate(&self, u: &DVector<f64>) -> (DVector<f64>, f64, Arc<dyn ModelTerms>) {
        let terms = self.terms(u.as_slice());
        let (r, lk) = self.residuals_of(&self.values(&*terms));
        *self.last.lock().expect("residual cache poisoned") =
            Some((u.clone(), r.clone(), terms.clone()));
        (r, lk, terms)
    }

    /// [`Self::residuals_and_log_exposure`], remembered so that a following
    /// [`Self::jacobian_at`] at the same `u` does not evaluate the model there again.
    pub fn evaluate_at(&self, u: &DVector<f64>) -> (DVector<f64>, f64) {
        let (r, lk, _) = self.evaluate(u);
        (r, lk)
    }

    /// [`Self::evaluate_at`], also returning the model terms (e.g. for
    /// [`ModelTerms::capped_slices`]).
    pub fn evaluate_terms_at(&self, u: &DVector<f64>) -> (DVector<f64>, f64, Arc<dyn ModelTerms>) {
        self.evaluate(u)
    }

    /// Central-difference Jacobian (twice the cost; used to check the forward one).
    pub fn jacobian_central(&self, u: &DVector<f64>, step: f64) -> DMatrix<f64> {
        let cols: Vec<DVector<f64>> = (0..u.len())
            .into_par_iter()
            .map(|j| {
                let h = step * u[j].abs().max(1.0);
                let (mut a, mut b) = (u.clone(), u.clone());
                a[j] += h;
                b[j] -= h;
                (self.residuals(a.as_slice()) - self.residuals(b.as_slice())) / (2.0 * h)
            })
            .collect();
        DMatrix::from_columns(&cols)
    }
}

impl Operator for LogResidualProblem<'_> {
    type Param = DVector<f64>;
    type Output = DVector<f64>;

    fn apply(&self, u: &DVector<f64>) -> Result<DVector<f64>, ArgminError> {
        self.stop_if_cancelled()?;
        Ok(self.evaluate(u).0)
    }
}

impl Jacobian for LogResidualProblem<'_> {
    type Param = DVector<f64>;
    type Jacobian = DMatrix<f64>;

    fn jacobian(&self, u: &DVector<f64>) -> Result<DMatrix<f64>, ArgminError> {
        self.stop_if_cancelled()?;
        Ok(self.jacobian_at(u))
    }
}

impl LogResidualProblem<'_> {
    /// The Jacobian at `u`: analytic when the model provides it and [`Self::analytic`]
    /// is set ([`Self::jacobian_analytic`]), else by forward differences. Reuses the
    /// residuals and terms of the last evaluation when it was at `u` (the solver
    /// evaluates a point before its Jacobian).
    pub fn jacobian_at(&self, u: &DVector<f64>) -> DMatrix<f64> {
        let cached = self
            .last
            .lock()
            .expect("residual cache poisoned")
            .as_ref()
            .filter(|(cu, _, _)| cu == u)
            .map(|(_, r, t)| (r.clone(), t.clone()));
        let (r0, base) = match cached {
            Some(c) => c,
            None => {
                let (r, _, t) = self.evaluate(u);
                (r, t)
            }
        };
        if self.analytic {
            if let Some(j) = self.jacobian_analytic(u, &*base) {
                return j;
            }
        }
        self.jacobian_forward(u, &r0, &*base)
    }
}

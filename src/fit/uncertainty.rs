//! Linearised parameter uncertainty at the optimum: covariance `s^2 (J^T J)^+` in the
//! solver's unbounded coordinates `u`, mapped to file units with the reparameterisation
//! derivative (delta method: `SE(x) = |dx/du| SE(u)`), and the correlation matrix.
//!
//! A free parameter is flagged *unconstrained* when the data does not pin it down:
//! - it loads on a (numerically) null direction of `J^T J` (singular value below
//!   `1e-10` of the largest): its standard error is reported as `null` (infinite);
//! - or one standard error either side spans most of its range: more than half of it for
//!   the bounded maps, a factor above `e^4` for the exp ones ([`reparam::spans_most`]);
//! - or when the other values leave it without effect (the model's
//!   [`crate::models::FiberModel::inert`]; the fur model: `sigma_m_s`, `sigma_m_a` and `g`
//!   when `kappa < 1e-3`, the medulla (nearly) absent, so the scattered lobes that carry
//!   these parameters vanish).

use super::problem::{LogResidualProblem, ParamLayout};
use super::reparam;
use crate::models::Param;
use nalgebra::{DMatrix, DVector};

/// Residual RMS below which a fit reproduces its data to rounding (`sqrt(s^2)` of the
/// solver's residuals: log differences over the data's log range, as in the NRMSE):
/// noise-free data of the model itself, whose standard errors are ~0 and mean nothing.
pub const ROUNDING_RMS: f64 = 1e-9;

/// SE(u) above which a parameter counts as unconstrained.
pub const MAX_SE_U: f64 = 2.0;
/// Why a free parameter counts as not constrained by the data.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Why {
    /// On its bound ([`reparam::at_bound`]): the map's derivative all but vanishes there.
    Bound,
    /// On a singular direction of `J^T J`, left out of the pseudo-inverse.
    Singular,
    /// `u ± SE(u)` spans most of its range ([`reparam::spans_most`]): it stays in the
    /// covariance.
    Wide,
    /// The other values leave it without effect ([`crate::models::FiberModel::inert`]; the
    /// fur model: a medulla parameter while `kappa` is ~0), with the model's reason.
    Inert(&'static str),
    /// Its effect on the residuals is (nearly) that of a parameter held on its bound
    /// ([`flag_coupled`]): the two trade off, and its standard error, conditional on the
    /// held value, says nothing of how far it could move.
    Coupled,
}

impl Why {
    /// The reason as fit files and the fit command print it.
    pub fn as_str(self) -> &'static str {
        match self {
            Why::Bound => "on its bound, where the linearised standard error is undefined",
            Why::Singular => "no information in the data at this value (singular direction)",
            Why::Wide => "standard error spans most of its range",
            Why::Inert(reason) => reason,
            Why::Coupled => "trades off with a parameter held on its bound (see conditional_on); its standard error assumes that value",
        }
    }

    /// The linearisation holds such a parameter fixed at its value (on a bound or a
    /// singular direction), so every other standard error is conditional on it.
    pub fn held(self) -> bool {
        matches!(self, Why::Bound | Why::Singular)
    }
}

impl std::fmt::Display for Why {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

#[derive(Clone, Debug, PartialEq)]
/// Uncertainty of a fit from the Jacobian at its optimum ([`estimate`]): standard errors,
/// unconstrained flags and correlations of the free parameters.
pub struct Uncertainty {
    /// File-unit standard error per parameter (`None`: fixed or infinite).
    pub se: Vec<Option<f64>>,
    /// Parameters flagged as not constrained by the data, with the reason.
    pub unconstrained: Vec<(Param, Why)>,
    /// Free parameters in the order of `correlation`.
    pub free: Vec<Param>,
    /// Correlation matrix of the free parameters (in `u`; NaN where undefined).
    pub correlation: DMatrix<f64>,
    /// Residual variance `s^2 = sum r^2 / (n - p - 1)` (`p` free parameters and the exposure).
    pub s2: f64,
    /// How far the local optimum of the linearised model is from the result: the largest
    /// Gauss-Newton step of a determined parameter in its standard errors
    /// ([`gauss_newton_step_se`], parameters on a bound held). A converged fit has it
    /// below the solver's `step_se` ([`super::STEP_SE`]).
    pub step_se: f64,
    /// Standard errors robust to residuals correlated along the sweeps ([`robust`]; set
    /// by the fitter, `None` with too few rows).
    pub robust: Option<Robust>,
}

impl Uncertainty {
    /// Free parameters on their bound ([`reparam::at_bound`]): the map's derivative all but
    /// vanishes there, so the linearisation holds them fixed and every other standard
    /// error is conditional on their bound value (profile intervals are not).
    pub fn at_bound(&self) -> Vec<Param> {
        self.unconstrained
            .iter()
            .filter(|(_, why)| *why == Why::Bound)
            .map(|(id, _)| *id)
            .collect()
    }

    /// Free parameters the linearisation holds fixed ([`Why::held`]): every other
    /// standard error is conditional on their fitted values.
    pub fn held(&self) -> Vec<Param> {
        self.unconstrained
            .iter()
            .filter(|(_, why)| why.held())
            .map(|(id, _)| *id)
            .collect()
    }
}

/// Share of a parameter's Jacobian column that the held parameters' effects explain
/// (multiple correlation `R`, [`flag_coupled`]) above which it counts as trading off with
/// them ([`Why::Coupled`]).
pub const COUPLED_R: f64 = 0.99;

/// The effect on the residuals of each parameter on its bound in `unc`, per unit of its
/// value: the secant from the fitted point (residuals `r` at `u`) a tenth of the way in
/// value to its map's interior edge (local, yet a step the clamped map can take), one
/// evaluation of `problem` each. The input of [`flag_coupled`].
pub fn bound_effects(
    problem: &LogResidualProblem,
    u: &DVector<f64>,
    r: &DVector<f64>,
    unc: &Uncertainty,
) -> Vec<(Param, DVector<f64>)> {
    unc.at_bound()
        .into_iter()
        .filter_map(|id| {
            let j = unc.free.iter().position(|&f| f == id)?;
            let (v0, v_edge) = (
                reparam::to_value(id, u[j]),
                reparam::to_value(id, reparam::interior_edge(id, u[j]).0),
            );
            let mut edge = u.clone();
            edge[j] = reparam::to_u(id, v0 + 0.1 * (v_edge - v0));
            let dv = reparam::to_value(id, edge[j]) - v0;
            (dv != 0.0).then(|| (id, (problem.residuals(edge.as_slice()) - r) / dv))
        })
        .collect()
}

/// Flag the free parameters whose Jacobian column (of `jac`) lies within [`COUPLED_R`]
/// (multiple correlation) in the span of the effects of the parameters held on their
/// bounds, given as `(id, column)`: the residuals' change from the bound to the map's
/// interior edge, per unit of value (the map's derivative has vanished at the bound, so
/// `jac`'s own column says nothing). Such a parameter's conditional SE is falsely tight:
/// the data fix only a combination with the held ones (two absorptions at correlation -1;
/// springbok's fit: `sigma_c_a` in the thousands with `kappa` at 0.9999 and `sigma_m_a` at 0).
pub fn flag_coupled(unc: &mut Uncertainty, jac: &DMatrix<f64>, held: &[(Param, DVector<f64>)]) {
    let cols: Vec<&DVector<f64>> = held
        .iter()
        .map(|(_, c)| c)
        .filter(|c| c.norm() > 0.0 && c.iter().all(|x| x.is_finite()))
        .collect();
    if cols.is_empty() {
        return;
    }
    let h = DMatrix::from_columns(&cols.iter().map(|c| c.normalize()).collect::<Vec<_>>());
    let svd = h.clone().svd(true, true);
    for (j, id) in unc.free.clone().into_iter().enumerate() {
        if held.iter().any(|(p, _)| *p == id) || unc.unconstrained.iter().any(|(p, _)| *p == id) {
            continue;
        }
        let col = jac.column(j).into_owned();
        let norm = col.norm();
        if norm.is_nan() || norm <= 0.0 {
            continue;
        }
        let Ok(x) = svd.solve(&col, 1e-12) else {
            continue;
        };
        let r = (&h * x).norm() / norm;
        if r >= COUPLED_R {
            unc.unconstrained.push((id, Why::Coupled));
        }
    }
}

/// A coordinate loading more than this on the null directions of [`pseudo_inverse`] is not
/// determined by the data.
pub const NULL_LOAD: f64 = 1e-6;

/// Residual variance `s^2 = |r|^2 / (n - p - 1)` of `p` free parameters: the exposure is
/// solved too (in closed form), one more unknown than the columns.
pub fn residual_variance(r: &DVector<f64>, p: usize) -> f64 {
    r.norm_squared() / r.len().saturating_sub(p + 1).max(1) as f64
}

/// The pseudo-inverse of `J^T J` (`p x p`), and per coordinate its load on the directions
/// left out (the null directions). `s^2` times it is the linearised covariance; shared by
/// the uncertainty estimate and the solver's standard-error stop ([`super::lm`]).
///
/// The cut is made on the scaled matrix `D J^T J D` with `D = diag(J^T J)^(-1/2)` (the
/// columns' cosine matrix): singular values below `1e-10` of the largest are near-exact
/// collinearity of columns, whatever the parameters' units or the bounded maps' slopes (an
/// unscaled cut dropped a column merely because its map's derivative was small). A zero
/// column is a null direction of its own.
pub fn pseudo_inverse(jtj: &DMatrix<f64>) -> (DMatrix<f64>, Vec<f64>) {
    let p = jtj.nrows();
    let d: Vec<f64> = (0..p)
        .map(|j| {
            let h = jtj[(j, j)];
            if h > 0.0 && h.is_finite() {
                1.0 / h.sqrt()
            } else {
                0.0
            }
        })
        .collect();
    let scaled = DMatrix::from_fn(p, p, |i, j| d[i] * jtj[(i, j)] * d[j]);
    let svd = scaled.svd(true, true);
    let smax = svd.singular_values.max();
    let v_t = svd.v_t.clone().unwrap_or_else(|| DMatrix::identity(p, p));
    let mut pinv = DMatrix::zeros(p, p);
    let mut null_load = vec![0.0; p];
    for (k, &sv) in svd.singular_values.iter().enumerate() {
        let row = v_t.row(k);
        if sv > 1e-10 * smax && sv > 0.0 {
            pinv += row.transpose() * row / sv;
        } else {
            for j in 0..p {
                null_load[j] += row[j] * row[j];
            }
        }
    }
    for j in 0..p {
        if d[j] == 0.0 {
            // Its scaled row and column are zero: the SVD gives it a null direction of its
            // own, but say so whatever the ordering of equal (zero) singular values.
            null_load[j] = 1.0;
        }
    }
    (
        DMatrix::from_fn(p, p, |i, j| d[i] * pinv[(i, j)] * d[j]),
        null_load,
    )
}

/// The largest step of a determined coordinate in its own standard errors,
/// `max_j |delta_j| / SE_j`, for the Gauss-Newton step `delta = -H^+ g` (`H = J^T J`,
/// `g = J^T r`) and the linearised covariance `s^2 H^+`: how far the local optimum of the
/// linearised model still is, in the statistic a user reads. Coordinates loading on a
/// singular direction or with `SE_j > max_se` are not determined by the data and left out
/// (0 when none is left).
pub fn gauss_newton_step_se(
    jtj: &DMatrix<f64>,
    grad: &DVector<f64>,
    r: &DVector<f64>,
    max_se: f64,
) -> f64 {
    let (pinv, null_load) = pseudo_inverse(jtj);
    step_se_with(
        jtj,
        grad,
        residual_variance(r, grad.len()),
        &pinv,
        &null_load,
        max_se,
    )
}

/// [`gauss_newton_step_se`] with `jtj`'s [`pseudo_inverse`] and the residual variance
/// `s2` already at hand.
fn step_se_with(
    jtj: &DMatrix<f64>,
    grad: &DVector<f64>,
    s2: f64,
    pinv: &DMatrix<f64>,
    null_load: &[f64],
    max_se: f64,
) -> f64 {
    let p = grad.len();
    // The determined coordinates, and their Gauss-Newton step with the others held: an
    // undetermined coordinate's own step (towards a bound, say) drags correlated ones
    // along in the full step without changing the cost, so only the conditional step
    // says how far the determined ones are from their optimum.
    let se: Vec<f64> = (0..p)
        .map(|j| (s2 * pinv[(j, j)]).max(0.0).sqrt())
        .collect();
    let det: Vec<usize> = (0..p)
        .filter(|&j| null_load[j] <= NULL_LOAD && se[j] <= max_se)
        .collect();
    if det.is_empty() {
        return 0.0;
    }
    let h_cc = DMatrix::from_fn(det.len(), det.len(), |a, b| jtj[(det[a], det[b])]);
    let g_c = DVector::from_fn(det.len(), |a, _| grad[det[a]]);
    let Some(delta) = h_cc.cholesky().map(|c| -c.solve(&g_c)) else {
        return f64::INFINITY;
    };
    let worst = det
        .iter()
        .zip(delta.iter())
        .fold(0.0f64, |w, (&j, d)| w.max(d.abs() / se[j].max(1e-300)));
    if worst.is_finite() {
        worst
    } else {
        f64::INFINITY
    }
}

/// `jac` with the columns flagged in `held` zeroed: the linearisation holds those
/// parameters at their value (on a bound), for [`estimate`] and [`robust`] alike.
fn hold_columns(jac: &DMatrix<f64>, held: &[bool]) -> DMatrix<f64> {
    let mut j = jac.clone();
    for (k, _) in held.iter().enumerate().filter(|(_, h)| **h) {
        j.column_mut(k).fill(0.0);
    }
    j
}

/// Sample indices in sweep order: rows of `(theta_i, theta_r)` in that order, `phi`
/// ascending within a row (`pts` as `(theta_i, theta_r, phi)`, any one unit).
pub fn sweep_order(pts: &[(f64, f64, f64)]) -> Vec<usize> {
    let mut order: Vec<usize> = (0..pts.len()).collect();
    order.sort_by(|&a, &b| {
        let (x, y) = (pts[a], pts[b]);
        x.0.total_cmp(&y.0)
            .then(x.1.total_cmp(&y.1))
            .then(x.2.total_cmp(&y.2))
    });
    order
}

/// Uncertainty from the Jacobian `jac` (n x p, free parameters) and residuals `r` at `u`.
pub fn estimate(
    layout: &ParamLayout,
    u: &DVector<f64>,
    jac: &DMatrix<f64>,
    r: &DVector<f64>,
) -> Uncertainty {
    let free = layout.free();
    let p = jac.ncols();
    let s2 = residual_variance(r, p);
    if p == 0 {
        // Every parameter fixed: nothing to estimate (and nalgebra's SVD refuses an empty
        // matrix).
        return Uncertainty {
            se: vec![None; layout.fixed.len()],
            unconstrained: Vec::new(),
            free,
            correlation: DMatrix::zeros(0, 0),
            s2,
            step_se: 0.0,
            robust: None,
        };
    }
    // Parameters on their bound are held at it: their columns are dropped, so every other
    // standard error is conditional on them (as `Why::held` says), however far into the
    // bound the map has taken them. (Left in, a column whose map's slope had not quite
    // vanished made the others marginal over it instead.)
    let bound: Vec<bool> = free
        .iter()
        .enumerate()
        .map(|(j, id)| reparam::at_bound(*id, u[j]))
        .collect();
    let j_held = hold_columns(jac, &bound);
    let jtj = j_held.transpose() * &j_held;
    let (mut cov, null_load) = pseudo_inverse(&jtj);
    let step_se = step_se_with(
        &jtj,
        &(j_held.transpose() * r),
        s2,
        &cov,
        &null_load,
        MAX_SE_U,
    );
    cov *= s2;
    let mut se = vec![None; layout.fixed.len()];
    let mut unconstrained = Vec::new();
    let (inert, inert_why) = layout.model.inert(&layout.file_values(u.as_slice()));
    for (j, id) in free.iter().enumerate() {
        let se_u = cov[(j, j)].max(0.0).sqrt();
        if bound[j] {
            // Not "no information": the data may well pin it (another start recovers an
            // interior value), but not through a derivative that has vanished.
            unconstrained.push((*id, Why::Bound));
            continue;
        }
        if null_load[j] > NULL_LOAD {
            unconstrained.push((*id, Why::Singular));
            continue;
        }
        se[id.index()] = Some(reparam::derivative(*id, u[j]).abs() * se_u);
        if reparam::spans_most(*id, u[j], se_u) {
            unconstrained.push((*id, Why::Wide));
        } else if inert.contains(&id.index()) {
            unconstrained.push((*id, Why::Inert(inert_why)));
        }
    }
    let mut corr = DMatrix::from_element(p, p, f64::NAN);
    for i in 0..p {
        for j in 0..p {
            let d = (cov[(i, i)] * cov[(j, j)]).sqrt();
            if d > 0.0 && null_load[i] <= NULL_LOAD && null_load[j] <= NULL_LOAD {
                corr[(i, j)] = (cov[(i, j)] / d).clamp(-1.0, 1.0);
            }
        }
    }
    Uncertainty {
        se,
        unconstrained,
        free,
        correlation: corr,
        s2,
        step_se,
        robust: None,
    }
}

/// Standard errors that allow residuals to be correlated along the goniometer's sweeps
/// (review M5). Each row `t` of samples sharing `(theta_i, theta_r)` contributes the score
/// `s_t = J_t^T r_t`, which moves the estimate by `z_t = H^+ s_t` (`H = J^T J`, parameters
/// on a bound held as in [`estimate`]); a parameter's variance is the long-run variance of
/// its `z_t` over the rows ([`long_run_variance`]): any correlation within a row (along
/// `phi`) is allowed, and between rows of one `theta_i` up to a bandwidth chosen from the
/// data, times `G / (G - 1)` for `G` rows. This is the diagonal of the sandwich
/// `H^+ Omega H^+` with a Newey-West `Omega` over rows. The independent-residual estimate
/// [`estimate`] understates the spread when the misfit is smooth in angle (model error, a
/// drifting lamp, a twisted fiber); this one still assumes rows of different `theta_i`,
/// and rows far apart in `theta_r`, independent (and neighbours in `theta_r` to be
/// neighbours in acquisition). Each parameter gets its own bandwidth, so these are
/// per-parameter variances, not one joint covariance. Like [`estimate`] it is local, and
/// model error is a bias it does not cover.
#[derive(Clone, Debug, PartialEq)]
pub struct Robust {
    /// File-unit standard error per parameter (`None` where [`estimate`] has none).
    pub se: Vec<Option<f64>>,
    /// Rows (distinct `(theta_i, theta_r)`) the scores are summed over.
    pub rows: usize,
    /// Per parameter, the lags in `theta_r` (rows of one `theta_i`) whose cross products
    /// are kept ([`long_run_variance`]).
    pub bandwidth: Vec<Option<usize>>,
    /// Lag-1 autocorrelation of consecutive residuals in `phi` within rows (pooled; across
    /// any gap a floor or a missing sample leaves): near 0 for independent noise, near 1
    /// for a smooth misfit.
    pub phi_lag1: f64,
    /// Parameters not flagged unconstrained whose robust `u +- SE(u)` spans most of their
    /// range ([`reparam::spans_most`]): the flags follow the independent-residual
    /// errors, so these are named apart.
    pub spans_most: Vec<Param>,
}

/// Fewest rows per free coordinate for [`robust`]: a long-run variance over few rows is
/// itself too noisy to report.
pub const ROBUST_MIN_ROWS_PER_PARAM: usize = 4;

/// The long-run variance of one parameter's influence series `z_t` (one value per row,
/// sequences of rows sharing `theta_i` in `theta_r` order), i.e. the variance of its sum
/// when neighbouring rows are correlated: `sum z_t^2 + 2 sum_l w_l sum_t z_t z_(t-l)` over
/// lags within sequences, Bartlett weights `w_l = 1 - l / (L + 1)` (Newey-West: never
/// negative), and the lag count `L`: Andrews' (1991) automatic bandwidth with an AR(1)
/// plug-in, `1.1447 (alpha T)^(1/3)`, `alpha = 4 rho^2 / ((1 - rho)^2 (1 + rho)^2)` for
/// sequences of `T` rows on average and lag-1 autocorrelation `rho` (clamped to 0.97), at
/// most one less than the longest sequence: rows strongly correlated in `theta_r` (a
/// smooth misfit) get many lags, independent ones none. A non-finite series gives NaN.
///
/// Not prewhitened (Andrews & Monahan 1992): that brought a row effect correlated at 0.5
/// from 17 % low to 1 % in this module's tests, but on the shipped fits, whose misfit is model error
/// smooth in `theta_r`, its recolouring `1 / (1 - rho)^2` ran into the `rho` clamp and
/// multiplied standard errors by up to 20 more (red fox `g` 0.022 to 0.46).
fn long_run_variance(z: &[f64], seqs: &[std::ops::Range<usize>]) -> (f64, usize) {
    let pairs = |l: usize| -> f64 {
        seqs.iter()
            .flat_map(|s| (s.start + l..s.end).map(move |t| (t, t - l)))
            .map(|(t, u)| z[t] * z[u])
            .sum()
    };
    let c0: f64 = z.iter().map(|v| v * v).sum();
    if !c0.is_finite() {
        return (f64::NAN, 0);
    }
    if c0 <= 0.0 {
        return (0.0, 0);
    }
    let rho = (pairs(1) / c0).clamp(-0.97, 0.97);
    let alpha = 4.0 * rho * rho / ((1.0 - rho).powi(2) * (1.0 + rho).powi(2));
    let t = z.len() as f64 / seqs.len().max(1) as f64;
    let longest = seqs.iter().map(|s| s.len()).max().unwrap_or(1);
    let lags = ((1.1447 * (alpha * t).cbrt()).floor() as usize).min(longest.saturating_sub(1));
    let mut v = c0;
    for l in 1..=lags {
        v += 2.0 * (1.0 - l as f64 / (lags as f64 + 1.0)) * pairs(l);
    }
    (if v.is_nan() { v } else { v.max(0.0) }, lags)
}

/// The sweep-correlation-robust standard errors ([`Robust`]) from the Jacobian `jac`
/// (n x p), residuals `r` and the samples' angles `pts` (`(theta_i, theta_r, phi)`, one per
/// residual), consistent with `unc` (same held parameters and singular directions). `None`
/// when there are fewer than [`ROBUST_MIN_ROWS_PER_PARAM`] rows per free coordinate, or
/// fewer than two samples per row on average (no sweeps to speak of).
pub fn robust(
    layout: &ParamLayout,
    u: &DVector<f64>,
    jac: &DMatrix<f64>,
    r: &DVector<f64>,
    pts: &[(f64, f64, f64)],
    unc: &Uncertainty,
) -> Option<Robust> {
    let free = layout.free();
    let held: Vec<bool> = free
        .iter()
        .map(|id| unc.unconstrained.contains(&(*id, Why::Bound)))
        .collect();
    let (var, rows, lags, phi_lag1) = sweep_robust_var(jac, r, pts, &held)?;
    let mut se = vec![None; layout.fixed.len()];
    let mut bandwidth = vec![None; layout.fixed.len()];
    for (j, id) in free.iter().enumerate() {
        if unc.se[id.index()].is_some() {
            se[id.index()] = Some(reparam::derivative(*id, u[j]).abs() * var[j].sqrt());
            bandwidth[id.index()] = Some(lags[j]);
        }
    }
    let spans_most = robust_spans_most(&free, u, &var, unc);
    Some(Robust {
        se,
        rows,
        bandwidth,
        phi_lag1,
        spans_most,
    })
}

/// The free parameters (`free`, at `u`, robust variances `var` in `u`) that `unc` gives a
/// standard error and does not flag, whose robust `u +- SE(u)` spans most of their range.
fn robust_spans_most(
    free: &[Param],
    u: &DVector<f64>,
    var: &[f64],
    unc: &Uncertainty,
) -> Vec<Param> {
    free.iter()
        .enumerate()
        .filter(|(_, id)| unc.se[id.index()].is_some())
        .filter(|(_, id)| !unc.unconstrained.iter().any(|(p, _)| p == *id))
        .filter(|(j, id)| reparam::spans_most(**id, u[*j], var[*j].sqrt()))
        .map(|(_, id)| *id)
        .collect()
}

/// The variances of [`robust`] in the solver's coordinates, with the columns flagged in
/// `held` zeroed, and the row count, each parameter's lag count and the residuals' lag-1
/// autocorrelation along `phi`.
///
/// Tried and dropped (2026-11-28): restoring each row's score as leave-one-row-out
/// residuals give it (CR3, `(I - G_g H^+)^-1 J_g^T r_g`, times `(G-1)/G`). In
/// `furfit se-calibration` (40 replicates per noise model) it raised robust SE / SD under
/// correlated noise for the short parameters only a little (alpha 0.56 -> 0.64, beta_n
/// 0.70 -> 0.79, g 0.62 -> 0.66; their coverage 72 / 80 / 77 % -> 72 / 82 / 77 %) and
/// inflated the rest (independent noise: 0.94-1.43 -> 1.07-1.56): the shortfall is the
/// fit absorbing noise correlated across rows, which a per-row leverage cannot restore.
fn sweep_robust_var(
    jac: &DMatrix<f64>,
    r: &DVector<f64>,
    pts: &[(f64, f64, f64)],
    held: &[bool],
) -> Option<(Vec<f64>, usize, Vec<usize>, f64)> {
    let p = jac.ncols();
    if p == 0 || pts.len() != r.len() || jac.nrows() != r.len() || held.len() != p {
        return None;
    }
    let order = sweep_order(pts);
    let j_held = hold_columns(jac, held);
    // Per row: theta_i and the score.
    let mut rows: Vec<(f64, DVector<f64>)> = Vec::new();
    let (mut lag_num, mut lag_den) = (0.0, 0.0);
    let mut prev: Option<usize> = None;
    for &i in &order {
        let (ti, tr, _) = pts[i];
        match prev {
            Some(k) if pts[k].0 == ti && pts[k].1 == tr => lag_num += r[k] * r[i],
            _ => rows.push((ti, DVector::zeros(p))),
        }
        lag_den += r[i] * r[i];
        let s = &mut rows.last_mut().expect("a row was pushed").1;
        *s += j_held.row(i).transpose() * r[i];
        prev = Some(i);
    }
    let g = rows.len();
    // Rows of a single sample (angles logged with encoder jitter, or no phi sweeps) are no
    // sweep structure: the estimate would fall back to about the independent one unsaid.
    if g < ROBUST_MIN_ROWS_PER_PARAM * p || 2 * g > pts.len() {
        return None;
    }
    // Sequences of rows sharing theta_i (already in theta_r order).
    let mut seqs: Vec<std::ops::Range<usize>> = Vec::new();
    for (k, row) in rows.iter().enumerate() {
        match seqs.last_mut() {
            Some(last) if rows[last.start].0 == row.0 => last.end = k + 1,
            _ => seqs.push(k..k + 1),
        }
    }
    // Each parameter's estimate moves by (H^+ s_t)_j per row's score: its variance is the
    // long-run variance of that series (the diagonal of H^+ Omega H^+, with a bandwidth
    // of its own).
    let (pinv, _) = pseudo_inverse(&(j_held.transpose() * &j_held));
    let infl: Vec<DVector<f64>> = rows.iter().map(|(_, s)| &pinv * s).collect();
    let mut var = vec![0.0; p];
    let mut lags = vec![0; p];
    for j in 0..p {
        let z: Vec<f64> = infl.iter().map(|v| v[j]).collect();
        let (v, l) = long_run_variance(&z, &seqs);
        var[j] = v * g as f64 / (g as f64 - 1.0);
        lags[j] = l;
    }
    let lag1 = if lag_den > 0.0 {
        lag_num / lag_den
    } else {
        0.0
    };
    Some((var, g, lags, lag1))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::ParamId;

    /// The fur model's parameter `id`.
    #[allow(non_snake_case)]
    fn P(id: ParamId) -> Param {
        id.into()
    }

    #[test]
    fn residual_variance_counts_the_exposure_as_an_unknown() {
        // 5 residuals, 2 free parameters and the exposure: 5 - 2 - 1 = 2 degrees of freedom.
        let r = DVector::from_vec(vec![1.0, -2.0, 0.5, 0.0, 1.5]);
        assert_eq!(residual_variance(&r, 2), 7.5 / 2.0);
        // Fewer residuals than unknowns: divide by 1, not by zero.
        assert_eq!(residual_variance(&r, 6), 7.5);
    }

    #[test]
    fn pseudo_inverse_cut_does_not_depend_on_units() {
        // Orthogonal columns 1e12 apart in scale are both determined: the cut is made on
        // the columns' cosine matrix, where both have unit diagonal. The inverse of a
        // diagonal matrix is exact up to one rounding per entry (1e-15 rel).
        let h = DMatrix::from_diagonal(&DVector::from_vec(vec![1e12, 1e-12, 3.0]));
        let (pinv, null) = pseudo_inverse(&h);
        assert_eq!(null, vec![0.0; 3]);
        for (j, want) in [1e-12, 1e12, 1.0 / 3.0].into_iter().enumerate() {
            assert!(
                (pinv[(j, j)] - want).abs() <= 1e-15 * want,
                "{j}: {}",
                pinv[(j, j)]
            );
        }
        // Two collinear columns (any scales) share one null direction, and the third
        // column, orthogonal to both, keeps its exact inverse and no null load.
        let a = [2e6, -4e6, 0.0];
        let c = DMatrix::from_fn(3, 3, |i, j| {
            if i == 2 || j == 2 {
                if i == j {
                    5e-9
                } else {
                    0.0
                }
            } else {
                a[i] * a[j] * 1e-6
            }
        });
        let (pinv, null) = pseudo_inverse(&c);
        // The unit null vector of the scaled pair is (1, 1)/sqrt(2): load 1/2 on each
        // (SVD rounding ~1e-15 on unit vectors).
        assert!(
            (null[0] - 0.5).abs() < 1e-12 && (null[1] - 0.5).abs() < 1e-12,
            "{null:?}"
        );
        assert_eq!(null[2], 0.0);
        assert!(
            (pinv[(2, 2)] - 2e8).abs() <= 1e-12 * 2e8,
            "{}",
            pinv[(2, 2)]
        );
    }

    /// A column within the span of the held effects (R = 0.995) is flagged, one at
    /// R = 0.98 and one orthogonal are not, and a held parameter itself is left alone.
    #[test]
    fn flag_coupled_uses_the_span_of_the_held_effects() {
        let n = 50;
        let a = DVector::from_fn(n, |i, _| ((i as f64) * 0.3).sin());
        let b = DVector::from_fn(n, |i, _| ((i as f64) * 0.7).cos());
        // Orthogonal to a and b (up to rounding): a third frequency.
        let c = DVector::from_fn(n, |i, _| ((i as f64) * 1.9).sin());
        let c = &c - &a * (a.dot(&c) / a.dot(&a));
        let c = &c - &b * (b.dot(&c) / b.dot(&b));
        let mix = |r: f64| (&a + &b).normalize() * r + c.normalize() * (1.0 - r * r).sqrt();
        let free = vec![
            P(ParamId::SigmaCA),
            P(ParamId::SigmaMA),
            P(ParamId::Eta),
            P(ParamId::L),
            P(ParamId::Kappa),
        ];
        let jac = DMatrix::from_columns(&[
            mix(0.995),
            mix(0.98),
            c.clone(),
            DVector::zeros(n),
            DVector::zeros(n),
        ]);
        let mut unc = Uncertainty {
            se: vec![None; 10],
            unconstrained: vec![(P(ParamId::Kappa), Why::Bound)],
            free,
            correlation: DMatrix::zeros(5, 5),
            s2: 1.0,
            step_se: 0.0,
            robust: None,
        };
        flag_coupled(
            &mut unc,
            &jac,
            &[
                (P(ParamId::Kappa), a.clone()),
                (P(ParamId::L), b.clone() * 3.0),
            ],
        );
        assert_eq!(
            unc.unconstrained,
            vec![
                (P(ParamId::Kappa), Why::Bound),
                (P(ParamId::SigmaCA), Why::Coupled)
            ]
        );
    }

    /// A goniometer-like grid (2 x 31 rows of 41 `phi`) and a design on it with one column
    /// varying along `phi`, one constant within a row and one mixed.
    fn sweep_design() -> (Vec<(f64, f64, f64)>, DMatrix<f64>) {
        let mut pts = Vec::new();
        for ti in [0.0, 30.0] {
            for tr in 0..31 {
                for ph in 0..41 {
                    pts.push((ti, tr as f64 * 2.0, ph as f64 * 9.0 - 180.0));
                }
            }
        }
        let x = DMatrix::from_fn(pts.len(), 3, |i, j| {
            let (ti, tr, ph) = pts[i];
            match j {
                0 => (ph / 40.0).cos(),
                1 => tr / 60.0 - 0.5,
                _ => (ph / 70.0).sin() * (1.0 + ti / 30.0) + 0.3 * tr / 60.0,
            }
        });
        (pts, x)
    }

    /// Replicated least squares on a goniometer-like grid (2 x 31 rows of 41 `phi`) with
    /// noise `row + along + 0.5 white`: `along` AR(1) in `phi` at `rho_phi`, `row` a row
    /// effect AR(1) in `theta_r` at `rho_row` (scale `row_sd`). Per column of a design
    /// with one column varying along `phi`, one constant within a row and one mixed: the
    /// mean independent-residual and sweep-robust standard errors over the spread of the
    /// estimates, and the mean lag-1 autocorrelation along `phi`.
    fn se_over_spread(rho_phi: f64, rho_row: f64, row_sd: f64) -> ([f64; 3], [f64; 3], f64) {
        use rand::SeedableRng;
        let (pts, x) = sweep_design();
        let n = pts.len();
        let xtx_inv = (x.transpose() * &x).try_inverse().expect("full rank");
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(7);
        let mut normal = || crate::simulate::trace::gauss(&mut rng);
        let reps = 400;
        let mut est = vec![[0.0; 3]; reps];
        let (mut se_iid, mut se_rob, mut lag1_mean) = ([0.0; 3], [0.0; 3], 0.0);
        for e in est.iter_mut() {
            let mut noise = vec![0.0; n];
            let (mut row_eff, mut along) = (0.0, 0.0);
            for (i, v) in noise.iter_mut().enumerate() {
                let (_, tr, ph) = pts[i];
                if ph == -180.0 {
                    row_eff = if tr == 0.0 {
                        normal()
                    } else {
                        rho_row * row_eff + (1.0 - rho_row * rho_row).sqrt() * normal()
                    };
                    along = normal();
                } else {
                    along = rho_phi * along + (1.0 - rho_phi * rho_phi).sqrt() * normal();
                }
                *v = row_sd * row_eff + along + 0.5 * normal();
            }
            let y = DVector::from_vec(noise);
            let beta = &xtx_inv * x.transpose() * &y;
            let r = &y - &x * &beta;
            let s2 = residual_variance(&r, 2);
            let (var, _, _, lag1) =
                sweep_robust_var(&x, &r, &pts, &[false; 3]).expect("enough rows");
            lag1_mean += lag1 / reps as f64;
            for j in 0..3 {
                e[j] = beta[j];
                se_iid[j] += (s2 * xtx_inv[(j, j)]).sqrt() / reps as f64;
                se_rob[j] += var[j].sqrt() / reps as f64;
            }
        }
        let (mut ri, mut rr) = ([0.0; 3], [0.0; 3]);
        for j in 0..3 {
            let sd = (est.iter().map(|e| e[j] * e[j]).sum::<f64>() / reps as f64).sqrt();
            ri[j] = se_iid[j] / sd;
            rr[j] = se_rob[j] / sd;
        }
        (ri, rr, lag1_mean)
    }

    /// Noise correlated along `phi` (rho 0.9) and between neighbouring rows (rho 0.5): the
    /// sweep-robust standard errors come close to the spread of the estimates, the
    /// independent-residual ones fall far short.
    #[test]
    fn sweep_robust_errors_match_the_spread_under_correlated_noise() {
        let (ri, rr, lag1) = se_over_spread(0.9, 0.5, 1.0);
        assert!(lag1 > 0.5, "smooth residuals along phi: {lag1}");
        for j in 0..3 {
            assert!(
                ri[j] < 0.6,
                "column {j}: independent SE should understate: {ri:?}"
            );
            // HAC estimates run 10-20 % low with some 60 rows (the data-chosen bandwidth
            // truncates the row effects' correlation; measured 0.82-0.99 here), hence 0.75;
            // the independent-residual ones run 0.14-0.48.
            assert!(
                (0.75..1.25).contains(&rr[j]),
                "column {j}: robust SE / spread {rr:?}"
            );
        }
    }

    /// Rows of one sample each (angles logged with jitter) are no sweep structure: no robust
    /// estimate rather than one that quietly equals the independent one (review M2); and
    /// a non-finite influence series gives NaN, not a standard error of 0.
    #[test]
    fn robust_needs_rows_of_several_samples_and_stays_nan_on_nan() {
        let n = 200;
        let pts: Vec<(f64, f64, f64)> = (0..n)
            .map(|i| (0.0, i as f64 * 0.1 + 1e-7 * (i % 3) as f64, 0.0))
            .collect();
        let jac = DMatrix::from_fn(n, 2, |i, j| ((i * (j + 1)) as f64 * 0.37).sin());
        let r = DVector::from_fn(n, |i, _| ((i * 7) as f64).cos());
        assert!(sweep_robust_var(&jac, &r, &pts, &[false; 2]).is_none());
        // The same samples in 20 rows of 10: an estimate.
        let rows: Vec<(f64, f64, f64)> = (0..n)
            .map(|i| (0.0, (i / 10) as f64, (i % 10) as f64))
            .collect();
        assert!(sweep_robust_var(&jac, &r, &rows, &[false; 2]).is_some());
        let z = [1.0, f64::NAN, 2.0];
        let whole = 0..z.len();
        assert!(long_run_variance(&z, std::slice::from_ref(&whole))
            .0
            .is_nan());
    }

    /// Independent noise: both estimates match the spread (400 replicates: the spread
    /// itself is known to about 4 %, and a sandwich over 62 rows adds a few %).
    #[test]
    fn sweep_robust_errors_agree_with_the_plain_ones_under_independent_noise() {
        let (ri, rr, lag1) = se_over_spread(0.0, 0.0, 0.0);
        assert!(lag1.abs() < 0.05, "independent residuals along phi: {lag1}");
        for j in 0..3 {
            assert!(
                (0.9..1.1).contains(&ri[j]),
                "column {j}: independent {ri:?}"
            );
            assert!((0.85..1.15).contains(&rr[j]), "column {j}: robust {rr:?}");
        }
    }

    /// Both kinds of standard error are reported in file units through the same map
    /// derivative: with independent noise they agree for parameters on an exp, a sigmoid
    /// and a tanh map alike (each `u` away from 0, where the maps' slopes differ most).
    #[test]
    fn robust_and_plain_errors_agree_in_file_units_under_independent_noise() {
        use rand::SeedableRng;
        let mut layout = ParamLayout::all_free(crate::models::default_model());
        let free = [P(ParamId::SigmaCA), P(ParamId::Eta), P(ParamId::Alpha)];
        for id in ParamId::ALL {
            if !free.contains(&P(id)) {
                layout.fixed[id.index()] = Some(0.5);
            }
        }
        let (pts, jac) = sweep_design();
        let n = pts.len();
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(11);
        let r = DVector::from_fn(n, |_, _| crate::simulate::trace::gauss(&mut rng));
        let u = DVector::from_vec(vec![0.7, -1.2, 0.4]);
        let mut unc = estimate(&layout, &u, &jac, &r);
        unc.robust = robust(&layout, &u, &jac, &r, &pts, &unc);
        let rob = unc.robust.as_ref().expect("62 rows of 41 samples");
        for id in free {
            let (plain, robust) = (unc.se[id.index()].unwrap(), rob.se[id.index()].unwrap());
            // One replicate over 62 rows: the robust estimate scatters ~10 % about the
            // plain one (the replicated test above pins the means); a unit slip would be
            // off by the map slope or by SE(u) itself, factors of 3 or more here.
            assert!(
                (0.7..1.4).contains(&(robust / plain)),
                "{id:?}: robust {robust} plain {plain}"
            );
        }
    }

    /// A parameter whose robust error spans most of its range is named unless it is
    /// already flagged; one with a narrow robust error, or without a standard error, is
    /// not (the flags follow the independent-residual errors).
    #[test]
    fn robust_spans_most_names_only_unflagged_wide_parameters() {
        let free = vec![
            P(ParamId::SigmaCA),
            P(ParamId::SigmaMS),
            P(ParamId::SigmaMA),
            P(ParamId::Eta),
        ];
        let mut unc = Uncertainty {
            se: vec![None; 10],
            unconstrained: vec![(P(ParamId::SigmaMA), Why::Wide)],
            free: free.clone(),
            correlation: DMatrix::zeros(4, 4),
            s2: 1.0,
            step_se: 0.0,
            robust: None,
        };
        for id in &free {
            unc.se[id.index()] = Some(0.1);
        }
        unc.se[P(ParamId::Eta).index()] = None;
        let u = DVector::zeros(4);
        // Exp maps span most above SE(u) = 2: sigma_c_a at 3 does, sigma_m_s at 1 does
        // not, sigma_m_a at 3 is flagged already, eta has no standard error.
        let var = [9.0, 1.0, 9.0, 100.0];
        assert_eq!(
            robust_spans_most(&free, &u, &var, &unc),
            vec![P(ParamId::SigmaCA)]
        );
    }
}

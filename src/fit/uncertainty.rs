//! Linearised parameter uncertainty at the optimum: covariance `s^2 (J^T J)^+` in the
//! solver's unbounded coordinates `u`, mapped to file units with the reparameterisation
//! derivative (delta method: `SE(x) = |dx/du| SE(u)`), and the correlation matrix.
//!
//! A free parameter is flagged *unconstrained* when the data does not pin it down:
//! - it loads on a (numerically) null direction of `J^T J` (singular value below
//!   `1e-10` of the largest): its standard error is reported as `null` (infinite);
//! - or one standard error either side spans most of its range: more than half of it for
//!   the bounded maps, a factor above `e^4` for the exp ones ([`reparam::spans_most`]);
//! - or, for `sigma_m_s`, `sigma_m_a` and `g`, when `kappa < 1e-3`: the medulla is (nearly)
//!   absent, so the scattered lobes that carry these parameters vanish.

use super::problem::{LogResidualProblem, ParamLayout};
use super::reparam;
use crate::params::{ParamId, N_PARAMS};
use nalgebra::{DMatrix, DVector};

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
    /// A medulla parameter while `kappa < KAPPA_ABSENT`.
    NoMedulla,
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
            Why::NoMedulla => "kappa ~ 0: no medulla, scattered lobes absent",
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

/// kappa below which the medulla parameters count as unconstrained whatever their
/// standard errors say. At kappa = 0.02 the scattered lobes still carried a median 13 %
/// of a profile in an audit (and g came back to 6e-4), so the rule waits for a medulla
/// 20 times thinner; between the two the standard errors decide.
pub const KAPPA_ABSENT: f64 = 1e-3;

#[derive(Clone, Debug, PartialEq)]
pub struct Uncertainty {
    /// File-unit standard error per parameter (`None`: fixed or infinite).
    pub se: [Option<f64>; N_PARAMS],
    /// Parameters flagged as not constrained by the data, with the reason.
    pub unconstrained: Vec<(ParamId, Why)>,
    /// Free parameters in the order of `correlation`.
    pub free: Vec<ParamId>,
    /// Correlation matrix of the free parameters (in `u`; NaN where undefined).
    pub correlation: DMatrix<f64>,
    /// Residual variance `s^2 = sum r^2 / (n - p - 1)` (`p` free parameters and the exposure).
    pub s2: f64,
    /// How far the local optimum of the linearised model is from the result: the largest
    /// Gauss-Newton step of a determined parameter in its standard errors
    /// ([`gauss_newton_step_se`], parameters on a bound held). A converged fit has it
    /// below the solver's `step_se` (0.1).
    pub step_se: f64,
}

impl Uncertainty {
    /// Free parameters on their bound ([`reparam::at_bound`]): the map's derivative all but
    /// vanishes there, so the linearisation holds them fixed and every other standard
    /// error is conditional on their bound value (profile intervals are not).
    pub fn at_bound(&self) -> Vec<ParamId> {
        self.unconstrained
            .iter()
            .filter(|(_, why)| *why == Why::Bound)
            .map(|(id, _)| *id)
            .collect()
    }

    /// Free parameters the linearisation holds fixed ([`Why::held`]): every other
    /// standard error is conditional on their fitted values.
    pub fn held(&self) -> Vec<ParamId> {
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
) -> Vec<(ParamId, DVector<f64>)> {
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
/// springbok's `sigma_c_a` 1859 with `kappa` 0.9998 and `sigma_m_a` at 0).
pub fn flag_coupled(unc: &mut Uncertainty, jac: &DMatrix<f64>, held: &[(ParamId, DVector<f64>)]) {
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
            se: [None; N_PARAMS],
            unconstrained: Vec::new(),
            free,
            correlation: DMatrix::zeros(0, 0),
            s2,
            step_se: 0.0,
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
    let mut j_held = jac.clone();
    for (j, _) in bound.iter().enumerate().filter(|(_, b)| **b) {
        j_held.column_mut(j).fill(0.0);
    }
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
    let mut se = [None; N_PARAMS];
    let mut unconstrained = Vec::new();
    let kappa = layout.file_values(u.as_slice())[ParamId::Kappa.index()];
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
        } else if kappa < KAPPA_ABSENT
            && matches!(id, ParamId::SigmaMS | ParamId::SigmaMA | ParamId::G)
        {
            unconstrained.push((*id, Why::NoMedulla));
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
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
            ParamId::SigmaCA,
            ParamId::SigmaMA,
            ParamId::Eta,
            ParamId::L,
            ParamId::Kappa,
        ];
        let jac = DMatrix::from_columns(&[
            mix(0.995),
            mix(0.98),
            c.clone(),
            DVector::zeros(n),
            DVector::zeros(n),
        ]);
        let mut unc = Uncertainty {
            se: [None; N_PARAMS],
            unconstrained: vec![(ParamId::Kappa, Why::Bound)],
            free,
            correlation: DMatrix::zeros(5, 5),
            s2: 1.0,
            step_se: 0.0,
        };
        flag_coupled(
            &mut unc,
            &jac,
            &[(ParamId::Kappa, a.clone()), (ParamId::L, b.clone() * 3.0)],
        );
        assert_eq!(
            unc.unconstrained,
            vec![
                (ParamId::Kappa, Why::Bound),
                (ParamId::SigmaCA, Why::Coupled)
            ]
        );
    }
}

//! The settings of a fit ([`FitOptions`]) and its result ([`FitOutcome`]).

use super::likelihood;
use super::problem::ParamLayout;
use super::uncertainty::Uncertainty;
use crate::cancel::Cancel;
use crate::error::{Error, Num, Result};
use crate::model::far::FarOptions;
use crate::models::{FiberModel, ModelParams, Param};

/// Default [`FitOptions::step_se`]. At 0.1 the red fox's polish crawled for 24 more
/// iterations (41 % of the fit's CPU time) from 0.16 to 0.09 standard errors: the
/// tolerance-mode cost jumps by ~5e-7 (chi^2 ~0.002) where a step tips a refinement
/// decision, about what each of those steps gained. The parameters of the two stops
/// differ by at most 0.09 of their standard errors (`reports/fit_speed.md`).
pub const STEP_SE: f64 = 0.25;

/// Settings of one fit.
#[derive(Clone, Debug)]
pub struct FitOptions {
    /// Seed of the Halton scramble and the subsample (the fit is deterministic given it).
    pub seed: u64,
    /// Halton points in the global stage.
    pub n_global: usize,
    /// Samples in the subsample used by the global stage and the multi-start LM.
    pub n_sub: usize,
    /// Starts that run LM.
    pub n_best: usize,
    /// Iteration cap of each LM run.
    pub max_iters: u64,
    /// Far-field options (default: tolerance mode 1e-4 from the paper's 8 / 5 initial
    /// segments).
    pub far: FarOptions,
    /// User start (file units); always among the LM starts.
    pub init: Option<Vec<f64>>,
    /// The model fitted and its fixed parameters (file units).
    pub layout: ParamLayout,
    /// Weight residuals by the relative standard error `sigma/value` (every sample needs
    /// one; [`channel_data`](super::channel_data) refuses otherwise).
    pub weighted: bool,
    /// Relative cost change that ends the final LM run when `step_se` is `None` (Ceres'
    /// `function_tolerance` 1e-6).
    pub ftol: f64,
    /// The final LM run ends when its Gauss-Newton step moves no parameter the data
    /// determines by more than this many standard errors (default [`STEP_SE`]: refits
    /// from other starts or after rounding-level changes then agree to a fraction of a
    /// standard error; the relative-cost test stopped up to ~1.5 standard errors short on
    /// flat valleys). See [`lm`](super::lm).
    pub step_se: Option<f64>,
    /// Broyden updates of the Jacobian after accepted LM steps ([`lm`](super::lm); a run still only
    /// stops on a finite-difference Jacobian).
    pub broyden: bool,
    /// Free parameters to give a profile-likelihood interval ([`likelihood`]; up to eight
    /// re-solves each, after the fit).
    pub profile: Vec<Param>,
    /// Relative floor of the data used ([`channel_data`](super::channel_data), [`DEFAULT_FLOOR`]).
    pub floor: f64,
    /// Try the model's nested reduction first ([`super::nested`]; the fur model: `kappa =
    /// 0`) and fit the full model only when it lowers the cost by more than noise.
    pub nested: bool,
    /// Starts (file units) that run LM in addition to the best scored ones, as `init`
    /// does, but not recorded as the user's (the nested stage hands its probe's best on).
    pub extra_starts: Vec<Vec<f64>>,
    /// Subsample costs of the model's presets and Halton design in this layout, where
    /// already scored (the nested stage scores both layouts before choosing one; NaN
    /// where not); the global stage then does not score them again.
    pub design_costs: Option<std::sync::Arc<Vec<f64>>>,
    /// Set from another thread, ends the fit with [`Error::Interrupted`] within about one
    /// model evaluation (the default token is never set: the binary ends on a signal).
    pub cancel: Cancel,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            seed: 0,
            n_global: 128,
            n_sub: 1500,
            n_best: 4,
            max_iters: 100,
            far: FarOptions::default(),
            init: None,
            layout: ParamLayout::all_free(crate::models::default_model()),
            weighted: false,
            ftol: 1e-6,
            step_se: Some(STEP_SE),
            broyden: true,
            profile: Vec::new(),
            floor: DEFAULT_FLOOR,
            nested: true,
            extra_starts: Vec::new(),
            design_costs: None,
            cancel: Cancel::default(),
        }
    }
}

impl FitOptions {
    /// The default options for fitting `model`.
    pub fn for_model(model: &'static dyn FiberModel) -> FitOptions {
        FitOptions {
            layout: ParamLayout::all_free(model),
            n_best: model.lm_starts(),
            ..FitOptions::default()
        }
    }

    /// The model fitted.
    pub fn model(&self) -> &'static dyn FiberModel {
        self.layout.model
    }

    /// The parameter `key` of the model fitted, or an error listing the model's.
    pub fn param(&self, key: &str) -> Result<Param> {
        let model = self.model();
        Param::by_name(model, key).ok_or_else(|| Error::Param {
            key: key.into(),
            msg: format!(
                "unknown parameter of model {} (expected one of: {})",
                model.name(),
                model
                    .specs()
                    .iter()
                    .map(|s| s.name)
                    .collect::<Vec<_>>()
                    .join(", ")
            ),
        })
    }

    /// Fix parameter `key` at `value` (file units), checked against its hard bound.
    pub fn fix(&mut self, key: &str, value: f64) -> Result<()> {
        let id = self.param(key)?;
        if !id.spec().contains(value) {
            return Err(Error::Param {
                key: key.into(),
                msg: format!(
                    "--fix value {} is outside its hard bound {}",
                    Num(value),
                    id.spec().bound_with_unit()
                ),
            });
        }
        // An angle is held in radians: 5e-324 deg becomes 0, which the model would floor
        // (`MIN_WIDTH`) but the fit's result check refuses after the whole fit. Elsewhere
        // (`--params`, `--init`) such a width is floored with a note.
        let held = id.spec().to_file(id.spec().to_internal(value));
        if !id.spec().contains(held) {
            return Err(Error::Param {
                key: key.into(),
                msg: format!(
                    "--fix value {} becomes {} in radians and back, outside its hard bound {}",
                    Num(value),
                    Num(held),
                    id.spec().bound_with_unit()
                ),
            });
        }
        if let Some(old) = self.layout.fixed[id.index()] {
            return Err(Error::Param {
                key: key.into(),
                msg: format!(
                    "fixed twice (--fix {key}={} and {key}={})",
                    Num(old),
                    Num(value)
                ),
            });
        }
        // -0 is 0 (a fit file showed `"kappa": -0.0`).
        self.layout.fixed[id.index()] = Some(value + 0.0);
        Ok(())
    }
}

/// One entry of the convergence trace.
#[derive(Clone, Debug, PartialEq)]
pub struct TraceEntry {
    /// `global` (best start after the global stage), `subsample` (LM on the subsample) or
    /// `full` (LM on all samples).
    pub stage: &'static str,
    /// Cumulative LM iteration.
    pub iter: u64,
    /// Seconds since the fit started (wall clock).
    pub time_s: f64,
    /// Root mean square of the residuals at that point (= NRMSE when unweighted) on the
    /// stage's data.
    pub nrmse: f64,
}

/// The result of fitting one channel.
#[derive(Clone, Debug)]
pub struct FitOutcome {
    /// The fitted parameters.
    pub params: ModelParams,
    /// Exposure `k` of the solve (weighted when `weighted`).
    pub exposure: f64,
    /// MODEL.md NRMSE (unit weights, its own optimal exposure) on the samples used.
    pub nrmse: f64,
    /// The exposure that NRMSE is taken at: `exposure` itself for an unweighted fit, the
    /// unweighted optimum for a weighted one (whose `exposure` minimises the weighted cost).
    pub nrmse_exposure: f64,
    /// Standard errors, flags and correlations at the optimum.
    pub uncertainty: Uncertainty,
    /// LM iterations of the final solve.
    pub iterations: u64,
    /// Model evaluations of the solve.
    pub evaluations: u64,
    /// Analytic Jacobians of the solve ([`crate::models::ModelTerms::jacobian`]; 0 for a
    /// model differentiated by finite differences, whose columns are in `evaluations`).
    pub jacobians: u64,
    /// How the Jacobians were taken: `analytic` or `finite differences`.
    pub jacobian: &'static str,
    /// Model evaluations x samples (for throughput figures).
    pub sample_evaluations: u64,
    /// Estimated seconds inside the model: evaluations x the wall time of one evaluation
    /// measured alone after the solve (fastest of three), a finite-difference column
    /// counted at the mean column cost of the final Jacobian (most recompute only the
    /// terms their parameter changes), an analytic Jacobian at the final one's cost.
    /// Summed over evaluations that may run side by side
    /// on several threads, so it can exceed the wall time (`model_time_share` > 1).
    pub model_time_s: f64,
    /// Starting points scored in the global stage.
    pub starts_global: usize,
    /// Starts that ran the multi-start LM.
    pub starts_lm: usize,
    /// Wall seconds of the fit (the profile intervals aside).
    pub wall_time_s: f64,
    /// Why the final LM run stopped (argmin's termination status).
    pub termination: String,
    /// Convergence trace of every stage.
    pub trace: Vec<TraceEntry>,
    /// Samples the fit used (valid, at or above the floor).
    pub n_used: usize,
    /// `(capped, slices)` of the far field at the result
    /// ([`crate::models::ModelTerms::capped_slices`]): capped slices are not guaranteed
    /// to the tolerance.
    pub capped_slices: (usize, usize),
    /// Profile-likelihood intervals of [`FitOptions::profile`] (not part of the fit's
    /// timing: they take `profile_time_s` after it).
    pub profile: Vec<likelihood::Interval>,
    /// Wall seconds of the profile intervals.
    pub profile_time_s: f64,
    /// What the nested-model stage decided, when it ran ([`super::nested`]).
    pub nested: Option<NestedTest>,
    /// Profile re-solves the solver failed on (scored at their start, so an interval end
    /// beside them may lie too far out).
    pub profile_failed: usize,
}

/// Default [`FitOptions::floor`]: samples more than eight decades below the channel's
/// largest value are left out. No goniometer resolves them (detector dynamic ranges reach
/// ~1e6), while noise-free model profiles run down to 1e-44 and underflow in the Gaussian
/// tails of narrow lobes; in log space such tails outweigh the lobes and sent the round
/// trip of a `kappa = 0` profile to a degenerate optimum (absorption ~1e13), which it
/// leaves with them out (`tests/fit_recovery.rs`).
pub const DEFAULT_FLOOR: f64 = 1e-8;

/// What the nested-model stage decided, written to the fit file (`solver.nested`).
#[derive(Clone, Debug)]
pub struct NestedTest {
    /// The reduction tried ([`crate::models::Reduction::name`]).
    pub name: &'static str,
    /// Parameter indices the reduction holds, and their values (file units).
    pub held: Vec<(usize, f64)>,
    /// The reduced model was kept (the full model did not lower the cost by more than
    /// noise).
    pub kept_reduced: bool,
    /// What decided: the F-test, or the global stage when the reduced model was not
    /// worth fitting.
    pub decided_by: &'static str,
    /// Samples of the probe (the fit's subsample).
    pub n: usize,
    /// Parameters the full model adds (`q`).
    pub q: usize,
    /// Residual degrees of freedom of the full model on the probe's samples.
    pub dof: usize,
    /// The reduced model's cost `0.5 sum r^2` on the probe's samples.
    pub cost_reduced: f64,
    /// The best full-model cost the probe found.
    pub cost_full: f64,
    /// The F statistic.
    pub f: f64,
    /// `P(F_{q, dof} > f)`.
    pub p_value: f64,
    /// Model evaluations of the probe.
    pub evaluations: u64,
    /// Wall seconds of the probe.
    pub seconds: f64,
}

impl NestedTest {
    /// One line for the progress output.
    pub fn summary(&self) -> String {
        if self.f.is_nan() {
            return format!(
                "nested model {} not fitted: the best full-model start costs {:.3e} on the \
                 subsample, the best nested one {:.3e}",
                self.name, self.cost_full, self.cost_reduced
            );
        }
        format!(
            "nested model {}: F = {:.3} on ({}, {}) degrees of freedom, p = {:.2e}: {}",
            self.name,
            self.f,
            self.q,
            self.dof,
            self.p_value,
            if self.kept_reduced {
                "kept (the full model lowers the cost by no more than noise)"
            } else {
                "the full model lowers the cost: fitting it"
            }
        )
    }
}

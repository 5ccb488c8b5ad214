//! The fit file `fits/<species>.json` (DATA.md "Layout"): parameters in file units
//! (loadable by [`ModelParams::load`]; the `model` key names the model), exposure, NRMSE as a fraction, uncertainty,
//! correlation, solver statistics, data provenance and the convergence trace.
//!
//! Everything except the wall-clock fields (`solver.wall_time_s`, `solver.model_time_s`,
//! `solver.model_time_share`, `trace[].time_s`) is a deterministic function of the data,
//! the options and the seed.

use super::options::NestedTest;
use super::{FitOptions, FitOutcome};
use crate::models::{FiberModel, ModelParams, Param};
use serde_json::{json, Map, Value};

/// Provenance of the data one fit used.
#[derive(Clone, Debug, Default)]
pub struct DataInfo {
    /// Per file: the path as given, the SHA-256 of its bytes, the path relative to the fit
    /// file's folder (tells a refit of these files from a fit of others of the same
    /// relative name run elsewhere, [`super::job::check_replace_fit`]) and the SHA-256 of
    /// its samples ([`crate::profile::samples_sha256`]).
    pub files: Vec<(String, String, String, String)>,
    /// Valid samples of the channel (finite, > 0).
    pub n_valid: usize,
    /// Invalid samples (kept in the profile, never fitted).
    pub n_invalid: usize,
    /// Valid samples left out below the relative floor (`FitOptions::floor`).
    pub n_below_floor: usize,
    /// Whether the data are labelled synthetic.
    pub synthetic: bool,
    /// Channel name (empty for a single unnamed channel).
    pub channel: String,
    /// Loader options the data was read with ([`super::job::load_options_json`]).
    pub load: Value,
    /// The loaders' notes on the data (collapsed duplicates, a radians warning ...).
    pub notes: Vec<String>,
}

/// Units of the model's keys, in file units.
pub fn units_json(model: &'static dyn FiberModel) -> Value {
    let mut m = Map::new();
    for id in Param::all(model) {
        m.insert(id.spec().name.into(), Value::from(id.spec().unit));
    }
    Value::Object(m)
}

fn num(x: f64) -> Value {
    if x.is_finite() {
        Value::from(x)
    } else {
        Value::Null
    }
}

/// What `uncertainty.robust` says of its method.
pub const ROBUST_METHOD: &str = "per-parameter diagonal of the sandwich H^+ Omega H^+ (H = J^T J with the same held parameters): each row of samples sharing (theta_i, theta_r) adds its score J^T r whole, so residuals may be correlated along phi, and rows of one theta_i up to `bandwidth` steps apart in theta_r add their Bartlett-weighted cross products (Newey-West, lags per parameter by Andrews' AR(1) plug-in rule), times G/(G-1) for G rows; rows of different theta_i, and rows far apart in theta_r, are still taken as independent; still linearised, and model error is a bias no standard error covers";

/// `uncertainty.robust` of a fit file: the sweep-correlation-robust standard errors, or
/// null with too few rows.
fn robust_json(model: &'static dyn FiberModel, rb: Option<&super::uncertainty::Robust>) -> Value {
    let Some(rb) = rb else {
        return Value::Null;
    };
    let se: Map<String, Value> = Param::all(model)
        .map(|id| {
            let v = rb.se[id.index()].map(num).unwrap_or(Value::Null);
            (id.spec().name.to_string(), v)
        })
        .collect();
    json!({
        "standard_error": se,
        "rows": rb.rows,
        "bandwidth": Param::all(model)
            .map(|id| (id.spec().name.to_string(), json!(rb.bandwidth[id.index()])))
            .collect::<Map<String, Value>>(),
        "phi_lag1_autocorrelation": num(rb.phi_lag1),
        // Not flagged unconstrained (the flags follow the independent-residual errors), yet
        // their robust error spans most of their range.
        "spans_most_of_range": rb.spans_most.iter().map(|id| id.spec().name).collect::<Vec<_>>(),
        "method": ROBUST_METHOD,
    })
}

/// `solver.nested` of a fit file.
fn nested_json(model: &dyn FiberModel, t: &NestedTest) -> Value {
    let held: Map<String, Value> = t
        .held
        .iter()
        .map(|&(i, v)| (model.specs()[i].name.to_string(), json!(v)))
        .collect();
    json!({
        "model": t.name,
        "held": held,
        "kept": t.kept_reduced,
        "decided_by": t.decided_by,
        "test": "F-test of nested least-squares models on the subsample",
        "samples": t.n,
        "added_parameters": t.q,
        "dof": t.dof,
        "cost_nested": num(t.cost_reduced),
        "cost_full": num(t.cost_full),
        "f": num(t.f),
        "p_value": num(t.p_value),
        "alpha": crate::fit::nested::ALPHA,
        // Its time is in `wall_time_s`; the record stays deterministic for a seed.
        "evaluations": t.evaluations,
    })
}

/// The JSON object of one channel's fit.
pub fn fit_json(out: &FitOutcome, opts: &FitOptions, data: &DataInfo) -> Value {
    let unc = &out.uncertainty;
    let model = opts.model();
    let mut se = Map::new();
    for id in Param::all(model) {
        se.insert(
            id.spec().name.into(),
            unc.se[id.index()].map(num).unwrap_or(Value::Null),
        );
    }
    // A kept nested model holds its parameters as `--fix` would.
    let held = |i: usize| {
        out.nested
            .as_ref()
            .is_some_and(|t| t.kept_reduced && t.held.iter().any(|&(k, _)| k == i))
    };
    let fixed: Vec<&str> = Param::all(model)
        .filter(|id| opts.layout.fixed[id.index()].is_some() || held(id.index()))
        .map(|id| id.spec().name)
        .collect();
    let unconstrained: Vec<Value> = unc
        .unconstrained
        .iter()
        .map(|(id, why)| json!({"key": id.spec().name, "reason": why.as_str()}))
        .collect();
    let keys: Vec<&str> = unc.free.iter().map(|id| id.spec().name).collect();
    let matrix: Vec<Vec<Value>> = (0..unc.correlation.nrows())
        .map(|i| {
            (0..unc.correlation.ncols())
                .map(|j| num(unc.correlation[(i, j)]))
                .collect()
        })
        .collect();
    let trace: Vec<Value> = out
        .trace
        .iter()
        .map(|t| json!({"stage": t.stage, "iter": t.iter, "time_s": t.time_s, "nrmse": t.nrmse}))
        .collect();
    let files: Vec<Value> = data
        .files
        .iter()
        .map(|(p, h, rel, s)| json!({"path": p, "sha256": h, "from_fit": rel, "samples_sha256": s}))
        .collect();
    json!({
        "model": model.name(),
        "params": out.params.to_json_value(),
        "units": units_json(model),
        "exposure": out.exposure,
        "nrmse": out.nrmse,
        // The exposure the NRMSE is taken at (MODEL.md: its own optimum, unweighted): equal
        // to `exposure` unless the fit is weighted.
        "nrmse_exposure": out.nrmse_exposure,
        "uncertainty": {
            "standard_error": se,
            "unconstrained": unconstrained,
            "fixed": fixed,
            "method": "linearised: s^2 (J^T J)^+ (pseudo-inverse) in the solver's bounded-map coordinates, mapped to file units by the map's derivative; s^2 = RSS / (n - p - 1) assumes independent residuals, so structured misfit (a model that is not the data's physics) makes these errors too small; --profile gives re-solved intervals",
            "at_bound": unc.at_bound().iter().map(|id| id.spec().name).collect::<Vec<_>>(),
            // Held at their value by the linearisation (on a bound or a singular
            // direction): every standard error above is conditional on them, and far too
            // small if the data favour other values of them.
            "conditional_on": unc.held().iter().map(|id| id.spec().name).collect::<Vec<_>>(),
            "robust": robust_json(model, unc.robust.as_ref()),
            "profile": (!out.profile.is_empty())
                .then(|| {
                    let mut v = crate::fit::likelihood::to_json(&out.profile, out.profile_time_s);
                    v["failed_resolves"] = serde_json::json!(out.profile_failed);
                    v
                }),
        },
        // In the solver's coordinates u (log space for the exp-mapped absorptions and
        // sigma_m_s), where the linearisation is made.
        "correlation": {"keys": keys, "matrix": matrix, "coordinates": "solver (u)"},
        "solver": {
            "name": "Levenberg-Marquardt (argmin), multi-start",
            "iterations": out.iterations,
            "evaluations": out.evaluations,
            // Analytic Jacobians (not in `evaluations`), or "finite differences", whose
            // columns are.
            "jacobian": out.jacobian,
            "jacobians": out.jacobians,
            "sample_evaluations": out.sample_evaluations,
            "starts": {"global": out.starts_global, "lm": out.starts_lm, "subsample": opts.n_sub},
            "max_iters": opts.max_iters,
            // The --init start (file units), so the fit can be reproduced.
            "init": opts.init.as_ref().map(|v| {
                Param::all(model)
                    .map(|id| (id.spec().name.to_string(), serde_json::json!(v[id.index()])))
                    .collect::<serde_json::Map<_, _>>()
            }),
            // The far field fitted: initial segments, and the tolerance (null: the fixed
            // segmentation) with its scattered step.
            "segments": {"unscattered": opts.far.n_unscattered, "scattered": opts.far.n_scattered},
            "tol": opts.far.tol,
            "scattered_step": opts.far.scattered_step,
            // theta_d slices of the final evaluation whose refinement hit its limit (their
            // model values are not guaranteed to `tol`).
            "capped_slices": {"capped": out.capped_slices.0, "slices": out.capped_slices.1},
            // How the model read the result (`FiberModel::notes`; the key keeps its first
            // name): for the fur model, where it leaves the medulla tables' (tau, g)
            // range, so the scattered lobes were evaluated with the shape at the nearest
            // table edge, and a roughness below the model's floor.
            "table_notes": model.notes(&out.params.values),
            "weighted": opts.weighted,
            "wall_time_s": out.wall_time_s,
            "model_time_s": out.model_time_s,
            // Estimated model seconds (`FitOutcome::model_time_s`, summed over evaluations
            // that ran side by side) per wall second: above 1 on several cores.
            "model_time_share": out.model_time_s / out.wall_time_s.max(1e-12),
            "termination": out.termination,
            // The local optimum's distance from the result in standard errors (converged:
            // below the solver's 0.1).
            "gauss_newton_step_se": num(unc.step_se),
            // The nested model tried first and the F-test that kept it or not
            // (`fit::nested`); null when it was not tried.
            "nested": out.nested.as_ref().map(|t| nested_json(model, t)),
        },
        "data": {
            "files": files,
            "n_valid": data.n_valid,
            "n_invalid": data.n_invalid,
            "floor": opts.floor,
            "n_below_floor": data.n_below_floor,
            "n_used": out.n_used,
            "synthetic": data.synthetic,
            "channel": data.channel,
            "load": data.load,
            "notes": data.notes,
        },
        "tool_version": crate::TOOL_VERSION,
        "seed": opts.seed,
        "trace": trace,
    })
}

/// Read back the parameters and exposure of a fit file value (same rules as
/// [`ModelParams::from_json_value`]).
pub fn params_of(v: &Value) -> crate::Result<(ModelParams, f64)> {
    ModelParams::from_json_value(v, None)
}

//! The model interface itself ([`FiberModel`], [`ModelTerms`]) and its plain types:
//! presets, predictions, the `h` integral, parameter handles and the solver's bounded maps.
//! See [`super`]'s module doc for what every model predicts. Below the models' rooms and
//! the registry: it names no model.

use super::bsdf::NearBsdf;
use super::points::Points;
use crate::model::far::FarOptions;
use crate::model::{LobeSet, LobeValues};
use crate::params::ParamSpec;

/// A named parameter set of a model (file units, in [`FiberModel::specs`] order).
#[derive(Clone, Copy, Debug)]
pub struct Preset {
    /// The preset's name, as `--params` accepts it (`red-fox`, `blond`).
    pub name: &'static str,
    /// Parameter values in file units, in [`FiberModel::specs`] order.
    pub values: &'static [f64],
}

/// What [`FiberModel::predict`] returns: per-lobe values (no exposure) at every point, and
/// `(capped, slices)`: how many of the model's slices could not be refined to the
/// tolerance (their values are not guaranteed to it), of how many.
#[derive(Clone, Debug, Default)]
pub struct Prediction {
    /// Per-lobe values (no exposure) at every point, in point order.
    pub lobes: Vec<LobeValues>,
    /// `(capped, slices)`: slices whose refinement hit its limit, of all the model's
    /// slices.
    pub capped: (usize, usize),
}

/// Which integral over `h` a prediction uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Integral {
    /// The model's own far field (fast; the tolerance contract of [`FarOptions::tol`]).
    Far,
    /// The near field integrated over `h` by adaptive quadrature (~1e-10 relative; slow):
    /// the reference the far field is tested against.
    NearQuadrature,
}

impl std::fmt::Debug for dyn FiberModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl Integral {
    /// The integral's name, as [`Integral::parse`] reads it and profiles record it.
    pub fn name(self) -> &'static str {
        match self {
            Integral::Far => "far",
            Integral::NearQuadrature => "near-quadrature",
        }
    }

    /// Parse `far` or `near-quadrature`.
    pub fn parse(s: &str) -> crate::Result<Integral> {
        match s.trim().to_ascii_lowercase().as_str() {
            "far" => Ok(Integral::Far),
            "near-quadrature" | "near_quadrature" | "quadrature" => Ok(Integral::NearQuadrature),
            other => Err(crate::Error::Invalid(format!(
                "unknown integral '{other}' (expected far or near-quadrature)"
            ))),
        }
    }
}

/// One parameter of one model: what the fitter, the reports and the uncertainty hold
/// instead of a model's own parameter names.
#[derive(Clone, Copy)]
pub struct Param {
    /// The model the parameter belongs to.
    pub model: &'static dyn FiberModel,
    /// Position in the model's parameter vector.
    pub index: usize,
}

impl Param {
    /// The parameters of `model`, in vector order.
    pub fn all(model: &'static dyn FiberModel) -> impl Iterator<Item = Param> {
        (0..model.specs().len()).map(move |index| Param { model, index })
    }

    /// The parameter named `name` of `model`.
    pub fn by_name(model: &'static dyn FiberModel, name: &str) -> Option<Param> {
        Param::all(model).find(|p| p.spec().name == name)
    }

    /// Position in the model's parameter vector.
    pub fn index(self) -> usize {
        self.index
    }

    /// Name, unit and hard bounds.
    pub fn spec(self) -> &'static ParamSpec {
        &self.model.specs()[self.index]
    }

    /// The file key (`eta`, `beta_m`, ...).
    pub fn name(self) -> &'static str {
        self.spec().name
    }

    /// The solver's bounded map.
    pub fn map(self) -> Map {
        self.model.map(self.index)
    }
}

impl PartialEq for Param {
    fn eq(&self, o: &Self) -> bool {
        self.index == o.index && self.model.name() == o.model.name()
    }
}

impl Eq for Param {}

impl std::fmt::Debug for Param {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A nested model inside a [`FiberModel`] ([`FiberModel::reduction`]): the parameters
/// held and their values (file units). It must be the full model at those values, so
/// that the fitter's test of one against the other is a test of nested models.
#[derive(Debug)]
pub struct Reduction {
    /// What the nested model is, for messages and fit files (`kappa = 0 (no medulla)`).
    pub name: &'static str,
    /// `(parameter index, value in file units)`: the first is the one that switches the
    /// extra lobes off; the others are inert there and held at any in-bound value.
    pub fixed: &'static [(usize, f64)],
}

/// One fiber scattering model (see the module doc). Object safe: the generic code holds
/// `&'static dyn FiberModel`.
pub trait FiberModel: Send + Sync + 'static {
    /// Registry name (`yan2017`, `marschner2003`, `chiang2016`), as `--model` and fit
    /// files spell it.
    fn name(&self) -> &'static str;

    /// One line for humans: authors, year, lobes.
    fn title(&self) -> &'static str;

    /// Name, unit, hard bounds (file units) of each parameter, in vector order.
    fn specs(&self) -> &'static [ParamSpec];

    /// The lobes' names, at most five, in [`LobeValues`] slot order.
    fn lobe_names(&self) -> &'static [&'static str];

    /// Parse a `--lobes` list of this model's lobe names (case-insensitive, each at most
    /// once) or `all`.
    fn parse_lobes(&self, s: &str) -> crate::Result<LobeSet> {
        parse_lobes(self.lobe_names(), s)
    }

    /// The solver's smooth bounded map of parameter `i` (file units).
    fn map(&self, i: usize) -> Map;

    /// The box the fitter's global stage samples for parameter `i`: `(lo, hi, log_scale)`
    /// in file units (plausible values, inside the hard bounds).
    fn plausible_box(&self, i: usize) -> (f64, f64, bool);

    /// Named parameter sets: starts of the fitter's global stage, and names `--params`
    /// accepts for this model.
    fn presets(&self) -> &'static [Preset];

    /// Checks across parameters beyond each one's hard bound (internal units; called
    /// after those). Errors name the model and the parameter.
    fn check(&self, _p: &[f64]) -> crate::Result<()> {
        Ok(())
    }

    /// Notes on how the model reads these parameters (internal units): tables left,
    /// widths floored. `synth` and `render` print them, fits record them.
    fn notes(&self, _p: &[f64]) -> Vec<String> {
        Vec::new()
    }

    /// The coordinate of a `(theta_i, theta_r)` pair that the model's far-field set-up is
    /// shared along (the fur model's slices are per `theta_d`): the fitter's subsample
    /// keeps whole slices of it, so a subsample is cheap to evaluate.
    fn slice_of(&self, theta_i: f64, theta_r: f64) -> f64 {
        crate::model::geometry::theta_d(theta_i, theta_r)
    }

    /// Free parameters these values (file units) leave without any effect, and why (the
    /// fur model: the medulla's parameters when `kappa` is ~0). The fitter flags them
    /// unconstrained whatever their standard errors say.
    fn inert(&self, _file: &[f64]) -> (Vec<usize>, &'static str) {
        (Vec::new(), "")
    }

    /// A simpler model nested in this one that the fitter tries first
    /// ([`crate::fit::nested`]): some parameters held at values where others go inert (the
    /// fur model: `kappa = 0`, no medulla). `None` (the default): no such model.
    fn reduction(&self) -> Option<&'static Reduction> {
        None
    }

    /// Starts that run Levenberg-Marquardt by default ([`crate::fit::FitOptions::n_best`]):
    /// 4, more for a model whose cost has many basins.
    fn lm_starts(&self) -> usize {
        4
    }

    /// Does [`FarOptions::tol`] change this model's far field (adaptive refinement)? The
    /// fitter's coarse screens ([`crate::fit`]) are pointless for a model that ignores it.
    fn refines(&self) -> bool {
        false
    }

    /// The lobes that can be non-zero for these parameters (internal units).
    fn active_lobes(&self, _p: &[f64]) -> LobeSet {
        LobeSet((1u8 << self.lobe_names().len()) - 1)
    }

    /// Per-lobe prediction (no exposure) of the lobes in `lobes` at every point of
    /// `points` (others 0). `p` is in internal units and within the hard bounds.
    /// The model exploits the grid's structure (cached in `points`).
    fn predict(
        &self,
        p: &[f64],
        points: &Points,
        far: &FarOptions,
        lobes: LobeSet,
        integral: Integral,
    ) -> Prediction;

    /// The terms of the far-field prediction of all lobes at `p`, kept so that the
    /// fitter's finite-difference columns recompute only what a parameter changes.
    fn terms(&self, p: &[f64], points: &Points, far: &FarOptions) -> Box<dyn ModelTerms>;

    /// The near field as a path tracer's BCSDF ([`NearBsdf`]) for the parameters of the
    /// r, g and b channels (internal units, each within the hard bounds), or `None` when
    /// the model has none: `furfit render` then refuses it, naming the model. (The fur
    /// model's renderer is [`crate::render::bsdf`], with its far field and multi-scale.)
    fn render_bsdf(&self, _rgb: [&[f64]; 3]) -> Option<Box<dyn NearBsdf>> {
        None
    }
}

/// A model's far-field prediction at one parameter set, kept by the fitter
/// ([`FiberModel::terms`]).
pub trait ModelTerms: Send + Sync {
    /// Model value (no exposure, lobes summed) at every point, into `out`.
    fn values(&self, points: &Points, out: &mut [f64]);

    /// The terms at `p`, which differs from these terms' parameters only in parameter
    /// `changed` (a finite-difference step). A model may reuse what `changed` cannot reach
    /// and replay its refinement decisions, so the terms are a smooth function of the step.
    fn with_change(
        &self,
        p: &[f64],
        changed: usize,
        points: &Points,
        far: &FarOptions,
    ) -> Box<dyn ModelTerms>;

    /// `(capped, slices)` as in [`Prediction::capped`].
    fn capped_slices(&self) -> (usize, usize);

    /// The model values at these terms' parameters and their derivatives with respect to
    /// every parameter (internal units), computed analytically (forward-mode derivatives,
    /// [`super::dual`]); `None` (the default) when the model does not provide them, and the
    /// fitter differentiates by finite differences ([`ModelTerms::with_change`]).
    fn jacobian(&self, _points: &Points) -> Option<ValueJacobian> {
        None
    }
}

/// What [`ModelTerms::jacobian`] returns: the values (as [`ModelTerms::values`]) and the
/// derivatives `d[i * n_params + k] = d value_i / d p_k`, `p` in internal units.
#[derive(Clone, Debug)]
pub struct ValueJacobian {
    /// Model values at every point, as [`ModelTerms::values`] gives them.
    pub values: Vec<f64>,
    /// Number of parameters: the row length of `d`.
    pub n_params: usize,
    /// Row-major derivatives, `d[i * n_params + k] = d value_i / d p_k`.
    pub d: Vec<f64>,
}

/// [`ModelTerms`] that keep only the values: every change recomputes them in full.
pub struct PlainTerms {
    /// The model whose far field the values are, which recomputes them on a change.
    pub model: &'static dyn FiberModel,
    /// Far-field values (no exposure, lobes summed) at every point.
    pub values: Vec<f64>,
    /// `(capped, slices)` of the prediction, as in [`Prediction::capped`].
    pub capped: (usize, usize),
}

impl PlainTerms {
    /// The far-field values of all lobes of `model` at `p`.
    pub fn new(
        model: &'static dyn FiberModel,
        p: &[f64],
        points: &Points,
        far: &FarOptions,
    ) -> PlainTerms {
        let pred = model.predict(p, points, far, LobeSet::ALL, Integral::Far);
        PlainTerms {
            model,
            values: pred.lobes.iter().map(|l| l.sum()).collect(),
            capped: pred.capped,
        }
    }
}

impl ModelTerms for PlainTerms {
    fn values(&self, _points: &Points, out: &mut [f64]) {
        out.copy_from_slice(&self.values);
    }

    fn with_change(
        &self,
        p: &[f64],
        _changed: usize,
        points: &Points,
        far: &FarOptions,
    ) -> Box<dyn ModelTerms> {
        Box::new(PlainTerms::new(self.model, p, points, far))
    }

    fn capped_slices(&self) -> (usize, usize) {
        self.capped
    }
}

/// Parse `s`, a comma list of the names in `names` (case-insensitive, each at most once)
/// or `all`, into the set of their slots.
pub fn parse_lobes(names: &[&str], s: &str) -> crate::Result<LobeSet> {
    let all = LobeSet((1u8 << names.len()) - 1);
    if s.trim().eq_ignore_ascii_case("all") {
        return Ok(all);
    }
    let mut set = LobeSet::NONE;
    for part in s.split(',') {
        if part.trim().eq_ignore_ascii_case("all") {
            return Err(crate::Error::Invalid(format!(
                "lobes '{s}': 'all' stands alone (it already includes every lobe)"
            )));
        }
        let i = names
            .iter()
            .position(|n| n.eq_ignore_ascii_case(part.trim()))
            .ok_or_else(|| {
                crate::Error::Invalid(format!(
                    "unknown lobe '{}' (expected {} or all)",
                    part.trim(),
                    names.join(", ")
                ))
            })?;
        // Refused like a repeated --modes entry: a repeat is most likely a typo for
        // another lobe.
        if set.0 & (1 << i) != 0 {
            return Err(crate::Error::Invalid(format!(
                "lobes '{s}': {} given twice",
                names[i]
            )));
        }
        set = LobeSet(set.0 | (1 << i));
    }
    Ok(set)
}

/// Clamp of the solver coordinate for sigmoid and exp maps (sigmoid(30) = 1 - 9.4e-14:
/// representable below 1).
pub const U_MAX: f64 = 30.0;
/// Clamp for tanh maps: tanh(30) rounds to exactly 1.0 in f64, tanh(17) = 1 - 3.4e-15 does not.
pub const U_MAX_TANH: f64 = 17.0;

/// The shape of one parameter's smooth bounded map from the solver's unbounded coordinate
/// `u` to its value (file units); see [`crate::fit::reparam`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Map {
    /// `lo + span * sigmoid(u)`.
    Sigmoid {
        /// The lower bound (file units).
        lo: f64,
        /// The width of the range: the upper bound is `lo + span`.
        span: f64,
    },
    /// `scale * tanh(u)`.
    Tanh {
        /// The half-width of the symmetric range `(-scale, scale)`.
        scale: f64,
    },
    /// `exp(u)`.
    Exp,
}

impl Map {
    /// `u` clamped so that rounding can never land on an open bound.
    pub fn clamp_u(self, u: f64) -> f64 {
        let m = match self {
            Map::Tanh { .. } => U_MAX_TANH,
            _ => U_MAX,
        };
        u.clamp(-m, m)
    }

    /// The value (file units) at `u`.
    pub fn to_value(self, u: f64) -> f64 {
        let u = self.clamp_u(u);
        match self {
            Map::Sigmoid { lo, span } => lo + span * sigmoid(u),
            Map::Tanh { scale } => scale * u.tanh(),
            Map::Exp => u.exp(),
        }
    }

    /// `d value / d u` at `u`; 0 beyond the clamp.
    pub fn derivative(self, u: f64) -> f64 {
        if self.clamp_u(u) != u {
            return 0.0;
        }
        match self {
            Map::Sigmoid { span, .. } => {
                let s = sigmoid(u);
                span * s * (1.0 - s)
            }
            Map::Tanh { scale } => {
                let t = u.tanh();
                scale * (1.0 - t * t)
            }
            Map::Exp => u.exp(),
        }
    }

    /// The coordinate of value `v`; a value on or beyond a bound maps to the clamp.
    pub fn to_u(self, v: f64) -> f64 {
        let u = match self {
            // Clamped first: a value beyond the range maps to the clamp, not to NaN (-> 0).
            Map::Sigmoid { lo, span } => logit(((v - lo) / span).clamp(0.0, 1.0)),
            Map::Tanh { scale } => (v / scale).clamp(-1.0, 1.0).atanh(),
            Map::Exp => v.ln(),
        };
        if u.is_nan() {
            0.0
        } else {
            self.clamp_u(u)
        }
    }
}

fn sigmoid(u: f64) -> f64 {
    1.0 / (1.0 + (-u).exp())
}

fn logit(y: f64) -> f64 {
    (y / (1.0 - y)).ln()
}

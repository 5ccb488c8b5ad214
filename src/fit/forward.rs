//! The forward model the fitter evaluates: the far-field value `sum_p M_p N_p` (MODEL.md
//! "What a goniometer sample predicts", before the exposure `k`) at a list of goniometer
//! points.
//!
//! Every model evaluation goes through the model interface ([`crate::models`]): the
//! fitter's terms are [`crate::models::FiberModel::terms`], and these helpers call the
//! same predictions (for the fur model the grid prediction of [`crate::synth::GridPlan`],
//! the model `furfit synth` writes), so the fitter never re-implements any physics.

use crate::model::far::FarOptions;
use crate::model::{FurModel, LobeSet, LobeValues};
use crate::models::{Integral, ModelParams};
use crate::params::FurParams;
use crate::synth::ModelKind;

pub use crate::models::Points;

/// Model value (no exposure) of the lobes in `lobes` at every point, written into `out`
/// (`out.len() == points.len()`): the far field of [`crate::synth::predict`], summed over
/// lobes. `params` must be within the hard bounds.
pub fn predict_points(
    params: &FurParams,
    points: &Points,
    far: &FarOptions,
    lobes: LobeSet,
    out: &mut [f64],
) {
    debug_assert_eq!(out.len(), points.len());
    let model = FurModel::new(params);
    let v = points.plan().predict(&model, lobes, ModelKind::Far, far);
    for (o, l) in out.iter_mut().zip(&v) {
        *o = l.sum();
    }
}

/// Model value (no exposure) of any model's parameters at every point, written into
/// `out`: [`crate::models::FiberModel::predict`] summed over lobes.
pub fn predict_model(params: &ModelParams, points: &Points, far: &FarOptions, out: &mut [f64]) {
    debug_assert_eq!(out.len(), points.len());
    let pred = params
        .model
        .predict(&params.values, points, far, LobeSet::ALL, Integral::Far);
    for (o, l) in out.iter_mut().zip(&pred.lobes) {
        *o = l.sum();
    }
}

/// Per-lobe model values (no exposure) at every point (for per-lobe plots).
pub fn predict_lobes(params: &FurParams, points: &Points, far: &FarOptions) -> Vec<LobeValues> {
    let model = FurModel::new(params);
    points
        .plan()
        .predict(&model, LobeSet::ALL, ModelKind::Far, far)
}

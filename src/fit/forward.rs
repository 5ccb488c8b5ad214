//! The forward model the fitter evaluates: the far-field value `sum_p M_p N_p` (MODEL.md
//! "What a goniometer sample predicts", before the exposure `k`) at a list of goniometer
//! points.
//!
//! Every model evaluation of the fitter goes through this module: [`predict_points`] and
//! [`ModelTerms`] call the grid prediction of [`crate::synth::GridPlan`] (the model
//! `furfit synth` writes), so the fitter never re-implements any physics.

use crate::model::far::{Decisions, FarOptions};
use crate::model::{FurModel, LobeSet, LobeValues};
use crate::params::FurParams;
use crate::params::ParamId;
use crate::synth::{ModelKind, PairTerms};
use std::sync::Arc;

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

/// The two factors of the far-field prediction at one parameter set, all five lobes:
/// `N_p` per `(theta_d, phi)` and the longitudinal terms per theta pair
/// ([`GridPlan::azimuthal_terms`], [`GridPlan::longitudinal_terms`]).
#[derive(Clone, Debug)]
pub struct ModelTerms {
    n: Vec<Vec<LobeValues>>,
    m: Vec<PairTerms>,
    /// Each slice's far-field refinement decisions, replayed by [`Self::with_change`].
    decisions: Arc<Vec<Decisions>>,
}

impl ModelTerms {
    /// All terms at `params`.
    pub fn new(params: &FurParams, points: &Points, far: &FarOptions) -> ModelTerms {
        let model = FurModel::new(params);
        let plan = points.plan();
        let (n, decisions) = plan.far_terms_taped(&model, LobeSet::ALL, far, None);
        ModelTerms {
            n,
            m: plan.longitudinal_terms(&model, LobeSet::ALL),
            decisions: Arc::new(decisions),
        }
    }

    /// The terms at `params`, which differ from the parameters of `self` only in
    /// `changed` (a finite-difference step): the azimuthal terms that cannot depend on
    /// `changed` ([`FurModel::azimuthal_dependence`]) are reused, the rest recomputed with
    /// the far field's refinement decisions of `self` replayed ([`Decisions`]), so the
    /// terms are a smooth function of the step. Equal to [`ModelTerms::new`] at `params`
    /// unless the step tips a refinement decision (tested), at a fraction of the cost for
    /// `alpha`, `beta_m` and `g`.
    pub fn with_change(
        &self,
        params: &FurParams,
        changed: ParamId,
        points: &Points,
        far: &FarOptions,
    ) -> ModelTerms {
        self.with_lobes(params, FurModel::azimuthal_dependence(changed), points, far)
    }

    /// [`Self::with_change`] recomputing the azimuthal terms of the lobes in `dep` (with
    /// the decisions of `self` replayed) and reusing the others.
    pub fn with_lobes(
        &self,
        params: &FurParams,
        dep: LobeSet,
        points: &Points,
        far: &FarOptions,
    ) -> ModelTerms {
        let model = FurModel::new(params);
        let plan = points.plan();
        let mut n = self.n.clone();
        if dep != LobeSet::NONE {
            let (fresh, _) = plan.far_terms_taped(&model, dep, far, Some(&self.decisions));
            for (row, new_row) in n.iter_mut().zip(&fresh) {
                for (v, nv) in row.iter_mut().zip(new_row) {
                    for l in dep.iter() {
                        v.set(l, nv[l]);
                    }
                }
            }
        }
        ModelTerms {
            n,
            m: plan.longitudinal_terms(&model, LobeSet::ALL),
            decisions: self.decisions.clone(),
        }
    }

    /// `(capped, slices)`: how many of the far field's `theta_d` slices hit the
    /// tolerance-mode refinement limit in these terms' build
    /// ([`crate::synth::capped_slices`]), of how many.
    pub fn capped_slices(&self) -> (usize, usize) {
        (
            crate::synth::capped_slices(&self.decisions),
            self.decisions.len(),
        )
    }

    /// Model value (no exposure, lobes summed) at every point, into `out`.
    pub fn values(&self, points: &Points, out: &mut [f64]) {
        use rayon::prelude::*;
        debug_assert_eq!(out.len(), points.len());
        out.par_iter_mut()
            .zip(points.plan().combine(&self.n, &self.m))
            .for_each(|(o, l)| *o = l.sum());
    }
}

/// Per-lobe model values (no exposure) at every point (for per-lobe plots).
pub fn predict_lobes(params: &FurParams, points: &Points, far: &FarOptions) -> Vec<LobeValues> {
    let model = FurModel::new(params);
    points
        .plan()
        .predict(&model, LobeSet::ALL, ModelKind::Far, far)
}

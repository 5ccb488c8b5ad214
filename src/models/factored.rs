//! Far fields that factor over a [`SlicePlan`] (Chiang, Marschner): the [`Factored`]
//! trait a model implements, and the [`FactoredTerms`] the fitter keeps, with the
//! product-rule Jacobian.

use super::interface::{ModelTerms, ValueJacobian};
use super::points::{Points, SlicePlan};
use crate::model::far::FarOptions;
use crate::model::{LobeSet, LobeValues};
use std::marker::PhantomData;
use std::sync::Arc;

/// A far field that factors over a [`SlicePlan`]: `L` lobes, each the product of an
/// azimuthal term per `(slice, |phi|)` and a longitudinal term per pair (Chiang,
/// Marschner). [`FactoredTerms`] keeps both for the fitter.
pub trait Factored<const L: usize>: Sized + Send + Sync + 'static {
    /// The model at a parameter vector (internal units, validated).
    fn from_params(p: &[f64]) -> Self;
    /// Parameters that only the longitudinal terms read.
    const LONGITUDINAL: &'static [usize];
    /// The azimuthal term of every slice and `|phi|` of `plan`.
    fn azimuthal_terms(&self, plan: &SlicePlan) -> Vec<Vec<[f64; L]>>;
    /// The longitudinal term of every pair of `plan`.
    fn longitudinal_terms(&self, plan: &SlicePlan) -> Vec<[f64; L]>;

    /// The derivatives of [`Self::azimuthal_terms`] with respect to every parameter
    /// (internal units), per slice `phis.len() * n_params` entries, entry
    /// `phi * n_params + k` the derivative by parameter `k` (zero for one the terms do not
    /// read). `None` (the default): not provided, and the fitter differentiates by
    /// finite differences.
    fn azimuthal_gradients(&self, _plan: &SlicePlan) -> Option<Vec<Vec<[f64; L]>>> {
        None
    }

    /// The derivatives of [`Self::longitudinal_terms`] likewise: `pairs.len() * n_params`
    /// entries, `pair * n_params + k`.
    fn longitudinal_gradients(&self, _plan: &SlicePlan) -> Option<Vec<[f64; L]>> {
        None
    }

    /// Both factors at these parameters, as [`FactoredTerms`] keeps them.
    fn factors(&self, plan: &SlicePlan) -> Factors<L> {
        Factors {
            n: self.azimuthal_terms(plan),
            m: self.longitudinal_terms(plan),
        }
    }
}

/// The two factors of a [`Factored`] far field at one parameter set.
#[derive(Clone, Debug)]
pub struct Factors<const L: usize> {
    /// Azimuthal term per slice and `|phi|`, indexed `[slice][phi][lobe]`.
    pub n: Vec<Vec<[f64; L]>>,
    /// Longitudinal term per `(theta_i, theta_r)` pair, indexed `[pair][lobe]`.
    pub m: Vec<[f64; L]>,
}

impl<const L: usize> Factors<L> {
    /// Per-lobe values at every point of `plan`.
    pub fn lobes<'a>(&'a self, plan: &'a SlicePlan) -> impl Iterator<Item = [f64; L]> + 'a {
        plan.index.iter().map(move |&(s, f, pr)| {
            let n = &self.n[s as usize][f as usize];
            let m = &self.m[pr as usize];
            std::array::from_fn(|p| m[p] * n[p])
        })
    }

    /// Per-lobe values as [`LobeValues`], the lobes outside `set` zero.
    pub fn lobe_values<'a>(
        &'a self,
        plan: &'a SlicePlan,
        set: LobeSet,
    ) -> impl Iterator<Item = LobeValues> + 'a {
        self.lobes(plan).map(move |v| {
            let mut out = LobeValues::default();
            for (i, x) in v.into_iter().enumerate() {
                if set.0 & (1 << i) != 0 {
                    out.0[i] = x;
                }
            }
            out
        })
    }
}

/// [`ModelTerms`] of a [`Factored`] model: a step in one of its `LONGITUDINAL`
/// parameters recomputes only the longitudinal terms, any other only the azimuthal ones.
///
/// When the model provides both factors' gradients ([`Factored::azimuthal_gradients`],
/// [`Factored::longitudinal_gradients`]), [`ModelTerms::jacobian`] combines them by the
/// product rule: `d(sum_p M_p N_p) = sum_p (dM_p N_p + M_p dN_p)`.
pub struct FactoredTerms<M, const L: usize> {
    /// The point list's slice structure, which the factors index.
    pub plan: Arc<SlicePlan>,
    /// Both factors at the parameters the terms were computed at.
    pub factors: Factors<L>,
    /// The parameters (internal units) the factors were computed at.
    params: Vec<f64>,
    model: PhantomData<fn() -> M>,
}

impl<M: Factored<L>, const L: usize> FactoredTerms<M, L> {
    /// The terms of model `M` at `p` (internal units, validated) on `plan`.
    pub fn new(p: &[f64], plan: Arc<SlicePlan>) -> FactoredTerms<M, L> {
        let factors = M::from_params(p).factors(&plan);
        FactoredTerms {
            plan,
            factors,
            params: p.to_vec(),
            model: PhantomData,
        }
    }
}

impl<M: Factored<L>, const L: usize> ModelTerms for FactoredTerms<M, L> {
    fn values(&self, _points: &Points, out: &mut [f64]) {
        for (o, v) in out.iter_mut().zip(self.factors.lobes(&self.plan)) {
            *o = v.iter().sum();
        }
    }

    fn with_change(
        &self,
        p: &[f64],
        changed: usize,
        _points: &Points,
        _far: &FarOptions,
    ) -> Box<dyn ModelTerms> {
        let model = M::from_params(p);
        let factors = if M::LONGITUDINAL.contains(&changed) {
            Factors {
                n: self.factors.n.clone(),
                m: model.longitudinal_terms(&self.plan),
            }
        } else {
            Factors {
                n: model.azimuthal_terms(&self.plan),
                m: self.factors.m.clone(),
            }
        };
        Box::new(FactoredTerms::<M, L> {
            plan: self.plan.clone(),
            factors,
            params: p.to_vec(),
            model: PhantomData,
        })
    }

    fn jacobian(&self, _points: &Points) -> Option<ValueJacobian> {
        let model = M::from_params(&self.params);
        let (dn, dm) = rayon::join(
            || model.azimuthal_gradients(&self.plan),
            || model.longitudinal_gradients(&self.plan),
        );
        let (dn, dm) = (dn?, dm?);
        let k = self.params.len();
        let plan = &self.plan;
        let mut values = vec![0.0; plan.index.len()];
        let mut d = vec![0.0; plan.index.len() * k];
        for (i, &(s, f, pr)) in plan.index.iter().enumerate() {
            let (s, f, pr) = (s as usize, f as usize, pr as usize);
            let n = &self.factors.n[s][f];
            let m = &self.factors.m[pr];
            values[i] = (0..L).map(|p| m[p] * n[p]).sum();
            for j in 0..k {
                let (dn, dm) = (&dn[s][f * k + j], &dm[pr * k + j]);
                d[i * k + j] = (0..L).map(|p| dm[p] * n[p] + m[p] * dn[p]).sum();
            }
        }
        Some(ValueJacobian {
            values,
            n_params: k,
            d,
        })
    }

    fn capped_slices(&self) -> (usize, usize) {
        (0, self.plan.slices.len())
    }
}

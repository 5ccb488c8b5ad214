//! Goniometer points with the grid structures models find in them, kept between
//! evaluations (a fit evaluates the same points hundreds of times).

use super::{LobeSet, LobeValues, ModelTerms, ValueJacobian};
use crate::model::far::FarOptions;
use crate::synth::GridPlan;
use std::any::Any;
use std::collections::HashMap;
use std::marker::PhantomData;
use std::sync::{Arc, Mutex, OnceLock};

/// A model's grid structure of a point list, type-erased so each model keeps its own.
type Cached = Arc<dyn Any + Send + Sync>;

/// Goniometer points `(theta_i, theta_r, phi)` in radians, with the fur model's
/// [`GridPlan`] and any other model's plan found on first use and kept.
#[derive(Default)]
pub struct Points {
    pub pts: Vec<(f64, f64, f64)>,
    plan: OnceLock<Arc<GridPlan>>,
    plans: Mutex<Vec<(&'static str, Cached)>>,
}

impl Clone for Points {
    fn clone(&self) -> Self {
        Points {
            pts: self.pts.clone(),
            plan: self.plan.clone(),
            plans: Mutex::new(self.plans.lock().map(|p| p.clone()).unwrap_or_default()),
        }
    }
}

impl std::fmt::Debug for Points {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Points").field("pts", &self.pts).finish()
    }
}

impl PartialEq for Points {
    fn eq(&self, other: &Self) -> bool {
        self.pts == other.pts
    }
}

impl Points {
    /// Points from a list (radians).
    pub fn new(pts: Vec<(f64, f64, f64)>) -> Points {
        Points {
            pts,
            ..Points::default()
        }
    }

    pub fn len(&self) -> usize {
        self.pts.len()
    }

    pub fn is_empty(&self) -> bool {
        self.pts.is_empty()
    }

    pub fn push(&mut self, theta_i: f64, theta_r: f64, phi: f64) {
        self.pts.push((theta_i, theta_r, phi));
        self.plan = OnceLock::new();
        self.plans = Mutex::new(Vec::new());
    }

    /// The grid `theta_i x theta_r x phi` given in degrees ([`crate::synth::grid_points`]).
    pub fn grid_degrees(theta_i: &[f64], theta_r: &[f64], phi: &[f64]) -> Points {
        Points::new(
            crate::synth::grid_points(theta_i, theta_r, phi)
                .into_iter()
                .map(|(ti, tr, ph)| (ti.to_radians(), tr.to_radians(), ph.to_radians()))
                .collect(),
        )
    }

    /// The points at the given indices.
    pub fn subset(&self, idx: &[usize]) -> Points {
        Points::new(idx.iter().map(|&i| self.pts[i]).collect())
    }

    /// The fur model's grid structure of the points (built on first use).
    pub fn plan(&self) -> &GridPlan {
        self.plan.get_or_init(|| Arc::new(GridPlan::new(&self.pts)))
    }

    /// A model's own grid structure `T` of the points under `key` (the model's name),
    /// built by `build` on first use and kept.
    pub fn cached<T: Any + Send + Sync>(
        &self,
        key: &'static str,
        build: impl FnOnce(&[(f64, f64, f64)]) -> T,
    ) -> Arc<T> {
        let mut plans = self.plans.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, p)) = plans.iter().find(|(k, _)| *k == key) {
            if let Ok(t) = p.clone().downcast::<T>() {
                return t;
            }
        }
        let t = Arc::new(build(&self.pts));
        plans.retain(|(k, _)| *k != key);
        plans.push((key, t.clone()));
        t
    }
}

/// A point list's structure for a model whose prediction factors into an azimuthal term per
/// `(slice, |phi|)` and a longitudinal term per `(theta_i, theta_r)` pair: the distinct
/// slice coordinates (the model's `key(theta_i, theta_r)`: Chiang's `theta_o`, Marschner's
/// `|theta_d|`), each slice's distinct `|phi|` (both far fields are even in `phi`), the
/// distinct pairs, and each point's indices into them.
#[derive(Debug, Default)]
pub struct SlicePlan {
    pub slices: Vec<f64>,
    pub phis: Vec<Vec<f64>>,
    pub pairs: Vec<(f64, f64)>,
    /// Per point: (slice, phi within the slice, pair).
    pub index: Vec<(u32, u32, u32)>,
}

impl SlicePlan {
    /// The plan of `pts` (radians) with slices keyed by `key(theta_i, theta_r)`; keys are
    /// compared bit for bit (a rounding twin only costs one more slice).
    pub fn new(pts: &[(f64, f64, f64)], key: impl Fn(f64, f64) -> f64) -> SlicePlan {
        let mut plan = SlicePlan::default();
        let mut slice_of: HashMap<u64, u32> = HashMap::new();
        let mut phi_of: Vec<HashMap<u64, u32>> = Vec::new();
        let mut pair_of: HashMap<(u64, u64), u32> = HashMap::new();
        for &(ti, tr, ph) in pts {
            let k = key(ti, tr);
            let s = *slice_of.entry(k.to_bits()).or_insert_with(|| {
                plan.slices.push(k);
                plan.phis.push(Vec::new());
                phi_of.push(HashMap::new());
                (plan.slices.len() - 1) as u32
            });
            let a = ph.abs();
            let phis = &mut plan.phis[s as usize];
            let f = *phi_of[s as usize].entry(a.to_bits()).or_insert_with(|| {
                phis.push(a);
                (phis.len() - 1) as u32
            });
            let pr = *pair_of
                .entry((ti.to_bits(), tr.to_bits()))
                .or_insert_with(|| {
                    plan.pairs.push((ti, tr));
                    (plan.pairs.len() - 1) as u32
                });
            plan.index.push((s, f, pr));
        }
        plan
    }
}

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
    pub n: Vec<Vec<[f64; L]>>,
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
    pub plan: Arc<SlicePlan>,
    pub factors: Factors<L>,
    /// The parameters (internal units) the factors were computed at.
    params: Vec<f64>,
    model: PhantomData<fn() -> M>,
}

impl<M: Factored<L>, const L: usize> FactoredTerms<M, L> {
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cached_plans_are_built_once_and_dropped_on_push() {
        let mut p = Points::new(vec![(0.0, 0.1, 0.2)]);
        let calls = std::cell::Cell::new(0);
        let build = |pts: &[(f64, f64, f64)]| {
            calls.set(calls.get() + 1);
            pts.len()
        };
        assert_eq!(*p.cached("a", build), 1);
        assert_eq!(*p.cached("a", build), 1);
        assert_eq!(calls.get(), 1);
        p.push(0.0, 0.0, 0.0);
        assert_eq!(*p.cached("a", build), 2);
        assert_eq!(calls.get(), 2);
    }
}

//! Goniometer points with the grid structures models find in them, kept between
//! evaluations (a fit evaluates the same points hundreds of times).

use crate::model::grid_plan::GridPlan;
use std::any::Any;
use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

/// A model's grid structure of a point list, type-erased so each model keeps its own.
type Cached = Arc<dyn Any + Send + Sync>;

/// Goniometer points `(theta_i, theta_r, phi)` in radians, with the fur model's
/// [`GridPlan`] and any other model's plan found on first use and kept.
#[derive(Default)]
pub struct Points {
    /// The points `(theta_i, theta_r, phi)`, radians, in the order values are returned.
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

    /// Number of points.
    pub fn len(&self) -> usize {
        self.pts.len()
    }

    /// Whether there are no points.
    pub fn is_empty(&self) -> bool {
        self.pts.is_empty()
    }

    /// Append a point (radians); the cached plans are dropped, since they no longer cover
    /// the list.
    pub fn push(&mut self, theta_i: f64, theta_r: f64, phi: f64) {
        self.pts.push((theta_i, theta_r, phi));
        self.plan = OnceLock::new();
        self.plans = Mutex::new(Vec::new());
    }

    /// The grid `theta_i x theta_r x phi` given in degrees
    /// ([`crate::model::grid_plan::grid_points`]).
    pub fn grid_degrees(theta_i: &[f64], theta_r: &[f64], phi: &[f64]) -> Points {
        Points::new(
            crate::model::grid_plan::grid_points(theta_i, theta_r, phi)
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
    /// Distinct slice coordinates, in order of first appearance.
    pub slices: Vec<f64>,
    /// Per slice: its distinct `|phi|`, in order of first appearance.
    pub phis: Vec<Vec<f64>>,
    /// Distinct `(theta_i, theta_r)` pairs, the longitudinal terms' arguments.
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

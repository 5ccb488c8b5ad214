//! The forward model the fitter evaluates: the far-field value `sum_p M_p N_p` (MODEL.md
//! "What a goniometer sample predicts", before the exposure `k`) at a list of goniometer
//! points.
//!
//! All model evaluations of the fitter go through [`predict_points`]; it is the single
//! place that calls into the model, so the fitter never re-implements any physics.

use crate::model::far::FarOptions;
use crate::model::{FurModel, LobeSet, LobeValues};
use crate::params::FurParams;
use crate::params::ParamId;
use crate::synth::{GridPlan, ModelKind, PairTerms};
use std::sync::{Arc, OnceLock};

/// Parse `--segments N,M` (unscattered, scattered; or one `N` for both) into the paper's
/// fixed-segmentation far field ([`FarOptions::paper`] with those counts). The fitter uses a
/// fixed segmentation, not the tolerance-driven refinement, so the model is the same smooth
/// function of the parameters everywhere (finite-difference Jacobians see no refinement
/// switching).
pub fn parse_segments(s: &str) -> crate::Result<FarOptions> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let num = |t: &str| -> crate::Result<usize> {
        match t.parse::<usize>() {
            Ok(n) if (1..=4096).contains(&n) => Ok(n),
            _ => Err(crate::Error::Invalid(format!(
                "--segments: '{t}' is not a segment count in 1..=4096"
            ))),
        }
    };
    let (a, b) = match parts.as_slice() {
        [a] => (num(a)?, num(a)?),
        [a, b] => (num(a)?, num(b)?),
        _ => {
            return Err(crate::Error::Invalid(format!(
                "--segments: expected N or N,M, found '{s}'"
            )))
        }
    };
    Ok(FarOptions {
        n_unscattered: a,
        n_scattered: b,
        ..FarOptions::paper()
    })
}

/// Goniometer points `(theta_i, theta_r, phi)` in radians, with their grid structure
/// ([`GridPlan`]) found on first use and kept, since a fit evaluates the same points
/// hundreds of times.
#[derive(Clone, Debug, Default)]
pub struct Points {
    pub pts: Vec<(f64, f64, f64)>,
    plan: OnceLock<Arc<GridPlan>>,
}

impl PartialEq for Points {
    fn eq(&self, other: &Self) -> bool {
        self.pts == other.pts
    }
}

impl Points {
    pub fn len(&self) -> usize {
        self.pts.len()
    }

    pub fn is_empty(&self) -> bool {
        self.pts.is_empty()
    }

    pub fn push(&mut self, theta_i: f64, theta_r: f64, phi: f64) {
        self.pts.push((theta_i, theta_r, phi));
        self.plan = OnceLock::new();
    }

    /// The grid `theta_i x theta_r x phi` given in degrees ([`crate::synth::grid_points`]).
    pub fn grid_degrees(theta_i: &[f64], theta_r: &[f64], phi: &[f64]) -> Points {
        let mut p = Points::default();
        for (ti, tr, ph) in crate::synth::grid_points(theta_i, theta_r, phi) {
            p.push(ti.to_radians(), tr.to_radians(), ph.to_radians());
        }
        p
    }

    /// The points at the given indices.
    pub fn subset(&self, idx: &[usize]) -> Points {
        Points {
            pts: idx.iter().map(|&i| self.pts[i]).collect(),
            plan: OnceLock::new(),
        }
    }

    /// The grid structure of the points (built on first use).
    pub fn plan(&self) -> &GridPlan {
        self.plan.get_or_init(|| Arc::new(GridPlan::new(&self.pts)))
    }
}

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
}

impl ModelTerms {
    /// All terms at `params`.
    pub fn new(params: &FurParams, points: &Points, far: &FarOptions) -> ModelTerms {
        let model = FurModel::new(params);
        let plan = points.plan();
        ModelTerms {
            n: plan.azimuthal_terms(&model, LobeSet::ALL, ModelKind::Far, far),
            m: plan.longitudinal_terms(&model, LobeSet::ALL),
        }
    }

    /// The terms at `params`, which differ from the parameters of `self` only in
    /// `changed`: the azimuthal terms that cannot depend on `changed`
    /// ([`FurModel::azimuthal_dependence`]) are reused, the rest recomputed. Equal to
    /// [`ModelTerms::new`] at `params` (tested), at a fraction of the cost for `alpha`,
    /// `beta_m` and `g`.
    pub fn with_change(
        &self,
        params: &FurParams,
        changed: ParamId,
        points: &Points,
        far: &FarOptions,
    ) -> ModelTerms {
        let dep = FurModel::azimuthal_dependence(changed);
        if dep == LobeSet::ALL {
            return ModelTerms::new(params, points, far);
        }
        let model = FurModel::new(params);
        let plan = points.plan();
        let mut n = self.n.clone();
        if dep != LobeSet::NONE {
            let fresh = plan.azimuthal_terms(&model, dep, ModelKind::Far, far);
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
        }
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
